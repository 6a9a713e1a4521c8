// Post-processor: CL data (formats/cl_data.hpp, tool-tip positions) -> RS-274 G-code for a
// 3-axis mill, in the subset that both LinuxCNC and grbl 1.1 accept: G0 G1 G17 G21 G90 G94,
// M3 M5 M8 M9 M2/M30, words X Y Z F S, parenthesised comments, lines under 80 characters, plain
// decimal numbers (no exponents).
#pragma once

#include <optional>
#include <ostream>
#include <string>

#include "formats/cl_data.hpp"

namespace photomill::toolpath {

enum class CoolantMode { Auto, On, Off };  // Auto: as the CL data says (COOLNT/ON)
enum class ProgramEnd { M2, M30 };

struct GcodeOptions {
  // Tool-tip height of the rapid plane the program starts and ends on (the tool goes there first,
  // before any horizontal move). Unset: the highest Z of the CL data.
  std::optional<double> safe_z_mm;
  // Spindle speed: set overrides the CL data's SPINDL; `spindle` false writes no S/M3/M5.
  std::optional<double> spindle_rpm;
  bool spindle = true;
  CoolantMode coolant = CoolantMode::Auto;
  int decimals = 4;               // digits after the point for X Y Z (F and S: up to 1)
  ProgramEnd end = ProgramEnd::M30;
  bool percent = false;           // '%' lines around the program (LinuxCNC tape markers)
};

// Writes the program. Rapids that move both horizontally and down are split into the horizontal
// move first, then the vertical one (and horizontally-and-up rapids: up first), so a rapid never
// descends diagonally towards the part. Each other CL move becomes exactly one G0/G1 line.
// Throws InputError(source, 0, ...) for CL data a 3-axis mill cannot run (a tool axis other than
// +Z, a feed move without feed) and UsageError for bad options (safe Z below the path).
void write_gcode(std::ostream& out, const ClData& cl, const GcodeOptions& options, const std::string& source);

// Fixed-point text with at most `decimals` digits after the point, trailing zeros removed,
// "-0" written as "0" (G-code readers do not all accept exponents).
std::string gcode_number(double value, int decimals);

}  // namespace photomill::toolpath
