// Cutting simulation (issue 26, deliverable 4): a stock box cut by CL programs in turn (roughing,
// then finishing, each with its own cutter) on a z-map, move by move, and what is left compared
// with the surface: material left (everywhere, and where the last cutter can reach), gouges,
// rapids that meet material and feed moves that go down into it steeply (plunges).
//
// The z-map: a grid of vertical lines over the stock, each holding the material's top; a move
// lowers the lines the cutter passes over to its swept bottom (zmap.hpp swept_cutter_bottom:
// flat, bull-nose or ball). The part's height H is the surface's at each node (Newton on
// S_xy(u, v) = (x, y)); off the surface the node is not judged.
//
// Where the last cutter can reach: the surface closed by that cutter (the morphological closing
// of the height field, Serra's "Image Analysis and Mathematical Morphology", 1982, with the
// cutter's profile f as the structuring function):
//   T(p) = max over |q - p| <= R of H(q) - f(|q - p|)    (the lowest tip at p, "inverse offset")
//   E(x) = min over |x - p| <= R of T(p) + f(|x - p|)    (the lowest that cutter can cut at x)
// Material left is measured along the surface normal to first order: (top - max(H, E)) n_z -
// allowance, n_z from central differences of H.
#pragma once

#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "toolpath/roughing.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {

struct CutsimProgram {
  std::string name;
  ClData cl;
  Cutter cutter;
};

struct CutsimOptions {
  std::optional<StockBox> stock;  // unset: the surface's box grown by stock_margin_mm
  double stock_margin_mm = 2;
  double cell_mm = 0.2;
  double allowance_mm = 0;        // material meant to stay on the surface (0 after finishing)
  double plunge_angle_deg = 45;   // a feed move going down more steeply into material is a plunge
  double tolerance_mm = 1e-4;     // material removed by less than this is not a cut
  int threads = 0;
};

struct CutsimProgramFigures {
  std::string name;
  std::size_t moves = 0;
  double feed_length_mm = 0, rapid_length_mm = 0;
  double feed_time_min = 0;        // sum of feed length / feed
  std::size_t rapids_into_material = 0;
  std::size_t plunges = 0;         // feed moves steeper than the plunge angle into material under the axis
  std::string first_fault;         // the first rapid or plunge, described
};

struct CutsimResult {
  StockBox stock;
  double cell_mm = 0;
  std::size_t nodes = 0;           // nodes over the surface inside the stock
  double max_left_mm = 0, p95_left_mm = 0;  // above surface + allowance, along the normal
  Eigen::Vector3d max_left_at = Eigen::Vector3d::Zero();
  double max_left_reachable_mm = 0, p95_left_reachable_mm = 0;  // above the last cutter's reach
  Eigen::Vector3d max_left_reachable_at = Eigen::Vector3d::Zero();
  std::size_t unreachable_nodes = 0;  // where the last cutter's reach is over 0.001 mm above H
  double max_gouge_mm = 0;         // deepest cut below the surface, along the normal
  Eigen::Vector3d max_gouge_at = Eigen::Vector3d::Zero();
  std::vector<CutsimProgramFigures> programs;
  HeightGrid material, part;       // the z-maps, for a picture
  double seconds = 0;
};

// Throws UsageError for bad options or a program without a cutter, GeometryError for a stock
// that misses the surface or a grid over 100 million nodes.
CutsimResult simulate_cutting(const BSplineSurface& surface, const std::vector<CutsimProgram>& programs,
                              const CutsimOptions& options);

// The stderr summary: one line per program (length, time at feed, faults) and two of what is left.
std::vector<std::string> cutsim_summary(const CutsimResult& result);
// The JSON report: tool, version, options, stock, programs[], left, gouge.
void write_cutsim_report(std::ostream& out, const CutsimResult& result, const CutsimOptions& options);

// A PNG top view: the material left above the surface (+ allowance) in colour (gouges in
// magenta), the stock's outline, axes in mm and a colour bar.
std::vector<unsigned char> render_cutsim_png(const CutsimResult& result, double allowance_mm);

}  // namespace photomill::toolpath
