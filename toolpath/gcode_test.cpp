// The post: number formatting, program structure, the rapid splitting, refusals; and a real path
// read back by an independent Python G-code reader (toolpath/gcode_check.py) and compared with
// its CL data move by move.
#include "toolpath/gcode.hpp"

#include <fstream>
#include <sstream>

#include <limits>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/toolpath.hpp"

namespace photomill::toolpath {
namespace {

struct NumberCase {
  double value;
  int decimals;
  const char* text;
};

class GcodeNumber : public ::testing::TestWithParam<NumberCase> {};

TEST_P(GcodeNumber, FixedPointWithoutTrailingZeros) {
  EXPECT_EQ(gcode_number(GetParam().value, GetParam().decimals), GetParam().text);
}

INSTANTIATE_TEST_SUITE_P(Values, GcodeNumber,
                         ::testing::Values(NumberCase{12.5, 4, "12.5"}, NumberCase{-0.00001, 4, "0"},
                                           NumberCase{1e-4, 4, "0.0001"}, NumberCase{3.0, 4, "3"},
                                           NumberCase{-75.123456, 4, "-75.1235"}, NumberCase{1e7, 4, "10000000"},
                                           NumberCase{0.5, 0, "0"}, NumberCase{1200, 1, "1200"}));

ClData small_cl() {
  ClData cl;
  cl.part_name = "bracket (left)";
  cl.tool_diameter_mm = 6;
  cl.tool_corner_radius_mm = 3;
  cl.spindle_rpm = 12000;
  cl.coolant = true;
  cl.moves = {{ClMove::Kind::Rapid, {0, 0, 40}, std::nullopt, 0},
              {ClMove::Kind::Rapid, {0, 0, 11}, std::nullopt, 0},
              {ClMove::Kind::Feed, {0, 0, 10}, std::nullopt, 300},
              {ClMove::Kind::Feed, {5, 0, 10.25}, std::nullopt, 1000},
              {ClMove::Kind::Feed, {10, 0, 10.5}, std::nullopt, 1000},
              {ClMove::Kind::Rapid, {10, 0, 40}, std::nullopt, 0}};
  return cl;
}

std::string post(const ClData& cl, const GcodeOptions& o = {}) {
  std::ostringstream out;
  write_gcode(out, cl, o, "test.cl");
  return out.str();
}

TEST(Gcode, ProgramStructure) {
  const std::string g = post(small_cl());
  EXPECT_EQ(g,
            "(photomill clpost: bracket  left )\n"
            "(tool D6 R3 mm, Z = tool tip)\n"
            "G21 G90 G94 G17\n"
            "G0 Z40\n"
            "S12000 M3\n"
            "M8\n"
            "G0 X0 Y0 Z40\n"
            "G0 Z11\n"
            "G1 Z10 F300\n"
            "G1 X5 Z10.25 F1000\n"
            "G1 X10 Z10.5\n"
            "G0 Z40\n"
            "M9\n"
            "M5\n"
            "M30\n");
}

TEST(Gcode, OptionsChangeTheFrame) {
  GcodeOptions o;
  o.spindle = false;
  o.coolant = CoolantMode::Off;
  o.end = ProgramEnd::M2;
  o.percent = true;
  o.safe_z_mm = 50;
  const std::string g = post(small_cl(), o);
  EXPECT_EQ(g.rfind("%\n", 0), 0u);
  EXPECT_NE(g.find("G0 Z50\n"), std::string::npos);
  EXPECT_EQ(g.find("M3"), std::string::npos);
  EXPECT_EQ(g.find("M8"), std::string::npos);
  EXPECT_NE(g.find("M2\n%\n"), std::string::npos);
  o.safe_z_mm = 20;  // below the CL data's own rapid plane
  EXPECT_THROW(post(small_cl(), o), UsageError);
}

TEST(Gcode, RefusesNonsenseSafeZAndSpindleSpeeds) {
  for (double z : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    GcodeOptions o;
    o.safe_z_mm = z;
    EXPECT_THROW(post(small_cl(), o), UsageError) << z;
  }
  for (double rpm : {0.0, -12000.0, std::numeric_limits<double>::quiet_NaN()}) {
    GcodeOptions o;
    o.spindle_rpm = rpm;
    EXPECT_THROW(post(small_cl(), o), UsageError) << rpm;
  }
  // Without any speed the program is still written (a spindle started by hand), with a warning
  // (tested through clpost in toolpath_cli_test): no S or M3 in it.
  ClData no_speed = small_cl();
  no_speed.spindle_rpm.reset();
  EXPECT_EQ(post(no_speed).find("M3\n"), std::string::npos);  // (M30 ends the program)
}

TEST(Gcode, DiagonalRapidsAreSplitSoTheToolNeverDescendsAcross) {
  ClData cl = small_cl();
  // From (10, 0, 40): down and across in one rapid, then up and across.
  cl.moves.push_back({ClMove::Kind::Rapid, {20, 5, 15}, std::nullopt, 0});
  cl.moves.push_back({ClMove::Kind::Rapid, {30, 5, 45}, std::nullopt, 0});
  const std::string g = post(cl);
  EXPECT_NE(g.find("G0 X20 Y5\nG0 Z15\n"), std::string::npos) << g;  // across at height, then down
  EXPECT_NE(g.find("G0 Z45\nG0 X30\n"), std::string::npos) << g;     // up first, then across
}

TEST(Gcode, RefusesWhatA3AxisMillCannotRun) {
  ClData tilted = small_cl();
  tilted.moves[3].axis = Eigen::Vector3d(0, 0.6, 0.8);
  EXPECT_THROW(post(tilted), InputError);
  ClData plus_z = small_cl();
  plus_z.moves[3].axis = Eigen::Vector3d(0, 0, 1);
  EXPECT_NO_THROW(post(plus_z));
  EXPECT_THROW(post(ClData{}), InputError);
  GcodeOptions o;
  o.decimals = 9;
  EXPECT_THROW(post(small_cl(), o), UsageError);
}

// Every line within grbl's 80-character buffer, whatever the part name.
TEST(Gcode, LinesFitGrblsBuffer) {
  ClData cl = small_cl();
  cl.part_name = std::string(300, 'x') + "(nested)";
  std::istringstream lines(post(cl));
  for (std::string line; std::getline(lines, line);) EXPECT_LE(line.size(), 80u) << line;
}

// A real path through the independent reader: every CL move found in the G-code.
TEST(Gcode, IndependentReaderSeesTheSameMovesAsTheClData) {
  ToolpathOptions o;
  o.scallop_mm = 0.05;
  o.chord_tol_mm = 0.02;
  o.spindle_rpm = 10000;
  o.coolant = true;
  BSplineSurface s = test::cylinder_surface(20, true);
  s.boundary_uv = {{0.1, 0.1}, {0.9, 0.2}, {0.8, 0.9}, {0.2, 0.8}};  // retracts and links both
  const ToolpathResult r = generate_toolpath(s, o);
  photomill::test::TempDir dir;
  const auto ngc = dir.path() / "part.ngc", csv = dir.path() / "part.csv";
  {
    std::ofstream g(ngc);
    write_gcode(g, r.cl, {}, "part.cl");
    std::ofstream c(csv);
    write_cl_csv(c, r.cl);
  }
  const photomill::test::ToolResult res = photomill::test::run_tool(
      "/usr/bin/env", {"python3", std::string(PHOTOMILL_SOURCE_DIR) + "/toolpath/gcode_check.py", ngc.string(), csv.string()});
  EXPECT_EQ(res.exit_code, 0) << res.out << res.err;
  EXPECT_NE(res.out.find("ok: " + std::to_string(r.cl.moves.size()) + " CL moves"), std::string::npos) << res.out;

  // The reader is not a rubber stamp: a G-code line moved by 0.01 mm is caught.
  std::ifstream in(ngc);
  std::stringstream text;
  text << in.rdbuf();
  std::string program = text.str();
  const auto at = program.find("G1 X");
  ASSERT_NE(at, std::string::npos);
  program.insert(at + 4, "1");  // X12.3 -> X112.3
  std::ofstream(ngc) << program;
  const photomill::test::ToolResult bad = photomill::test::run_tool(
      "/usr/bin/env", {"python3", std::string(PHOTOMILL_SOURCE_DIR) + "/toolpath/gcode_check.py", ngc.string(), csv.string()});
  EXPECT_EQ(bad.exit_code, 1) << bad.out;
}

}  // namespace
}  // namespace photomill::toolpath
