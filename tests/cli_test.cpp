// Golden CLI cases for every photomill executable, in the manner of PROJ's test_cct.yaml: the
// arguments, standard input, expected exit code, and substrings expected on stdout and stderr.
// Stage-specific cases (bad inputs, pipes) live beside each stage; this table checks the tool
// contract every binary shares.
#include <gtest/gtest.h>

#include "tests/run_tool.hpp"

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

const std::vector<std::string> kStages{"calib", "detect", "match", "triangulate", "fitsurf", "toolpath", "clpost", "targets"};

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

}  // namespace
}  // namespace photomill::test
