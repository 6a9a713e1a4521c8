// ArUco markers against truth: the edge fit on exactly rendered quadrilaterals, detect_markers on
// synth scenes (corner RMS against the true projections, OpenCV's own refinement on the same
// images for comparison, no wrong ids), OpenCV's tutorial photos with their gold corners, custom
// dictionary files, rejected markers, and golden CLI cases for detect's marker and feature modes.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "detect/gold_corners.hpp"
#include "detect/markers.hpp"
#include "detect/photo_cli.hpp"
#include "formats/error.hpp"
#include "formats/features.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"
#include "tools/synth/dataset.hpp"
#include "tools/synth/test_scene.hpp"

namespace photomill::detect {
namespace {

const std::string kAruco = std::string(PHOTOMILL_SHARED_DIR) + "/data/opencv-aruco/";

// ---------------------------------------------------------------------------------------------
// The edge fit on a quadrilateral rendered exactly: a black polygon on white, 16 x 16 samples per
// pixel (pixel x covers [x - 1/2, x + 1/2]), blurred.

struct EdgeCase {
  double angle_deg;
  double blur_px;     // Gaussian sigma, 0: none (box-filtered pixels only)
  double perspective; // corner displacement, fraction of the side
  int degree;
};

void PrintTo(const EdgeCase& c, std::ostream* os) {
  *os << "angle " << c.angle_deg << " deg, blur " << c.blur_px << " px, perspective " << c.perspective << ", degree "
      << c.degree;
}

cv::Mat render_quad(const std::array<Eigen::Vector2d, 4>& q, cv::Size size, double blur_px) {
  // 16 x 16 samples per pixel at u = x + (a + 1/2)/16 - 1/2; a sample is black if it lies inside
  // the (convex, clockwise on screen) quadrilateral.
  const int ss = 16;
  cv::Mat out(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      int inside = 0;
      for (int b = 0; b < ss; ++b) {
        for (int a = 0; a < ss; ++a) {
          const Eigen::Vector2d p(x + (a + 0.5) / ss - 0.5, y + (b + 0.5) / ss - 0.5);
          bool in = true;
          for (int k = 0; k < 4 && in; ++k) {
            const Eigen::Vector2d e = q[(k + 1) % 4] - q[k], r = p - q[k];
            in = e.x() * r.y() - e.y() * r.x() >= 0;
          }
          inside += in ? 1 : 0;
        }
      }
      out.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(220 - 190.0 * inside / (ss * ss));
    }
  }
  if (blur_px > 0) cv::GaussianBlur(out, out, cv::Size(0, 0), blur_px);
  return out;
}

class EdgeFitOnRenderedQuads : public ::testing::TestWithParam<EdgeCase> {};

TEST_P(EdgeFitOnRenderedQuads, CornersWithinTwoHundredthsOfAPixel) {
  const EdgeCase c = GetParam();
  // Through int: a negative double converted to unsigned is undefined (clang's UBSan stops on it).
  std::mt19937 rng(static_cast<unsigned>(static_cast<int>(c.angle_deg * 10 + c.blur_px * 100)));
  std::uniform_real_distribution<double> u(-1, 1);
  const double a = c.angle_deg * M_PI / 180, side = 60;
  const Eigen::Vector2d centre(100.3, 95.7);
  std::array<Eigen::Vector2d, 4> truth;
  const std::array<Eigen::Vector2d, 4> unit{Eigen::Vector2d(-1, -1), {1, -1}, {1, 1}, {-1, 1}};
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d p = unit[k] * side / 2 + Eigen::Vector2d(u(rng), u(rng)) * c.perspective * side;
    truth[k] = centre + Eigen::Vector2d(std::cos(a) * p.x() - std::sin(a) * p.y(), std::sin(a) * p.x() + std::cos(a) * p.y());
  }
  const cv::Mat image = render_quad(truth, cv::Size(200, 190), c.blur_px);
  std::array<Eigen::Vector2d, 4> start;
  for (int k = 0; k < 4; ++k) start[k] = truth[k] + Eigen::Vector2d(u(rng), u(rng)) * 0.8;  // OpenCV's polygon is ~1 px off
  EdgeFitOptions o;
  o.degree = c.degree;
  const EdgeFit fit = refine_marker_corners(image, start, 6, o);
  ASSERT_TRUE(fit.ok) << fit.failure;
  for (int k = 0; k < 4; ++k) EXPECT_LT((fit.corners[k] - truth[k]).norm(), 0.02) << "corner " << k;
  EXPECT_NEAR(fit.contrast, 190, 10);
  if (c.blur_px >= 0.8) {
    EXPECT_NEAR(fit.blur_px, c.blur_px, 0.25 * c.blur_px);
  }
}

INSTANTIATE_TEST_SUITE_P(Quads, EdgeFitOnRenderedQuads,
                         ::testing::Values(EdgeCase{0, 0, 0, 3}, EdgeCase{17, 0, 0.05, 3}, EdgeCase{33, 0.8, 0.1, 3},
                                           EdgeCase{71, 1.5, 0.1, 3}, EdgeCase{45, 0.5, 0.08, 1},
                                           EdgeCase{-28, 1.0, 0.12, 2}));

// The quick start (markers.hpp: cells of 6 px or more, here 10) takes the fine pass from the
// coarse one's curves in one round; on these renders it must find the corners the full fit finds
// (both within 0.02 px of the truth, within 0.005 px of each other). Its speed is measured by
// tools/detect_marker_bench, not here.
TEST(EdgeFit, QuickStartFindsTheCornersOfTheFullFit) {
  for (const EdgeCase& c : {EdgeCase{0, 0, 0, 3}, EdgeCase{17, 0.4, 0.05, 3}, EdgeCase{33, 0.8, 0.1, 3},
                            EdgeCase{-28, 1.0, 0.12, 2}, EdgeCase{64, 1.5, 0.1, 3}}) {
    std::mt19937 rng(static_cast<unsigned>(static_cast<int>(c.angle_deg * 10 + c.blur_px * 100 + 3)));
    std::uniform_real_distribution<double> u(-1, 1);
    const double a = c.angle_deg * M_PI / 180, side = 60;
    const Eigen::Vector2d centre(100.3, 95.7);
    std::array<Eigen::Vector2d, 4> truth, start;
    const std::array<Eigen::Vector2d, 4> unit{Eigen::Vector2d(-1, -1), {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d p = unit[k] * side / 2 + Eigen::Vector2d(u(rng), u(rng)) * c.perspective * side;
      truth[k] = centre + Eigen::Vector2d(std::cos(a) * p.x() - std::sin(a) * p.y(), std::sin(a) * p.x() + std::cos(a) * p.y());
      start[k] = truth[k] + Eigen::Vector2d(u(rng), u(rng)) * 0.8;
    }
    const cv::Mat image = render_quad(truth, cv::Size(200, 190), c.blur_px);
    EdgeFitOptions quick, full;
    quick.degree = full.degree = c.degree;
    full.quick_start_min_cell_px = 1000;
    const EdgeFit q = refine_marker_corners(image, start, 6, quick);
    const EdgeFit f = refine_marker_corners(image, start, 6, full);
    ASSERT_TRUE(q.ok) << q.failure;
    ASSERT_TRUE(f.ok) << f.failure;
    for (int k = 0; k < 4; ++k) {
      EXPECT_LT((q.corners[k] - truth[k]).norm(), 0.02) << ::testing::PrintToString(c) << ", corner " << k;
      EXPECT_LT((f.corners[k] - truth[k]).norm(), 0.02) << ::testing::PrintToString(c) << ", corner " << k;
      EXPECT_LT((q.corners[k] - f.corners[k]).norm(), 0.005) << ::testing::PrintToString(c) << ", corner " << k;
    }
  }
}

// Unblurred renders: the model's sigma runs to its lower bound (0.05 px), where a step that would
// take it below holds it on the bound and solves the other parameters (an active bound). The
// corners must stay exact there. (The iterations are printed, not bounded: GCC's build took 31-35
// for the 12 edge fits of each render, 45-80 without the active bound, but clang's sanitizer build
// took 58 at 0 degrees with it, unexplained so far.)
TEST(EdgeFit, SharpEdgesAreFittedWithTheBlurOnItsLowerBound) {
  for (const double angle_deg : {0.0, 17.0, 41.0}) {
    std::mt19937 rng(static_cast<unsigned>(angle_deg * 10 + 7));
    std::uniform_real_distribution<double> u(-1, 1);
    const double a = angle_deg * M_PI / 180, side = 60;
    const Eigen::Vector2d centre(100.3, 95.7);
    std::array<Eigen::Vector2d, 4> truth, start;
    const std::array<Eigen::Vector2d, 4> unit{Eigen::Vector2d(-1, -1), {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d p = unit[k] * side / 2 + Eigen::Vector2d(u(rng), u(rng)) * 0.05 * side;
      truth[k] = centre + Eigen::Vector2d(std::cos(a) * p.x() - std::sin(a) * p.y(), std::sin(a) * p.x() + std::cos(a) * p.y());
      start[k] = truth[k] + Eigen::Vector2d(u(rng), u(rng)) * 0.8;
    }
    const cv::Mat image = render_quad(truth, cv::Size(200, 190), 0);
    const EdgeFit fit = refine_marker_corners(image, start, 6, EdgeFitOptions{});
    ASSERT_TRUE(fit.ok) << fit.failure;
    for (int k = 0; k < 4; ++k) EXPECT_LT((fit.corners[k] - truth[k]).norm(), 0.02) << angle_deg << " deg, corner " << k;
    EXPECT_LT(fit.blur_px, 0.06) << angle_deg << " deg";
    EXPECT_GT(fit.iterations, 0) << angle_deg << " deg";
    std::cerr << "[ detect   ] unblurred quad at " << angle_deg << " deg: " << fit.iterations
              << " Levenberg-Marquardt iterations over the 12 edge fits, mean blur " << fit.blur_px << " px\n";
  }
}

TEST(EdgeFit, FailsWithAReasonOnAFlatImage) {
  const cv::Mat flat(100, 100, CV_8UC1, cv::Scalar(128));
  const EdgeFit fit = refine_marker_corners(flat, {Eigen::Vector2d(20, 20), {80, 20}, {80, 80}, {20, 80}}, 6, {});
  EXPECT_FALSE(fit.ok);
  EXPECT_FALSE(fit.failure.empty());
}

// Corner errors against the truth, in px.
struct CornerErrors {
  double sum_sq = 0, max = 0;
  std::size_t count = 0, wrong_ids = 0, markers = 0;
  void add(double e) {
    sum_sq += e * e;
    max = std::max(max, e);
    ++count;
  }
  double rms() const { return count ? std::sqrt(sum_sq / static_cast<double>(count)) : 0; }
};

// ---------------------------------------------------------------------------------------------
// Small, blurred ArUco markers with their code (the size of OpenCV's tutorial photos' markers:
// 3-4.5 px per cell). The black border is one cell wide, so the band across an edge reaches the
// border's inner edge, where a white code cell lifts the border's dark side. Rendered 16x
// oversampled (the marker drawn by OpenCV, warped by a homography), blurred, box-filtered down.

struct SmallMarker {
  cv::Mat image;
  std::array<Eigen::Vector2d, 4> truth;  // the black square's corners TL TR BR BL, px
};

// The marker with its corners at `truth` (TL TR BR BL, px) in a size x size image.
SmallMarker render_marker_at(const MarkerDictionary& dictionary, int id, const std::array<Eigen::Vector2d, 4>& truth,
                             int size, double blur_px, double noise, std::mt19937& rng) {
  const int cells = dictionary.bits_per_side() + 2, ss = 16;
  SmallMarker out;
  out.truth = truth;
  std::vector<cv::Point2f> from, to;
  const int marker_px = cells * 40;
  cv::Mat marker;
  cv::aruco::drawMarker(cv::Ptr<cv::aruco::Dictionary>(dictionary.opencv()), id, marker_px, marker, 1);
  const std::array<cv::Point2f, 4> marker_corners{cv::Point2f(-0.5f, -0.5f), {marker_px - 0.5f, -0.5f},
                                                  {marker_px - 0.5f, marker_px - 0.5f}, {-0.5f, marker_px - 0.5f}};
  for (int k = 0; k < 4; ++k) {
    // Low-resolution pixel x (centre at x) covers high-resolution pixels 16x .. 16x + 15.
    from.push_back(marker_corners[k]);
    to.emplace_back(static_cast<float>((truth[k].x() + 0.5) * ss - 0.5), static_cast<float>((truth[k].y() + 0.5) * ss - 0.5));
  }
  cv::Mat fine;
  cv::warpPerspective(marker, fine, cv::getPerspectiveTransform(from, to), cv::Size(size * ss, size * ss), cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT, cv::Scalar(255));
  fine.convertTo(fine, CV_32F, 190.0 / 255, 30);
  cv::GaussianBlur(fine, fine, cv::Size(0, 0), blur_px * ss);
  cv::resize(fine, fine, cv::Size(size, size), 0, 0, cv::INTER_AREA);
  std::normal_distribution<double> n(0, noise);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) fine.at<float>(y, x) += static_cast<float>(n(rng));
  }
  fine.convertTo(out.image, CV_8U);
  return out;
}

SmallMarker render_small_marker(const MarkerDictionary& dictionary, int id, double px_per_cell, double blur_px,
                                double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const int cells = dictionary.bits_per_side() + 2;
  const double side = px_per_cell * cells, a = u(rng) * M_PI;
  const int size = static_cast<int>(std::ceil(side * 1.6)) + 12;
  const Eigen::Vector2d centre(size / 2.0 + 0.37 * u(rng), size / 2.0 + 0.37 * u(rng));
  const std::array<Eigen::Vector2d, 4> unit{Eigen::Vector2d(-1, -1), {1, -1}, {1, 1}, {-1, 1}};
  std::array<Eigen::Vector2d, 4> truth;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d p = unit[k] * side / 2 + Eigen::Vector2d(u(rng), u(rng)) * 0.08 * side;
    truth[k] = centre + Eigen::Vector2d(std::cos(a) * p.x() - std::sin(a) * p.y(), std::sin(a) * p.x() + std::cos(a) * p.y());
  }
  return render_marker_at(dictionary, id, truth, size, blur_px, noise, rng);
}

TEST(EdgeFit, TheCodeCellsInsideTheBorderKeepSmallMarkersCornersWhereTheyAre) {
  const auto dictionary = MarkerDictionary::predefined("DICT_6X6_250");
  const int cells = dictionary.bits_per_side() + 2;
  std::mt19937 rng(20261206);
  std::normal_distribution<double> start_error(0, 0.5);
  CornerErrors with_code, without_code;
  int refused_with = 0, refused_without = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const double px_per_cell = 3 + 0.0625 * trial, blur_px = 0.6 + 0.025 * trial;
    const int id = (trial * 37) % 250;
    const SmallMarker m = render_small_marker(dictionary, id, px_per_cell, blur_px, 2, rng);
    std::array<Eigen::Vector2d, 4> start;
    for (int k = 0; k < 4; ++k) start[k] = m.truth[k] + Eigen::Vector2d(start_error(rng), start_error(rng));
    const EdgeFit fit = refine_marker_corners(m.image, start, cells, EdgeFitOptions{}, dictionary.code(id));
    const EdgeFit plain = refine_marker_corners(m.image, start, cells, EdgeFitOptions{});
    if (fit.ok) {
      for (int k = 0; k < 4; ++k) with_code.add((fit.corners[k] - m.truth[k]).norm());
    } else {
      ++refused_with;
    }
    if (plain.ok) {
      for (int k = 0; k < 4; ++k) without_code.add((plain.corners[k] - m.truth[k]).norm());
    } else {
      ++refused_without;
    }
  }
  std::cerr << "[ detect   ] 24 markers of 3-4.4 px per cell, blur 0.6-1.2 px: with the code corners RMS "
            << with_code.rms() << " px (max " << with_code.max << "), " << refused_with << " refused; without "
            << without_code.rms() << " px (max " << without_code.max << "), " << refused_without << " refused\n";
  EXPECT_EQ(refused_with, 0);
  EXPECT_LT(with_code.rms(), 0.05);
  EXPECT_LT(3 * with_code.rms(), without_code.rms());
}

// A marker seen at a grazing angle: a sharp parallelogram whose sides meet at 30-40 degrees, 7-9 px
// per cell along its long sides and 4-5 px along its short ones (a 10 mm marker on a part's flank,
// as on the demo's part_08). Across a long side the border is only short side x sin(angle) / cells
// wide, 2-3 px: the band must stay inside it. Sized by the short side's length instead, the band
// reached into the code cells and these corners were 0.059 px RMS, up to 0.34 px off.
TEST(EdgeFit, AGrazingMarkersBandStaysInsideItsThinBorder) {
  const auto dictionary = MarkerDictionary::predefined("DICT_4X4_100");
  const int cells = dictionary.bits_per_side() + 2;
  std::mt19937 rng(20261207);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> start_error(0, 0.3);
  CornerErrors errors;
  int refused = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const double angle = (35 + 5 * u(rng)) * M_PI / 180, long_px = (8 + u(rng)) * cells, short_px = (4.5 + 0.5 * u(rng)) * cells;
    const double turn = u(rng) * M_PI;
    const Eigen::Vector2d along(std::cos(turn), std::sin(turn));
    const Eigen::Vector2d side(std::cos(turn + angle), std::sin(turn + angle));
    const int size = static_cast<int>(std::ceil(long_px + short_px)) + 24;
    const Eigen::Vector2d centre(size / 2.0 + 0.37 * u(rng), size / 2.0 + 0.37 * u(rng));
    const Eigen::Vector2d tl = centre - 0.5 * (long_px * along + short_px * side);
    const std::array<Eigen::Vector2d, 4> truth{tl, tl + long_px * along, tl + long_px * along + short_px * side,
                                               tl + short_px * side};
    const int id = (trial * 13) % 100;
    const SmallMarker m = render_marker_at(dictionary, id, truth, size, 0.1, 2, rng);
    std::array<Eigen::Vector2d, 4> start;
    for (int k = 0; k < 4; ++k) start[k] = m.truth[k] + Eigen::Vector2d(start_error(rng), start_error(rng));
    const EdgeFit fit = refine_marker_corners(m.image, start, cells, EdgeFitOptions{}, dictionary.code(id));
    if (!fit.ok) {
      ++refused;
      continue;
    }
    for (int k = 0; k < 4; ++k) errors.add((fit.corners[k] - m.truth[k]).norm());
  }
  std::cerr << "[ detect   ] 24 markers at 30-40 degrees, 4-9 px per cell: corners RMS " << errors.rms() << " px (max "
            << errors.max << "), " << refused << " refused\n";
  EXPECT_EQ(refused, 0);
  EXPECT_LT(errors.rms(), 0.04);
  EXPECT_LT(errors.max, 0.15);
}

// The demo's twelve photos against synth's true projections (issue #30's bound: 0.03 px RMS). Its
// worst marker is a grazing one on the part (part_08, id 15, sides at 43 degrees), 0.31 px off
// before the border's width across an edge took the angle into account.
TEST(DemoPhotos, MarkerCornersWithinThreeHundredthsOfAPixel) {
  const std::string demo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";
  std::map<std::pair<std::string, PointId>, Eigen::Vector2d> truth;
  std::ifstream truth_file(demo + "observations.csv");
  for (const Observation& ob : read_observations(truth_file, demo + "observations.csv")) {
    truth[{ob.image, ob.point_id}] = {ob.u_px, ob.v_px};
  }
  const MarkerDictionary dict = MarkerDictionary::predefined("DICT_4X4_100");
  CornerErrors errors;
  for (int k = 0; k < 12; ++k) {
    const std::string name = "part_" + std::string(k < 10 ? "0" : "") + std::to_string(k) + ".jpg";
    const cv::Mat grey = cv::imread(demo + name, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << name;
    const MarkerDetection d = detect_markers(grey, name, dict, MarkerDetectOptions{});
    for (const Observation& ob : d.observations()) {
      const auto it = truth.find({name, ob.point_id});
      if (it == truth.end()) {
        ++errors.wrong_ids;
        continue;
      }
      errors.add((Eigen::Vector2d(ob.u_px, ob.v_px) - it->second).norm());
    }
  }
  std::cout << "[ detect   ] demo: " << errors.count << " corners, RMS " << errors.rms() << " px, max " << errors.max
            << " px\n";
  EXPECT_EQ(errors.wrong_ids, 0u);
  EXPECT_GE(errors.count, 850u);
  EXPECT_LE(errors.rms(), 0.03);
  EXPECT_LE(errors.max, 0.2);
}

// ---------------------------------------------------------------------------------------------
// Synth scenes: the part on its plate with plate markers (24 mm) and part markers (10 mm), seen
// from the default ring of views, rendered at 1000 x 750.

struct SceneCase {
  std::string name;
  double noise_sigma;   // grey levels
  int jpeg_quality;     // 0: no JPEG round trip
  std::uint64_t seed;
};

void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.name; }

class MarkersOnSynth : public ::testing::TestWithParam<SceneCase> {};

TEST_P(MarkersOnSynth, EdgeFitBeatsOpenCVsRefinementThreefoldAndStaysUnderFiveHundredths) {
  const SceneCase c = GetParam();
  synth::SynthOptions o = synth::test::small_options();
  o.camera = synth::test::small_camera(1000, 750, 1200);
  o.views.count = 4;
  o.seed = c.seed;
  o.render.noise_sigma = c.noise_sigma;
  const synth::PartScene scene = synth::make_part_scene(o);
  const synth::PartRayScene rays(scene);
  const MarkerDictionary dict = MarkerDictionary::predefined(scene.dictionary);
  MarkerDetectOptions edges, subpix;
  subpix.refinement = CornerRefinement::Subpix;
  CornerErrors ours, opencv;
  std::size_t truth_plate_markers = 0, found_plate_markers = 0;
  std::map<int, bool> on_part;
  for (const auto& m : scene.markers) on_part[m.id] = m.on_part;
  int view = 0;
  for (const Pose& pose : synth::part_view_poses(o)) {
    cv::Mat image = synth::render(rays, o.camera, pose, o.render, static_cast<std::uint64_t>(view++));
    if (c.jpeg_quality > 0) image = cv::imdecode(synth::encode_image(image, "jpg", c.jpeg_quality), cv::IMREAD_GRAYSCALE);
    std::map<PointId, Eigen::Vector2d> truth;
    for (const Observation& ob : synth::marker_observations(rays, o.camera, pose)) truth[ob.point_id] = {ob.u_px, ob.v_px};
    for (const auto& m : scene.markers) {
      bool all = !m.on_part;
      for (int k = 0; k < 4; ++k) all = all && truth.count(static_cast<PointId>(m.id) * 4 + k);
      truth_plate_markers += all ? 1 : 0;
    }
    for (auto [options, errors] : {std::pair{&edges, &ours}, std::pair{&subpix, &opencv}}) {
      const MarkerDetection d = detect_markers(image, pose.image, dict, *options);
      errors->markers += d.marker_ids.size();
      for (const Observation& ob : d.observations()) {
        const auto it = truth.find(ob.point_id);
        if (it == truth.end()) {
          ++errors->wrong_ids;
          continue;
        }
        errors->add((Eigen::Vector2d(ob.u_px, ob.v_px) - it->second).norm());
      }
      if (options == &edges) {
        for (int id : d.marker_ids) found_plate_markers += on_part[id] ? 0 : 1;
        for (const auto& r : d.rejected) {
          std::cout << "[ detect   ] " << pose.image << ": rejected " << r.marker_id << ": " << r.reason << "\n";
        }
      }
    }
  }
  std::cout << "[ detect   ] " << c.name << ": edge fit " << ours.count << " corners, RMS " << ours.rms() << " px, max "
            << ours.max << " px; OpenCV CORNER_REFINE_SUBPIX " << opencv.count << " corners, RMS " << opencv.rms()
            << " px, max " << opencv.max << " px; ratio " << opencv.rms() / ours.rms() << "\n";
  EXPECT_EQ(ours.wrong_ids, 0u);
  EXPECT_EQ(opencv.wrong_ids, 0u);
  EXPECT_GE(found_plate_markers * 10, truth_plate_markers * 9);
  ASSERT_GE(ours.count * 10, opencv.count * 9) << "the edge fit rejected too many markers";
  EXPECT_LE(ours.rms(), 0.05);
  EXPECT_GE(opencv.rms(), 3 * ours.rms());
}

INSTANTIATE_TEST_SUITE_P(Scenes, MarkersOnSynth,
                         ::testing::Values(SceneCase{"noise 0, lossless", 0, 0, 7},
                                           SceneCase{"noise 1, JPEG 90 (synth's default quality)", 1, 90, 11}),
                         [](const auto& info) { return "Case" + std::to_string(info.index); });

// ---------------------------------------------------------------------------------------------
// OpenCV's tutorial photos (../shared/data/README.md) and the gold corners of OpenCV's tests.

struct Gold {
  std::map<int, std::array<Eigen::Vector2d, 4>> corners;
};

Gold read_gold(const std::string& image) { return {read_gold_corners(kAruco + "gold_corners.txt", image)}; }

// Mean outward offset of the 50 % grey-level crossing from the gold marker edges (mid-edges).
double crossing_offset_from_gold(const cv::Mat& grey, const Gold& gold) {
  auto sample = [&](double x, double y) {
    const int i = static_cast<int>(std::floor(x)), j = static_cast<int>(std::floor(y));
    const double fx = x - i, fy = y - j;
    auto at = [&](int r, int c) { return static_cast<double>(grey.at<std::uint8_t>(r, c)); };
    return (1 - fy) * ((1 - fx) * at(j, i) + fx * at(j, i + 1)) + fy * ((1 - fx) * at(j + 1, i) + fx * at(j + 1, i + 1));
  };
  double sum = 0;
  int n = 0;
  for (const auto& [id, q] : gold.corners) {
    const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    for (int e = 0; e < 4; ++e) {
      const Eigen::Vector2d a = q[e], b = q[(e + 1) % 4], d = (b - a).normalized();
      Eigen::Vector2d nrm(-d.y(), d.x());
      if (nrm.dot(centre - a) > 0) nrm = -nrm;
      for (double t = 0.3; t <= 0.71; t += 0.1) {
        const Eigen::Vector2d p = a + t * (b - a);
        std::vector<double> prof;
        for (double s = -2; s <= 2.0001; s += 0.05) prof.push_back(sample(p.x() + s * nrm.x(), p.y() + s * nrm.y()));
        const double mid = 0.5 * (*std::min_element(prof.begin(), prof.end()) + *std::max_element(prof.begin(), prof.end()));
        for (std::size_t k = 0; k + 1 < prof.size(); ++k) {
          if (prof[k] < mid && prof[k + 1] >= mid) {
            sum += -2 + 0.05 * (static_cast<double>(k) + (mid - prof[k]) / (prof[k + 1] - prof[k]));
            ++n;
            break;
          }
        }
      }
    }
  }
  return sum / n;
}

struct PhotoCase {
  std::string image;
  std::string dictionary;  // predefined name, or "file:" + path
  std::set<int> ids;
};

void PrintTo(const PhotoCase& c, std::ostream* os) { *os << c.image; }

class TutorialPhotos : public ::testing::TestWithParam<PhotoCase> {};

TEST_P(TutorialPhotos, FindExactlyTheGoldMarkersWhereTheImageEdgesAre) {
  const PhotoCase c = GetParam();
  const cv::Mat grey = cv::imread(kAruco + c.image, cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(grey.empty());
  const MarkerDictionary dict = c.dictionary.rfind("file:", 0) == 0 ? MarkerDictionary::from_file(c.dictionary.substr(5))
                                                                    : MarkerDictionary::predefined(c.dictionary);
  const Gold gold = read_gold(c.image);
  ASSERT_EQ(gold.corners.size(), c.ids.size());
  // OpenCV's own polygon corners: OpenCV's test criterion, every coordinate within 1 px of gold.
  MarkerDetectOptions none;
  none.refinement = CornerRefinement::None;
  const MarkerDetection raw = detect_markers(grey, c.image, dict, none);
  EXPECT_EQ(std::set<int>(raw.marker_ids.begin(), raw.marker_ids.end()), c.ids);
  for (std::size_t k = 0; k < raw.marker_ids.size(); ++k) {
    for (int j = 0; j < 4; ++j) {
      const Eigen::Vector2d d = raw.corners[k][j] - gold.corners.at(raw.marker_ids[k])[j];
      EXPECT_LE(d.cwiseAbs().maxCoeff(), 1.0) << "marker " << raw.marker_ids[k] << " corner " << j;
    }
  }
  // The edge fit: the same markers, none rejected. The gold corners are OpenCV's unrefined
  // polygon corners rounded to whole pixels; they sit inside the marker, where the contour's
  // black boundary pixels are. The refined corners lie where the image's 50 % edge crossings
  // meet: outwards of gold by what the crossings measure, within the rounding.
  const MarkerDetection fit = detect_markers(grey, c.image, dict, {});
  EXPECT_EQ(std::set<int>(fit.marker_ids.begin(), fit.marker_ids.end()), c.ids);
  EXPECT_TRUE(fit.rejected.empty());
  const double crossing = crossing_offset_from_gold(grey, gold);
  double outward = 0, expected = 0, worst = 0;
  int n = 0;
  for (std::size_t k = 0; k < fit.marker_ids.size(); ++k) {
    const auto& q = gold.corners.at(fit.marker_ids[k]);
    const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    for (int j = 0; j < 4; ++j) {
      const Eigen::Vector2d d = fit.corners[k][j] - q[j];
      const Eigen::Vector2d u = (q[(j + 1) % 4] - q[j]).normalized(), v = (q[(j + 3) % 4] - q[j]).normalized();
      const double half_angle = 0.5 * std::acos(std::clamp(u.dot(v), -1.0, 1.0));
      outward += d.dot((q[j] - centre).normalized());
      expected += crossing / std::sin(half_angle);  // both edges moved out by `crossing`
      worst = std::max(worst, d.cwiseAbs().maxCoeff());
      ++n;
    }
  }
  outward /= n;
  expected /= n;
  std::cout << "[ detect   ] " << c.image << ": edge-fit corners lie " << outward << " px outwards of gold on average (the "
            << "50 % crossings are " << crossing << " px outside the gold edges: " << expected
            << " px at the corners); largest coordinate difference " << worst << " px\n";
  EXPECT_GT(crossing, 0.1);  // gold really is inside the image's edges
  EXPECT_NEAR(outward, expected, 0.15);
  EXPECT_LE(worst, 2.0);
}

INSTANTIATE_TEST_SUITE_P(OpenCV, TutorialPhotos,
                         ::testing::Values(PhotoCase{"singlemarkersoriginal.jpg", "DICT_6X6_250", {23, 40, 62, 98, 124, 203}},
                                           PhotoCase{"gboriginal.png", "file:" + kAruco + "tutorial_dict.yml",
                                                     [] {
                                                       std::set<int> s;
                                                       for (int i = 0; i < 35; ++i) s.insert(i);
                                                       return s;
                                                     }()}),
                         [](const auto& info) { return "Photo" + std::to_string(info.index); });

// ---------------------------------------------------------------------------------------------
// Dictionaries, rejections, helpers.

TEST(MarkerDictionary, ReadsOpenCVsTutorialDictionary) {
  const MarkerDictionary d = MarkerDictionary::from_file(kAruco + "tutorial_dict.yml");
  EXPECT_EQ(d.marker_count(), 35);
  EXPECT_EQ(d.bits_per_side(), 6);
  EXPECT_EQ(d.max_correction_bits(), 0);  // the file has none: OpenCV's readDictionary default
  // Same codes as OpenCV's own reader.
  cv::FileStorage fs(kAruco + "tutorial_dict.yml", cv::FileStorage::READ);
  cv::aruco::Dictionary ref;
  ASSERT_TRUE(ref.readDictionary(fs.root()));
  EXPECT_EQ(cv::norm(ref.bytesList, d.opencv()->bytesList, cv::NORM_INF), 0);
}

struct BadDictionary {
  std::string text;
  std::string message;
};

void PrintTo(const BadDictionary& c, std::ostream* os) { *os << c.message; }

class BadDictionaries : public ::testing::TestWithParam<BadDictionary> {};

TEST_P(BadDictionaries, AreRefusedNamingTheProblem) {
  test::TempDir dir;
  const auto path = (dir.path() / "dict.yml").string();
  std::ofstream(path) << GetParam().text;
  try {
    MarkerDictionary::from_file(path);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), path);
    EXPECT_NE(std::string(e.what()).find(GetParam().message), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Files, BadDictionaries,
    ::testing::Values(BadDictionary{"%YAML:1.0\nmarkersize: 4\nmarker_0: \"1010101010101010\"\n", "missing key 'nmarkers'"},
                      BadDictionary{"%YAML:1.0\nnmarkers: 2\nmarkersize: 4\nmarker_0: \"1010101010101010\"\n",
                                    "missing key 'marker_1'"},
                      BadDictionary{"%YAML:1.0\nnmarkers: 1\nmarkersize: 4\nmarker_0: \"10101\"\n", "16 characters"},
                      BadDictionary{"%YAML:1.0\nnmarkers: 1\nmarkersize: 4\nmarker_0: \"101010101010101x\"\n", "'0' or '1'"},
                      BadDictionary{"this is not yaml: [\n", "dictionary"}));

TEST(MarkerDictionary, MissingFileIsNamed) {
  EXPECT_THROW(MarkerDictionary::from_file("/nonexistent/dict.yml"), InputError);
}

// A white page with markers drawn by OpenCV, each `side` px, at the given positions.
cv::Mat page(const std::vector<std::pair<int, cv::Point>>& markers, int side, int dark = 0, int light = 255) {
  cv::Mat img(400, 600, CV_8UC1, cv::Scalar(light));
  const auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  for (const auto& [id, at] : markers) {
    cv::Mat m;
    cv::aruco::drawMarker(dict, id, side, m, 1);
    m.convertTo(m, CV_8U, (light - dark) / 255.0, dark);
    m.copyTo(img(cv::Rect(at.x, at.y, side, side)));
  }
  cv::GaussianBlur(img, img, cv::Size(0, 0), 0.8);
  return img;
}

TEST(DetectMarkers, AnIdSeenTwiceInOneImageIsRejectedBothTimes) {
  const cv::Mat img = page({{3, {60, 60}}, {3, {300, 80}}, {7, {150, 220}}}, 90);
  const MarkerDetection d = detect_markers(img, "page", MarkerDictionary::predefined("DICT_4X4_50"), {});
  EXPECT_EQ(d.marker_ids, std::vector<int>{7});
  ASSERT_EQ(d.rejected.size(), 2u);
  for (const auto& r : d.rejected) {
    EXPECT_EQ(r.marker_id, 3);
    EXPECT_NE(r.reason.find("2 times"), std::string::npos) << r.reason;
  }
}

TEST(DetectMarkers, AMarkerWhoseEdgeFitFailsIsRejectedWithTheReason) {
  // Contrast 40 grey levels: OpenCV decodes it; an edge fit that asks for 60 refuses it.
  const cv::Mat img = page({{5, {100, 100}}}, 120, 100, 140);
  MarkerDetectOptions none;
  none.refinement = CornerRefinement::None;
  const auto dict = MarkerDictionary::predefined("DICT_4X4_50");
  ASSERT_EQ(detect_markers(img, "page", dict, none).marker_ids, std::vector<int>{5});
  ASSERT_EQ(detect_markers(img, "page", dict, {}).marker_ids, std::vector<int>{5});
  MarkerDetectOptions strict;
  strict.edges.min_contrast = 60;
  const MarkerDetection d = detect_markers(img, "page", dict, strict);
  EXPECT_TRUE(d.marker_ids.empty());
  ASSERT_EQ(d.rejected.size(), 1u);
  EXPECT_EQ(d.rejected[0].marker_id, 5);
  EXPECT_NE(d.rejected[0].reason.find("contrast"), std::string::npos) << d.rejected[0].reason;
}

TEST(DetectMarkers, ObservationsNumberCornersByMarkerIdTimesFour) {
  const cv::Mat img = page({{9, {60, 60}}, {2, {300, 150}}}, 100);
  const MarkerDetection d = detect_markers(img, "page.png", MarkerDictionary::predefined("DICT_4X4_50"), {});
  const auto obs = d.observations();
  ASSERT_EQ(obs.size(), 8u);
  EXPECT_EQ(obs[0].point_id, 8);   // marker 2, corner 0 (top-left)
  EXPECT_EQ(obs[4].point_id, 36);  // marker 9, corner 0
  // Corner 0 of marker 9 is its top-left: the drawn marker spans [60, 160) x [60, 160), so its
  // outer corner is at (59.5, 59.5) in OpenCV's pixel-centre convention.
  EXPECT_NEAR(obs[4].u_px, 59.5, 0.05);
  EXPECT_NEAR(obs[4].v_px, 59.5, 0.05);
  EXPECT_NEAR(obs[6].u_px, 159.5, 0.05);  // corner 2, bottom-right
  EXPECT_NEAR(obs[6].v_px, 159.5, 0.05);
}

TEST(ScaleBars, FourSidesPerMarker) {
  const auto bars = marker_scale_bars({5, 2, 5}, 24);
  ASSERT_EQ(bars.size(), 8u);
  EXPECT_EQ(bars[0], (ScaleBar{8, 9, 24, {}}));
  EXPECT_EQ(bars[3], (ScaleBar{11, 8, 24, {}}));
  EXPECT_EQ(bars[7], (ScaleBar{23, 20, 24, {}}));
}

TEST(IdRanges, ParseAndRefuse) {
  EXPECT_EQ(parse_id_ranges("0-3,7,9-10", "--marker-ids"), (std::vector<int>{0, 1, 2, 3, 7, 9, 10}));
  EXPECT_THROW(parse_id_ranges("3-1", "--marker-ids"), UsageError);
  EXPECT_THROW(parse_id_ranges("a", "--marker-ids"), UsageError);
  EXPECT_THROW(parse_id_ranges("-2", "--marker-ids"), UsageError);
}

// ---------------------------------------------------------------------------------------------
// Golden CLI cases.

struct CliFixture : ::testing::Test {
  test::TempDir dir;
  std::string path(const std::string& name) const { return (dir.path() / name).string(); }
  std::string write_page() const {
    const std::string p = path("page.png");
    cv::imwrite(p, page({{9, {60, 60}}, {2, {300, 150}}, {4, {420, 40}}}, 100));
    return p;
  }
};

TEST_F(CliFixture, MarkersFeaturesAndScaleBarsInOneRun) {
  const std::string img = write_page();
  const auto r = test::run_tool("detect", {"--aruco", "DICT_4X4_50", img, "-o", path("obs.csv"), "--features", path("feat"),
                                           "--mask-markers", "--marker-mm", "24", "--marker-ids", "2,4",
                                           "--scale-bars-out", path("bars.csv")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  EXPECT_NE(r.err.find("page.png: 3 markers"), std::string::npos) << r.err;
  std::ifstream obs_file(path("obs.csv"));
  const auto obs = read_observations(obs_file, "obs.csv");
  EXPECT_EQ(obs.size(), 12u);
  std::ifstream bars_file(path("bars.csv"));
  EXPECT_EQ(read_scale_bars(bars_file, "bars.csv").size(), 8u);
  std::ifstream feat_file(path("feat/page.png.feat"));
  const FeatureSet fs = read_features(feat_file, "page.png.feat");
  EXPECT_EQ(fs.image, img);
  EXPECT_EQ(fs.image_width_px, 600);
}

TEST_F(CliFixture, CustomDictionaryOnTheGridBoardPhoto) {
  const auto r = test::run_tool("detect", {"--aruco-dict-file", kAruco + "tutorial_dict.yml", kAruco + "gboriginal.png"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream out(r.out);
  EXPECT_EQ(read_observations(out, "stdout").size(), 140u);
}

struct GoldenCase {
  std::string name;
  std::vector<std::string> args;  // "{dir}" is the temp dir, "{page}" an image with markers
  int exit_code;
  std::string stderr_has;
};

void PrintTo(const GoldenCase& c, std::ostream* os) { *os << c.name; }

class DetectCli : public CliFixture, public ::testing::WithParamInterface<GoldenCase> {};

TEST_P(DetectCli, Golden) {
  const GoldenCase& c = GetParam();
  std::ofstream(path("notimage.jpg")) << "hello";
  const std::string page_path = write_page();
  std::vector<std::string> args;
  for (std::string a : c.args) {
    for (auto [key, value] : {std::pair<std::string, std::string>{"{dir}", dir.path().string()}, {"{page}", page_path}}) {
      for (auto at = a.find(key); at != std::string::npos; at = a.find(key)) a.replace(at, key.size(), value);
    }
    args.push_back(a);
  }
  const auto r = test::run_tool("detect", args);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(path("out.csv"))) << "a failed run left its output";
  EXPECT_TRUE(r.out.empty());
}

INSTANTIATE_TEST_SUITE_P(
    Cases, DetectCli,
    ::testing::Values(
        GoldenCase{"missing_image", {"--aruco", "DICT_4X4_50", "{dir}/missing.jpg", "-o", "{dir}/out.csv"}, 1, "missing.jpg"},
        GoldenCase{"not_an_image",
                   {"--aruco", "DICT_4X4_50", "{page}", "{dir}/notimage.jpg", "-o", "{dir}/out.csv"},
                   1,
                   "notimage.jpg: not a readable image"},
        GoldenCase{"features_of_a_bad_image_removed",
                   {"--aruco", "DICT_4X4_50", "{page}", "{dir}/notimage.jpg", "--features", "{dir}/feat", "-o",
                    "{dir}/out.csv", "-j", "1"},
                   1,
                   "not a readable image"},
        GoldenCase{"unknown_dictionary", {"--aruco", "DICT_9X9_1", "{page}"}, 2, "DICT_9X9_1"},
        GoldenCase{"missing_dictionary_file", {"--aruco-dict-file", "{dir}/nodict.yml", "{page}"}, 1, "nodict.yml"},
        GoldenCase{"mask_without_markers", {"--features", "{dir}/feat", "--mask-markers", "{page}"}, 2, "--mask-markers"},
        // Features alone make no observations: a named output would stay unwritten (exit 0 before).
        GoldenCase{"output_without_markers", {"--features", "{dir}/feat", "-o", "{dir}/obs.csv", "{page}"}, 2,
                   "no observations to write"},
        GoldenCase{"clearance_without_mask",
                   {"--aruco", "DICT_4X4_50", "--features", "{dir}/feat", "--mask-clearance-per-size", "1", "{page}"},
                   2,
                   "needs --mask-markers"},
        GoldenCase{"scale_bars_without_side", {"--aruco", "DICT_4X4_50", "--scale-bars-out", "{dir}/b.csv", "{page}"}, 2,
                   "--marker-mm"},
        GoldenCase{"both_dictionaries",
                   {"--aruco", "DICT_4X4_50", "--aruco-dict-file", "{dir}/d.yml", "{page}"},
                   2,
                   "excludes"},
        GoldenCase{"negative_cap_cell", {"--features", "{dir}/feat", "--cap-cell-px", "-1", "{page}"}, 2, "--cap-cell-px"},
        GoldenCase{"threads_out_of_range", {"--aruco", "DICT_4X4_50", "--threads", "-1", "{page}"}, 2,
                   "--threads: Value -1 not in range 0 to 1024"},
        GoldenCase{"jobs_is_the_old_name_of_threads", {"--aruco", "DICT_4X4_50", "--jobs", "1025", "{page}"}, 2,
                   "--threads: Value 1025 not in range 0 to 1024"},
        GoldenCase{"nothing_to_detect", {"{page}"}, 2, "--aruco DICT"},
        GoldenCase{"no_images", {"--aruco", "DICT_4X4_50"}, 2, "no images"}),
    [](const auto& info) { return info.param.name; });

TEST_F(CliFixture, AFailedFeatureRunLeavesNoFeatureFiles) {
  std::ofstream(path("notimage.jpg")) << "hello";
  const std::string img = write_page();
  const auto r = test::run_tool("detect", {"--features", path("feat"), img, path("notimage.jpg"), "-j", "1"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(std::filesystem::exists(path("feat/page.png.feat")));
}

}  // namespace
}  // namespace photomill::detect
