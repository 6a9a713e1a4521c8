// One case per triangulate option of the scale, the bundle adjustment and the pose search (issue
// 22): the option parses and has its documented effect (docs/triangulate.md, --help) in the JSON
// report or an output; a value out of its range exits 2 naming the option. Input: the synthetic
// scenes of triangulate/test_scene.hpp written to a temporary folder.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

using photomill::test::count_of;
using photomill::test::json_number;
using photomill::test::json_raw;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

// Sized: the plain scene whose tracks give each observation a size_px, every third one 12 px and
// 0.6 px off (the rest 1 px and exact): weighting by size tells them apart.
// TwoView: 1000 part points seen in every view that sees them, and two-view tracks: three wrong
// matches (6 mm along the first view's ray) and one true point.
enum class Scene { Plain, Markers, Outliers, Sized, TwoView };

// A scene's files: tracks.csv, camera.yaml, control.csv, and bars.csv (one bar without a sigma).
class SceneFiles {
public:
  explicit SceneFiles(Scene kind) {
    test::SceneOptions o;
    if (kind == Scene::Markers) o.plate_marker_side_mm = 20;
    if (kind == Scene::Outliers) o.outlier_fraction = 0.02;
    if (kind == Scene::TwoView) o.random_part_points = 1000;
    test::SceneTruth t = test::make_scene(o);
    if (kind == Scene::TwoView) {
      const std::vector<std::pair<double, double>> at = {{3.1, -2.4}, {-20, 10}, {25, 15}, {10.3, -7.9}};
      for (std::size_t k = 0; k < at.size(); ++k) {
        const auto [x, y] = at[k];
        test::add_two_view_track(t, 900000 + static_cast<TrackId>(k), 2 * k, 2 * k + 1,
                                 {x, y, test::part_height_mm(o, x, y)}, k < 3 ? 6.0 : 0.0);
      }
    }
    if (kind == Scene::Sized) test::give_sizes_spoil_large(t.tracks);
    write("tracks.csv", [&](std::ostream& s) { write_tracks(s, t.tracks); });
    write("camera.yaml", [&](std::ostream& s) { write_camera_yaml(s, t.camera); });
    write("control.csv", [&](std::ostream& s) { write_control_points(s, t.plate_points); });
    write("poses.csv", [&](std::ostream& s) { write_poses(s, t.poses); });
    const auto& p = t.plate_points;
    write("bars.csv", [&](std::ostream& s) {
      s << "point_a,point_b,distance_mm\n" << p.front().point_id << "," << p.back().point_id << ","
        << (p.front().xyz_mm - p.back().xyz_mm).norm() << "\n";
    });
  }
  template <typename F>
  void write(const std::string& name, const F& f) {
    std::ofstream out(dir_.path() / name, std::ios::binary);
    out.precision(17);
    f(out);
  }
  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }

private:
  TempDir dir_;
};

const SceneFiles& files(Scene kind) {
  static const SceneFiles plain(Scene::Plain), markers(Scene::Markers), outliers(Scene::Outliers), sized(Scene::Sized),
      two_view(Scene::TwoView);
  return kind == Scene::Markers    ? markers
         : kind == Scene::Outliers ? outliers
         : kind == Scene::Sized    ? sized
         : kind == Scene::TwoView  ? two_view
                                   : plain;
}

struct Outcome {
  ToolResult r;
  std::string report;
  std::string refined_camera;  // --refined-camera's file, when "{refined}" is among the arguments
};

// triangulate on a scene; "{control}" and "{bars}" in `args` name the scene's files. Without
// either datum the run uses the control points.
Outcome triangulate(Scene kind, std::vector<std::string> args) {
  const SceneFiles& f = files(kind);
  TempDir dir;
  bool datum = false;
  for (std::string& a : args) {
    if (a == "{control}") a = f.path("control.csv"), datum = true;
    if (a == "{bars}") a = f.path("bars.csv"), datum = true;
    if (a == "{poses}") a = f.path("poses.csv"), datum = true;
    if (a == "{refined}") a = (dir.path() / "refined.yaml").string();
    if (a == "--marker-side-mm" || a == "--arbitrary-scale") datum = true;
  }
  if (!datum) args.insert(args.end(), {"--control-points", f.path("control.csv")});
  const auto report = dir.path() / "report.json";
  args.insert(args.end(), {f.path("tracks.csv"), "-c", f.path("camera.yaml"), "-o", (dir.path() / "cloud.ply").string(),
                           "--report", report.string()});
  Outcome run{run_tool("triangulate", args), "", ""};
  run.report = photomill::test::read_file(report);
  run.refined_camera = photomill::test::read_file(dir.path() / "refined.yaml");
  return run;
}

const Outcome& plain() {
  static const Outcome run = triangulate(Scene::Plain, {});
  return run;
}
const Outcome& two_view() {
  static const Outcome run = triangulate(Scene::TwoView, {});
  return run;
}
double two_view_field(const Outcome& r, const std::string& key) { return json_number(r.report, key, "two_view_check"); }
const Outcome& plain_outliers() {
  static const Outcome run = triangulate(Scene::Outliers, {});
  return run;
}

// Observations removed as outliers (each carries a residual_px) and marker sides left out.
std::size_t removed(const Outcome& r) { return count_of(r.report, "\"residual_px\":"); }
std::size_t unused_bars(const Outcome& r) { return count_of(r.report, "\"used\":false"); }

struct OptionCase {
  const char* name;
  Scene scene;
  std::vector<std::string> args;
  int exit_code;
  std::string stderr_has;
  std::function<void(const Outcome&)> check;
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class TriangulateOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(TriangulateOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = triangulate(c.scene, c.args);
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

OptionCase bad(const char* name, std::vector<std::string> args, std::string option) {
  return {name, Scene::Plain, std::move(args), 2, std::move(option), nullptr};
}

INSTANTIATE_TEST_SUITE_P(
    Options, TriangulateOption,
    ::testing::Values(
        // Outputs
        OptionCase{"refined_camera", Scene::Plain, {"--refine-intrinsics", "focal", "--refined-camera", "{refined}"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_NE(r.refined_camera.find("camera_matrix"), std::string::npos) << r.refined_camera;
                     EXPECT_NE(r.report.find("\"refined_camera\":["), std::string::npos);
                   }},
        bad("refined_camera_without_refinement", {"--refined-camera", "{refined}"}, "--refined-camera"),
        // Scale
        OptionCase{"scale_bar_sigma_mm", Scene::Plain, {"--scale-bars", "{bars}", "--scale-bar-sigma-mm", "0.25"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "sigma_mm", "scale_bars"), 0.25) << r.report; }},
        bad("scale_bar_sigma_mm_zero", {"--scale-bar-sigma-mm", "0"}, "--scale-bar-sigma-mm"),
        OptionCase{"marker_side_sigma_mm", Scene::Markers, {"--marker-side-mm", "20", "--marker-side-sigma-mm", "0.03"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "origin", "scale_bars"), "\"marker_side\"");
                     EXPECT_EQ(json_number(r.report, "sigma_mm", "scale_bars"), 0.03) << r.report;
                   }},
        bad("marker_side_sigma_mm_negative", {"--marker-side-sigma-mm", "-1"}, "--marker-side-sigma-mm"),
        OptionCase{"marker_side_tolerance", Scene::Markers, {"--marker-side-mm", "20", "--marker-side-tolerance", "1e-7"}, 0, "",
                   [](const Outcome& r) {
                     // Noisy sides differ from their median by more than 1e-7 of it: most are left out.
                     EXPECT_GT(unused_bars(r), 0u) << r.report;
                     EXPECT_EQ(unused_bars(triangulate(Scene::Markers, {"--marker-side-mm", "20"})), 0u);
                   }},
        bad("marker_side_tolerance_zero", {"--marker-side-tolerance", "0"}, "--marker-side-tolerance"),
        // Known poses
        OptionCase{"known_poses", Scene::Plain, {"--known-poses", "{poses}"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "pose_initialisation"), "\"known_poses\"");
                     EXPECT_EQ(json_raw(r.report, "type", "datum"), "\"known_poses\"") << r.report;
                     EXPECT_EQ(json_number(r.report, "known_poses", "datum"), 12);
                     EXPECT_EQ(json_raw(r.report, "pose_sigma_mm", "datum"), "null");
                   }},
        OptionCase{"pose_sigma_mm", Scene::Plain,
                   {"--known-poses", "{poses}", "--pose-sigma-mm", "0.5", "--pose-sigma-deg", "0.05"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "pose_sigma_mm", "datum"), 0.5) << r.report;
                     EXPECT_EQ(json_number(r.report, "pose_sigma_deg", "datum"), 0.05);
                   }},
        bad("pose_sigma_mm_alone", {"--known-poses", "{poses}", "--pose-sigma-mm", "1"}, "--pose-sigma-deg"),
        bad("pose_sigma_deg_zero", {"--known-poses", "{poses}", "--pose-sigma-mm", "1", "--pose-sigma-deg", "0"},
            "--pose-sigma-deg"),
        bad("pose_sigma_without_known_poses", {"--pose-sigma-mm", "1", "--pose-sigma-deg", "1"}, "--known-poses"),
        // Bundle adjustment
        OptionCase{"loss_scale_px", Scene::Plain, {"--loss", "cauchy", "--loss-scale-px", "3.5"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "loss_scale_px", "bundle_adjustment"), 3.5); }},
        bad("loss_scale_px_zero", {"--loss-scale-px", "0"}, "--loss-scale-px"),
        OptionCase{"observation_sigma_px", Scene::Plain, {"--observation-sigma-px", "0.7"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "observation_sigma_estimated"), "false");
                     EXPECT_EQ(json_number(r.report, "sigma_px", "observation_classes"), 0.7) << r.report;
                     EXPECT_EQ(json_raw(plain().report, "observation_sigma_estimated"), "true");
                   }},
        bad("observation_sigma_px_zero", {"--observation-sigma-px", "0"}, "--observation-sigma-px"),
        OptionCase{"coded_id_limit", Scene::Plain, {"--coded-id-limit", "1000000"}, 0, "",
                   [](const Outcome& r) {
                     // The part's points (ids from 100000) become coded targets: one class left.
                     EXPECT_EQ(r.report.find("\"natural\":"), std::string::npos) << r.report;
                     EXPECT_NE(plain().report.find("\"natural\":"), std::string::npos) << plain().report;
                   }},
        bad("coded_id_limit_negative", {"--coded-id-limit", "-1"}, "--coded-id-limit"),
        OptionCase{"ignore_feature_size", Scene::Sized, {"--coded-id-limit", "0", "--ignore-feature-size"}, 0, "",
                   [](const Outcome& r) {
                     // Every observation weighed alike: the 0.6 px noise of the large features is
                     // spread over all, the fit's residuals differ from the size-weighted run's.
                     const Outcome weighted = triangulate(Scene::Sized, {"--coded-id-limit", "0"});
                     ASSERT_EQ(weighted.r.exit_code, 0) << weighted.r.err;
                     const double alike = json_number(r.report, "final_rms_px");
                     const double by_size = json_number(weighted.report, "final_rms_px");
                     ASSERT_TRUE(std::isfinite(alike) && std::isfinite(by_size)) << r.report;
                     EXPECT_NE(alike, by_size);
                   }},
        OptionCase{"outlier_sigmas", Scene::Outliers, {"--outlier-sigmas", "1000", "--outlier-max-px", "100"}, 0, "",
                   // (the report also lists what triangulation itself dropped, beyond --max-reproj-px)
                   [](const Outcome& r) { EXPECT_LT(removed(r), removed(plain_outliers())) << r.report; }},
        bad("outlier_sigmas_zero", {"--outlier-sigmas", "0"}, "--outlier-sigmas"),
        OptionCase{"outlier_min_px", Scene::Outliers, {"--outlier-min-px", "20", "--outlier-max-px", "50"}, 0, "",
                   // The outliers are 8 px off: below a 20 px threshold, fewer are removed.
                   [](const Outcome& r) { EXPECT_LT(removed(r), removed(plain_outliers())) << r.report; }},
        bad("outlier_min_px_above_max", {"--outlier-min-px", "3", "--outlier-max-px", "2"}, "--outlier-min-px"),
        OptionCase{"outlier_max_px", Scene::Outliers, {"--outlier-min-px", "0", "--outlier-max-px", "0.08"}, 0, "",
                   // Beyond 0.08 px always: many noisy (0.05 px) observations go with the outliers.
                   [](const Outcome& r) { EXPECT_GT(removed(r), 2 * removed(plain_outliers())) << r.report; }},
        bad("outlier_max_px_zero", {"--outlier-max-px", "0"}, "--outlier-max-px"),
        OptionCase{"max_iterations", Scene::Plain, {"--max-iterations", "1"}, 0, "",
                   [](const Outcome& r) { EXPECT_LE(json_number(r.report, "final_iterations", "bundle_adjustment"), 1); }},
        bad("max_iterations_zero", {"--max-iterations", "0"}, "--max-iterations"),
        OptionCase{"function_tolerance", Scene::Plain, {"--arbitrary-scale", "--function-tolerance", "0.5"}, 0, "",
                   // Stop once an iteration lowers the cost by less than half: fewer iterations (in
                   // all: the last adjustment starts from the outlier rounds' converged one; without
                   // control points the images are registered one by one, each followed by one).
                   [](const Outcome& r) {
                     const Outcome strict = triangulate(Scene::Plain, {"--arbitrary-scale"});
                     EXPECT_LT(json_number(r.report, "total_iterations", "bundle_adjustment"),
                               json_number(strict.report, "total_iterations", "bundle_adjustment"))
                         << r.report << strict.report;
                   }},
        bad("function_tolerance_zero", {"--function-tolerance", "0"}, "--function-tolerance"),
        // The adjustments between registrations stop sooner; the final one is as converged.
        // (Without control points the images are registered one by one, each followed by one.)
        OptionCase{"intermediate_function_tolerance", Scene::Plain,
                   {"--arbitrary-scale", "--intermediate-function-tolerance", "0.5"}, 0, "",
                   [](const Outcome& r) {
                     const Outcome strict =
                         triangulate(Scene::Plain, {"--arbitrary-scale", "--intermediate-function-tolerance", "1e-12"});
                     EXPECT_GT(json_number(r.report, "runs", "bundle_adjustment"), 3) << r.report;
                     EXPECT_LT(json_number(r.report, "total_iterations", "bundle_adjustment"),
                               json_number(strict.report, "total_iterations", "bundle_adjustment"))
                         << r.report;
                     EXPECT_NEAR(json_number(r.report, "final_rms_px"), json_number(strict.report, "final_rms_px"), 1e-6);
                   }},
        bad("intermediate_function_tolerance_zero", {"--intermediate-function-tolerance", "0"},
            "--intermediate-function-tolerance"),
        // --preset features: all intrinsics refined, 2 outlier rounds, function tolerance 1e-6.
        OptionCase{"preset_features", Scene::Plain, {"--preset", "features"}, 0, "",
                   [](const Outcome& r) {
                     const Outcome spelt = triangulate(Scene::Plain, {"--refine-intrinsics", "all", "--outlier-rounds", "2",
                                                                      "--function-tolerance", "1e-6"});
                     // (The same settings: equal but for the threads' summation order, ~1e-14.)
                     const std::vector<double> k = photomill::test::json_array(r.report, "refined_camera");
                     const std::vector<double> k_spelt = photomill::test::json_array(spelt.report, "refined_camera");
                     ASSERT_EQ(k.size(), 9u) << r.report;
                     ASSERT_EQ(k_spelt.size(), k.size());
                     for (std::size_t i = 0; i < k.size(); ++i) EXPECT_NEAR(k[i], k_spelt[i], 1e-9 * (1 + std::abs(k[i])));
                     EXPECT_NEAR(json_number(r.report, "final_rms_px"), json_number(spelt.report, "final_rms_px"), 1e-9);
                     EXPECT_GT(std::abs(json_number(r.report, "final_rms_px") - json_number(plain().report, "final_rms_px")), 1e-6)
                         << "the preset refines the camera: another fit than the plain run's";
                     EXPECT_EQ(json_raw(r.report, "refine_intrinsics"), "\"all\"");
                     const Outcome held = triangulate(Scene::Plain, {"--preset", "features", "--refine-intrinsics", "none"});
                     EXPECT_EQ(json_raw(held.report, "refine_intrinsics"), "\"none\"") << "the option given wins";
                   }},
        bad("preset_unknown", {"--preset", "fast"}, "--preset"),
        OptionCase{"covariance_max_parameters", Scene::Plain, {"--covariance-max-parameters", "10"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "method", "uncertainty"), "\"per_point_fixed_poses\"");
                     EXPECT_EQ(json_raw(plain().report, "method", "uncertainty"), "\"full_covariance\"");
                   }},
        bad("covariance_max_parameters_text", {"--covariance-max-parameters", "many"}, "--covariance-max-parameters"),
        // Poses and triangulation
        // No track's rays meet at 120 degrees or more.
        OptionCase{"min_angle_deg", Scene::Plain, {"--min-angle-deg", "120"}, 1, "small_angle", nullptr},
        // Issue #25: NaN, infinities and absurd values are bad usage at parse time (CLI::PositiveNumber
        // and CLI::Range let NaN through), the range in --help.
        OptionCase{"min_angle_deg_nan", Scene::Plain, {"--min-angle-deg", "nan"}, 2, "--min-angle-deg: 'nan' is not in [0, 180]", nullptr},
        OptionCase{"max_reproj_px_inf", Scene::Plain, {"--max-reproj-px", "inf"}, 2, "--max-reproj-px: 'inf' is not in (0, 10000]", nullptr},
        OptionCase{"function_tolerance_nan", Scene::Plain, {"--function-tolerance", "nan"}, 2, "--function-tolerance", nullptr},
        OptionCase{"ransac_confidence_nan", Scene::Plain, {"--ransac-confidence", "nan"}, 2, "--ransac-confidence", nullptr},
        // The work limit: Ceres iterations over all adjustments; a few are not enough for the scene.
        OptionCase{"max_total_iterations", Scene::Plain, {"--max-total-iterations", "1"}, 1,
                   "Ceres iterations in all, the work limit --max-total-iterations", nullptr},
        OptionCase{"max_total_iterations_zero", Scene::Plain, {"--max-total-iterations", "0"}, 2, "--max-total-iterations", nullptr},
        OptionCase{"covariance_max_parameters_absurd", Scene::Plain, {"--covariance-max-parameters", "1e12"}, 2,
                   "--covariance-max-parameters", nullptr},
        bad("min_angle_deg_negative", {"--min-angle-deg", "-1"}, "--min-angle-deg"),
        OptionCase{"max_reproj_px", Scene::Outliers, {"--max-reproj-px", "100", "--outlier-rounds", "0"}, 0, "",
                   [](const Outcome& r) { EXPECT_GT(json_number(r.report, "final_rms_px"), 0); }},
        bad("max_reproj_px_zero", {"--max-reproj-px", "0"}, "--max-reproj-px"),
        OptionCase{"ransac_threshold_px", Scene::Plain, {"--ransac-threshold-px", "1"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "registered_images"), 12); }},
        bad("ransac_threshold_px_zero", {"--ransac-threshold-px", "0"}, "--ransac-threshold-px"),
        OptionCase{"ransac_confidence", Scene::Plain, {"--ransac-confidence", "0.9"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "registered_images"), 12); }},
        bad("ransac_confidence_0_3", {"--ransac-confidence", "0.3"}, "--ransac-confidence"),
        OptionCase{"ransac_iterations", Scene::Plain, {"--ransac-iterations", "50"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "registered_images"), 12); }},
        bad("ransac_iterations_zero", {"--ransac-iterations", "0"}, "--ransac-iterations"),
        OptionCase{"control_min_points", Scene::Plain, {"--control-min-points", "1000"}, 0, "",
                   [](const Outcome& r) {
                     // No image sees 1000 control points: the poses come from the image pairs instead.
                     EXPECT_EQ(json_raw(r.report, "pose_initialisation"), "\"incremental+control_alignment\"");
                     EXPECT_EQ(json_raw(plain().report, "pose_initialisation"), "\"control_pnp\"");
                   }},
        bad("control_min_points_three", {"--control-min-points", "3"}, "--control-min-points"),
        OptionCase{"pnp_min_inliers", Scene::Plain,
                   {"--arbitrary-scale", "--pnp-min-inliers", "100000", "--relative-min-scale-points", "0"}, 0, "",
                   // Only the initial pair: no image can be added by PnP (nor by relative pose).
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "registered_images"), 2) << r.r.err; }},
        OptionCase{"relative_min_scale_points", Scene::Plain, {"--arbitrary-scale", "--pnp-min-inliers", "100000"}, 0, "",
                   // Without PnP every image is registered from its relative pose to one in the model.
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "registered_images"), 12) << r.r.err;
                     EXPECT_EQ(count_of(r.report, "\"registered_by\":\"relative_pose\""), 10u) << r.report;
                   }},
        bad("relative_min_scale_points_negative", {"--relative-min-scale-points", "-1"}, "--relative-min-scale-points"),
        bad("pnp_min_inliers_three", {"--pnp-min-inliers", "3"}, "--pnp-min-inliers"),
        OptionCase{"min_shared_tracks", Scene::Plain, {"--scale-bars", "{bars}", "--min-shared-tracks", "100000"}, 1,
                   "no two images share 100000", nullptr},
        bad("min_shared_tracks_four", {"--min-shared-tracks", "4"}, "--min-shared-tracks"),
        OptionCase{"initial_min_angle_deg", Scene::Plain, {"--scale-bars", "{bars}", "--initial-min-angle-deg", "179"}, 1,
                   "median angle below 179", nullptr},
        bad("initial_min_angle_deg_negative", {"--initial-min-angle-deg", "-1"}, "--initial-min-angle-deg"),
        // Two-view points: the default run removes the three wrong matches and keeps the true one.
        OptionCase{"two_view_defaults", Scene::TwoView, {}, 0, "--two-view-sigmas",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "ran", "two_view_check"), "true") << r.report;
                     EXPECT_EQ(two_view_field(r, "checked"), 4);
                     EXPECT_EQ(two_view_field(r, "removed_off_neighbours"), 3);
                     EXPECT_EQ(two_view_field(r, "kept"), 1);
                     EXPECT_EQ(json_number(r.report, "two_view_off_neighbours", "tracks_dropped"), 3);
                     EXPECT_EQ(json_raw(plain().report, "ran", "two_view_check"), "false") << "no two-view point";
                   }},
        OptionCase{"no_two_view_check", Scene::TwoView, {"--no-two-view-check"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "enabled", "two_view_check"), "false") << r.report;
                     EXPECT_EQ(two_view_field(r, "checked"), 0);
                     EXPECT_EQ(json_number(r.report, "points"), json_number(two_view().report, "points") + 3);
                   }},
        OptionCase{"two_view_sigmas", Scene::TwoView, {"--two-view-sigmas", "1e5"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(two_view_field(r, "sigmas"), 1e5);
                     EXPECT_EQ(two_view_field(r, "removed_off_neighbours"), 0) << r.report;
                   }},
        bad("two_view_sigmas_zero", {"--two-view-sigmas", "0"}, "--two-view-sigmas"),
        OptionCase{"two_view_tolerance_mm", Scene::TwoView, {"--two-view-tolerance-mm", "50"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(two_view_field(r, "tolerance_mm"), 50);
                     EXPECT_EQ(two_view_field(r, "removed_off_neighbours"), 0) << r.report;
                   }},
        // Without a scale a tolerance in mm is not applied (the sigma test alone: the wrong
        // matches still go), and the warning says so and gives the reach in the model's units.
        OptionCase{"two_view_tolerance_mm_arbitrary_scale", Scene::TwoView,
                   {"--arbitrary-scale", "--two-view-tolerance-mm", "50"}, 0,
                   "(--two-view-tolerance-mm not applied: the scale is arbitrary)",
                   [](const Outcome& r) {
                     EXPECT_EQ(two_view_field(r, "tolerance_mm"), 0) << r.report;
                     EXPECT_EQ(two_view_field(r, "removed_off_neighbours"), 3) << r.report;
                     EXPECT_NE(r.r.err.find("units of the arbitrary scale (--two-view-reach)"), std::string::npos) << r.r.err;
                     EXPECT_NE(two_view().r.err.find(" mm (--two-view-reach)"), std::string::npos) << two_view().r.err;
                   }},
        bad("two_view_tolerance_mm_negative", {"--two-view-tolerance-mm", "-1"}, "--two-view-tolerance-mm"),
        OptionCase{"two_view_reach", Scene::TwoView, {"--two-view-reach", "0.01"}, 0, "",
                   // Nothing seen in three views is that close: every two-view point unsupported.
                   [](const Outcome& r) { EXPECT_EQ(two_view_field(r, "removed_unsupported"), 4) << r.report; }},
        bad("two_view_reach_zero", {"--two-view-reach", "0"}, "--two-view-reach"),
        OptionCase{"two_view_neighbours", Scene::TwoView, {"--two-view-neighbours", "5"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(two_view_field(r, "neighbours"), 5);
                     EXPECT_LT(two_view_field(r, "spacing_mm"), two_view_field(two_view(), "spacing_mm"))
                         << "the 5th neighbour is nearer than the 12th";
                   }},
        bad("two_view_neighbours_two", {"--two-view-neighbours", "2"}, "--two-view-neighbours")),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill::triangulate
