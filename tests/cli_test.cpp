// Golden CLI cases for every photomill executable, in the manner of PROJ's test_cct.yaml: the
// arguments, standard input, expected exit code, and substrings expected on stdout and stderr.
// Stage-specific cases (bad inputs, pipes) live beside each stage; this table checks the tool
// contract every binary shares.
#include <gtest/gtest.h>

#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::test {
namespace {

struct CliCase {
  std::string tool;
  std::vector<std::string> args;
  std::string stdin_text;
  int exit_code;
  std::string stdout_has;   // empty: stdout must be empty
  std::string stderr_has;   // empty: not checked
};

void PrintTo(const CliCase& c, std::ostream* os) {
  *os << c.tool;
  for (const auto& a : c.args) *os << " " << a;
}

class Cli : public ::testing::TestWithParam<CliCase> {};

TEST_P(Cli, GoldenCase) {
  const CliCase& c = GetParam();
  const ToolResult r = run_tool(c.tool, c.args, c.stdin_text);
  EXPECT_EQ(r.exit_code, c.exit_code) << "stderr: " << r.err;
  if (c.stdout_has.empty()) {
    EXPECT_EQ(r.out, "") << "stdout must carry nothing here";
  } else {
    EXPECT_NE(r.out.find(c.stdout_has), std::string::npos) << r.out;
  }
  if (!c.stderr_has.empty()) {
    EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  }
}

const std::vector<std::string> kStages{"calib", "detect", "match", "triangulate", "densify", "fitsurf", "toolpath", "clpost", "targets", "report", "pick"};

// The contract every binary shares: --help (with the example) and --version exit 0 on stdout;
// an unknown option is bad usage (exit 2) named on stderr.
std::vector<CliCase> contract_cases() {
  std::vector<CliCase> cases;
  for (const auto& t : kStages) {
    cases.push_back({t, {"--help"}, "", 0, "Example:", ""});
    cases.push_back({t, {"--version"}, "", 0, t + " (photomill) ", ""});
    cases.push_back({t, {"--no-such-option"}, "", 2, "", "--no-such-option"});
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Contract, Cli, ::testing::ValuesIn(contract_cases()));

// Stages whose issue has not landed yet: they must say so and fail, never fake output.
std::vector<CliCase> unbuilt_cases() {
  std::vector<CliCase> cases;
  for (const auto& t : kStages) {
    // A stage that is built gets real golden cases in its own test file instead.
    const ToolResult probe = run_tool(t, {}, "");
    if (probe.err.find("not built yet") == std::string::npos) continue;
    cases.push_back({t, {}, "", 1, "", t + ": this stage is not built yet"});
    cases.push_back({t, {"-"}, "some input\n", 1, "", "not built yet"});
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Unbuilt, Cli, ::testing::ValuesIn(unbuilt_cases()));
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(Cli);

// Progress on stderr without -v (issue 27): every long stage names the step it is in. With
// PHOTOMILL_PROGRESS_AFTER_S=0 every step prints at its start (by default only steps that last
// 2 s do, which a test must not time); -q prints nothing. The demo's true marker observations
// through match, triangulate, then the demo's scan sample through fitsurf and toolpath.
TEST(Progress, EveryStageNamesItsStepsWithoutVerbose) {
  TempDir dir;
  const std::string demo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";
  const std::string tracks = (dir.path() / "tracks.csv").string(), cloud = (dir.path() / "cloud.ply").string();
  const std::string surface = (dir.path() / "surface.txt").string();
  struct Run {
    std::string tool;
    std::vector<std::string> args;
    std::vector<std::string> steps;
  };
  const std::vector<Run> runs = {
      {"match", {demo + "observations.csv", "--camera", demo + "camera.yaml", "-o", tracks}, {"match: matching"}},
      {"triangulate",
       {tracks, "--camera", demo + "camera.yaml", "--control-points", demo + "control_points.csv", "-o", cloud},
       {"triangulate: orienting 12 images", "triangulate: final bundle adjustment of 12 images",
        "triangulate: uncertainty of every point"}},
      {"fitsurf",
       {demo + "surface.ply", "--keep-box", "-85,-60,-5,85,60,100", "--net", "20x14", "-o", surface},
       {"fitsurf: selecting the part's points", "fitsurf: fitting ", "fitsurf: the data's outline"}},
      {"toolpath", {surface, "--tool-radius-mm", "3", "--scallop-mm", "0.05", "--verify", "-o", "/dev/null"},
       {"toolpath: planning the passes", "toolpath: verifying the path on a z-map"}},
  };
  ::setenv("PHOTOMILL_PROGRESS_AFTER_S", "0", 1);
  for (const Run& run : runs) {
    const ToolResult r = run_tool(run.tool, run.args);
    ASSERT_EQ(r.exit_code, 0) << run.tool << ": " << r.err;
    for (const auto& step : run.steps) EXPECT_NE(r.err.find(step), std::string::npos) << step << "\n" << r.err;
    std::vector<std::string> quiet = run.args;
    quiet.insert(quiet.begin(), "-q");
    const ToolResult q = run_tool(run.tool, quiet);
    EXPECT_EQ(q.exit_code, 0) << run.tool << ": " << q.err;
    EXPECT_EQ(q.err, "") << run.tool << " -q";
  }
  ::unsetenv("PHOTOMILL_PROGRESS_AFTER_S");
}

}  // namespace
}  // namespace photomill::test
