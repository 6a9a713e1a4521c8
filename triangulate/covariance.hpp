// Uncertainty of the adjusted points: the marginal covariance of each point from the bundle
// adjustment's normal equations, through the Schur complement on the cameras, scaled by the
// a-posteriori variance factor. Falls back to a per-point estimate with the poses held fixed
// when the reduced camera system is too large to invert densely.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "triangulate/bundle.hpp"
#include "triangulate/scene.hpp"

namespace photomill::triangulate {

struct CovarianceOptions {
  // Largest reduced system (pose, intrinsics and scale-bar point parameters) inverted densely
  // for the full covariance; larger problems use the per-point approximation.
  std::size_t max_reduced_parameters = 3000;
  int threads = 0;
};

enum class CovarianceMethod { Full, PerPoint };
const char* to_string(CovarianceMethod method);

struct PointUncertainty {
  CovarianceMethod method = CovarianceMethod::Full;
  // sigma0^2 = sum r^2 / (m - n): whitened residuals r, m residual components, n free parameters
  // (1 when there is no redundancy, then the a-priori sigmas are taken as they are).
  double variance_factor = 1;
  std::size_t redundancy = 0;               // m - n
  // Per track: Sigma_X, the point's marginal covariance times sigma0^2 (mm^2); NaN for tracks
  // outside the adjustment, 0 for fixed control points.
  std::vector<Eigen::Matrix3d> covariance_mm2;
  // Per track: sqrt(lambda_max(Sigma_X)), the standard deviation along the point's worst
  // direction (the semi-major axis of its standard error ellipsoid) in mm; NaN for tracks
  // outside the adjustment, 0 for fixed control points. See largest_axis_sigma_mm.
  std::vector<double> sigma_mm;
};

// Normal equations of the whitened problem N = J^T J (Triggs et al. 2000, sec. 6; H&Z A6.3),
// ordered as [f | e] with e the points eliminated by the Schur complement and f the rest:
//   N = [U W; W^T V],  S = U - W V^-1 W^T,  Sigma_f = S^-1,
//   Sigma_e_i = V_i^-1 + V_i^-1 W_i^T Sigma_f W_i V_i^-1   (H&Z eq. A6.13),
// each multiplied by sigma0^2. Jacobians by automatic differentiation of the residuals
// (residuals.hpp); the robust loss is left out (the inliers lie in its quadratic region).
// Per-point method: Sigma_e_i = sigma0^2 V_i^-1 (poses and intrinsics treated as exact).
// The gauge must be fixed by the setup (control points, a fixed image and scale bars, or a fixed
// translation coordinate); a singular S also falls back to the per-point method.
// The standard deviation of a point along its worst direction:
//   sigma_max = sqrt(lambda_max(Sigma_X)),
// the semi-major axis of the standard (1-sigma) error ellipsoid of X, whose axes are the
// eigenvectors of Sigma_X and half-lengths the square roots of its eigenvalues (Hartley &
// Zisserman 2004, sec. 5.2, the uncertainty ellipsoid of an estimate; Mikhail, Bethel & McGlone
// 2001, error ellipsoids). For a point seen at a narrow intersection angle this axis lies along
// its rays (depth sigma ~ lateral sigma / sin(angle)), which the RMS per axis sqrt(trace / 3)
// dilutes and the reprojection error does not see at all. 0 for a zero matrix, NaN for a
// non-finite one.
double largest_axis_sigma_mm(const Eigen::Matrix3d& covariance_mm2);

PointUncertainty point_uncertainty(const Scene& scene, const BundleSetup& setup, const BundleOptions& bundle,
                                   const CovarianceOptions& options);

}  // namespace photomill::triangulate
