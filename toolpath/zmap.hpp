// Verification of a ball-end CL path by z-map simulation: a grid of vertical lines over the part,
// each cut down to the lowest point the ball reaches when swept along every CL move (rapids
// included), compared with the surface's height at that grid node. Reports the real largest
// scallop (material left) and the deepest gouge (material removed below the surface), then
// refines the worst grid nodes by a local search between the nodes.
#pragma once

#include <cstddef>
#include <limits>
#include <optional>

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

// Throws UsageError for a non-positive cell or radius, GeometryError if the grid would exceed
// 100 million nodes or the window misses the surface.
ZmapResult simulate_zmap(const BSplineSurface& surface, const ClData& cl, const ZmapOptions& options);

}  // namespace photomill::toolpath
