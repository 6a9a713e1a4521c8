// Golden CLI cases for toolpath and clpost (arguments, stdin, exit code, what stdout and stderr
// must hold), and the pipeline surface -> toolpath -> clpost -> independent G-code reader.
#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/cad.hpp"
#include "formats/json_value.hpp"
#include "formats/surface.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

namespace fs = std::filesystem;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

// A small, quick surface: the 60 x 30 mm ridge.
std::string ridge_text() {
  std::ostringstream s;
  write_surface(s, test::cylinder_surface(20, true));
  return s.str();
}

// Fast settings for the CLI cases.
const std::vector<std::string> kQuick{"--scallop-mm", "0.05", "--chord-tol-mm", "0.02"};

std::vector<std::string> quick(std::vector<std::string> args) {
  args.insert(args.end(), kQuick.begin(), kQuick.end());
  return args;
}

struct CliCase {
  const char* name;
  std::string tool;
  std::vector<std::string> args;
  std::string stdin_text;
  int exit_code;
  std::string stdout_starts;  // empty: stdout must be empty
  std::string stderr_has;     // empty: not checked
};

void PrintTo(const CliCase& c, std::ostream* os) { *os << c.name; }

class ToolpathCli : public ::testing::TestWithParam<CliCase> {};

TEST_P(ToolpathCli, GoldenCase) {
  const CliCase& c = GetParam();
  const ToolResult r = run_tool(c.tool, c.args, c.stdin_text);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  if (c.stdout_starts.empty()) {
    EXPECT_EQ(r.out, "");
  } else {
    EXPECT_EQ(r.out.rfind(c.stdout_starts, 0), 0u) << r.out.substr(0, 200);
  }
  if (!c.stderr_has.empty()) {
    EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  }
}

std::string bad_surface() {
  // Line 3 ("poles") carries a word instead of a number.
  return "photomill-surface v1\ndegrees 3 3\npoles four 4\n";
}

const std::string kTilted = "$$ five-axis\nUNITS/MM\nFEDRAT/MMPM,500\nGOTO/0,0,10,0,0.6,0.8\nEND\nFINI\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, ToolpathCli,
    ::testing::Values(
        CliCase{"missing_file", "toolpath", {"no-such.surf"}, "", 1, "", "toolpath: no-such.surf"},
        CliCase{"malformed_line", "toolpath", {"-"}, bad_surface(), 1, "", "<stdin>:3:"},
        CliCase{"empty_stdin", "toolpath", {}, "", 1, "", "<stdin>"},
        CliCase{"bad_direction", "toolpath", {"--direction", "w"}, "", 2, "", "--direction"},
        CliCase{"bad_pattern", "toolpath", {"--pattern", "spiral"}, "", 2, "", "--pattern"},
        CliCase{"chord_over_scallop", "toolpath", {"--chord-tol-mm", "0.02", "-"}, ridge_text(), 2, "",
                "must be below --scallop-mm"},
        CliCase{"negative_radius", "toolpath", {"--tool-radius-mm", "-3", "-"}, ridge_text(), 2, "", "--tool-radius-mm"},
        CliCase{"face_of_text_surface", "toolpath", quick({"--face", "2", "-"}), ridge_text(), 2, "", "--face 2"},
        CliCase{"apt_on_stdout", "toolpath", quick({"-"}), ridge_text(), 0, "$$ photomill CL data v1", "passes"},
        CliCase{"csv_on_stdout", "toolpath", quick({"--format", "csv", "-"}), ridge_text(), 0,
                "# photomill run=test rows=1720\nmove,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nrapid,", ""},
        CliCase{"quiet", "toolpath", quick({"-q", "-"}), ridge_text(), 0, "$$ photomill CL data v1", ""},
        CliCase{"clpost_tilted_axis", "clpost", {}, kTilted, 1, "", "only +Z"},
        CliCase{"clpost_missing", "clpost", {"no-such.cl"}, "", 1, "", "clpost: no-such.cl"},
        CliCase{"clpost_bad_record", "clpost", {}, "$$ x\nUNITS/MM\nSPIN/42\n", 1, "", "<stdin>:3:"},
        CliCase{"clpost_bad_coolant", "clpost", {"--coolant", "mist"}, "", 2, "", "--coolant"},
        CliCase{"clpost_nan_safe_z", "clpost", {"--safe-z-mm", "nan"},
                "UNITS/MM\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,5\nEND\nFINI\n", 2, "",
                "clpost: --safe-z-mm: Value nan is not a finite number (see --help)\n"},
        CliCase{"clpost_zero_spindle", "clpost", {"--spindle-rpm", "0"},
                "UNITS/MM\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,5\nEND\nFINI\n", 2, "",
                "clpost: --spindle-rpm: '0' is not in (0, 1e6] (see --help)\n"},
        CliCase{"clpost_no_spindle_speed_warns", "clpost", {},
                "UNITS/MM\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,5\nEND\nFINI\n", 0,
                "(photomill clpost: photomill)\nG21 G90 G94 G17\nG0 Z20\nG0 X0 Y0 Z20\nG1 Z5 F800\n",
                "warning: <stdin>: no spindle speed"},
        CliCase{"clpost_cut_short", "clpost", {"--spindle-rpm", "9000"},
                "UNITS/MM\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,27.9077\nGOTO/10,0,2", 1, "",
                "<stdin>:6: the CL data ends without FINI"},
        CliCase{"clpost_apt", "clpost", {"--spindle-rpm", "9000"},
                "UNITS/MM\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,5\nGOTO/10,0,5\nEND\nFINI\n", 0,
                "(photomill clpost: photomill)\nG21 G90 G94 G17\nG0 Z20\nS9000 M3\nG0 X0 Y0 Z20\nG1 Z5 F800\nG1 X10\n", "" }),
    [](const auto& info) { return std::string(info.param.name); });

TEST(ToolpathCli, QuietStderrAndVerboseNothingOnStdoutButData) {
  const ToolResult quiet = run_tool("toolpath", quick({"-q", "-"}), ridge_text());
  EXPECT_EQ(quiet.err, "");
  const ToolResult normal = run_tool("toolpath", quick({"-"}), ridge_text());
  EXPECT_EQ(normal.out, quiet.out) << "messages never reach stdout";
}

TEST(ToolpathCli, OutputFileOnlyOnSuccess) {
  TempDir dir;
  const fs::path out = dir.path() / "part.cl", surf = dir.path() / "ridge.surf";
  std::ofstream(surf) << ridge_text();
  ToolResult r = run_tool("toolpath", quick({"-o", out.string(), "missing.surf"}));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(out));
  r = run_tool("toolpath", quick({"-o", out.string(), surf.string()}));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  ASSERT_TRUE(fs::exists(out));
  // Nothing but the output file was left behind (no temporary files).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);
}

// A surface fitted to a cloud oriented without a datum (`units arbitrary`) is refused: one line
// naming the file and why, exit 1, no output. The same surface in mm is machined.
TEST(ToolpathCli, RefusesASurfaceOfArbitraryScale) {
  TempDir dir;
  const fs::path out = dir.path() / "part.cl", surf = dir.path() / "ridge.surf";
  BSplineSurface ridge = test::cylinder_surface(20, true);
  ridge.units = "arbitrary";
  {
    std::ofstream f(surf);
    write_surface(f, ridge);
  }
  ToolResult r = run_tool("toolpath", quick({"-o", out.string(), surf.string()}));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "toolpath: " + surf.string() +
                       ": the surface's scale is arbitrary (fitted from a cloud oriented without a datum): a tool path "
                       "needs mm; give triangulate control points, scale bars, --marker-side-mm or known poses\n");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
  std::ostringstream text;
  write_surface(text, ridge);
  r = run_tool("toolpath", quick({"-"}), text.str());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("toolpath: <stdin>: the surface's scale is arbitrary", 0), 0u) << r.err;
  ridge.units = "mm";
  {
    std::ofstream f(surf);
    write_surface(f, ridge);
  }
  r = run_tool("toolpath", quick({"-o", out.string(), surf.string()}));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(out));
  // STEP and IGES can only say mm: the files fitsurf writes from such a surface say it in their
  // header (STEP's description, IGES's start section), and toolpath refuses them too.
  fs::remove(out);
  ridge.units = "arbitrary";
  for (const char* name : {"ridge.step", "ridge.igs"}) {
    const fs::path cad = dir.path() / name;
    if (cad.extension() == ".step") {
      write_step(ridge, cad.string());
    } else {
      write_iges(ridge, cad.string());
    }
    for (bool all_faces : {false, true}) {
      std::vector<std::string> args{"-o", out.string(), cad.string()};
      if (all_faces) args.push_back("--all-faces");
      r = run_tool("toolpath", quick(args));
      EXPECT_EQ(r.exit_code, 1) << name;
      EXPECT_NE(r.err.find(cad.string() + ": the surface's scale is arbitrary"), std::string::npos) << r.err;
      EXPECT_FALSE(fs::exists(out));
    }
  }
}

TEST(ToolpathCli, StepAndIgesInputGiveOnlyClDataOnStdout) {
  TempDir dir;
  const BSplineSurface ridge = test::cylinder_surface(20, true);
  const fs::path step = dir.path() / "ridge.step", iges = dir.path() / "ridge.igs";
  write_step(ridge, step.string());
  write_iges(ridge, iges.string());
  const ToolResult text = run_tool("toolpath", quick({"-"}), ridge_text());
  for (const fs::path& p : {step, iges}) {
    const ToolResult r = run_tool("toolpath", quick({p.string()}));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out.rfind("$$ photomill CL data v1: tool tip positions, mm\n$$ photomill run=test\nPARTNO/", 0), 0u)
        << r.out.substr(0, 300);
    // The same surface gives the same path as the photomill text (the CAD round trip is exact
    // to the last digits, so compare the number of moves).
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), std::count(text.out.begin(), text.out.end(), '\n')) << p;
  }
  // STEP through stdin, and a face that does not exist.
  std::ifstream in(step);
  std::stringstream data;
  data << in.rdbuf();
  const ToolResult piped = run_tool("toolpath", quick({"-"}), data.str());
  EXPECT_EQ(piped.exit_code, 0) << piped.err;
  EXPECT_EQ(piped.out.rfind("$$ photomill CL data v1", 0), 0u);
  const ToolResult face = run_tool("toolpath", quick({"--face", "1", step.string()}));
  EXPECT_EQ(face.exit_code, 2);
  EXPECT_NE(face.err.find("has 1 face"), std::string::npos) << face.err;
}

// --all-faces on a STEP file of one face (no neighbours: nothing to mesh or check) and the ways
// to ask for it wrongly.
TEST(ToolpathCli, AllFacesOnOneFaceAndItsMisuses) {
  TempDir dir;
  const BSplineSurface ridge = test::cylinder_surface(20, true);
  const fs::path step = dir.path() / "ridge.step", json = dir.path() / "r.json";
  write_step(ridge, step.string());
  const ToolResult single = run_tool("toolpath", quick({step.string()}));
  const ToolResult all = run_tool("toolpath", quick({"--all-faces", "--report", json.string(), step.string()}));
  EXPECT_EQ(all.exit_code, 0) << all.err;
  EXPECT_NE(all.err.find("part: 1 of 1 faces machined"), std::string::npos) << all.err;
  // The same passes as the single-face run (one face: no whole-part changes).
  EXPECT_EQ(std::count(all.out.begin(), all.out.end(), '\n'), std::count(single.out.begin(), single.out.end(), '\n'));
  const JsonValue report = parse_json(photomill::test::read_file(json), json.string());
  ASSERT_NE(report.at("path.machined_faces"), nullptr);
  EXPECT_EQ(report.at("path.machined_faces")->number, 1);
  EXPECT_EQ(report.at("verify")->type, JsonValue::Type::Null);
  const ToolResult text = run_tool("toolpath", quick({"--all-faces", "-"}), ridge_text());
  EXPECT_EQ(text.exit_code, 1);
  EXPECT_NE(text.err.find("not a STEP or IGES file"), std::string::npos) << text.err;
  EXPECT_TRUE(text.out.empty());
  const ToolResult both = run_tool("toolpath", quick({"--all-faces", "--face", "0", step.string()}));
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_NE(both.err.find("exclude each other"), std::string::npos) << both.err;
  const ToolResult png = run_tool("toolpath", quick({"--all-faces", "--preview", (dir.path() / "p.png").string(), step.string()}));
  EXPECT_EQ(png.exit_code, 2);
  EXPECT_FALSE(fs::exists(dir.path() / "p.png"));
  const ToolResult coarse = run_tool("toolpath", quick({"--all-faces", "--mesh-tol-mm", "0.001", step.string()}));
  EXPECT_EQ(coarse.exit_code, 2);
  EXPECT_NE(coarse.err.find("--mesh-tol-mm"), std::string::npos) << coarse.err;
  // A part of one face is meshed for --verify (at the given deflection): the z-map runs.
  const ToolResult verified =
      run_tool("toolpath", quick({"--all-faces", "--verify", "--zmap-cell-mm", "0.25", "--gouge-tol-mm", "0.01",
                                  "--mesh-tol-mm", "0.005", step.string()}));
  EXPECT_EQ(verified.exit_code, 0) << verified.err;
  EXPECT_NE(verified.err.find("swept ball against the part's mesh"), std::string::npos) << verified.err;
}

// The real CAD part (issue 26): FreeCAD's 100 x 60 x 20 mm box with 8 mm fillets on its top edges,
// ten faces. All faces that face up in one run, the four walls and the underside reported, and
// the program checked against the whole solid: with a 3 mm ball, h 0.01 mm, e 0.005 mm, the
// swept ball reaches at most 0.001 mm into the part's mesh (0.0002 mm from the faces), and the
// material left on the machined faces is within h along the normal.
TEST(FilletedBox, AllUpwardFacesInOneRunCheckedAgainstTheSolid) {
  const fs::path box = fs::path(PHOTOMILL_SHARED_DIR) / "data" / "cad-parts" / "filleted_box.step";
  if (!fs::exists(box)) GTEST_SKIP() << box << " is missing (../shared/data)";
  TempDir dir;
  const fs::path json = dir.path() / "r.json", cl = dir.path() / "part.cl";
  const ToolResult r = run_tool("toolpath", {"--all-faces", "--verify", "--tool-radius-mm", "3", "--scallop-mm", "0.01",
                                             "--chord-tol-mm", "0.005", "--spindle-rpm", "12000", "--report", json.string(),
                                             "-o", cl.string(), box.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("5 of 10 faces machined (4 vertical walls, 1 facing down)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("vertical wall, not machined"), std::string::npos) << r.err;
  const JsonValue report = parse_json(photomill::test::read_file(json), json.string());
  const auto number = [&](const char* path) {
    const JsonValue* v = report.at(path);
    EXPECT_NE(v, nullptr) << path;
    return v && v->is_number() ? v->number : std::nan("");
  };
  EXPECT_EQ(number("path.machined_faces"), 5);
  EXPECT_EQ(number("path.wall_faces"), 4);
  EXPECT_EQ(number("path.down_faces"), 1);
  EXPECT_GT(number("path.cl_points"), 50000);
  EXPECT_LE(number("verify.max_penetration_mm"), 0.001);
  EXPECT_LE(number("verify.max_gouge_normal_mm"), 0.001);
  EXPECT_LE(number("verify.p95_left_normal_mm"), 0.01);
  EXPECT_LE(number("verify.max_left_normal_mm"), 0.0101);
  EXPECT_GT(number("verify.nodes"), 500000);
  // One face of it: the underside is machined with a warning that it faces down; a wall is refused.
  const ToolResult under = run_tool("toolpath", quick({"--face", "3", box.string()}));
  EXPECT_EQ(under.exit_code, 0) << under.err;
  EXPECT_NE(under.err.find("face 3 faces down in its part"), std::string::npos) << under.err;
  const ToolResult wall = run_tool("toolpath", quick({"--face", "0", box.string()}));
  EXPECT_EQ(wall.exit_code, 1);
  EXPECT_NE(wall.err.find("vertical wall"), std::string::npos) << wall.err;
  EXPECT_TRUE(wall.out.empty());
  // The program posts, spindle first.
  const ToolResult g = run_tool("clpost", {cl.string()});
  EXPECT_EQ(g.exit_code, 0) << g.err;
  EXPECT_LT(g.out.find(" M3"), g.out.find("\nG1 ")) << g.out.substr(0, 400);
}

TEST(ToolpathCli, PreviewReportAndVerify) {
  TempDir dir;
  const fs::path png = dir.path() / "p.png", json = dir.path() / "r.json";
  const ToolResult r = run_tool(
      "toolpath", quick({"--verify", "--zmap-cell-mm", "0.2", "--preview", png.string(), "--report", json.string(), "-"}),
      ridge_text());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("z-map"), std::string::npos) << r.err;
  ASSERT_TRUE(fs::exists(png));
  EXPECT_EQ(photomill::test::read_file(png).substr(1, 3), "PNG");
  const std::string report = photomill::test::read_file(json);
  for (const char* key : {"\"cl_points\":", "\"feed_length_mm\":", "\"max_chord_error_mm\":", "\"gouges\":", "\"verify\":",
                          "\"max_scallop_mm\":", "\"max_gouge_mm\":"}) {
    EXPECT_NE(report.find(key), std::string::npos) << key;
  }
  // The report is valid JSON (checked by Python's parser).
  const ToolResult parsed = run_tool("/usr/bin/env", {"python3", "-c", "import json,sys; json.load(open(sys.argv[1]))", json.string()});
  EXPECT_EQ(parsed.exit_code, 0) << parsed.err;
}

TEST(ToolpathCli, GroovePathReportsWhereItWouldGouge) {
  std::ostringstream surf;
  write_surface(surf, test::trough_surface(2.2));
  const ToolResult lifted = run_tool("toolpath", quick({"-"}), surf.str());
  EXPECT_EQ(lifted.exit_code, 0) << lifted.err;
  EXPECT_NE(lifted.err.find("would gouge the surface"), std::string::npos) << lifted.err;
  EXPECT_NE(lifted.err.find("the tool was lifted clear"), std::string::npos);
  EXPECT_NE(lifted.err.find("concave radius"), std::string::npos);
  const ToolResult reported = run_tool("toolpath", quick({"--no-lift", "-"}), surf.str());
  EXPECT_EQ(reported.exit_code, 0);
  EXPECT_NE(reported.err.find("NOT lifted"), std::string::npos) << reported.err;
  EXPECT_NE(lifted.out, reported.out);
}

// The whole chain through the executables: toolpath -> clpost, read back by the Python reader.
TEST(ToolpathCli, PipelineThroughClpostReadsBackInAnIndependentReader) {
  TempDir dir;
  const fs::path csv = dir.path() / "part.csv", ngc = dir.path() / "part.ngc";
  const ToolResult apt = run_tool("toolpath", quick({"--spindle-rpm", "12000", "--coolant", "-"}), ridge_text());
  ASSERT_EQ(apt.exit_code, 0) << apt.err;
  ASSERT_EQ(run_tool("toolpath", quick({"--format", "csv", "-o", csv.string(), "-"}), ridge_text()).exit_code, 0);
  const ToolResult post = run_tool("clpost", {"-o", ngc.string()}, apt.out);
  ASSERT_EQ(post.exit_code, 0) << post.err;
  const std::string program = photomill::test::read_file(ngc);
  EXPECT_NE(program.find("S12000 M3\nM8\n"), std::string::npos);
  EXPECT_NE(program.find("M9\nM5\nM30\n"), std::string::npos);
  const ToolResult check = run_tool(
      "/usr/bin/env", {"python3", std::string(PHOTOMILL_SOURCE_DIR) + "/toolpath/gcode_check.py", ngc.string(), csv.string()});
  EXPECT_EQ(check.exit_code, 0) << check.out << check.err;
  // The APT file itself, read by an independent APT reader: fixed-point numbers only, LOADTL and
  // CUTTER before the first motion, the spindle on before the first feed, the CSV's moves exactly.
  const fs::path cl = dir.path() / "part.cl";
  std::ofstream(cl, std::ios::binary) << apt.out;
  const ToolResult apt_check = run_tool(
      "/usr/bin/env", {"python3", std::string(PHOTOMILL_SOURCE_DIR) + "/toolpath/apt_check.py", cl.string(), csv.string()});
  EXPECT_EQ(apt_check.exit_code, 0) << apt_check.out << apt_check.err;
  EXPECT_NE(apt.out.find("LOADTL/1\nCUTTER/"), std::string::npos) << apt.out.substr(0, 300);
  // clpost also reads the CSV form.
  const ToolResult from_csv = run_tool("clpost", {csv.string()});
  EXPECT_EQ(from_csv.exit_code, 0) << from_csv.err;
  EXPECT_NE(from_csv.out.find("G1 "), std::string::npos);
}

// The linuxcnc dialect through LinuxCNC's own interpreter (rs274, Debian package linuxcnc-uspace,
// run standalone with a tool table): two tools (T M6, G43 H), no error, the spindle started
// before the first feed, and every CL point of both files among its canonical moves, in order;
// the same with fitted arcs. Skipped where rs274 is not installed.
TEST(ClpostRs274, LinuxcncDialectRunsInLinuxcncsInterpreter) {
  if (run_tool("/bin/sh", {"-c", "command -v rs274"}).exit_code != 0) {
    if (std::getenv("CI") != nullptr) FAIL() << "rs274 is not installed (scripts/install-deps.sh --tests installs linuxcnc-uspace)";
    GTEST_SKIP() << "rs274 is not installed (Debian package linuxcnc-uspace; scripts/install-deps.sh --tests installs it)";
  }
  TempDir dir;
  const fs::path cl = dir.path() / "part.cl", csv = dir.path() / "part.csv", tbl = dir.path() / "tool.tbl";
  ASSERT_EQ(run_tool("toolpath", quick({"--spindle-rpm", "12000", "--coolant", "-o", cl.string(), "-"}), ridge_text()).exit_code, 0);
  ASSERT_EQ(run_tool("toolpath", quick({"--format", "csv", "-o", csv.string(), "-"}), ridge_text()).exit_code, 0);
  std::ofstream(tbl) << "T1 P1 D6 Z0 ;ball 6\nT2 P2 D6 Z0 ;ball 6\n";
  std::vector<std::array<double, 3>> points;  // the CL points of both files
  {
    std::istringstream rows(photomill::test::read_file(csv));
    std::string line;
    do std::getline(rows, line);  // the stamp (a '#' comment), the header
    while (line.rfind('#', 0) == 0);
    while (std::getline(rows, line)) {
      std::array<double, 3> p{};
      std::sscanf(line.c_str() + line.find(',') + 1, "%lf,%lf,%lf", &p[0], &p[1], &p[2]);
      points.push_back(p);
    }
  }
  for (const bool arcs : {false, true}) {
    SCOPED_TRACE(arcs ? "with --arc-tol-mm" : "lines only");
    const fs::path ngc = dir.path() / "part.ngc", canon = dir.path() / "canon.txt";
    // With arcs the second tool cuts a circle (r 8 mm at Z 10, 2 degrees apart), which the ridge's
    // passes (straight along X, or up and over in YZ) have none of.
    const fs::path circle = dir.path() / "circle.csv";
    {
      std::ofstream c(circle);
      c << "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nrapid,38,0,12,,,,0\nfeed,38,0,10,,,,300\n";
      for (int k = 1; k <= 180; ++k) {
        const double a = k * 3.141592653589793 / 90;
        c << "feed," << 30 + 8 * std::cos(a) << "," << 8 * std::sin(a) << ",10,,,,800\n";
      }
    }
    std::vector<std::string> args{"--dialect", "linuxcnc", "--tool-numbers", "1,2", cl.string(),
                                  arcs ? circle.string() : cl.string(), "-o", ngc.string()};
    if (arcs) args.insert(args.end(), {"--arc-tol-mm", "0.02"});
    const ToolResult post = run_tool("clpost", args);
    ASSERT_EQ(post.exit_code, 0) << post.err;
    const ToolResult r = run_tool("/usr/bin/env", {"rs274", "-t", tbl.string(), "-g", ngc.string(), canon.string()});
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    const std::string out = photomill::test::read_file(canon);
    EXPECT_NE(out.find("CHANGE_TOOL(2)"), std::string::npos);
    EXPECT_NE(out.find("PROGRAM_END()"), std::string::npos) << out.substr(out.size() > 2000 ? out.size() - 2000 : 0);
    const auto spindle = out.find("START_SPINDLE_CLOCKWISE"), feed = out.find("STRAIGHT_FEED(");
    ASSERT_NE(feed, std::string::npos);
    EXPECT_LT(spindle, feed);
    // Canonical end points (X, Y, Z are the first three numbers of each motion call).
    std::vector<std::array<double, 3>> moves;
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);) {
      for (const char* call : {"STRAIGHT_TRAVERSE(", "STRAIGHT_FEED(", "ARC_FEED("}) {
        const auto at = line.find(call);
        if (at == std::string::npos) continue;
        std::array<double, 5> v{};
        std::sscanf(line.c_str() + at + std::strlen(call), "%lf, %lf, %lf, %lf, %lf", &v[0], &v[1], &v[2], &v[3], &v[4]);
        // ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end_point, ...)
        if (std::string(call) == "ARC_FEED(") {
          std::sscanf(line.c_str() + at + std::strlen(call), "%lf, %lf, %*f, %*f, %*d, %lf", &v[0], &v[1], &v[2]);
        }
        moves.push_back({v[0], v[1], v[2]});
      }
    }
    if (arcs) {
      EXPECT_GE(photomill::test::count_of(out, "ARC_FEED("), 4u);  // 360 degrees, at most 90 each
      continue;  // points inside an arc are no canonical end point (gcode_test holds them to the tolerance)
    }
    std::size_t k = 0, missing = 0;
    for (const auto& p : points) {
      for (int pass = 0; pass < 2; ++pass) {  // each point: found from where the last one was (both files)
        std::size_t j = k;
        while (j < moves.size() && !(std::abs(moves[j][0] - p[0]) < 6e-5 && std::abs(moves[j][1] - p[1]) < 6e-5 &&
                                     std::abs(moves[j][2] - p[2]) < 6e-5)) {
          ++j;
        }
        if (j < moves.size()) {
          k = j;
          break;
        }
        if (pass == 1) ++missing;
      }
    }
    EXPECT_EQ(missing, 0u) << "of " << points.size() << " CL points";
  }
}

}  // namespace
}  // namespace photomill::toolpath
