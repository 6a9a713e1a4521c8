// Bad usage is exit 2 with one line on stderr (issue #25, "Options"): every numeric option of
// detect, match, calib, clpost and targets (report has none) shows its range in --help and refuses NaN and
// absurd values (1e300) at parse time; a blank file name among the arguments is bad usage (it
// was "cannot open", exit 1, or read stdin); CLI11's own refusals are one line (they were two:
// "Run with --help for more information."); triangulate's "no datum" is bad usage (the options
// fixing the scale are missing: docs/errors.md, "Bad usage").
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "tests/run_tool.hpp"

namespace photomill::test {
namespace {

namespace fs = std::filesystem;

// One --help: a binary, with a subcommand or not.
struct Help {
  std::string binary;
  std::vector<std::string> command;  // {} or {"plate"}
};

void PrintTo(const Help& h, std::ostream* os) {
  *os << h.binary;
  for (const auto& c : h.command) *os << " " << c;
}

// The numeric options of a --help text: (name, the rest of its line after the name).
std::vector<std::pair<std::string, std::string>> numeric_options(const std::string& help) {
  std::vector<std::pair<std::string, std::string>> out;
  const std::regex line(R"(^\s+(?:-\w,)?(--[a-z0-9-]+)(?:,--[a-z0-9-]+)*\s+((?:FLOAT|INT|UINT)\b.*)$)");
  std::istringstream in(help);
  for (std::string l; std::getline(in, l);) {
    std::smatch m;
    if (std::regex_match(l, m, line)) out.emplace_back(m[1].str(), m[2].str());
  }
  return out;
}

// The one line a refusal prints, or a failure naming what it printed instead.
::testing::AssertionResult one_usage_line(const ToolResult& r, const std::string& binary, const std::string& has) {
  if (r.exit_code != 2) return ::testing::AssertionFailure() << "exit " << r.exit_code << ": " << r.err;
  if (!r.out.empty()) return ::testing::AssertionFailure() << "stdout: " << r.out;
  if (r.err.empty() || r.err.find('\n') != r.err.size() - 1) {
    return ::testing::AssertionFailure() << "not one line on stderr:\n" << r.err;
  }
  if (r.err.rfind(binary + ": ", 0) != 0) return ::testing::AssertionFailure() << "not '" << binary << ": ...': " << r.err;
  if (r.err.find(has) == std::string::npos) return ::testing::AssertionFailure() << "'" << has << "' not named: " << r.err;
  return ::testing::AssertionSuccess();
}

class NumericOptions : public ::testing::TestWithParam<Help> {};

// Every numeric option says its range in --help (report has none: its options are a folder, a
// file, a title and a flag) ("in [a - b]", or "in (a - b]" for a quantity
// that must be more than a), and NaN and 1e300 are exit 2 naming it.
TEST_P(NumericOptions, ShowTheirRangeAndRefuseNanAndAbsurdValues) {
  const Help& h = GetParam();
  std::vector<std::string> help_args = h.command;
  help_args.push_back("--help");
  const ToolResult help = run_tool(h.binary, help_args);
  ASSERT_EQ(help.exit_code, 0) << help.err;
  const auto options = numeric_options(help.out);
  ASSERT_FALSE(options.empty()) << help.out;
  // Options of the main command that a subcommand's help repeats are tested there.
  for (const auto& [name, rest] : options) {
    if (name == "--help" || name == "--version") continue;
    // " in [a - b]" (CLI::Range) or ":in (a, b]" (formats/option_checks.hpp).
    EXPECT_TRUE(rest.find("in [") != std::string::npos || rest.find("in (") != std::string::npos)
        << h.binary << " " << name << " shows no range in --help: " << rest;
    // Integer options refuse 1e300 by its conversion; floating-point ones by their range (the
    // lower end of a range is as sure: a process a value, each a few tenths of a second).
    const bool floating = rest.rfind("FLOAT", 0) == 0;
    for (const std::string value : {"nan", "1e300"}) {
      if (!floating && value != "nan") continue;
      std::vector<std::string> args = h.command;
      args.push_back(name + "=" + value);
      TempDir dir;
      const ToolResult r = run_tool(h.binary, args, "", dir.path());
      EXPECT_TRUE(one_usage_line(r, h.binary, name)) << h.binary << " " << name << "=" << value;
      EXPECT_TRUE(fs::is_empty(dir.path())) << h.binary << " " << name << "=" << value << " wrote a file";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Binaries, NumericOptions,
                         ::testing::Values(Help{"detect", {}}, Help{"match", {}}, Help{"calib", {}}, Help{"clpost", {}},
                                           Help{"targets", {"charuco"}}, Help{"targets", {"plate"}}),
                         [](const ::testing::TestParamInfo<Help>& info) {
                           std::string n = info.param.binary;
                           for (const auto& c : info.param.command) n += "_" + c;
                           return n;
                         });

struct UsageCase {
  std::string name;
  std::string binary;
  std::vector<std::string> args;
  std::string has;  // the line names this
};

void PrintTo(const UsageCase& c, std::ostream* os) { *os << c.name; }

class Usage : public ::testing::TestWithParam<UsageCase> {};

TEST_P(Usage, IsExitTwoWithOneLine) {
  const UsageCase& c = GetParam();
  TempDir dir;
  const fs::path demo = fs::path(PHOTOMILL_SOURCE_DIR) / "data" / "demo";
  for (const char* f : {"observations.csv", "camera.yaml", "board_points.csv", "board_observations.csv"}) {
    fs::copy_file(demo / f, dir.path() / f);
  }
  std::string tracks = read_file(demo / "observations.csv");
  tracks.replace(tracks.find("point_id"), 8, "track_id");
  std::ofstream(dir.path() / "tracks.csv", std::ios::binary) << tracks;
  std::set<std::string> names_before;
  for (const auto& e : fs::directory_iterator(dir.path())) names_before.insert(e.path().filename().string());
  const ToolResult r = run_tool(c.binary, c.args, "", dir.path());
  EXPECT_TRUE(one_usage_line(r, c.binary, c.has));
  std::set<std::string> names_after;
  for (const auto& e : fs::directory_iterator(dir.path())) names_after.insert(e.path().filename().string());
  EXPECT_EQ(names_after, names_before) << "a refused run left files behind";
}

INSTANTIATE_TEST_SUITE_P(
    Cases, Usage,
    ::testing::Values(
        // A blank name among the photos or inputs ('' from an empty make variable): bad usage.
        UsageCase{"detect_blank_photo", "detect", {"--aruco", "DICT_4X4_50", "a.png", "", "-o", "m.csv"}, "a blank name"},
        UsageCase{"detect_spaces_photo", "detect", {"--aruco", "DICT_4X4_50", "  ", "-o", "m.csv"}, "a blank name"},
        UsageCase{"calib_blank_input", "calib", {"--control", "board_points.csv", "", "-o", "cam.yaml"}, "a blank name"},
        UsageCase{"match_blank_input", "match", {"observations.csv", "", "-o", "tracks.csv"}, "a blank name"},
        UsageCase{"clpost_blank_input", "clpost", {"", "-o", "part.nc"}, "a blank name"},
        UsageCase{"report_blank_folder", "report", {"", "-o", "r.html"}, "a blank name"},
        // CLI11's refusals: one line (no "Run with --help for more information." after it).
        UsageCase{"detect_unknown_option", "detect", {"--no-such-option"}, "--no-such-option"},
        UsageCase{"calib_excluded_options", "calib", {"--chessboard", "9x6", "--charuco", "5x7", "x.csv"}, "excludes"},
        UsageCase{"match_bad_choice", "match", {"--refine", "best", "observations.csv"}, "--refine"},
        UsageCase{"targets_bad_subcommand_option", "targets", {"plate", "--squares", "5x7"}, "--squares"},
        // No datum: none of the options that fix the scale was given (bad usage, not bad data).
        UsageCase{"triangulate_no_datum", "triangulate", {"-c", "camera.yaml", "tracks.csv", "-o", "cloud.ply"},
                  "triangulate: no datum: give control points (--control-points)"}),
    [](const ::testing::TestParamInfo<UsageCase>& info) { return info.param.name; });

}  // namespace
}  // namespace photomill::test
