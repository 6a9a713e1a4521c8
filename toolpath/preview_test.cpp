// The PNG preview decodes, has the part's aspect ratio, and shows feed moves, rapids and gouges
// in their colours.
#include "toolpath/preview.hpp"

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

int count_colour(const cv::Mat& img, const cv::Vec3b& bgr, int tol) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      if (std::abs(p[0] - bgr[0]) <= tol && std::abs(p[1] - bgr[1]) <= tol && std::abs(p[2] - bgr[2]) <= tol) ++n;
    }
  }
  return n;
}

TEST(Preview, ShowsPassesRapidsAndGouges) {
  // The trough (radius 2.2 < R) gives gouges; one-way passes give rapids.
  const BSplineSurface s = test::trough_surface(2.2);
  ToolpathOptions o;
  o.scallop_mm = 0.2;
  o.chord_tol_mm = 0.05;
  o.pattern = Pattern::OneWay;
  const ToolpathResult r = generate_toolpath(s, o);
  ASSERT_GT(r.stats.gouge_points, 0u);
  PreviewOptions po;
  po.width_px = 600;
  const auto png = render_preview_png(s, r, po);
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(std::string(png.begin() + 1, png.begin() + 4), "PNG");
  const cv::Mat img = cv::imdecode(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 600);
  // 60 x 30 mm drawn 560 px wide: 280 px high plus margins and the legend line.
  EXPECT_NEAR(img.rows, 280 + 40 + 28, 2);
  EXPECT_GT(count_colour(img, {120, 40, 0}, 10), 500) << "feed moves";
  EXPECT_GT(count_colour(img, {40, 40, 220}, 10), 100) << "rapids";
  EXPECT_GT(count_colour(img, {220, 0, 220}, 10), 20) << "gouge marks";
}

TEST(Preview, NothingToDrawIsAGeometryError) {
  BSplineSurface s = test::cylinder_surface(0, true);
  for (auto& p : s.poles_mm) p.x() = 0, p.y() = 0;
  ToolpathResult empty;
  EXPECT_THROW(render_preview_png(s, empty), GeometryError);
}

}  // namespace
}  // namespace photomill::toolpath
