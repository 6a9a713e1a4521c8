// One case per calib option of the model, the optimisers and the quality checks (issue 22): the
// option parses and has its documented effect (docs/calib.md, --help) in the JSON report; a value
// out of its range exits 2 naming the option. Input: the demo's ChArUco observations (10 views).
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::calib {
namespace {

using photomill::test::json_array;
using photomill::test::json_number;
using photomill::test::json_raw;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

const std::string kDemo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";

struct Outcome {
  ToolResult r;
  std::string report;
};

Outcome calib(std::vector<std::string> args) {
  TempDir dir;
  const auto report = dir.path() / "report.json";
  args.insert(args.end(), {kDemo + "board_observations.csv", "--control", kDemo + "board_points.csv", "--image-size",
                           "2000x1500", "--report", report.string(), "-o", (dir.path() / "camera.yaml").string()});
  Outcome run{run_tool("calib", args), ""};
  run.report = photomill::test::read_file(report);
  return run;
}

const Outcome& plain() {
  static const Outcome run = calib({});
  return run;
}

std::vector<double> distortion(const Outcome& r) { return json_array(r.report, "distortion", "camera"); }
std::size_t rejected(const Outcome& r) { return photomill::test::count_of(r.report, "\"rejected\":true"); }

struct OptionCase {
  const char* name;
  std::vector<std::string> args;
  int exit_code;
  std::string stderr_has;
  std::function<void(const Outcome&)> check;
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class CalibOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(CalibOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = calib(c.args);
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

TEST(CalibOption, PlainRunEstimatesEveryCoefficient) {
  // The baseline the cases compare with: fx != fy, p1, p2, k3 free, 5 coefficients.
  ASSERT_EQ(plain().r.exit_code, 0) << plain().r.err;
  const auto d = distortion(plain());
  ASSERT_EQ(d.size(), 5u) << plain().report;
  EXPECT_NE(d[2], 0);
  EXPECT_NE(d[3], 0);
  EXPECT_NE(d[4], 0);
  EXPECT_NE(json_number(plain().report, "fx_px", "camera"), json_number(plain().report, "fy_px", "camera"));
}

OptionCase bad(const char* name, std::vector<std::string> args, std::string option) {
  return {name, std::move(args), 2, std::move(option), nullptr};
}

INSTANTIATE_TEST_SUITE_P(
    Options, CalibOption,
    ::testing::Values(
        OptionCase{"fix_aspect_ratio", {"--fix-aspect-ratio"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "fx_px", "camera"), json_number(r.report, "fy_px", "camera"));
                     EXPECT_EQ(json_raw(r.report, "fix_aspect_ratio", "model"), "true");
                   }},
        OptionCase{"fix_principal_point", {"--fix-principal-point"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_NEAR(json_number(r.report, "cx_px", "camera"), 999.5, 0.5);
                     EXPECT_NEAR(json_number(r.report, "cy_px", "camera"), 749.5, 0.5);
                     EXPECT_EQ(json_raw(r.report, "fix_principal_point", "model"), "true");
                   }},
        OptionCase{"zero_tangent", {"--zero-tangent"}, 0, "",
                   [](const Outcome& r) {
                     const auto d = distortion(r);
                     ASSERT_EQ(d.size(), 5u);
                     EXPECT_EQ(d[2], 0);
                     EXPECT_EQ(d[3], 0);
                     EXPECT_NE(d[0], 0);
                   }},
        OptionCase{"fix_k3", {"--fix-k3"}, 0, "",
                   [](const Outcome& r) {
                     const auto d = distortion(r);
                     ASSERT_EQ(d.size(), 5u);
                     EXPECT_EQ(d[4], 0);
                     EXPECT_NE(d[0], 0);
                   }},
        OptionCase{"rational_model", {"--rational-model"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(distortion(r).size(), 8u) << r.report;
                     EXPECT_EQ(json_raw(r.report, "rational", "model"), "true");
                   }},
        OptionCase{"max_iterations", {"--optimizer", "lm", "--max-iterations", "2"}, 0, "",
                   [](const Outcome& r) {
                     // Ceres stops after 2 iterations (its report's "iterations" also counts iteration 0).
                     EXPECT_EQ(json_raw(r.report, "converged", "optimizer_stats"), "false");
                     EXPECT_NE(r.r.err.find("Number of iterations: 2."), std::string::npos) << r.r.err;
                   }},
        bad("max_iterations_zero", {"--max-iterations", "0"}, "--max-iterations"),
        OptionCase{"simplex_scaling", {"--optimizer", "simplex", "--simplex-scaling", "diagonal",
                                       "--simplex-max-evaluations", "3000"}, 0, "",
                   [](const Outcome& r) { EXPECT_EQ(json_raw(r.report, "simplex_scaling", "optimizer_stats"), "\"diagonal\""); }},
        bad("simplex_scaling_bad", {"--simplex-scaling", "whitened"}, "--simplex-scaling"),
        OptionCase{"simplex_max_evaluations", {"--optimizer", "simplex", "--simplex-max-evaluations", "500"}, 0, "",
                   [](const Outcome& r) {
                     const double n = json_number(r.report, "evaluations", "optimizer_stats");
                     EXPECT_GT(n, 0);
                     EXPECT_LE(n, 500);
                   }},
        bad("simplex_max_evaluations_zero", {"--simplex-max-evaluations", "0"}, "--simplex-max-evaluations"),
        OptionCase{"simplex_ftol", {"--optimizer", "simplex", "--simplex-ftol", "0.5", "--simplex-max-evaluations", "5000"}, 0, "",
                   [](const Outcome& r) {
                     // A loose tolerance ends the runs far sooner than the default's.
                     const Outcome tight = calib({"--optimizer", "simplex", "--simplex-max-evaluations", "5000"});
                     EXPECT_LT(json_number(r.report, "evaluations", "optimizer_stats"),
                               json_number(tight.report, "evaluations", "optimizer_stats"));
                   }},
        bad("simplex_ftol_negative", {"--simplex-ftol", "-1"}, "--simplex-ftol"),
        OptionCase{"reject_factor", {"--reject-factor", "1.01", "--reject-min-px", "0"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "factor", "rejection"), 1.01);
                     EXPECT_GT(rejected(r), 0u) << r.report;
                     // 0: never.
                     EXPECT_EQ(rejected(calib({"--reject-factor", "0", "--reject-min-px", "0"})), 0u);
                   }},
        bad("reject_factor_negative", {"--reject-factor", "-1"}, "--reject-factor"),
        OptionCase{"reject_min_px", {"--reject-factor", "1.01", "--reject-min-px", "100"}, 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(json_number(r.report, "min_px", "rejection"), 100);
                     EXPECT_EQ(rejected(r), 0u) << "no view has an RMS above 100 px";
                   }},
        bad("reject_min_px_negative", {"--reject-min-px", "-0.5"}, "--reject-min-px"),
        OptionCase{"min_views", {"--min-views", "20"}, 0, "",
                   [](const Outcome& r) {
                     // Warn below this many views ...
                     EXPECT_EQ(json_number(r.report, "min_views", "rejection"), 20);
                     EXPECT_NE(r.r.err.find("warning: only 10 views used"), std::string::npos) << r.r.err;
                     EXPECT_EQ(plain().r.err.find("views used"), std::string::npos) << plain().r.err;
                     // ... and rejection keeps at least this many.
                     EXPECT_LE(rejected(calib({"--reject-factor", "1.01", "--reject-min-px", "0", "--min-views", "9"})), 1u);
                   }},
        bad("min_views_zero", {"--min-views", "0"}, "--min-views"),
        OptionCase{"min_points", {"--min-points", "1000"}, 1, "no view has the 1000 control points", nullptr},
        bad("min_points_three", {"--min-points", "3"}, "--min-points")),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill::calib
