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

namespace photomill::toolpath {
namespace {

// gcode_check.py on a program file against CL CSV files, with extra arguments.
photomill::test::ToolResult check_program(const std::string& program, const std::vector<ClData>& cls,
                                          std::vector<std::string> extra = {}) {
  photomill::test::TempDir dir;
  const auto ngc = dir.path() / "part.ngc";
  std::ofstream(ngc) << program;
  std::vector<std::string> args{"python3", std::string(PHOTOMILL_SOURCE_DIR) + "/toolpath/gcode_check.py", ngc.string()};
  for (std::size_t i = 0; i < cls.size(); ++i) {
    const auto csv = dir.path() / ("part" + std::to_string(i) + ".csv");
    std::ofstream c(csv);
    write_cl_csv(c, cls[i]);
    args.push_back(csv.string());
  }
  args.insert(args.end(), extra.begin(), extra.end());
  return photomill::test::run_tool("/usr/bin/env", args);
}

const char* dialect_name(Dialect d) {
  switch (d) {
    case Dialect::Generic: return "generic";
    case Dialect::LinuxCnc: return "linuxcnc";
    case Dialect::Grbl: return "grbl";
    case Dialect::Fanuc: return "fanuc";
    case Dialect::Mach3: return "mach3";
  }
  return "";
}

ClData ridge_cl() {
  ToolpathOptions o;
  o.scallop_mm = 0.05;
  o.chord_tol_mm = 0.02;
  o.spindle_rpm = 10000;
  o.coolant = true;
  BSplineSurface s = test::cylinder_surface(20, true);
  s.boundary_uv = {{0.1, 0.1}, {0.9, 0.2}, {0.8, 0.9}, {0.2, 0.8}};
  return generate_toolpath(s, o).cl;
}

class GcodeDialect : public ::testing::TestWithParam<Dialect> {};

// Every dialect's program of a real path, read by the independent reader with that controller's
// documented word set: no word outside it, the spindle turning before every feed, every CL move
// found (Fanuc: to its 3 decimals).
TEST_P(GcodeDialect, IndependentReaderAcceptsItsWordsAndFindsEveryMove) {
  static const ClData cl = ridge_cl();
  GcodeOptions o;
  o.dialect = GetParam();
  std::ostringstream out;
  write_gcode(out, cl, o, "part.cl");
  const auto r = check_program(out.str(), {cl}, {"--dialect", dialect_name(GetParam()), "--tol", "0.0006"});
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("ok: " + std::to_string(cl.moves.size()) + " CL moves"), std::string::npos) << r.out;
  // And with fitted arcs, every CL point within the tolerance of the posted path.
  o.arc_tol_mm = 0.02;
  std::ostringstream arcs;
  write_gcode(arcs, cl, o, "part.cl");
  const auto ra = check_program(arcs.str(), {cl}, {"--dialect", dialect_name(GetParam()), "--tol", "0.0006", "--path-tol", "0.021"});
  EXPECT_EQ(ra.exit_code, 0) << ra.out << ra.err;
}

// Each dialect's frame, in order: what it must write and what it must not.
TEST_P(GcodeDialect, FrameWordsInOrder) {
  GcodeOptions o;
  o.dialect = GetParam();
  const std::string g = post(small_cl(), o);
  const auto at = [&](const std::string& s) { return g.find(s); };
  const auto before = [&](const std::string& a, const std::string& b) {
    ASSERT_NE(at(a), std::string::npos) << a << "\n" << g;
    ASSERT_NE(at(b), std::string::npos) << b << "\n" << g;
    EXPECT_LT(at(a), at(b)) << a << " before " << b << "\n" << g;
  };
  switch (GetParam()) {
    case Dialect::Generic:
      EXPECT_EQ(g, post(small_cl()));
      break;
    case Dialect::LinuxCnc:
      before("G21 G90 G94 G17 G40 G49 G80\nG64 P0.005\n", "T1 M6\nG0 G43 H1 Z40\nS12000 M3\nM8\n");
      before("S12000 M3", "G1 ");
      EXPECT_EQ(at("%"), std::string::npos);
      break;
    case Dialect::Grbl:
      before("G21 G90 G94 G17\nG0 Z40\nS12000 M3\nM8\n", "G1 ");
      for (const char* word : {"\nT1", "M6", "G43", "G64", "%", "\nO1"}) EXPECT_EQ(at(word), std::string::npos) << word;
      break;
    case Dialect::Fanuc:
      EXPECT_EQ(g.rfind("%\nO1000\n(PHOTOMILL CLPOST: BRACKET  LEFT )\n", 0), 0u) << g;
      before("G21\nG17 G40 G49 G80 G90 G94\nG54\n", "T1 M06\nG0 G43 H1 Z40.\nS12000 M03\nM08\n");
      before("M08", "G1 Z10. F300.\nG1 X5. Z10.25 F1000.\n");
      EXPECT_EQ(g.substr(g.size() - 14), "M09\nM05\nM30\n%\n");
      break;
    case Dialect::Mach3:
      before("G21 G90 G94 G17 G40 G49 G80\nG64\n", "T1 M6\nG0 G43 H1 Z40\nS12000 M3\nM8\n");
      EXPECT_EQ(at("G64 P"), std::string::npos);
      break;
  }
  std::istringstream lines(g);
  for (std::string line; std::getline(lines, line);) EXPECT_LE(line.size(), 80u) << line;
}

INSTANTIATE_TEST_SUITE_P(All, GcodeDialect,
                         ::testing::Values(Dialect::Generic, Dialect::LinuxCnc, Dialect::Grbl, Dialect::Fanuc, Dialect::Mach3),
                         [](const auto& info) { return std::string(dialect_name(info.param)); });

// Two CL files, two tools: the tool list and the estimate in the header, the spindle stopped
// before and started after each change, before any feed; the reader follows both files.
TEST(Gcode, SeveralClInputsOneToolEach) {
  ClData rough = small_cl(), finish = small_cl();
  rough.tool_diameter_mm = 10;
  rough.tool_corner_radius_mm = 1;
  rough.spindle_rpm = 8000;
  finish.coolant = false;
  for (ClMove& m : finish.moves) m.tip_mm.x() += 20;
  GcodeOptions o;
  o.dialect = Dialect::LinuxCnc;
  o.tool_numbers = {3, 5};
  std::ostringstream out;
  const PostStats st = write_gcode(out, {{rough, "rough.cl"}, {finish, "finish.cl"}}, o);
  const std::string g = out.str();
  EXPECT_NE(g.find("(T3 D10 R1 mm, Z = tool tip: rough.cl)\n(T5 D6 R3 mm, Z = tool tip: finish.cl)\n"), std::string::npos) << g;
  EXPECT_NE(g.find("G0 Z40\nM9\nM5\nT5 M6\nG0 G43 H5 Z40\nS12000 M3\nG0 X20 Y0 Z40\n"), std::string::npos) << g;
  EXPECT_EQ(st.tool_changes, 2u);
  // Feed: 1 + 2 x sqrt(25 + 0.0625) mm per file, at 300 and 1000 mm/min; rapids (from the first
  // known position): 29 down, 29.5 up, 10 across (X10 -> X20), 29 down, 29.5 up; 15 s per change.
  const double seg = std::sqrt(25 + 0.0625);
  const double feed_s = 2 * (1.0 / 300 + 2 * seg / 1000) * 60;
  const double rapid_mm = 29 + 29.5 + 10 + 29 + 29.5;
  EXPECT_NEAR(st.feed_mm, 2 * (1 + 2 * seg), 1e-9);
  EXPECT_NEAR(st.rapid_mm, rapid_mm, 1e-9);
  EXPECT_NEAR(st.time_s, feed_s + rapid_mm / 5000 * 60 + 2 * 15, 1e-9);
  EXPECT_NE(g.find("(estimated cycle time 0.6 min, 2 tool changes"), std::string::npos) << g;
  const auto r = check_program(g, {rough, finish}, {"--dialect", "linuxcnc"});
  EXPECT_EQ(r.exit_code, 0) << r.out;

  // grbl has no tool changer: an M0 pause with the tool in a comment, the spindle started again.
  o.dialect = Dialect::Grbl;
  std::ostringstream grbl;
  write_gcode(grbl, {{rough, "rough.cl"}, {finish, "finish.cl"}}, o);
  EXPECT_NE(grbl.str().find("M5\n(tool 5: D6 R3 mm - change it, touch off Z, resume)\nM0\nG0 Z40\nS12000 M3\n"), std::string::npos)
      << grbl.str();
  const auto rg = check_program(grbl.str(), {rough, finish}, {"--dialect", "grbl"});
  EXPECT_EQ(rg.exit_code, 0) << rg.out;
  // The reader is not a rubber stamp: without the second M3 the feeds of tool 5 run unspun.
  std::string unspun = grbl.str();
  unspun.erase(unspun.rfind("S12000 M3\n"), 10);
  EXPECT_EQ(check_program(unspun, {rough, finish}, {"--dialect", "grbl"}).exit_code, 1);
  // ... and a LinuxCNC program is no grbl program.
  EXPECT_EQ(check_program(g, {rough, finish}, {"--dialect", "grbl"}).exit_code, 1);
}

// A feed move too short to write (here: none at all) that changes the feed: the change goes on
// the next line written, not lost with the skipped one (found by scripts/bench-clpost.sh).
TEST(Gcode, FeedOfASkippedMoveIsWrittenOnTheNextLine) {
  ClData cl = small_cl();
  cl.moves.insert(cl.moves.begin() + 3, {ClMove::Kind::Feed, {0, 0, 10.00001}, std::nullopt, 700});
  cl.moves[4].feed_mm_per_min = 700;
  const std::string g = post(cl);
  EXPECT_NE(g.find("G1 Z10 F300\nG1 X5 Z10.25 F700\nG1 X10 Z10.5 F1000\n"), std::string::npos) << g;
  EXPECT_EQ(check_program(g, {cl}).exit_code, 0);
}

TEST(Gcode, RefusesOptionsTheDialectHasNoWordFor) {
  GcodeOptions o;
  o.blend_tol_mm = 0.01;  // G64 P: LinuxCNC only
  EXPECT_THROW(post(small_cl(), o), UsageError);
  o = {};
  o.dialect = Dialect::Grbl;
  o.percent = true;
  EXPECT_THROW(post(small_cl(), o), UsageError);
  o = {};
  o.origin = Origin::TopCorner;  // without a stock box
  EXPECT_THROW(post(small_cl(), o), UsageError);
  o = {};
  o.tool_numbers = {1, 2};  // two numbers, one input
  EXPECT_THROW(post(small_cl(), o), UsageError);
  o = {};
  o.work_offset = 53;
  EXPECT_THROW(post(small_cl(), o), UsageError);
}

// The origin at the stock top: the program is the CL data moved by (xmin, ymin, zmax) or the top
// centre, which the reader confirms with the same offset.
TEST(Gcode, OriginAtTheStockTop) {
  const ClData cl = small_cl();
  GcodeOptions o;
  o.dialect = Dialect::Fanuc;
  o.origin = Origin::TopCentre;
  o.stock = StockBox{{-2, -4, 0}, {12, 4, 12}};
  o.safe_z_mm = 40;
  const std::string g = post(cl, o);
  EXPECT_NE(g.find("(SET G54: X0 Y0 = CENTRE OF THE STOCK TOP)\n(SET G54: Z0 = TOP OF THE STOCK, Z 12 OF THE CL DATA)\n"),
            std::string::npos) << g;
  EXPECT_NE(g.find("G0 X-5. Y0. Z28.\nG0 Z-1.\nG1 Z-2. F300.\n"), std::string::npos) << g;
  const auto r = check_program(g, {cl}, {"--dialect", "fanuc", "--offset", "5,0,12"});
  EXPECT_EQ(r.exit_code, 0) << r.out;
}

// Arc fitting: points on a circle at constant Z become one arc; the arc stays within the
// tolerance of every point and of the straight path between them; a helix or a line stays G1.
TEST(Gcode, FitArcsKeepsThePathWithinTolerance) {
  const double r = 8, tol = 0.005;
  std::vector<Motion> lines;
  const Eigen::Vector3d start(r, 0, -1);
  for (int k = 1; k <= 40; ++k) {  // 2 degrees apart, counter-clockwise: sagitta 8 (1 - cos 1 deg) = 0.0012 mm
    const double a = k * 2 * 3.141592653589793 / 180;
    lines.push_back({Motion::Kind::Line, {r * std::cos(a), r * std::sin(a), -1}, Eigen::Vector2d::Zero(), 500});
  }
  const std::vector<Motion> arcs = fit_arcs(start, lines, tol, 90);
  ASSERT_EQ(arcs.size(), 1u);
  EXPECT_EQ(arcs[0].kind, Motion::Kind::ArcCcw);
  EXPECT_NEAR(arcs[0].centre_mm.norm(), 0, 1e-9);
  // Samples along the arc: each within tol of the polyline; each original point on the arc.
  const auto polyline_distance = [&](const Eigen::Vector3d& q) {
    double best = 1e9;
    Eigen::Vector3d a = start;
    for (const Motion& m : lines) {
      const Eigen::Vector3d d = m.end_mm - a;
      const double t = std::clamp((q - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * d - q).norm());
      a = m.end_mm;
    }
    return best;
  };
  for (int s = 0; s <= 800; ++s) {
    const double a = s * 80.0 / 800 * 3.141592653589793 / 180;
    EXPECT_LE(polyline_distance({r * std::cos(a), r * std::sin(a), -1}), tol) << s;
  }
  // Beyond the largest sweep: two arcs. Clockwise: G2.
  EXPECT_EQ(fit_arcs(start, lines, tol, 45).size(), 2u);
  std::vector<Motion> reversed;
  for (int k = 38; k >= 0; --k) reversed.push_back(lines[k]);
  reversed.push_back({Motion::Kind::Line, start, Eigen::Vector2d::Zero(), 500});
  const auto cw = fit_arcs(lines.back().end_mm, reversed, tol, 90);
  ASSERT_EQ(cw.size(), 1u);
  EXPECT_EQ(cw[0].kind, Motion::Kind::ArcCw);
  // A tolerance below the chords' sagitta, a helix, a change of feed or a straight line: no arc.
  EXPECT_EQ(fit_arcs(start, lines, 0.001, 90).size(), lines.size());
  std::vector<Motion> helix = lines, straight = lines, feeds = lines;
  for (std::size_t k = 0; k < helix.size(); ++k) helix[k].end_mm.z() -= 0.01 * static_cast<double>(k + 1);
  for (std::size_t k = 0; k < straight.size(); ++k) straight[k].end_mm = {r, static_cast<double>(k + 1), -1};
  for (std::size_t k = 0; k < feeds.size(); k += 2) feeds[k].feed_mm_per_min = 600;
  EXPECT_EQ(fit_arcs(start, helix, tol, 90).size(), lines.size());
  EXPECT_EQ(fit_arcs(start, straight, tol, 90).size(), lines.size());
  EXPECT_EQ(fit_arcs(start, feeds, tol, 90).size(), lines.size());

  // Posted: one G3 with I J from the start, read back within the tolerance.
  ClData cl;
  cl.spindle_rpm = 9000;
  cl.moves.push_back({ClMove::Kind::Rapid, {r, 0, 5}, std::nullopt, 0});
  cl.moves.push_back({ClMove::Kind::Feed, start, std::nullopt, 300});
  for (const Motion& m : lines) cl.moves.push_back({ClMove::Kind::Feed, m.end_mm, std::nullopt, 500});
  GcodeOptions o;
  o.arc_tol_mm = tol;
  const std::string g = post(cl, o);
  EXPECT_NE(g.find("G1 Z-1 F300\nG3 X1.3892 Y7.8785 I-8 J0 F500\nG0 Z5\n"), std::string::npos) << g;
  EXPECT_EQ(check_program(g, {cl}, {"--path-tol", "0.005"}).exit_code, 0);
  // The reader is not a rubber stamp: the same arc the other way round (G2) misses the points.
  std::string wrong = g;
  wrong.replace(wrong.find("G3 "), 3, "G2 ");
  EXPECT_EQ(check_program(wrong, {cl}, {"--path-tol", "0.005"}).exit_code, 1);
}

}  // namespace
}  // namespace photomill::toolpath
