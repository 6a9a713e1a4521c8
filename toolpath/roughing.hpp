// Roughing: a stock box cleared down to the surface plus an allowance by z-level area clearing
// with a flat or bull-nose end mill (issue 26, deliverable 1). Output: CL data (tool tips), to be
// posted by clpost and followed by toolpath's ball-end finishing.
//
// Method (z-level, offset-contour clearing, as in Held's "On the Computational Geometry of
// Pocket Machining", 1991, and the waterline/z-level roughing of CAM systems):
//  1. The part's height H on a grid over the stock box (cell `cell_mm`): the surface's height
//     (zmap.hpp, Newton on S_xy(u, v) = (x, y)), taken as the largest of each node and its 8
//     neighbours plus |z''| cell^2 / 4 (z'' from second differences: how far a peak between
//     nodes can rise above the nearest node), so that the surface between nodes does not rise
//     above it; off the surface, the stock's bottom.
//  2. The lowest tool-tip height at every node (inverse tool offset, "drop cutter" on the grid):
//       T(p) = max over nodes q with |q - p| <= R of  H(q) + allowance - f(|q - p|),
//     with the end mill's profile f(rho) = 0 for rho <= R - r_c and
//     f(rho) = r_c - sqrt(r_c^2 - (rho - R + r_c)^2) on the corner (r_c = 0: flat end mill).
//  3. Levels z_k = stock top - k step-down down to min T, the last level at min T + `flat_tol_mm`
//     (so that a floor not quite level is cut at it too; below the level above it), plus a level
//     at the top of every flat: nodes whose T is within a 1-degree slope of its four
//     neighbours', grouped in runs of T within `flat_tol_mm`, a run holding at least 2 % of the
//     stock's nodes (a plate, a terrace), so flats are cut to the allowance instead of keeping a
//     stair of up to a step-down.
//  4. At each level the tool centre may go where T <= z (the free region). Its Euclidean distance
//     D to the nearest forbidden node (OpenCV's exact distanceTransform; the grid's border counts
//     as forbidden, and the grid reaches R + 2 cells beyond the stock, so the outermost contours
//     run in the air) gives the offset contours D = d0 + j step-over (Held's offset curves), each
//     a closed loop traced on the grid (findContours) and simplified (Douglas-Peucker, tolerance
//     `simplify_mm`); d0 keeps the simplified loops inside the free region.
//  5. Each free component is cut from its innermost contour outwards (largest D first), so every
//     loop cuts at most one step-over of material on one side. Climb milling with an M3 spindle
//     keeps the material on the cutter's right: outer loops counter-clockwise, holes clockwise.
//  7. Rest machining (`rest_after`): the material's top starts as the stock cut by earlier
//     programs (cut_material, their own cutters), and at each level the free region is kept only
//     within R + step-over of nodes whose material still stands more than `rest_min_mm` above
//     the level: a smaller tool clears what a larger one could not reach, and nothing else.
//  6. Entries never plunge into material: a material-height map (stock top, lowered by every cut)
//     says whether the tool can go straight down (air, or cleared by an earlier level) or must
//     ramp down along its loop at `ramp_angle_deg` (or helix down, `helix_radius_mm`, on a loop
//     too short to ramp along). A loop that allows neither is left uncut and counted.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {

enum class MillingDirection { Climb, Conventional };

struct StockBox {
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero(), max_mm = Eigen::Vector3d::Zero();
};

// The default stock: the surface's xy box grown by margin_mm on every side, from the surface's
// lowest point to its highest plus margin_mm (heights sampled on a grid of max(cell, 0.5) mm).
StockBox default_stock_box(const BSplineSurface& surface, double margin_mm, double cell_mm, int threads);

// "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX" (mm, C locale); throws UsageError naming --stock-box-mm.
StockBox parse_stock_box(const std::string& text);

// An earlier program on the same stock and the cutter it ran with (rest machining).
struct PriorCut {
  ClData cl;
  Cutter cutter;
};

struct RoughingOptions {
  double tool_diameter_mm = 6;       // end mill diameter D = 2R
  double corner_radius_mm = 0;       // r_c: 0 flat, 0 < r_c <= R bull-nose
  double step_down_mm = 2;           // depth between levels
  double step_over_mm = 0;           // between offset contours; 0: 40 % of the diameter
  double flat_tol_mm = 0.1;          // a flat: level tip heights within this over 2 % of the stock (0: none)
  double allowance_mm = 0.5;         // material left on the surface for finishing
  std::optional<StockBox> stock;     // unset: the surface's box grown by stock_margin_mm (not below its lowest point)
  double stock_margin_mm = 2;        // around and above the surface, for the default stock
  MillingDirection direction = MillingDirection::Climb;
  double ramp_angle_deg = 3;         // entry ramps and helices descend at most this steeply
  double helix_radius_mm = 0;        // 0: half the tool radius
  double feed_mm_per_min = 1000;
  double plunge_feed_mm_per_min = 300;  // ramps, helices and straight descents
  double retract_mm = 5;             // safe plane above the stock top
  double clearance_mm = 1;           // rapid down to this height above material, then feed
  double cell_mm = 0.2;              // grid spacing
  double simplify_mm = 0;            // path simplification tolerance; 0: half a cell
  std::size_t max_moves = 5000000;   // work limit: more CL moves than this is an error
  std::vector<PriorCut> rest_after;  // rest machining: clear only what these programs left
  double rest_min_mm = 0.05;         // rest machining: thinner material above a level is left
  int threads = 0;
  std::string part_name = "photomill";
  std::optional<double> spindle_rpm;
  bool coolant = false;
};

struct RoughingStats {
  StockBox stock;
  std::size_t levels = 0;
  std::size_t flat_levels = 0;     // of those, levels at flats
  double top_level_mm = 0, bottom_level_mm = 0;
  std::size_t loops = 0;           // offset contours cut
  std::size_t ramps = 0, helices = 0, straight_entries = 0, links = 0;
  std::size_t skipped_loops = 0;   // loops no ramp or helix could enter (material left there)
  std::size_t rest_levels = 0;     // rest machining: levels with material left to clear
  double feed_length_mm = 0, rapid_length_mm = 0;
  double cycle_time_min = 0;       // feed length / feed + descents / plunge feed (no rapids)
  double safe_z_mm = 0;
  double step_over_mm = 0;
  double seconds = 0;
};

struct RoughingResult {
  ClData cl;
  RoughingStats stats;
};

// What is left of a stock box after CL programs, on a z-map (toolpath's cut_material): the
// material's top against the surface's height at every node over the surface inside the stock
// (vertical differences).
struct StockCheck {
  double cell_mm = 0;
  std::size_t nodes = 0;            // nodes over the surface inside the stock box
  double allowance_mm = 0;
  double max_left_mm = 0;           // largest material above surface + allowance
  double p95_left_mm = 0;           // its 95th percentile over the nodes
  double max_into_allowance_mm = 0; // deepest cut below surface + allowance (0: none)
  Eigen::Vector3d into_allowance_at = Eigen::Vector3d::Zero();  // surface point there
  double max_gouge_mm = 0;          // deepest cut below the surface itself (0: none)
  Eigen::Vector3d gouge_at = Eigen::Vector3d::Zero();
  double seconds = 0;
};
struct CutProgram {
  const ClData* cl = nullptr;
  Cutter cutter;
};
StockCheck check_stock(const BSplineSurface& surface, const StockBox& stock, const std::vector<CutProgram>& programs,
                       double allowance_mm, double cell_mm, int threads);

// Throws UsageError for options out of range, GeometryError for a stock that misses the surface
// or a grid over 100 million nodes, and WorkLimitError (GeometryError) beyond max_moves.
void validate(const RoughingOptions& options);
RoughingResult generate_roughing(const BSplineSurface& surface, const RoughingOptions& options);

}  // namespace photomill::toolpath
