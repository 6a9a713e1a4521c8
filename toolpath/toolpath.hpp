// The iso-parametric ball-end finishing path of the paper's section 5, all seven steps: passes
// (steps 1, 5, 6: iso_passes.hpp), forward steps (steps 2, 3: forward_step.hpp), CC -> CL with
// gouge lifting (steps 4, 7: cutter.hpp), then retracts, rapids and links between passes, as CL
// data (formats/cl_data.hpp). Input: one B-spline surface; output: CL data plus what the report
// and the preview show.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "toolpath/cutter.hpp"
#include "toolpath/iso_passes.hpp"

namespace photomill::toolpath {

enum class Pattern { ZigZag, OneWay };

// The largest ball radius accepted (mm): ball-end mills stop near 25 mm (a 50 mm ball); a radius
// of kilometres (1e9 mm was tried: no answer within 60 s) is a typing error, not a tool. The
// drop cutter looks at every surface sample within R, so the time grows with R^2: on the demo's
// surface R 3 takes 4.4 s, R 25 24 s, R 100 101 s.
constexpr double kMaxToolRadiusMm = 50;

// Default work limit (--max-cl-points): CL points computed while stepping along the passes, kept
// or rejected. The demo's finishing (Makefile.example: R 3, h 0.01, e 0.005) keeps 86 992 in
// 4.4 s, freeform_face.step 29 954; the default is 23 times the demo, and a runaway stops there
// (about 100 s at the demo's rate) with an error naming the option instead of running on.
constexpr std::size_t kDefaultMaxClPoints = 2'000'000;

struct ToolpathOptions {
  double tool_radius_mm = 3;         // R, ball end
  double scallop_mm = 0.01;          // h: highest material left above the surface (cusps + chords)
  double chord_tol_mm = 0.005;       // e: chord error between consecutive CC points; e < h
  double gouge_tol_mm = 0.0005;      // deepest a straight move may dip into the surface
  double stock_mm = 0;               // a: allowance left on the surface (roughing)
  PassDirection direction = PassDirection::U;
  Pattern pattern = Pattern::ZigZag;
  bool lift = true;                  // lift the tool out of gouges (false: report them only)
  double max_step_mm = 2;            // longest forward step
  double feed_mm_per_min = 1000;     // cutting feed
  double plunge_feed_mm_per_min = 300;  // feed of the last `clearance_mm` down onto a pass
  std::optional<double> safe_z_mm;   // rapid plane (tool tip, mm); unset: top + retract_mm
  double retract_mm = 5;             // safe plane above the highest of surface and path
  double clearance_mm = 1;           // rapid down to this height above a pass start, then feed
  double ramp_angle_deg = 0;         // > 0: enter a pass by a ramp along it this steep (0: straight down)
  double drop_sample_mm = 0.5;       // drop-cutter sample spacing on the surface
  double side_sample_mm = 1;         // spacing of the side-step samples along a pass
  int threads = 0;                   // 0 = all cores
  std::size_t max_cl_points = kDefaultMaxClPoints;  // work limit: more CL points is an error
  // Carried into the CL data.
  std::string part_name = "photomill";
  std::optional<double> spindle_rpm;
  bool coolant = false;
};

// Throws UsageError for values out of range (non-positive sizes, e >= h, h >= R, ...).
void validate(const ToolpathOptions& options);

// Consecutive CL points of one pass flagged as gouges (where the tangent ball would cut into the
// surface): where, how deep, and why.
struct GougeRun {
  std::size_t pass = 0;             // index of the pass line (from lines.size() on: edge passes)
  Eigen::Vector3d first_cc = Eigen::Vector3d::Zero();  // CC points at either end of the run, mm
  Eigen::Vector3d last_cc = Eigen::Vector3d::Zero();
  Eigen::Vector3d deepest_contact = Eigen::Vector3d::Zero();  // where the ball touched, deepest point
  std::size_t points = 0;
  double max_depth_mm = 0;          // largest gouge depth (how far it was, or would be, lifted)
  double min_concave_radius_mm = 0; // tightest concave radius of curvature on the run (inf: none)
  bool lifted = false;
};

// One machined piece of a pass line: its CL points in cutting order.
struct PassSegment {
  std::size_t pass = 0;             // index of the pass line; from lines.size() on: edge passes
  PassDirection direction = PassDirection::U;  // the parameter it runs along
  std::vector<CutterLocation> points;
};

struct ToolpathStats {
  std::size_t passes = 0;           // pass lines
  std::size_t edge_passes = 0;      // passes along slanted domain edges (after the lines)
  std::size_t segments = 0;         // machined pieces of pass lines
  std::size_t cl_points = 0;        // CL points on passes
  std::size_t moves = 0;            // all CL moves (rapids, plunges, links included)
  double feed_length_mm = 0;        // length of all feed moves
  double rapid_length_mm = 0;
  double min_side_step_mm = 0, max_side_step_mm = 0;
  double min_forward_step_mm = 0, max_forward_step_mm = 0;
  double max_chord_error_mm = 0;    // largest CC chord error accepted (dense check)
  double max_ball_dip_mm = 0;       // largest dip of a straight move into the surface accepted
  std::size_t gouge_points = 0;
  double max_gouge_depth_mm = 0;
  std::size_t retracts = 0;         // links made by retract-rapid-plunge
  std::size_t rejected_steps = 0;   // forward-step proposals that failed the check
  double safe_z_mm = 0;
  double seconds = 0;               // wall time of generate_toolpath
};

struct ToolpathResult {
  ClData cl;
  std::vector<PassLine> lines;
  std::vector<PassSegment> segments;  // in machining order
  std::vector<GougeRun> gouges;
  ToolpathStats stats;
};

// All seven steps. Throws UsageError for bad options and GeometryError for surfaces that give no
// path (degenerate, folded, or an empty boundary polygon).
ToolpathResult generate_toolpath(const BSplineSurface& surface, const ToolpathOptions& options);

}  // namespace photomill::toolpath
