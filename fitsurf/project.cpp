// Foot points by Newton's method (The NURBS Book 6.1); formulas in project.hpp.
#include "fitsurf/project.hpp"

#include <algorithm>
#include <cmath>

#include "fitsurf/evaluate.hpp"
#include "geometry/parallel.hpp"
#include "formats/bspline.hpp"

namespace photomill::fitsurf {

FootPoint project_point(const BSplineSurface& s, const Eigen::Vector3d& q, Eigen::Vector2d uv,
                        const ProjectionOptions& options) {
  // Plain variables, not structured bindings: lambdas capture them in clang 14 too.
  const std::pair<double, double> du = domain_u(s), dv = domain_v(s);
  const double u0 = du.first, u1 = du.second, v0 = dv.first, v1 = dv.second;
  auto clamp = [&](Eigen::Vector2d x) {
    return Eigen::Vector2d(std::clamp(x.x(), u0, u1), std::clamp(x.y(), v0, v1));
  };
  uv = clamp(uv);
  SurfaceDerivatives d = evaluate(s, uv.x(), uv.y());
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    const Eigen::Vector3d r = d.p - q;
    const double f = r.dot(d.su), g = r.dot(d.sv);
    const double a = d.su.squaredNorm(), b = d.su.dot(d.sv), c = d.sv.squaredNorm();
    double j00 = a + r.dot(d.suu), j01 = b + r.dot(d.suv), j11 = c + r.dot(d.svv);
    double det = j00 * j11 - j01 * j01;
    if (!(j00 > 0 && det > 0)) {  // not a minimum's basin: Gauss-Newton
      j00 = a;
      j01 = b;
      j11 = c;
      det = j00 * j11 - j01 * j01;
      if (!(det > 0)) break;  // singular surface point: keep the current foot point
    }
    Eigen::Vector2d full(-(j11 * f - j01 * g) / det, -(-j01 * f + j00 * g) / det);
    // A parameter on a domain edge that the step pushes outwards stays there, and the other one
    // takes its own 1-D Newton step (the foot point on that boundary curve).
    const bool u_held = (uv.x() <= u0 && full.x() < 0) || (uv.x() >= u1 && full.x() > 0);
    const bool v_held = (uv.y() <= v0 && full.y() < 0) || (uv.y() >= v1 && full.y() > 0);
    if (u_held && v_held) break;
    if (u_held) full = Eigen::Vector2d(0, j11 > 0 ? -g / j11 : -g / c);
    if (v_held) full = Eigen::Vector2d(j00 > 0 ? -f / j00 : -f / a, 0);
    // Converged when the (clamped) step would move the foot point less than the tolerance.
    const Eigen::Vector2d step0 = clamp(uv + full) - uv;
    if ((step0.x() * d.su + step0.y() * d.sv).norm() < options.step_tolerance_mm) break;
    // Halve the step while it moves away from Q (a safeguard far from the solution).
    double scale = 1.0;
    Eigen::Vector2d next;
    SurfaceDerivatives dn;
    bool descent = false;
    for (int halving = 0; halving <= 4 && !descent; ++halving, scale *= 0.5) {
      next = clamp(uv + scale * full);
      dn = evaluate(s, next.x(), next.y());
      descent = (dn.p - q).squaredNorm() <= r.squaredNorm();
    }
    if (!descent) break;  // keep the current point
    uv = next;
    d = dn;
  }
  FootPoint fp;
  fp.uv = uv;
  fp.point = d.p;
  const Eigen::Vector3d r = q - d.p;
  const double dist = r.norm();
  fp.signed_distance_mm = r.dot(d.su.cross(d.sv)) < 0 ? -dist : dist;
  return fp;
}

void project_points(const BSplineSurface& surface, const std::vector<Eigen::Vector3d>& points,
                    std::vector<Eigen::Vector2d>& uv, std::vector<double>& signed_distance_mm,
                    const ProjectionOptions& options, int threads) {
  signed_distance_mm.resize(points.size());
  geometry::parallel_blocks(points.size(), threads, 512, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t k = begin; k < end; ++k) {
      const FootPoint fp = project_point(surface, points[k], uv[k], options);
      uv[k] = fp.uv;
      signed_distance_mm[k] = fp.signed_distance_mm;
    }
  });
}

}  // namespace photomill::fitsurf
