// Post-processor: CL data (formats/cl_data.hpp, tool-tip positions) -> RS-274 G-code for a
// 3-axis mill, in one of five dialects (docs/toolpath.md, "The G-code (clpost)"): `generic`, the
// subset both LinuxCNC and grbl 1.1 accept (G0 G1 G17 G21 G90 G94, M3 M5 M8 M9 M2/M30, X Y Z F S;
// the default, unchanged from earlier versions), `linuxcnc` (T M6, G43 H, G64 P), `grbl` (grbl
// 1.1's documented words only), `fanuc` (Fanuc 0i / Haas: %, O number, G54, T M06, G43 H, every
// coordinate with a decimal point) and `mach3`. Parenthesised comments, lines under 80 characters,
// plain decimal numbers (no exponents). Several CL inputs make one program, one tool each.
#pragma once

#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"

namespace photomill::toolpath {

enum class CoolantMode { Auto, On, Off };  // Auto: as the CL data says (COOLNT/ON)
enum class ProgramEnd { M2, M30 };
enum class Dialect { Generic, LinuxCnc, Grbl, Fanuc, Mach3 };
// Where X0 Y0 Z0 of the program is: the CL data's own frame (the plate), or the top face of the
// stock box at its min-X/min-Y corner or at its centre.
enum class Origin { Plate, TopCorner, TopCentre };

// Axis-aligned stock block in the CL data's frame, mm.
struct StockBox {
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d max_mm = Eigen::Vector3d::Zero();
};

struct GcodeOptions {
  // Tool-tip height of the rapid plane the program starts and ends on and changes tools on (the
  // tool goes there first, before any horizontal move), in the CL data's frame. Unset: the
  // highest Z of the CL data (of all inputs).
  std::optional<double> safe_z_mm;
  // Spindle speed: set overrides every input's SPINDL; `spindle` false writes no S/M3/M5.
  std::optional<double> spindle_rpm;
  bool spindle = true;
  CoolantMode coolant = CoolantMode::Auto;
  // Digits after the point for X Y Z I J (F and S: up to 1). Unset: 4, Fanuc 3 (its IS-B least
  // input increment, 0.001 mm).
  std::optional<int> decimals;
  ProgramEnd end = ProgramEnd::M30;
  bool percent = false;           // '%' lines around the program (always for Fanuc, never for grbl)
  Dialect dialect = Dialect::Generic;
  std::optional<int> work_offset;  // 54..59: G54..G59 written after the modes (Fanuc: 54 if unset)
  Origin origin = Origin::Plate;
  std::optional<StockBox> stock;   // required unless origin is Plate; also checks the path
  std::optional<double> blend_tol_mm;  // LinuxCNC's G64 P (path blending tolerance); unset: 0.005
  int program_number = 1000;       // Fanuc's O word, 1..7999 (8000-9999 are protected/macros)
  std::vector<int> tool_numbers;   // one per CL input, >= 1; empty: 1, 2, ... in input order
  double rapid_mm_per_min = 5000;  // for the estimated cycle time only
  double tool_change_s = 15;       // for the estimated cycle time only: per change or pause
  // Arc fitting: runs of G1 moves on a circle in a plane parallel to XY become G2/G3 (I J
  // incremental), each CL point and the straight path between them within this distance of the
  // arc. Unset: off.
  std::optional<double> arc_tol_mm;
  double max_arc_deg = 90;         // largest sweep of one fitted arc
};

// One CL input: its data and the name used in messages and in the tool list.
struct ClInput {
  ClData cl;
  std::string source;
};

// What a posted program does, for the header's estimate and for the tests and measurements.
struct PostStats {
  std::size_t lines = 0;         // lines written
  std::size_t arcs = 0;          // G2/G3 lines
  std::size_t tool_changes = 0;  // T M6 or M0 pauses
  double feed_mm = 0;            // path length of G1/G2/G3
  double rapid_mm = 0;           // path length of G0 (from the first known position)
  double time_s = 0;             // feed_mm at each move's F + rapid_mm at rapid_mm_per_min + changes
};

// Writes the program. Rapids that move both horizontally and down are split into the horizontal
// move first, then the vertical one (and horizontally-and-up rapids: up first), so a rapid never
// descends diagonally towards the part. Each other CL move becomes exactly one G0/G1 line (unless
// arc fitting replaces a run of them). Between inputs: up to the safe plane, coolant and spindle
// off, the tool change (T M6 and G43 H in linuxcnc, fanuc and mach3; an M0 pause with a comment in
// generic and grbl, which have no tool changer), spindle and coolant on again before any feed.
// Throws InputError(source, 0, ...) for CL data a 3-axis mill cannot run (a tool axis other than
// +Z, a feed move without feed, no moves) and UsageError for bad options (safe Z below the path, a
// missing stock box, an option the dialect has no word for).
PostStats write_gcode(std::ostream& out, const std::vector<ClInput>& inputs, const GcodeOptions& options);
PostStats write_gcode(std::ostream& out, const ClData& cl, const GcodeOptions& options, const std::string& source);

// Fixed-point text with at most `decimals` digits after the point, trailing zeros removed,
// "-0" written as "0" (G-code readers do not all accept exponents).
std::string gcode_number(double value, int decimals);

// One motion of a posted program, in the program's frame.
struct Motion {
  enum class Kind { Rapid, Line, ArcCw, ArcCcw };  // G0, G1, G2, G3 (arcs in the XY plane, G17)
  Kind kind = Kind::Line;
  Eigen::Vector3d end_mm = Eigen::Vector3d::Zero();
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // arcs: the centre (absolute X, Y)
  double feed_mm_per_min = 0;                           // Line and arcs
};

// Replaces runs of at least three consecutive Line motions (same feed, same Z) whose points lie
// on one circle by arcs: see gcode.cpp for the test. `start` is the position before motions[0].
std::vector<Motion> fit_arcs(const Eigen::Vector3d& start, const std::vector<Motion>& motions, double tol_mm,
                             double max_sweep_deg);

}  // namespace photomill::toolpath
