// One case per toolpath and clpost option (and the common --quiet/--verbose of formats/tool.cpp):
// the option parses and has its documented effect (docs/toolpath.md, --help), and a value out of
// its range exits 2 naming the option.
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "formats/surface.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

using photomill::test::count_of;
using photomill::test::json_number;
using photomill::test::json_raw;
using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

std::string ridge_text() {
  std::ostringstream s;
  write_surface(s, test::cylinder_surface(20, true));
  return s.str();
}

struct Outcome {
  ToolResult r;
  std::string report;  // toolpath's --report JSON (empty for clpost)
};

// toolpath on the 60 x 30 mm ridge with quick tolerances, a JSON report beside.
Outcome toolpath_run(std::vector<std::string> args) {
  TempDir dir;
  const auto report = dir.path() / "report.json";
  args.insert(args.end(), {"--scallop-mm", "0.05", "--chord-tol-mm", "0.02", "--report", report.string(), "-"});
  Outcome run{run_tool("toolpath", args, ridge_text()), ""};
  run.report = photomill::test::read_file(report);
  return run;
}

// A short CL program: rapid to Z20, feed down to Z5 and across; coordinates with 4 decimals.
const std::string kCl =
    "UNITS/MM\nSPINDL/RPM,9000,CLW\nRAPID\nGOTO/0,0,20\nFEDRAT/MMPM,800\nGOTO/0,0,5.1234\nGOTO/10.5678,0,5.1234\nEND\nFINI\n";

Outcome clpost_run(const std::vector<std::string>& args) { return {run_tool("clpost", args, kCl), ""}; }

// The CSV rows (move,x,y,z,...) of toolpath --format csv.
struct Row {
  std::string move;
  double x, y, z;
};
std::vector<Row> csv_rows(const std::string& csv) {
  std::vector<Row> rows;
  std::istringstream in(csv);
  std::string line;
  do std::getline(in, line);  // the stamp (a '#' comment), the header
  while (line.rfind('#', 0) == 0);
  while (std::getline(in, line)) {
    std::istringstream l(line);
    Row r;
    std::string f;
    std::getline(l, r.move, ',');
    std::getline(l, f, ',');
    r.x = std::stod(f);
    std::getline(l, f, ',');
    r.y = std::stod(f);
    std::getline(l, f, ',');
    r.z = std::stod(f);
    rows.push_back(r);
  }
  return rows;
}

struct OptionCase {
  const char* name;
  std::function<Outcome()> run;
  int exit_code;
  std::string stderr_has;                   // for exit 2: the option's name
  std::function<void(const Outcome&)> check;    // the documented effect (exit 0 cases)
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class ToolpathOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(ToolpathOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = c.run();
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

auto tp(std::vector<std::string> args) { return [args] { return toolpath_run(args); }; }
auto cp(std::vector<std::string> args) { return [args] { return clpost_run(args); }; }
OptionCase bad(const char* name, std::function<Outcome()> run, std::string option) {
  return {name, std::move(run), 2, std::move(option), nullptr};
}

double safe_z(const Outcome& r) { return json_number(r.report, "safe_z_mm", "options"); }

INSTANTIATE_TEST_SUITE_P(
    Options, ToolpathOption,
    ::testing::Values(
        // toolpath
        OptionCase{"gouge_tol_mm", tp({"--gouge-tol-mm", "0.002"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_DOUBLE_EQ(json_number(r.report, "gouge_tol_mm", "options"), 0.002);
                     EXPECT_LE(json_number(r.report, "max_ball_dip_mm", "path"), 0.002);
                   }},
        bad("gouge_tol_mm_zero", tp({"--gouge-tol-mm", "0"}), "--gouge-tol-mm"),
        // Issue #25: numeric options are checked at parse time (NaN, absurd values), the range in --help.
        bad("tool_radius_mm_absurd", tp({"--tool-radius-mm", "1e9"}), "--tool-radius-mm: '1e9' is not in (0, 50]"),
        bad("tool_radius_mm_nan", tp({"--tool-radius-mm", "nan"}), "--tool-radius-mm: 'nan' is not in (0, 50]"),
        bad("scallop_mm_inf", tp({"--scallop-mm", "inf"}), "--scallop-mm"),
        bad("threads_absurd", tp({"--threads", "100000"}), "--threads"),
        OptionCase{"max_cl_points", tp({"--max-cl-points", "300"}), 1, "(the work limit, --max-cl-points)", nullptr},
        bad("max_cl_points_zero", tp({"--max-cl-points", "0"}), "--max-cl-points"),
        OptionCase{"help_shows_ranges", tp({"--help"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_NE(r.r.out.find("--tool-radius-mm FLOAT:in (0, 50]"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("--max-cl-points UINT:in [1, 1e10]"), std::string::npos) << r.r.out;
                   }},
        OptionCase{"stock_mm", tp({"--stock-mm", "0.5"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_DOUBLE_EQ(json_number(r.report, "stock_mm", "options"), 0.5);
                     // The ridge's top is level: the path (and so the safe plane) rises by the allowance
                     // (to 0.01 mm: the highest tip position is sampled along the passes).
                     EXPECT_NEAR(safe_z(r) - safe_z(toolpath_run({})), 0.5, 0.01);
                   }},
        bad("stock_mm_negative", tp({"--stock-mm", "-1"}), "--stock-mm"),
        OptionCase{"max_step_mm", tp({"--max-step-mm", "0.25"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_DOUBLE_EQ(json_number(r.report, "max_step_mm", "options"), 0.25);
                     EXPECT_LE(json_number(r.report, "max_forward_step_mm", "path"), 0.25 + 1e-9);
                   }},
        bad("max_step_mm_zero", tp({"--max-step-mm", "0"}), "--max-step-mm"),
        OptionCase{"feed_mm_per_min", tp({"--feed-mm-per-min", "1234"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("FEDRAT/MMPM,1234\n"), std::string::npos); }},
        bad("feed_mm_per_min_zero", tp({"--feed-mm-per-min", "0"}), "--feed-mm-per-min"),
        OptionCase{"plunge_feed_mm_per_min", tp({"--plunge-feed-mm-per-min", "77"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("FEDRAT/MMPM,77\n"), std::string::npos); }},
        bad("plunge_feed_negative", tp({"--plunge-feed-mm-per-min", "-5"}), "--plunge-feed-mm-per-min"),
        OptionCase{"safe_z_mm", tp({"--safe-z-mm", "55", "--format", "csv"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_DOUBLE_EQ(safe_z(r), 55);
                     const auto rows = csv_rows(r.r.out);
                     ASSERT_FALSE(rows.empty());
                     EXPECT_EQ(rows.front().move, "rapid");
                     EXPECT_DOUBLE_EQ(rows.front().z, 55);
                   }},
        bad("safe_z_mm_below_top", tp({"--safe-z-mm", "-100"}), "--safe-z-mm"),
        OptionCase{"retract_mm", tp({"--retract-mm", "12"}), 0, "",
                   [](const Outcome& r) { EXPECT_NEAR(safe_z(r) - safe_z(toolpath_run({})), 12 - 5, 1e-9); }},
        bad("retract_mm_negative", tp({"--retract-mm", "-1"}), "--retract-mm"),
        OptionCase{"clearance_mm", tp({"--clearance-mm", "3", "--format", "csv"}), 0, "",
                   [](const Outcome& r) {
                     // A pass starts with a rapid down to 3 mm above its start, then a feed straight down.
                     const auto rows = csv_rows(r.r.out);
                     int plunges = 0;
                     for (std::size_t i = 1; i < rows.size(); ++i) {
                       const Row &a = rows[i - 1], &b = rows[i];
                       if (a.move == "rapid" && b.move == "feed" && a.x == b.x && a.y == b.y) {
                         EXPECT_NEAR(a.z - b.z, 3, 1e-6);
                         ++plunges;
                       }
                     }
                     EXPECT_GT(plunges, 0);
                   }},
        bad("clearance_mm_negative", tp({"--clearance-mm", "-1"}), "--clearance-mm"),
        OptionCase{"ramp_angle_deg", tp({"--ramp-angle-deg", "5", "--clearance-mm", "2", "--format", "csv"}), 0, "",
                   [](const Outcome& r) {
                     // No pass is entered straight down: after each rapid down, the feeds come
                     // back along the pass no steeper than 5 degrees relative to it, and reach it.
                     const auto rows = csv_rows(r.r.out);
                     int entries = 0;
                     for (std::size_t i = 1; i < rows.size(); ++i) {
                       const Row &a = rows[i - 1], &b = rows[i];
                       if (a.move != "rapid" || b.move != "feed") continue;
                       EXPECT_FALSE(a.x == b.x && a.y == b.y) << "a straight-down entry at row " << i;
                       ++entries;
                     }
                     EXPECT_GT(entries, 0);
                   }},
        bad("ramp_angle_deg_steep", tp({"--ramp-angle-deg", "50"}), "--ramp-angle-deg"),
        OptionCase{"drop_sample_mm", tp({"--drop-sample-mm", "0.25"}), 0, "",
                   [](const Outcome& r) { EXPECT_DOUBLE_EQ(json_number(r.report, "drop_sample_mm", "options"), 0.25); }},
        bad("drop_sample_mm_zero", tp({"--drop-sample-mm", "0"}), "--drop-sample-mm"),
        OptionCase{"side_sample_mm", tp({"--side-sample-mm", "2"}), 0, "",
                   [](const Outcome& r) { EXPECT_GT(json_number(r.report, "passes", "path"), 0); }},
        bad("side_sample_mm_zero", tp({"--side-sample-mm", "0"}), "--side-sample-mm"),
        OptionCase{"part_name", tp({"--part-name", "ridge7"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("PARTNO/ridge7\n"), std::string::npos); }},
        bad("part_name_two_lines", tp({"--part-name", "a\nb"}), "--part-name"),
        // formats/tool.cpp, common to all tools
        OptionCase{"quiet", tp({"--quiet"}), 0, "", [](const Outcome& r) { EXPECT_EQ(r.r.err, ""); }},
        OptionCase{"verbose", tp({"--verbose"}), 0, "",
                   [](const Outcome& r) {
                     const Outcome normal = toolpath_run({});
                     EXPECT_GT(r.r.err.size(), normal.r.err.size()) << r.r.err;
                     EXPECT_EQ(r.r.out, normal.r.out);
                   }},
        // clpost
        OptionCase{"clpost_safe_z_mm", cp({"--safe-z-mm", "30"}), 0, "",
                   [](const Outcome& r) {
                     // Up to the rapid plane first, and back to it at the end.
                     EXPECT_NE(r.r.out.find("\nG0 Z30\n"), std::string::npos) << r.r.out;
                     EXPECT_GE(count_of(r.r.out, "Z30\n"), 2u) << r.r.out;
                   }},
        bad("clpost_safe_z_mm_below_top", cp({"--safe-z-mm", "10"}), "--safe-z-mm"),
        OptionCase{"clpost_no_spindle", cp({"--no-spindle"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(r.r.out.find("M3\n"), std::string::npos) << r.r.out;
                     EXPECT_EQ(r.r.out.find("M5\n"), std::string::npos) << r.r.out;
                     EXPECT_EQ(r.r.out.find("S9000"), std::string::npos) << r.r.out;
                     EXPECT_NE(clpost_run({}).r.out.find("S9000 M3"), std::string::npos);
                   }},
        OptionCase{"clpost_decimals", cp({"--decimals", "2"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_NE(r.r.out.find("X10.57"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("Z5.12"), std::string::npos) << r.r.out;
                     EXPECT_EQ(r.r.out.find("5.123"), std::string::npos) << r.r.out;
                   }},
        bad("clpost_decimals_seven", cp({"--decimals", "7"}), "--decimals"),
        OptionCase{"clpost_end", cp({"--end", "M2"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_NE(r.r.out.find("\nM2\n"), std::string::npos) << r.r.out;
                     EXPECT_EQ(r.r.out.find("M30"), std::string::npos) << r.r.out;
                   }},
        bad("clpost_end_bad", cp({"--end", "M5"}), "--end"),
        OptionCase{"clpost_percent", cp({"--percent"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(r.r.out.rfind("%\n", 0), 0u) << r.r.out;
                     EXPECT_GE(r.r.out.size(), 2u);
                     EXPECT_EQ(r.r.out.substr(r.r.out.size() - 2), "%\n") << r.r.out;
                     EXPECT_EQ(count_of(clpost_run({}).r.out, "%"), 0u);
                   }},
        OptionCase{"clpost_dialect", cp({"--dialect", "linuxcnc"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_NE(r.r.out.find("\nT1 M6\nG0 G43 H1 Z20\nS9000 M3\n"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("\nG64 P0.005\n"), std::string::npos) << r.r.out;
                   }},
        bad("clpost_dialect_bad", cp({"--dialect", "heidenhain"}), "--dialect"),
        OptionCase{"clpost_work_offset", cp({"--work-offset", "G55"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("\nG55\n"), std::string::npos) << r.r.out; }},
        bad("clpost_work_offset_bad", cp({"--work-offset", "G53"}), "--work-offset"),
        OptionCase{"clpost_origin_and_stock_box_mm",
                   cp({"--origin", "top-corner", "--stock-box-mm", "-5,-5,0,15,5,8", "--safe-z-mm", "20"}), 0, "",
                   [](const Outcome& r) {
                     // Program = CL - (xmin, ymin, zmax): the feed to (10.5678, 0, 5.1234) at X15.5678 Y5 Z-2.8766.
                     EXPECT_NE(r.r.out.find("G0 X5 Y5 Z12\nG1 Z-2.8766 F800\nG1 X15.5678\n"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("Z0 = top of the stock, Z 8 of the CL data"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("X0 Y0 = stock corner at min X, min Y"), std::string::npos) << r.r.out;
                   }},
        OptionCase{"clpost_origin_top_centre", cp({"--origin", "top-centre", "--stock-box-mm", "-5,-5,0,15,5,8"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("G0 X-5 Y0 Z12\nG1 Z-2.8766 F800\nG1 X5.5678\n"), std::string::npos) << r.r.out; }},
        bad("clpost_origin_without_stock_box_mm", cp({"--origin", "top-centre"}), "--stock-box-mm"),
        bad("clpost_stock_box_mm_five_values", cp({"--stock-box-mm", "0,0,0,1,1"}), "--stock-box-mm"),
        bad("clpost_stock_box_mm_empty", cp({"--stock-box-mm", "0,0,5,1,1,5"}), "--stock-box-mm"),
        OptionCase{"clpost_blend_tol_mm", cp({"--dialect", "linuxcnc", "--blend-tol-mm", "0.02"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("\nG64 P0.02\n"), std::string::npos) << r.r.out; }},
        bad("clpost_blend_tol_mm_not_linuxcnc", cp({"--dialect", "grbl", "--blend-tol-mm", "0.02"}), "--blend-tol-mm"),
        bad("clpost_blend_tol_mm_zero", cp({"--dialect", "linuxcnc", "--blend-tol-mm", "0"}), "--blend-tol-mm"),
        OptionCase{"clpost_program_number", cp({"--dialect", "fanuc", "--program-number", "4321"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(r.r.out.rfind("%\nO4321\n", 0), 0u) << r.r.out; }},
        bad("clpost_program_number_macro", cp({"--dialect", "fanuc", "--program-number", "9000"}), "--program-number"),
        OptionCase{"clpost_tool_numbers", cp({"--dialect", "fanuc", "--tool-numbers", "7"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(r.r.out.find("\nT7 M06\nG0 G43 H7 Z20.\n"), std::string::npos) << r.r.out; }},
        bad("clpost_tool_numbers_two_for_one", cp({"--tool-numbers", "1,2"}), "--tool-numbers"),
        bad("clpost_tool_numbers_zero", cp({"--tool-numbers", "0"}), "--tool-numbers"),
        OptionCase{"clpost_rapid_mm_per_min", cp({"--dialect", "grbl", "--rapid-mm-per-min", "1000"}), 0, "",
                   [](const Outcome& r) {
                     // Feeds 14.8766 + 10.5678 mm at 800 mm/min = 1.908 s; rapid 0 (the first position is unknown).
                     EXPECT_NE(r.r.out.find("(estimated cycle time 0 min, 0 tool changes"), std::string::npos) << r.r.out;
                     EXPECT_NE(r.r.out.find("at 1000 mm/min"), std::string::npos) << r.r.out;
                   }},
        bad("clpost_rapid_mm_per_min_zero", cp({"--rapid-mm-per-min", "0"}), "--rapid-mm-per-min"),
        OptionCase{"clpost_tool_change_s", cp({"--dialect", "mach3", "--tool-change-s", "120"}), 0, "",
                   [](const Outcome& r) {
                     // One tool change (T1 M6) of 2 min + 1.9 s of feed.
                     EXPECT_NE(r.r.out.find("(estimated cycle time 2 min, 1 tool changes"), std::string::npos) << r.r.out;
                   }},
        bad("clpost_tool_change_s_negative", cp({"--tool-change-s", "-1"}), "--tool-change-s"),
        OptionCase{"clpost_arc_tol_mm", cp({"--arc-tol-mm", "0.01"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(r.r.out, clpost_run({}).r.out); }},  // straight lines: no arc
        bad("clpost_arc_tol_mm_zero", cp({"--arc-tol-mm", "0"}), "--arc-tol-mm")),
    [](const auto& info) { return std::string(info.param.name); });

// --stock-uncertainty and --stock-sigma-k: a uniform sigma of 0.25 mm over the ridge raises the
// whole surface, and so the path and its safe plane, by k sigma; the report says so.
TEST(ToolpathStockOption, RaisesThePathByKSigma) {
  TempDir dir;
  const auto grid = dir.path() / "u.csv";
  {
    std::ofstream f(grid);
    f << "x_mm,y_mm,sigma_mm\n";
    for (int j = -40; j <= 40; j += 2) {
      for (int i = -40; i <= 40; i += 2) f << i << "," << j << ",0.25\n";
    }
  }
  const Outcome r = toolpath_run({"--stock-uncertainty", grid.string(), "--stock-sigma-k", "2"});
  ASSERT_EQ(r.r.exit_code, 0) << r.r.err;
  EXPECT_NE(r.r.err.find("uncertainty-aware stock (2.00 sigma"), std::string::npos) << r.r.err;
  EXPECT_DOUBLE_EQ(json_number(r.report, "k", "uncertainty_stock"), 2);
  EXPECT_NEAR(json_number(r.report, "max_mm", "uncertainty_stock"), 0.5, 1e-12);
  EXPECT_NEAR(safe_z(r) - safe_z(toolpath_run({})), 0.5, 0.01);
  // The default k is 2; without the option the report's entry is null.
  const Outcome d = toolpath_run({"--stock-uncertainty", grid.string()});
  EXPECT_NEAR(json_number(d.report, "max_mm", "uncertainty_stock"), 0.5, 1e-12);
  EXPECT_NE(toolpath_run({}).report.find("\"uncertainty_stock\":null"), std::string::npos);
}

TEST(ToolpathStockOption, BadValuesAndFilesAreRefused) {
  EXPECT_EQ(toolpath_run({"--stock-sigma-k", "2"}).r.exit_code, 2);  // without a grid
  const Outcome neg = toolpath_run({"--stock-uncertainty", "u.csv", "--stock-sigma-k", "-1"});
  EXPECT_EQ(neg.r.exit_code, 2);
  EXPECT_NE(neg.r.err.find("--stock-sigma-k"), std::string::npos) << neg.r.err;
  TempDir dir;
  const auto grid = dir.path() / "bad.csv";
  std::ofstream(grid) << "x_mm,y_mm,sigma_mm\n0,0,0.1\n1,0,-0.1\n";
  const Outcome bad = toolpath_run({"--stock-uncertainty", grid.string()});
  EXPECT_EQ(bad.r.exit_code, 1);
  EXPECT_NE(bad.r.err.find("bad.csv:3: sigma_mm must be finite and not negative"), std::string::npos) << bad.r.err;
  EXPECT_EQ(count_of(bad.r.err, "\n"), 1u) << bad.r.err;
}

}  // namespace
}  // namespace photomill::toolpath
