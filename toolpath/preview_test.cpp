// The PNG preview decodes, has the part's aspect ratio, and shows feed moves coloured by height
// (both ends of the scale), rapids, gouges, the start and end marks in their colours.
#include "toolpath/preview.hpp"

#include <vector>

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "formats/plot.hpp"
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
  const Eigen::Vector2i size = preview_size_px(60, 30, po);
  EXPECT_EQ(img.rows, size.y());
  // 60 x 30 mm: the plot keeps the aspect ratio, so the picture is less than twice as high as
  // the plot's width over 2 plus the room of the axes and legend.
  EXPECT_LT(img.rows, 600);
  const auto count = [&](const Eigen::Vector3i& c) { return count_colour(img, cv::Vec3b(c[0], c[1], c[2]), 10); };
  EXPECT_GT(count(kRapidBgr), 100) << "rapids";
  EXPECT_GT(count(kGougeBgr), 20) << "gouge marks";
  EXPECT_GT(count(kStartBgr), 60) << "start mark";
  EXPECT_GT(count(kEndBgr), 100) << "end mark";
}

// Feed moves are coloured by the tool tip's height: on the slanted plane z = 20 + 0.3 y the plot
// (left of the colour bar) holds pixels near the viridis colours of many heights, the lowest and
// the highest among them.
TEST(Preview, FeedMovesAreColouredByHeight) {
  const BSplineSurface s = test::cylinder_surface(0, true);
  ToolpathOptions o;
  o.scallop_mm = 0.2;
  o.chord_tol_mm = 0.05;
  const ToolpathResult r = generate_toolpath(s, o);
  PreviewOptions po;
  po.width_px = 600;
  const cv::Mat img = cv::imdecode(render_preview_png(s, r, po), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  const cv::Mat plot_area = img(cv::Rect(0, 0, img.cols - plot::kColourBarAreaPx - 10, img.rows));
  std::vector<int> bins(21, 0);
  for (int y = 0; y < plot_area.rows; ++y) {
    for (int x = 0; x < plot_area.cols; ++x) {
      const cv::Vec3b p = plot_area.at<cv::Vec3b>(y, x);
      for (int b = 0; b <= 20; ++b) {
        const cv::Scalar c = plot::viridis(b / 20.0);
        if (std::abs(p[0] - c[0]) + std::abs(p[1] - c[1]) + std::abs(p[2] - c[2]) < 30) {
          ++bins[static_cast<std::size_t>(b)];
          break;
        }
      }
    }
  }
  int heights = 0;
  for (int n : bins) heights += n >= 20;
  EXPECT_GE(heights, 12) << "feed moves in the colours of many heights";
  EXPECT_GE(bins.front() + bins[1], 20) << "the lowest feed moves";
  EXPECT_GE(bins.back() + bins[19], 20) << "the highest feed moves";
}

TEST(Preview, NothingToDrawIsAGeometryError) {
  BSplineSurface s = test::cylinder_surface(0, true);
  for (auto& p : s.poles_mm) p.x() = 0, p.y() = 0;
  ToolpathResult empty;
  EXPECT_THROW(render_preview_png(s, empty), GeometryError);
}

}  // namespace
}  // namespace photomill::toolpath
