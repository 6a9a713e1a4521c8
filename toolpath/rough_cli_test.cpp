// Golden CLI cases for rough (arguments, stdin, exit code, what stdout and stderr must hold), one
// per option, and rough -> clpost.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

namespace fs = std::filesystem;
using photomill::test::count_of;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

// A 40 x 40 mm plate with a dome 8 mm high in its middle.
std::string dome_text() {
  std::ostringstream s;
  write_surface(s, test::interpolate_height_field([](double x, double y) { return 8 * std::exp(-(x * x + y * y) / 50.0); },
                                                  -20, 20, -20, 20, 21, 21));
  return s.str();
}

std::string replace_first(std::string text, const std::string& what, const std::string& with) {
  const auto pos = text.find(what);
  return pos == std::string::npos ? text : text.replace(pos, what.size(), with);
}

// Fast settings for the CLI cases.
std::vector<std::string> quick(std::vector<std::string> args) {
  for (const char* a : {"--cell-mm", "0.5", "--step-down-mm", "4"}) args.push_back(a);
  return args;
}

struct CliCase {
  const char* name;
  std::vector<std::string> args;
  int exit_code;
  std::string stdout_has;  // empty: stdout must be empty
  std::string stderr_has;  // empty: not checked
};

void PrintTo(const CliCase& c, std::ostream* os) { *os << c.name; }

class RoughCli : public ::testing::TestWithParam<CliCase> {};

TEST_P(RoughCli, GoldenCase) {
  const CliCase& c = GetParam();
  const ToolResult r = run_tool("rough", c.args, dome_text());
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  if (c.stdout_has.empty()) {
    EXPECT_EQ(r.out, "");
  } else {
    EXPECT_NE(r.out.find(c.stdout_has), std::string::npos) << r.out.substr(0, 300);
  }
  if (!c.stderr_has.empty()) {
    EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RoughCli,
    ::testing::Values(
        CliCase{"apt", quick({"-"}), 0, "CUTTER/6,0\n", "levels (2 at flats) from z"},
        CliCase{"no_flats", quick({"--flat-tol-mm", "0", "-"}), 0, "GOTO/", "levels (0 at flats) from z"},
        CliCase{"flat_tol_over_step_down", quick({"--flat-tol-mm", "5", "-"}), 2, "", "--flat-tol-mm"},
        CliCase{"csv", quick({"--format", "csv", "-"}), 0, "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nrapid,", ""},
        CliCase{"bad_format", quick({"--format", "nc", "-"}), 2, "", "--format"},
        CliCase{"face_of_text", quick({"--face", "1", "-"}), 2, "", "--face 1"},
        CliCase{"diameter", quick({"--tool-diameter-mm", "8", "-"}), 0, "CUTTER/8,0\n", ""},
        CliCase{"diameter_zero", quick({"--tool-diameter-mm", "0", "-"}), 2, "", "--tool-diameter-mm"},
        CliCase{"bull_nose", quick({"--corner-radius-mm", "1", "-"}), 0, "CUTTER/6,1\n", ""},
        CliCase{"corner_too_big", quick({"--corner-radius-mm", "4", "-"}), 2, "", "--corner-radius-mm"},
        CliCase{"step_down_negative", {"--step-down-mm", "-2", "-"}, 2, "", "--step-down-mm"},
        CliCase{"step_over", quick({"--step-over-mm", "1.5", "-"}), 0, "GOTO/", "step-over 1.500 mm"},
        CliCase{"step_over_too_big", quick({"--step-over-mm", "4", "-"}), 2, "", "--step-over-mm"},
        CliCase{"allowance", quick({"--allowance-mm", "1", "-"}), 0, "GOTO/", "to 1.0"},
        CliCase{"allowance_nan", quick({"--allowance-mm", "nan", "-"}), 2, "", "--allowance-mm"},
        CliCase{"stock_box", quick({"--stock-box-mm", "-15,-15,0,15,15,9", "-"}), 0, "GOTO/",
                "stock -15.000,-15.000,0.000 to 15.000,15.000,9.000 mm"},
        CliCase{"stock_box_five_numbers", quick({"--stock-box-mm", "-15,-15,0,15,15", "-"}), 2, "", "--stock-box-mm"},
        CliCase{"stock_box_not_a_number", quick({"--stock-box-mm", "-15,-15,0,15,1x5,9", "-"}), 2, "", "'1x5' is not a number"},
        CliCase{"stock_box_inverted", quick({"--stock-box-mm", "15,-15,0,-15,15,9", "-"}), 2, "", "--stock-box-mm"},
        CliCase{"stock_box_beside", quick({"--stock-box-mm", "100,100,0,120,120,9", "-"}), 1, "", "does not overlap"},
        CliCase{"stock_below_the_part", quick({"--stock-box-mm", "-15,-15,0,15,15,0.3", "-"}), 1, "", "nothing to cut"},
        CliCase{"stock_margin", quick({"--stock-margin-mm", "0", "-"}), 0, "GOTO/", "to 20.000,20.000,"},
        CliCase{"conventional", quick({"--direction", "conventional", "-"}), 0, "GOTO/", ""},
        CliCase{"bad_direction", quick({"--direction", "up", "-"}), 2, "", "--direction"},
        CliCase{"ramp_angle", quick({"--ramp-angle-deg", "5", "-"}), 0, "GOTO/", ""},
        CliCase{"ramp_angle_steep", quick({"--ramp-angle-deg", "60", "-"}), 2, "", "--ramp-angle-deg"},
        CliCase{"helix_radius", quick({"--helix-radius-mm", "1", "-"}), 0, "GOTO/", ""},
        CliCase{"feeds", quick({"--feed-mm-per-min", "1500", "--plunge-feed-mm-per-min", "250", "-"}), 0, "FEDRAT/MMPM,1500", ""},
        CliCase{"plunge_feed_zero", quick({"--plunge-feed-mm-per-min", "0", "-"}), 2, "", "--plunge-feed-mm-per-min"},
        CliCase{"retract", quick({"--retract-mm", "10", "-"}), 0, "GOTO/", "safe z"},
        CliCase{"clearance_over_retract", quick({"--clearance-mm", "6", "-"}), 2, "", "--clearance-mm"},
        CliCase{"simplify", quick({"--simplify-mm", "0.1", "-"}), 0, "GOTO/", ""},
        CliCase{"simplify_too_big", quick({"--simplify-mm", "5", "-"}), 2, "", "--simplify-mm"},
        CliCase{"work_limit", quick({"--max-moves", "50", "-"}), 1, "", "--max-moves"},
        // Issue #25: every numeric option checked at parse time, the range in --help.
        CliCase{"tool_diameter_nan", quick({"--tool-diameter-mm", "nan", "-"}), 2, "", "--tool-diameter-mm: 'nan' is not in (0, 200]"},
        CliCase{"step_down_absurd", quick({"--step-down-mm", "1e9", "-"}), 2, "", "--step-down-mm: '1e9' is not in (0, 1000]"},
        CliCase{"cell_inf", quick({"--cell-mm", "inf", "-"}), 2, "", "--cell-mm"},
        CliCase{"max_moves_zero", quick({"--max-moves", "0", "-"}), 2, "", "--max-moves"},
        CliCase{"stock_box_absurd", quick({"--stock-box-mm", "-15,-15,0,15,15,1e300", "-"}), 2, "", "beyond ±1e6 mm"},
        CliCase{"help_shows_ranges", {"--help"}, 0, "--tool-diameter-mm FLOAT:in (0, 200]", ""},
        CliCase{"threads", quick({"--threads", "1", "-"}), 0, "GOTO/", ""},
        CliCase{"part_name_spindle_coolant", quick({"--part-name", "dome", "--spindle-rpm", "9000", "--coolant", "-"}), 0,
                "PARTNO/dome", ""},
        CliCase{"verify", quick({"--verify", "--zmap-cell-mm", "0.25", "-"}), 0, "GOTO/", "deepest cut into the allowance 0.000 mm"},
        CliCase{"quiet", quick({"-q", "-"}), 0, "GOTO/", ""},
        CliCase{"missing_file", {"no-such.surf"}, 1, "", "rough: no-such.surf"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(RoughCli, SpindleAndCoolantReachTheClData) {
  const ToolResult r = run_tool("rough", quick({"--spindle-rpm", "9000", "--coolant", "-"}), dome_text());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream in(r.out);
  const ClData cl = read_cl(in, "rough");
  EXPECT_EQ(cl.spindle_rpm, 9000);
  EXPECT_TRUE(cl.coolant);
  EXPECT_DOUBLE_EQ(cl.tool_diameter_mm, 6);
}

TEST(RoughCli, QuietWritesNothingOnStderrAndTheSameData) {
  const ToolResult quiet = run_tool("rough", quick({"-q", "-"}), dome_text());
  EXPECT_EQ(quiet.err, "");
  const ToolResult normal = run_tool("rough", quick({"-"}), dome_text());
  EXPECT_EQ(normal.out, quiet.out);
}

// rough, like toolpath, refuses a surface of arbitrary scale: one line, exit 1, no output; and so
// does cutsim, which compares a tool path in mm with the surface.
TEST(RoughCli, RefusesASurfaceOfArbitraryScale) {
  TempDir dir;
  const fs::path out = dir.path() / "rough.cl", surf = dir.path() / "dome.surf";
  std::ofstream(surf) << replace_first(dome_text(), "\ndegrees ", "\nunits arbitrary\ndegrees ");
  ToolResult r = run_tool("rough", quick({"-o", out.string(), surf.string()}));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "rough: " + surf.string() +
                       ": the surface's scale is arbitrary (fitted from a cloud oriented without a datum): a tool path "
                       "needs mm; give triangulate control points, scale bars, --marker-side-mm or known poses\n");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
  std::ofstream(surf) << dome_text();
  r = run_tool("rough", quick({"-o", out.string(), surf.string()}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ofstream(surf) << replace_first(dome_text(), "\ndegrees ", "\nunits arbitrary\ndegrees ");
  r = run_tool("cutsim", {surf.string(), out.string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(surf.string() + ": the surface's scale is arbitrary"), std::string::npos) << r.err;
}

TEST(RoughCli, OutputFileOnlyOnSuccessAndClpostPostsIt) {
  TempDir dir;
  const fs::path out = dir.path() / "rough.cl", surf = dir.path() / "dome.surf", ngc = dir.path() / "rough.ngc";
  std::ofstream(surf) << dome_text();
  ToolResult r = run_tool("rough", quick({"-o", out.string(), "--max-moves", "10", surf.string()}));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(out));
  r = run_tool("rough", quick({"-o", out.string(), "--spindle-rpm", "12000", surf.string()}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  r = run_tool("clpost", {out.string(), "-o", ngc.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream g(ngc);
  const std::string gcode((std::istreambuf_iterator<char>(g)), std::istreambuf_iterator<char>());
  // The spindle starts before the first feed move.
  const auto spindle = gcode.find("S12000 M3"), first_feed = gcode.find("\nG1 ");
  ASSERT_NE(spindle, std::string::npos);
  ASSERT_NE(first_feed, std::string::npos);
  EXPECT_LT(spindle, first_feed);
}

// Rest machining from the command line: a 10 mm end mill, then a 3 mm one after it; cutsim replays
// both on the stock: neither rapids nor plunges into material. A CSV program carries no cutter.
TEST(RoughCli, RestAfterALargerToolAndCutsimReplaysBoth) {
  TempDir dir;
  const fs::path surf = dir.path() / "dome.surf", big = dir.path() / "big.cl", rest = dir.path() / "rest.cl",
                 csv = dir.path() / "big.csv";
  std::ofstream(surf) << dome_text();
  ToolResult r = run_tool("rough", {"--cell-mm", "0.5", "--tool-diameter-mm", "10", "--step-down-mm", "3", "-o", big.string(),
                                    surf.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_tool("rough", {"--cell-mm", "0.5", "--tool-diameter-mm", "3", "--step-down-mm", "1", "--rest-after", big.string(),
                         "--rest-min-mm", "0.1", "--verify", "-o", rest.string(), surf.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("rest machining after 1 program"), std::string::npos) << r.err;
  r = run_tool("cutsim", {"--allowance-mm", "0.5", surf.string(), big.string(), rest.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(count_of(r.err, "0 rapids and 0 plunges into material"), 2u) << r.err;
  r = run_tool("rough", {"--cell-mm", "0.5", "--tool-diameter-mm", "10", "--step-down-mm", "3", "--format", "csv", "-o",
                         csv.string(), surf.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_tool("rough", {"--cell-mm", "0.5", "--tool-diameter-mm", "3", "--rest-after", csv.string(), "-o", rest.string(),
                         surf.string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no tool size"), std::string::npos) << r.err;
  // The same tool after itself: nothing left (the surface right after --rest-after is the surface).
  r = run_tool("rough", {"--cell-mm", "0.5", "--tool-diameter-mm", "10", "--step-down-mm", "3", "--rest-after", big.string(),
                         surf.string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("nothing left to cut"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  r = run_tool("rough", {"--tool-diameter-mm", "3", "--rest-after", big.string(), "--rest-min-mm", "0", surf.string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--rest-min-mm"), std::string::npos) << r.err;
}

// cutsim on rough's program: every option, its outputs, its refusals.
TEST(CutsimCli, EveryOptionAndItsOutputs) {
  TempDir dir;
  const fs::path surf = dir.path() / "dome.surf", apt = dir.path() / "rough.cl", csv = dir.path() / "rough.csv";
  const fs::path report = dir.path() / "cut.json", picture = dir.path() / "cut.png";
  std::ofstream(surf) << dome_text();
  ASSERT_EQ(run_tool("rough", quick({surf.string(), "-o", apt.string()})).exit_code, 0);
  ASSERT_EQ(run_tool("rough", quick({"--format", "csv", surf.string(), "-o", csv.string()})).exit_code, 0);
  ToolResult r = run_tool("cutsim", {surf.string(), apt.string(), "--cell-mm", "0.5", "--allowance-mm", "0.5", "--plunge-angle-deg", "60",
                                     "--stock-margin-mm", "2", "--threads", "1", "--report", report.string(), "--picture",
                                     picture.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_NE(r.err.find("0 rapids and 0 plunges into material"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("where the last cutter reaches"), std::string::npos) << r.err;
  std::ifstream j(report);
  const std::string json((std::istreambuf_iterator<char>(j)), std::istreambuf_iterator<char>());
  EXPECT_NE(json.find("\"tool\":\"cutsim\""), std::string::npos) << json.substr(0, 200);
  EXPECT_NE(json.find("\"plunge_angle_deg\":60"), std::string::npos);
  EXPECT_GT(fs::file_size(picture), 1000u);
  // A given stock; the CSV program needs its cutter named.
  r = run_tool("cutsim", {surf.string(), csv.string(), "--cell-mm", "0.5", "--stock-box-mm", "-15,-15,0,15,15,9"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("no cutter"), std::string::npos) << r.err;
  r = run_tool("cutsim", {surf.string(), csv.string(), "--cell-mm", "0.5", "--stock-box-mm", "-15,-15,0,15,15,9", "--tool-diameter-mm", "6",
                          "--corner-radius-mm", "0", "-q"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  r = run_tool("cutsim", {surf.string(), apt.string(), "--face", "1"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--face 1"), std::string::npos) << r.err;
  r = run_tool("cutsim", {surf.string(), (dir.path() / "none.cl").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("none.cl"), std::string::npos) << r.err;
  r = run_tool("cutsim", {surf.string()});
  EXPECT_EQ(r.exit_code, 2) << "a CL program is required";
  // Issue #25: numeric options checked at parse time (NaN, absurd values), before any file is read.
  for (const auto& [option, value] : std::vector<std::pair<std::string, std::string>>{
           {"--cell-mm", "nan"}, {"--allowance-mm", "-1"}, {"--plunge-angle-deg", "120"}, {"--stock-margin-mm", "1e300"},
           {"--tool-diameter-mm", "inf"}, {"--corner-radius-mm", "nan"}, {"--threads", "-1"}}) {
    r = run_tool("cutsim", {surf.string(), apt.string(), option, value});
    EXPECT_EQ(r.exit_code, 2) << option << " " << value << ": " << r.err;
    EXPECT_NE(r.err.find(option + ": '" + value + "' is not in "), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace photomill::toolpath
