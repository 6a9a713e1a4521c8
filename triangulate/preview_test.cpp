// triangulate's PNG preview (preview.hpp): it decodes, has the asked size, shows the points in
// colour in both views and the cameras, keeps framing the scene when a wild point or a far camera
// is added, keeps the cameras in the oblique view, ticks the top view's axes in mm, and refuses
// an empty cloud. The command-line side is in cli_test.cpp.
#include "triangulate/preview.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

// The truth of the test scene as make_point_cloud would write it: plate points are control
// points; reprojection RMS and sigma vary over the points.
PointCloud truth_cloud(const test::SceneTruth& truth) {
  PointCloud cloud;
  std::vector<double> rms, sigma, control;
  for (const auto* set : {&truth.plate_points, &truth.part_points}) {
    for (const ControlPoint& p : *set) {
      cloud.points_mm.push_back(p.xyz_mm);
      rms.push_back(0.01 + 0.0005 * static_cast<double>(cloud.points_mm.size() % 100));
      sigma.push_back(0.002 + 0.0001 * static_cast<double>(cloud.points_mm.size() % 50));
      control.push_back(set == &truth.plate_points ? 1 : 0);
    }
  }
  cloud.properties = {{"reproj_rms_px", PlyScalar::Float32, rms},
                      {"sigma_mm", PlyScalar::Float64, sigma},
                      {"control", PlyScalar::UInt8, control}};
  return cloud;
}

cv::Mat decode(const std::vector<std::uint8_t>& png) { return cv::imdecode(png, cv::IMREAD_COLOR); }

// The two view panels of a preview `width_px` wide: left of the colour bar, above the text.
cv::Rect panel_rect(int width_px, int k) { return {k * ((width_px - 120) / 2), 0, (width_px - 120) / 2, width_px / 2 - 48}; }
cv::Rect panels_rect(int width_px) { return {0, 0, 2 * ((width_px - 120) / 2), width_px / 2 - 48}; }

// Pixels of a clearly saturated colour (the points' viridis colours, the axes, the frusta's top
// edges) in a region.
int coloured_in(const cv::Mat& img, const cv::Rect& r) {
  int n = 0;
  for (int y = r.y; y < r.y + r.height; ++y) {
    for (int x = r.x; x < r.x + r.width; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      n += std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]}) > 60 ? 1 : 0;
    }
  }
  return n;
}

// Dark pixels (camera frusta and labels, text, axes) in one panel.
int dark_in(const cv::Mat& img, const cv::Rect& r) {
  int n = 0;
  for (int y = r.y; y < r.y + r.height; ++y) {
    for (int x = r.x; x < r.x + r.width; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      n += c[0] < 80 && c[1] < 80 && c[2] < 80 ? 1 : 0;
    }
  }
  return n;
}

struct PreviewCase {
  const char* colour_by;
  int width_px;
};
void PrintTo(const PreviewCase& c, std::ostream* os) { *os << c.colour_by << "_" << c.width_px; }

class Preview : public ::testing::TestWithParam<PreviewCase> {};

TEST_P(Preview, ShowsPointsAndCameras) {
  const test::SceneTruth truth = test::make_scene({});
  const PointCloud cloud = truth_cloud(truth);
  PreviewOptions o;
  o.colour_by = GetParam().colour_by;
  o.width_px = GetParam().width_px;

  const cv::Mat img = decode(render_preview_png(cloud, truth.poses, truth.camera, o));
  ASSERT_FALSE(img.empty()) << "not a PNG OpenCV can read";
  EXPECT_EQ(img.cols, o.width_px);
  EXPECT_EQ(img.rows, o.width_px / 2);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img, mean, stddev);
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 30) << "blank picture";

  // Points in colour in each of the two panels (the axes triad alone is ~200 px).
  const cv::Mat bare = decode(render_preview_png(cloud, {}, truth.camera, o));
  for (int k = 0; k < 2; ++k) {
    EXPECT_GT(coloured_in(bare, panel_rect(o.width_px, k)), 1000 * o.width_px / 1600) << "panel " << k;
  }
  // The cameras add dark frustum lines to the oblique view (the top view is framed on the points).
  const cv::Rect oblique = panel_rect(o.width_px, 0);
  EXPECT_GT(dark_in(img, oblique), dark_in(bare, oblique) + 500) << "no camera drawn";
  // Issue 27: the frusta stay in their own panel: the top view, its axes and the colour bar are
  // the same pixels with or without the cameras.
  const cv::Rect rest(panel_rect(o.width_px, 1).x, 0, o.width_px - panel_rect(o.width_px, 1).x, panel_rect(o.width_px, 1).height);
  EXPECT_EQ(cv::norm(img(rest), bare(rest), cv::NORM_L1), 0) << "a camera drawn outside the oblique view";
  // The top view has x and y axes ticked in mm: dark tick numbers left of and below its plot.
  const cv::Rect top = panel_rect(o.width_px, 1);
  // (Ink: any pixel darker than the panel's ground; no point is drawn outside the plot.)
  const auto ink_in = [&](const cv::Rect& r) {
    int n = 0;
    for (int y = r.y; y < r.y + r.height; ++y) {
      for (int x = r.x; x < r.x + r.width; ++x) n += std::max({bare.at<cv::Vec3b>(y, x)[0], bare.at<cv::Vec3b>(y, x)[1], bare.at<cv::Vec3b>(y, x)[2]}) < 200;
    }
    return n;
  };
  EXPECT_GT(ink_in(cv::Rect(top.x + 2, top.y + 60, 60, top.height - 120)), 25) << "y axis numbers";
  EXPECT_GT(ink_in(cv::Rect(top.x + 80, top.y + top.height - 38, top.width - 100, 34)), 25) << "x axis numbers";
}

INSTANTIATE_TEST_SUITE_P(Triangulate, Preview,
                         ::testing::Values(PreviewCase{"rms", 1600}, PreviewCase{"sigma", 1600}, PreviewCase{"rms", 800}));

// One wild point far away and one camera far away must not shrink the scene to a dot: the
// framing follows the bulk of the points and the cameras near them.
TEST(Preview, FramesTheSceneRobustly) {
  const test::SceneTruth truth = test::make_scene({});
  const PointCloud cloud = truth_cloud(truth);
  const cv::Rect panels = panels_rect(PreviewOptions{}.width_px);
  const int base = coloured_in(decode(render_preview_png(cloud, {}, truth.camera)), panels);

  PointCloud wild = cloud;
  wild.points_mm.emplace_back(1e5, -2e5, 3e4);
  for (auto& p : wild.properties) p.values.push_back(p.values.back());
  std::vector<Pose> far = {truth.poses.front()};
  far.front().cam_from_world_translation_mm = Eigen::Vector3d(0, 0, 1e6);
  const int with_wild = coloured_in(decode(render_preview_png(wild, far, truth.camera)), panels);
  EXPECT_GT(with_wild, base * 8 / 10) << "coloured pixels " << with_wild << " against " << base;
  EXPECT_LT(with_wild, base * 12 / 10) << "coloured pixels " << with_wild << " against " << base;
}

// A cloud without a datum (units arbitrary): the legend says so and the axes, scale bar and
// colour bar say "units", not mm; the points are drawn alike.
TEST(Preview, SaysWhenTheScaleIsArbitrary) {
  const test::SceneTruth truth = test::make_scene({});
  PointCloud cloud = truth_cloud(truth);
  const cv::Mat mm = decode(render_preview_png(cloud, truth.poses, truth.camera));
  cloud.units = "arbitrary";
  const cv::Mat arbitrary = decode(render_preview_png(cloud, truth.poses, truth.camera));
  ASSERT_EQ(mm.size(), arbitrary.size());
  cv::Mat diff;
  cv::absdiff(mm, arbitrary, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  const int legend_top = mm.rows - 48;  // the two lines of text under the panels
  EXPECT_GT(cv::countNonZero(diff.rowRange(legend_top, mm.rows)), 200) << "the legend names the arbitrary scale";
  EXPECT_GT(cv::countNonZero(diff.rowRange(0, legend_top)), 0) << "axes, scale bar and colour bar in units";
}

// Several cameras: each frustum by its own camera. One pose's camera with half the focal length
// (a wider frustum) changes the drawing; a camera per pose that are all alike does not; another
// number of cameras than poses is refused.
TEST(Preview, DrawsEachFrustumWithItsOwnCamera) {
  const test::SceneTruth truth = test::make_scene({});
  const PointCloud cloud = truth_cloud(truth);
  const cv::Mat one = decode(render_preview_png(cloud, truth.poses, truth.camera));
  std::vector<Camera> each(truth.poses.size(), truth.camera);
  const cv::Mat alike = decode(render_preview_png(cloud, truth.poses, each));
  each[0].camera_matrix(0, 0) *= 0.5;
  each[0].camera_matrix(1, 1) *= 0.5;
  const cv::Mat wide = decode(render_preview_png(cloud, truth.poses, each));
  cv::Mat diff;
  cv::absdiff(one, alike, diff);
  EXPECT_EQ(cv::countNonZero(diff.reshape(1)), 0);
  cv::absdiff(one, wide, diff);
  EXPECT_GT(cv::countNonZero(diff.reshape(1)), 50) << "the first frustum is drawn wider";
  each.pop_back();
  EXPECT_THROW(render_preview_png(cloud, truth.poses, each), UsageError);
}

TEST(Preview, RefusesAnEmptyCloud) {
  const test::SceneTruth truth = test::make_scene({});
  EXPECT_THROW(render_preview_png(PointCloud{}, truth.poses, truth.camera), GeometryError);
}

TEST(Preview, RejectsBadOptions) {
  PreviewOptions o;
  o.colour_by = "views";
  EXPECT_THROW(validate(o), UsageError);
  o = {};
  o.width_px = 100;
  EXPECT_THROW(validate(o), UsageError);
}

}  // namespace
}  // namespace photomill::triangulate
