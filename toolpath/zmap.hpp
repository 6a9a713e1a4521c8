// Verification of a ball-end CL path by z-map simulation: a grid of vertical lines over the part,
// each cut down to the lowest point the ball reaches when swept along every CL move (rapids
// included), compared with the surface's height at that grid node. Reports the real largest
// scallop (material left) and the deepest gouge (material removed below the surface), then
// refines the worst grid nodes by a local search between the nodes.
#pragma once

#include <cstddef>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"

namespace photomill::toolpath {

// The lowest point of a ball of radius R whose centre moves straight from a to b, on the
// vertical line through xy (+inf if the ball never passes over xy). With the move's horizontal
// length l, unit direction e, slope m = (b_z - a_z) / l, the foot sigma0 = (xy - a_xy) . e, the
// horizontal distance d of xy from the move's line and r = sqrt(R^2 - d^2):
//   z(sigma) = a_z + m sigma - sqrt(r^2 - (sigma - sigma0)^2)  over sigma in [0, l],
// convex in sigma, least at sigma* = sigma0 - m r / sqrt(1 + m^2) with
//   z* = a_z + m sigma0 - r sqrt(1 + m^2),
// else at the nearer end of the move (the ball at a or b).
double swept_ball_bottom(const Eigen::Vector3d& centre_a, const Eigen::Vector3d& centre_b, double radius_mm,
                         const Eigen::Vector2d& xy);

struct ZmapOptions {
  double cell_mm = 0.1;          // grid spacing
  double tool_radius_mm = 3;     // R of the ball that cuts
  double stock_mm = 0;           // allowance the path was made for: scallops and gouges are
                                 // measured from the surface offset by this much
  int threads = 0;               // 0 = all cores
  // Optional horizontal window (min, max corners, mm); default the surface's extent.
  std::optional<Eigen::Vector2d> window_min, window_max;
  int refine_candidates = 12;    // worst nodes refined by local search, for each of scallop and gouge
};

struct ZmapResult {
  double cell_mm = 0;
  std::size_t nodes = 0;            // grid nodes over the surface (and inside its boundary polygon)
  std::size_t unmachined = 0;       // of those, nodes no ball passed over
  // Material left, measured along the surface normal: (z_cut - z_surface) n_z - stock (first
  // order in the distance; exact on planes). Largest value, refined between nodes, and where.
  double max_scallop_mm = -std::numeric_limits<double>::infinity();
  Eigen::Vector3d max_scallop_at = Eigen::Vector3d::Zero();  // surface point (x, y, z)
  double grid_max_scallop_mm = -std::numeric_limits<double>::infinity();  // before refinement
  // Deepest cut below the surface (the negative of the above where it is below zero), or 0.
  double max_gouge_mm = 0;
  Eigen::Vector3d max_gouge_at = Eigen::Vector3d::Zero();
  double grid_max_gouge_mm = 0;
  double max_excess_z_mm = -std::numeric_limits<double>::infinity();  // vertical, at the nodes
  double seconds = 0;
};

// The surface's height over a grid of nodes lo + (i, j) cell_mm, i < nx, j < ny, stored row by
// row (k = j nx + i): z(x, y) by Newton's method on S_xy(u, v) = (x, y), +inf off the surface or
// outside its boundary polygon.
struct HeightGrid {
  Eigen::Vector2d lo = Eigen::Vector2d::Zero();
  double cell_mm = 0;
  long nx = 0, ny = 0;
  std::vector<double> z;
  Eigen::Vector2d node_xy(long i, long j) const { return lo + cell_mm * Eigen::Vector2d(static_cast<double>(i), static_cast<double>(j)); }
};
// Fills grid.z for the nodes grid.lo, cell_mm, nx, ny give (any window, on or off the surface).
void sample_surface_heights(const BSplineSurface& surface, HeightGrid& grid, int threads);
// The surface's xy bounding box (min, max), from its sample grid (about 1 mm apart).
std::pair<Eigen::Vector2d, Eigen::Vector2d> surface_xy_extent(const BSplineSurface& surface);

// The x interval [x0, x1] of the row y = const within horizontal distance R of the segment
// [a, b] (a convex capsule, so the union of its two discs and its band is one interval); false
// where the row misses it.
bool capsule_row(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double R, double y, double& x0, double& x1);

// A milling cutter: radius R and corner radius r_c (0: flat end mill, R: ball end).
struct Cutter {
  double radius_mm = 3;
  double corner_radius_mm = 3;
};

// The cutter's profile above its tip at distance rho (<= R) from its axis:
//   f(rho) = 0 for rho <= R - r_c,  r_c - sqrt(r_c^2 - (rho - R + r_c)^2) beyond.
double cutter_lift(const Cutter& cutter, double rho);

// The lowest point of the cutter on the vertical line through xy while its tip moves straight
// from tip_a to tip_b (+inf if it never passes over xy). With the cutter's profile above its tip
// f(rho) = 0 for rho <= R - r_c, r_c - sqrt(r_c^2 - (rho - R + r_c)^2) beyond, the travel sigma
// in [0, l] along the move and rho(sigma) the line's distance from the axis:
//   z(sigma) = a_z + m sigma + f(rho(sigma)),  rho <= R.
// Flat (r_c = 0): linear in sigma, least at one end of the interval where rho <= R. Ball: the
// closed form of swept_ball_bottom. Bull-nose: f is convex and increasing, rho convex, so z is
// convex in sigma and a golden-section search finds its least.
double swept_cutter_bottom(const Eigen::Vector3d& tip_a, const Eigen::Vector3d& tip_b, const Cutter& cutter,
                           const Eigen::Vector2d& xy);

// One move: lowers material.z on the rows j_first..j_last (cut to the move's reach) wherever the
// cutter passes; returns the deepest it cut there (0: none) and, with deepest_at, where.
double cut_move_rows(HeightGrid& material, const Eigen::Vector3d& tip_a, const Eigen::Vector3d& tip_b, const Cutter& cutter,
                     long j_first, long j_last, Eigen::Vector2d* deepest_at = nullptr);

// Lowers material.z (the material's top at the grid's nodes) wherever the cutter passes along
// the CL moves (rapids included). Rows in blocks, in parallel.
void cut_material(HeightGrid& material, const ClData& cl, const Cutter& cutter, int threads);

// Throws UsageError for a non-positive cell or radius, GeometryError if the grid would exceed
// 100 million nodes or the window misses the surface.
ZmapResult simulate_zmap(const BSplineSurface& surface, const ClData& cl, const ZmapOptions& options);

}  // namespace photomill::toolpath
