// clpost: CL data (APT CL text or CSV, tool-tip positions) -> RS-274 G-code for a 3-axis mill
// that runs in LinuxCNC and grbl (G21 G90 G94 G17, G0/G1 X Y Z F, S M3/M5, M8/M9, M30).
#include "formats/cl_data.hpp"
#include "formats/tool.hpp"
#include "toolpath/gcode.hpp"

using namespace photomill;
using namespace photomill::toolpath;

int main(int argc, char** argv) {
  std::string input = "-", output = "-", coolant = "auto", end = "M30";
  bool no_spindle = false;
  GcodeOptions o;
  return tool::run(
      argc, argv,
      {"clpost", "CL data (APT or CSV) to G-code for 3-axis mills (LinuxCNC and grbl)",
       "toolpath part.surf | clpost --spindle-rpm 12000 -o part.ngc"},
      [&](CLI::App& app) {
        app.add_option("cl", input, "CL data: APT CL text or CSV ('-' = stdin)")->capture_default_str();
        app.add_option("-o,--output", output, "G-code output ('-' = stdout)")->capture_default_str();
        app.add_option("--safe-z-mm", o.safe_z_mm, "Tool-tip height of the rapid plane at start and end (default: highest Z in the CL data)");
        app.add_option("--spindle-rpm", o.spindle_rpm, "Spindle speed (default: the CL data's SPINDL)");
        app.add_flag("--no-spindle", no_spindle, "Write no S, M3 or M5 words");
        app.add_option("--coolant", coolant, "M8/M9: as the CL data says, always, or never")
            ->check(CLI::IsMember({"auto", "on", "off"}))->capture_default_str();
        app.add_option("--decimals", o.decimals, "Digits after the point for X Y Z (0..6)")->capture_default_str();
        app.add_option("--end", end, "Program end word")->check(CLI::IsMember({"M2", "M30"}))->capture_default_str();
        app.add_flag("--percent", o.percent, "Wrap the program in '%' lines (LinuxCNC tape markers)");
      },
      [&] {
        o.spindle = !no_spindle;
        o.coolant = coolant == "on" ? CoolantMode::On : coolant == "off" ? CoolantMode::Off : CoolantMode::Auto;
        o.end = end == "M2" ? ProgramEnd::M2 : ProgramEnd::M30;
        const auto in = tool::open_input(input);
        const ClData cl = read_cl(*in, tool::source_name(input));
        tool::OutputFile out(output);
        write_gcode(out.stream(), cl, o, tool::source_name(input));
        out.commit();
      });
}
