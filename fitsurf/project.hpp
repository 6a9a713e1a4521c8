// Point inversion: the foot point of a point on a B-spline surface (The NURBS Book, 6.1,
// eqs. 6.6-6.8), used for fitsurf's parameter correction and for the reported residuals.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "formats/surface.hpp"

namespace photomill::fitsurf {

struct ProjectionOptions {
  int max_iterations = 8;           // Newton steps per point
  // Converged when a step would move the foot point less than this: at a foot point the distance
  // is stationary, so stopping one step of size e early changes it by about e^2 / (2 distance).
  double step_tolerance_mm = 1e-4;
};

struct FootPoint {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // parameters of the foot point (in the domain)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // S(u, v)
  // |Q - S(u, v)| with the sign of (Q - S) . n, n = S_u x S_v / |S_u x S_v|: positive above the
  // surface (on the side its normal points to).
  double signed_distance_mm = 0;
};

// Newton's method on f(u,v) = r . S_u = 0, g(u,v) = r . S_v = 0, r = S(u,v) - Q, from (u0, v0):
//   J = [ |S_u|^2 + r.S_uu    S_u.S_v + r.S_uv ]     [du]      [f]
//       [ S_u.S_v + r.S_uv    |S_v|^2 + r.S_vv ],  J [dv] = -  [g],
// parameters clamped to the domain after each step (6.8 for an open surface; a parameter held
// on an edge leaves the other a 1-D Newton step along it). Where J is not
// positive definite (Q farther than the local radius of curvature) the step falls back to
// Gauss-Newton (J without the r terms), which always descends.
FootPoint project_point(const BSplineSurface& surface, const Eigen::Vector3d& q, Eigen::Vector2d uv0,
                        const ProjectionOptions& options = {});

// project_point for every point, starting from uv (updated in place); signed distances out.
// Runs on `threads` workers (0: all hardware threads).
void project_points(const BSplineSurface& surface, const std::vector<Eigen::Vector3d>& points,
                    std::vector<Eigen::Vector2d>& uv, std::vector<double>& signed_distance_mm,
                    const ProjectionOptions& options, int threads);

}  // namespace photomill::fitsurf
