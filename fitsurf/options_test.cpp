// One case per fitsurf option not covered by the golden cases (issue 22): the option parses and
// has its documented effect (docs/fitsurf.md, --help), read from the JSON report or the surface
// text; a value out of its range exits 2 naming the option.
#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fitsurf/test_shapes.hpp"
#include "formats/point_cloud.hpp"
#include "formats/uncertainty.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::fitsurf {
namespace {

using photomill::test::count_of;
using photomill::test::json_number;
using photomill::test::json_raw;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

std::string xyz_text(const std::vector<Eigen::Vector3d>& pts) {
  PointCloud c;
  c.points_mm = pts;
  std::ostringstream out;
  write_xyz(out, c);
  return out.str();
}

// The dome (z from 20 to 38 mm), 1500 points with 0.01 mm noise.
const std::string& dome() {
  static const std::string text = xyz_text(fitsurf::test::sample(fitsurf::test::shape("dome"), 1500, 0.01, 41));
  return text;
}

// The dome standing on a flat plate at z = 0 (400 points around it, 10 mm below its lowest edge).
const std::string& dome_on_plate() {
  static const std::string text = [] {
    std::vector<Eigen::Vector3d> pts = fitsurf::test::sample(fitsurf::test::shape("dome"), 1500, 0.01, 41);
    for (int k = 0; k < 400; ++k) pts.emplace_back(-100 + 10 * (k % 20) + 0.3, -100 + 10 * (k / 20) + 0.7, 0.2 * ((k * 7) % 5) / 4.0);
    return xyz_text(pts);
  }();
  return text;
}

// The dome over an L-shaped footprint (its x > 0, y > 0 quarter left out): a concave outline whose
// notch a fine grid traces and a coarse one does not.
const std::string& dome_l_shaped() {
  static const std::string text = [] {
    std::vector<Eigen::Vector3d> pts;
    for (const auto& p : fitsurf::test::sample(fitsurf::test::shape("dome"), 3000, 0.01, 41)) {
      if (!(p.x() > 0 && p.y() > 0)) pts.push_back(p);
    }
    return xyz_text(pts);
  }();
  return text;
}

// The dome as a walled part: its top over the rectangle (z 20 to 38 mm) on walls standing on a
// plate at z = 0 that reaches 10 mm beyond them (2 mm grid, 1 350 points).
constexpr int kWallPlatePoints = 1350;
const std::string& dome_on_walls() {
  static const std::string text = [] {
    std::vector<Eigen::Vector3d> pts = fitsurf::test::sample(fitsurf::test::shape("dome"), 3000, 0.01, 41);
    int plate = 0;
    for (double x = -84; x <= 84; x += 2) {
      for (double y = -59; y <= 59; y += 2) {
        if (std::abs(x) < 75 && std::abs(y) < 50) continue;
        pts.emplace_back(x, y, 0.01 * std::sin(x + y));
        ++plate;
      }
    }
    EXPECT_EQ(plate, kWallPlatePoints);
    return xyz_text(pts);
  }();
  return text;
}

// The dome as an ASCII PLY whose points carry sigma_mm (0.01 mm, as triangulate's would).
const std::string& dome_with_sigma() {
  static const std::string text = [] {
    PointCloud c;
    c.points_mm = fitsurf::test::sample(fitsurf::test::shape("dome"), 1500, 0.01, 41);
    PointProperty& sigma = c.add_property("scalar_sigma_mm", PlyScalar::Float64);
    std::fill(sigma.values.begin(), sigma.values.end(), 0.01);
    std::ostringstream out;
    write_ply(out, c, PlyEncoding::Ascii);
    return out.str();
  }();
  return text;
}

struct Outcome {
  ToolResult r;
  std::string report;
};

Outcome fit(std::vector<std::string> args, const std::string& cloud = dome()) {
  TempDir dir;
  const auto report = dir.path() / "report.json";
  args.insert(args.end(), {"--report", report.string(), "-"});
  Outcome run{run_tool("fitsurf", args, cloud), ""};
  run.report = photomill::test::read_file(report);
  return run;
}

// The round_rms_mm array's length: the fits made.
std::size_t rounds(const std::string& report) {
  const std::size_t b = report.find("\"round_rms_mm\":[");
  if (b == std::string::npos) return 0;
  const std::size_t e = report.find(']', b);
  const std::string items = report.substr(b + 16, e - b - 16);
  return items.empty() ? 0 : count_of(items, ",") + 1;
}

struct OptionCase {
  const char* name;
  std::function<Outcome()> run;
  int exit_code;
  std::string stderr_has;
  std::function<void(const Outcome&)> check;
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class FitsurfOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(FitsurfOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = c.run();
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

auto on(std::vector<std::string> args, const std::string& (*cloud)() = dome) {
  return [args, cloud] { return fit(args, cloud()); };
}
OptionCase bad(const char* name, std::vector<std::string> args, std::string option) {
  return {name, on(std::move(args)), 2, std::move(option), nullptr};
}

INSTANTIATE_TEST_SUITE_P(
    Options, FitsurfOption,
    ::testing::Values(
        // Selection
        OptionCase{"keep_above", on({"--keep-above", "0,0,1,-25"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_GT(json_number(r.report, "dropped_below", "selection"), 100);
                     EXPECT_EQ(json_number(r.report, "dropped_below", "selection") +
                                   json_number(r.report, "fitted_points", "selection"),
                               1500);
                   }},
        bad("keep_above_zero_normal", {"--keep-above", "0,0,0,5"}, "--keep-above"),
        // Issue #25: every numeric option checked at parse time (NaN, infinities, absurd values),
        // the range in --help (CLI::Range let NaN through: --max-slope-deg nan was taken).
        bad("max_slope_deg_nan", {"--max-slope-deg", "nan"}, "--max-slope-deg: 'nan' is not in [1, 90]"),
        bad("smoothing_nan", {"--smoothing", "nan"}, "--smoothing: 'nan' is not in [0, 1e15]"),
        bad("keep_box_inf", {"--keep-box", "-1,-1,-1,1,1,inf"}, "--keep-box"),
        bad("tolerance_absurd", {"--tolerance", "1e300"}, "--tolerance"),
        bad("max_rounds_absurd", {"--max-rounds", "100000"}, "--max-rounds"),
        bad("mesh_step_mm_nan", {"--mesh-step-mm", "nan"}, "--mesh-step-mm"),
        bad("cg_tolerance_one", {"--cg-tolerance", "1"}, "--cg-tolerance"),
        // The work limit on the unknowns: a net above it is refused before any work, naming the option.
        bad("max_net_poles", {"--net", "30x30", "--max-net-poles", "800"},
            "a 30x30 net has 900 poles, more than the work limit --max-net-poles 800"),
        bad("net_beyond_the_default_limit", {"--net", "1000x1000"}, "--max-net-poles 250000"),
        bad("max_net_poles_zero", {"--max-net-poles", "0"}, "--max-net-poles"),
        OptionCase{"plane_threshold_mm", on({"--drop-plane", "--plane-threshold-mm", "0.3"}, dome_on_plate), 0, "",
                   [](const Outcome& r) {
                     // The plate's points lie within 0.2 mm of z = 0: all of them belong to the plane.
                     EXPECT_EQ(json_number(r.report, "dropped_plane", "selection"), 400);
                     // Within 25 mm the dome's foot (z = 20 to 25 mm) belongs to the plane too.
                     const Outcome wide = fit({"--drop-plane", "--plane-threshold-mm", "25"}, dome_on_plate());
                     ASSERT_EQ(wide.r.exit_code, 0) << wide.r.err;
                     EXPECT_GT(json_number(wide.report, "dropped_plane", "selection"), 500);
                   }},
        bad("plane_threshold_mm_zero", {"--plane-threshold-mm", "0"}, "--plane-threshold-mm"),
        OptionCase{"walls_auto", on({}, dome_on_walls), 0, "the part stands on walls",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "dropped_floor", "walls"), kWallPlatePoints);
                     EXPECT_EQ(json_number(r.report, "fitted_points", "selection"), 3000);
                   }},
        // Off, the plate and the top make two layers where the walls stand: refused as a fold.
        OptionCase{"walls_off", on({"--walls", "off"}, dome_on_walls), 1, "folds over its projection plane", nullptr},
        bad("walls_unknown", {"--walls", "maybe"}, "--walls"),
        OptionCase{"wall_slope_deg", on({"--wall-slope-deg", "60"}, dome_on_walls), 0, "steeper than 60 degrees",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "dropped_floor", "walls"), kWallPlatePoints); }},
        bad("wall_slope_deg_too_low", {"--wall-slope-deg", "30"}, "--wall-slope-deg"),
        // A radius longer than the walls are high joins the plate to the top: no wall is found.
        OptionCase{"wall_radius_mm", on({"--wall-radius-mm", "30"}, dome_on_walls), 1, "folds over its projection plane",
                   [](const Outcome&) {
                     const Outcome small = fit({"--wall-radius-mm", "3"}, dome_on_walls());
                     ASSERT_EQ(small.r.exit_code, 0) << small.r.err;
                     EXPECT_NEAR(json_number(small.report, "radius_mm", "walls"), 5.5, 1.0);
                   }},
        bad("wall_radius_mm_zero", {"--wall-radius-mm", "0"}, "--wall-radius-mm"),
        // Surface
        OptionCase{"degree_u", on({"--degree-u", "2"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "degree_u", "surface"), 2);
                     EXPECT_EQ(json_number(r.report, "degree_v", "surface"), 3);
                     EXPECT_NE(r.r.out.find("\ndegrees 2 3\n"), std::string::npos) << r.r.out.substr(0, 100);
                   }},
        bad("degree_u_26", {"--degree-u", "26"}, "--degree-u"),
        OptionCase{"degree_v", on({"--degree-v", "4"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "degree_v", "surface"), 4);
                     EXPECT_NE(r.r.out.find("\ndegrees 3 4\n"), std::string::npos) << r.r.out.substr(0, 100);
                   }},
        bad("degree_v_zero", {"--degree-v", "0"}, "--degree-v"),
        OptionCase{"plane_xy", on({"--plane", "xy"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "parameter_plane", "surface"), "\"xy\"");
                     EXPECT_EQ(json_raw(r.report, "plane_normal", "surface"), "[0");
                   }},
        OptionCase{"plane_auto", on({"--plane", "auto"}), 0, "",
                   [](const Outcome& r) {
                     // The dome's slopes are the same over both planes: the best-fit plane is kept.
                     EXPECT_EQ(json_raw(r.report, "parameter_plane_option", "surface"), "\"auto\"");
                     EXPECT_EQ(json_raw(r.report, "parameter_plane", "surface"), "\"pca\"");
                     EXPECT_GT(json_number(r.report, "data_slope_xy_deg", "surface"), 10);
                     EXPECT_NEAR(json_number(r.report, "data_slope_xy_deg", "surface"),
                                 json_number(r.report, "data_slope_pca_deg", "surface"), 1.0);
                   }},
        bad("plane_bad", {"--plane", "yz"}, "--plane"),
        OptionCase{"outline_convex", on({"--outline", "convex"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "outline", "surface"), "\"convex\"");
                     EXPECT_GE(json_number(r.report, "boundary_vertices", "surface"), 3);
                     const Outcome none = fit({"--outline", "none"});
                     EXPECT_EQ(json_number(none.report, "boundary_vertices", "surface"), 0);
                   }},
        bad("outline_bad", {"--outline", "round"}, "--outline"),
        OptionCase{"max_slope_deg", on({"--max-slope-deg", "5", "--max-smoothing-factor", "1"}), 1, "slope", nullptr},
        bad("max_slope_deg_above_90", {"--max-slope-deg", "91"}, "--max-slope-deg"),
        OptionCase{"outline_cell_mm", on({"--outline", "concave", "--outline-cell-mm", "20"}, dome_l_shaped), 0, "",
                   [](const Outcome& r) {
                     const Outcome fine = fit({"--outline", "concave", "--outline-cell-mm", "4"}, dome_l_shaped());
                     ASSERT_EQ(fine.r.exit_code, 0) << fine.r.err;
                     // A coarser grid traces the outline with fewer vertices.
                     EXPECT_LT(json_number(r.report, "boundary_vertices", "surface"),
                               json_number(fine.report, "boundary_vertices", "surface"));
                   }},
        // Solving
        // The dome at 5 degrees curls at the smoothing given (max_slope_deg above); the ladder
        // finds a stiffer surface that keeps within the slopes.
        OptionCase{"max_smoothing_factor", on({"--max-slope-deg", "5"}), 0, "curled in its first round",
                   [](const Outcome& r) {
                     EXPECT_GT(json_number(r.report, "smoothing_mm4", "fit"), 0.011);
                     EXPECT_NE(r.report.find("\"smoothing_ladder\":[{\"smoothing\":0.01,"), std::string::npos) << r.report;
                     const Outcome off = fit({"--max-slope-deg", "5", "--max-smoothing-factor", "1"});
                     EXPECT_EQ(off.r.exit_code, 1) << off.r.err;
                     EXPECT_EQ(off.r.err.find("curled in its first round"), std::string::npos) << off.r.err;
                   }},
        bad("max_smoothing_factor_below_1", {"--max-smoothing-factor", "0.5"}, "--max-smoothing-factor"),
        bad("max_smoothing_factor_nan", {"--max-smoothing-factor", "nan"}, "--max-smoothing-factor"),
        OptionCase{"cg_tolerance", on({"--solver", "cg", "--cg-tolerance", "1e-14"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "solver", "fit"), "\"cg\"");
                     EXPECT_LT(json_number(r.report, "rms_mm", "residuals"), 0.02);
                   }},
        bad("cg_tolerance_zero", {"--solver", "cg", "--cg-tolerance", "0"}, "--cg-tolerance"),
        OptionCase{"noise_mm", on({"--noise-mm", "0.01"}), 0, "",
                   // The smoothing chosen so the residuals match the points' 0.01 mm noise (Reinsch).
                   [](const Outcome& r) {
                     const double chosen = json_number(r.report, "smoothing_mm4", "fit");
                     const double plain = json_number(fit({}).report, "smoothing_mm4", "fit");
                     ASSERT_TRUE(std::isfinite(chosen) && std::isfinite(plain)) << r.report;
                     EXPECT_NE(chosen, plain);
                     EXPECT_NEAR(json_number(r.report, "rms_mm", "residuals"), 0.01, 0.003) << r.report;
                   }},
        bad("noise_mm_negative", {"--noise-mm=-1"}, "--noise-mm"),
        // --preset features: weights by sigma (this cloud has none: refused naming it) and smoothing
        // of order 3; an option given wins.
        OptionCase{"preset_features", on({"--preset", "features"}), 1, "sigma_mm", nullptr},
        OptionCase{"preset_features_order", on({"--preset", "features"}, dome_with_sigma), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "weight_by_sigma"), "true");
                     EXPECT_EQ(json_number(r.report, "smoothing_order"), 3);
                     const Outcome second = fit({"--preset", "features", "--smoothing-order", "2"}, dome_with_sigma());
                     EXPECT_EQ(json_number(second.report, "smoothing_order"), 2) << "the option given wins";
                   }},
        bad("preset_unknown", {"--preset", "fast"}, "--preset"),
        OptionCase{"no_correction", on({"--no-correction"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_raw(r.report, "parameter_correction", "fit"), "false");
                     EXPECT_EQ(json_raw(fit({}).report, "parameter_correction", "fit"), "true");
                   }},
        OptionCase{"max_rounds", on({"--max-rounds", "1"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(rounds(r.report), 1u) << r.report;
                     EXPECT_GT(rounds(fit({}).report), 1u);
                   }},
        bad("max_rounds_zero", {"--max-rounds", "0"}, "--max-rounds"),
        OptionCase{"min_gain", on({"--min-gain", "0.9"}), 0, "",
                   // No round after the first lowers the RMS by 90 %: the second is the last.
                   [](const Outcome& r) { EXPECT_EQ(rounds(r.report), 2u) << r.report; }},
        bad("min_gain_one", {"--min-gain", "1"}, "--min-gain"),
        OptionCase{"robust_threshold", on({"--robust", "reject", "--robust-threshold", "3"}), 0, "",
                   [](const Outcome& r) {
                     const double scale = json_number(r.report, "robust_scale_mm", "fit");
                     EXPECT_NEAR(json_number(r.report, "robust_cutoff_mm", "fit"), 3 * scale, 1e-9 + 1e-9 * scale);
                   }},
        bad("robust_threshold_negative", {"--robust-threshold", "-1"}, "--robust-threshold"),
        OptionCase{"robust_floor_mm", on({"--robust", "reject", "--robust-floor-mm", "0.5"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_GE(json_number(r.report, "robust_scale_mm", "fit"), 0.5);
                     EXPECT_EQ(json_number(r.report, "outliers", "fit"), 0);
                   }},
        bad("robust_floor_mm_zero", {"--robust-floor-mm", "0"}, "--robust-floor-mm"),
        // Tolerance search
        OptionCase{"cv_folds", on({"--tolerance", "0.2", "--cv-folds", "3"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_number(r.report, "folds", "tolerance"), 3); }},
        bad("cv_folds_one", {"--tolerance", "0.05", "--cv-folds", "1"}, "--cv-folds"),
        bad("cv_folds_one_without_tolerance", {"--cv-folds", "1"}, "--cv-folds"),
        bad("tolerance_zero", {"--tolerance", "0"}, "--tolerance"),
        bad("tolerance_negative", {"--tolerance=-0.1"}, "--tolerance"),
        OptionCase{"max_poles", on({"--tolerance", "0.001", "--max-poles", "8"}), 1, "", nullptr},
        bad("max_poles_below_degree", {"--tolerance", "0.05", "--max-poles", "3"}, "--max-poles")),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill::fitsurf

namespace photomill::fitsurf {
namespace {

// --uncertainty writes the height's sigma grid (formats/uncertainty.hpp) at --uncertainty-cell-mm.
TEST(FitsurfUncertaintyOption, WritesTheGridAtItsCell) {
  TempDir dir;
  const std::string grid = (dir.path() / "u.csv").string(), surface = (dir.path() / "s.txt").string();
  const ToolResult r = run_tool("fitsurf", {"--uncertainty", grid, "--uncertainty-cell-mm", "2", "-o", surface, "-"}, dome());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("uncertainty: height sigma"), std::string::npos) << r.err;
  std::istringstream in(photomill::test::read_file(grid));
  const UncertaintyGrid g = read_uncertainty_grid(in, grid);
  EXPECT_DOUBLE_EQ(g.step_mm, 2);
  EXPECT_GT(g.nx * g.ny, 100u);
  const double top = *std::max_element(g.sigma_mm.begin(), g.sigma_mm.end());
  EXPECT_GT(top, 0);
  EXPECT_LT(top, 1);  // 0.01 mm noise, 1500 points
}

TEST(FitsurfUncertaintyOption, RefusesABadCellAndStdout) {
  const ToolResult zero = run_tool("fitsurf", {"--uncertainty", "u.csv", "--uncertainty-cell-mm", "0", "-"}, dome());
  EXPECT_EQ(zero.exit_code, 2);
  EXPECT_NE(zero.err.find("--uncertainty-cell-mm"), std::string::npos) << zero.err;
  const ToolResult out = run_tool("fitsurf", {"--uncertainty", "-", "-o", "s.txt", "-"}, dome());
  EXPECT_EQ(out.exit_code, 2);
  EXPECT_NE(out.err.find("only -o may write to stdout"), std::string::npos) << out.err;
}

}  // namespace
}  // namespace photomill::fitsurf
