// clpost: CL data (APT CL text or CSV, tool-tip positions; one file per tool) -> RS-274 G-code for
// a 3-axis mill: the subset LinuxCNC and grbl both run (default), or LinuxCNC, grbl 1.1,
// Fanuc/Haas or Mach3 programs with tool changes, a work offset and optional arc fitting.
#include <cmath>
#include <sstream>

#include "formats/cl_data.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"
#include "toolpath/gcode.hpp"

using namespace photomill;
using namespace photomill::toolpath;

namespace {

// "1,2.5,3" -> {1, 2.5, 3}; empty on anything that is not a comma-separated list of numbers.
// (One argument, so that the CL files after the option stay positional.)
std::vector<double> split_numbers(const std::string& text) {
  std::vector<double> v;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    std::size_t used = 0;
    double x = 0;
    try {
      x = std::stod(item, &used);
    } catch (const std::exception&) {
      return {};
    }
    if (used != item.size() || !std::isfinite(x)) return {};
    v.push_back(x);
  }
  return v;
}

// Checks an option's list: count values in [min_count, max_count], each in [lo, hi] (for integer
// ranges: whole numbers).
CLI::Validator number_list(std::size_t min_count, std::size_t max_count, double lo, double hi) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        const std::vector<double> v = split_numbers(text);
        const bool whole = lo >= 1;
        if (v.size() < min_count || v.size() > max_count) {
          return "expected " + (min_count == max_count ? std::to_string(min_count) : "a list of") + " comma-separated numbers, got '" + text + "'";
        }
        for (double x : v) {
          if (!(x >= lo && x <= hi) || (whole && x != std::floor(x))) return "'" + text + "' has a value outside " + gcode_number(lo, 0) + ".." + gcode_number(hi, 0);
        }
        return "";
      },
      "LIST");
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> inputs{"-"};
  std::string output = "-", coolant = "auto", end = "M30", dialect = "generic", work_offset, origin = "plate";
  std::string stock, tool_numbers;
  bool no_spindle = false;
  GcodeOptions o;
  return tool::run(
      argc, argv,
      {"clpost", "CL data (APT or CSV) to G-code for 3-axis mills (LinuxCNC, grbl, Fanuc/Haas, Mach3)",
       "toolpath part.surf | clpost --spindle-rpm 12000 -o part.ngc"},
      [&](CLI::App& app) {
        app.add_option("cl", inputs, "CL data: APT CL text or CSV, one file per tool in machining order ('-' = stdin)")
            ->capture_default_str();
        app.add_option("-o,--output", output, "G-code output ('-' = stdout)")->capture_default_str();
        app.add_option("--dialect", dialect, "Controller: generic = the words LinuxCNC and grbl share (no tool change)")
            ->check(CLI::IsMember({"generic", "linuxcnc", "grbl", "fanuc", "mach3"}))->capture_default_str();
        app.add_option("--safe-z-mm", o.safe_z_mm, "Tool-tip height of the rapid plane at start, end and tool changes, in the CL data's frame (default: highest Z in the CL data)")
            ->check(CLI::Range(-100'000.0, 100'000.0));
        app.add_option("--spindle-rpm", o.spindle_rpm, "Spindle speed for every tool (default: each CL file's SPINDL)")
            ->check(tool::positive_up_to(1e6));
        app.add_flag("--no-spindle", no_spindle, "Write no S, M3 or M5 words");
        app.add_option("--coolant", coolant, "M8/M9: as the CL data says, always, or never")
            ->check(CLI::IsMember({"auto", "on", "off"}))->capture_default_str();
        app.add_option("--decimals", o.decimals, "Digits after the point for X Y Z I J (default 4; fanuc 3)")
            ->check(CLI::Range(0, 6));
        app.add_option("--end", end, "Program end word")->check(CLI::IsMember({"M2", "M30"}))->capture_default_str();
        app.add_flag("--percent", o.percent, "Wrap the program in '%' lines (tape markers; always for fanuc, refused for grbl)");
        app.add_option("--work-offset", work_offset, "Work coordinate system to select (default: none; fanuc G54)")
            ->check(CLI::IsMember({"G54", "G55", "G56", "G57", "G58", "G59"}));
        app.add_option("--origin", origin, "Program zero: the CL data's own (plate), or the stock top at its min X/min Y corner or centre")
            ->check(CLI::IsMember({"plate", "top-corner", "top-centre"}))->capture_default_str();
        app.add_option("--stock-box-mm", stock, "Stock block XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX in the CL data's frame (needed by --origin top-*)")
            ->check(number_list(6, 6, -1e15, 1e15));
        app.add_option("--blend-tol-mm", o.blend_tol_mm, "LinuxCNC G64 P: path blending tolerance (linuxcnc only; default 0.005)")
            ->check(tool::positive_up_to(100.0));
        app.add_option("--program-number", o.program_number, "Fanuc O number, 1..7999")->check(CLI::Range(1, 7999))->capture_default_str();
        app.add_option("--tool-numbers", tool_numbers, "Tool number of each CL file, e.g. 1,4 (default 1, 2, ...)")
            ->check(number_list(1, 1000, 1, 9999));
        app.add_option("--rapid-mm-per-min", o.rapid_mm_per_min, "Rapid rate for the estimated cycle time")
            ->check(tool::positive_up_to(1e6))->capture_default_str();
        app.add_option("--tool-change-s", o.tool_change_s, "Seconds per tool change or pause, for the estimated cycle time")
            ->check(CLI::Range(0.0, 1e5))->capture_default_str();
        app.add_option("--arc-tol-mm", o.arc_tol_mm, "Fit G2/G3 arcs in XY to runs of G1 moves within this distance (default: off)")
            ->check(tool::positive_up_to(100.0));
      },
      [&] {
        o.spindle = !no_spindle;
        o.coolant = coolant == "on" ? CoolantMode::On : coolant == "off" ? CoolantMode::Off : CoolantMode::Auto;
        o.end = end == "M2" ? ProgramEnd::M2 : ProgramEnd::M30;
        o.dialect = dialect == "linuxcnc" ? Dialect::LinuxCnc : dialect == "grbl" ? Dialect::Grbl
                    : dialect == "fanuc" ? Dialect::Fanuc : dialect == "mach3" ? Dialect::Mach3 : Dialect::Generic;
        if (!work_offset.empty()) o.work_offset = std::stoi(work_offset.substr(1));
        o.origin = origin == "top-corner" ? Origin::TopCorner : origin == "top-centre" ? Origin::TopCentre : Origin::Plate;
        if (!stock.empty()) {
          const std::vector<double> v = split_numbers(stock);
          o.stock = StockBox{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
        }
        for (double t : split_numbers(tool_numbers)) o.tool_numbers.push_back(static_cast<int>(t));
        std::vector<ClInput> cls;
        for (const std::string& input : inputs) {
          const auto in = tool::open_input(input);
          cls.push_back({read_cl(*in, tool::source_name(input)), tool::source_name(input)});
        }
        tool::OutputFile out(output);
        const PostStats st = write_gcode(out.stream(), cls, o);
        out.commit();
        log::info(std::to_string(st.lines) + " lines, " + std::to_string(st.arcs) + " arcs, " +
                  std::to_string(st.tool_changes) + " tool changes, estimated " + gcode_number(st.time_s / 60, 1) + " min");
      });
}
