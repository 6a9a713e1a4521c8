// The outline of the fitted data in parameter space: a simple counter-clockwise polygon in (u,v)
// written with the surface (docs/formats.md, `boundary`), so toolpath stays on the part.
//
// Two constructions, both in the parameter rectangle scaled to mm (x = L_u u, y = L_v v) so
// that distances mean the same along u and v:
// - convex: the convex hull (Andrew's monotone chain), simplified by removing vertices closer
//   than the tolerance to the segment joining their neighbours (the result stays convex and lies
//   inside the hull). For sparse data such as marker points, whose hull is their outline.
// - concave: an occupancy grid of square cells (a few mean point spacings wide) marks the cells
//   holding data; a morphological closing bridges gaps of a cell or so, holes are filled, the
//   largest 4-connected region is kept (diagonal-only contacts are filled so its border is a
//   simple polygon), and its border along the cell edges is traced and simplified with
//   Douglas-Peucker. The outline lies within one cell of the outermost points. For dense data
//   with notches and concave sides.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace photomill::fitsurf {

enum class OutlineMethod { Auto, Concave, Convex, None };

struct OutlineOptions {
  OutlineMethod method = OutlineMethod::Auto;
  std::size_t concave_min_points = 2000;  // Auto: concave from this many points on, else convex
  double cell_mm = 0;             // concave: grid cell; 0 = cell_spacings x mean point spacing
  double cell_spacings = 3.0;
  int max_cells = 512;            // concave: cells along the longer side, at most
  int closing_cells = 1;          // concave: radius of the closing, in cells
  double simplify_mm = 0;         // 0 = one cell (concave) or half a mean spacing (convex)
};

// Outline of the points uv (parameters in [0,1]^2; points with a zero weight are left out;
// weights may be empty) for a parameter rectangle of length_u_mm x length_v_mm. Returns an empty
// polygon for OutlineMethod::None. Vertices lie in [0,1]^2, counter-clockwise, first not repeated.
std::vector<Eigen::Vector2d> data_outline(const std::vector<Eigen::Vector2d>& uv, const std::vector<double>& weights,
                                          double length_u_mm, double length_v_mm, const OutlineOptions& options);

// Geometry helpers (exposed for tests and for toolpath-style checks).
std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> points);  // CCW
double signed_area(const std::vector<Eigen::Vector2d>& polygon);                 // > 0 if CCW
bool point_in_polygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& x);
double segment_distance(const Eigen::Vector2d& x, const Eigen::Vector2d& a, const Eigen::Vector2d& b);  // to segment ab
double boundary_distance(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& x);  // to its closed edge
bool is_simple_polygon(const std::vector<Eigen::Vector2d>& polygon);

}  // namespace photomill::fitsurf
