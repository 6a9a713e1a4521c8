// Reprojection residuals with hand-written derivatives, for the cameras most photos use: OpenCV's
// five-coefficient model (k1 k2 p1 p2 k3; no rational, thin-prism or tilt terms). They compute the
// same residual as residuals.hpp's ReprojectionError and ReprojectionErrorWithIntrinsics<9>
// (whose automatic differentiation carries 18 derivatives per value and was ~30 % of the
// demo's bundle adjustments, docs/measurements/triangulate.md); the other models keep those.
#pragma once

#include <ceres/ceres.h>

#include "geometry/camera_model.hpp"

namespace photomill::triangulate {

// True if the analytic residuals below can stand for the camera model's projection.
constexpr bool analytic_projection_applies(const geometry::ModelShape& shape) {
  return !shape.rational && !shape.thin_prism && !shape.tilted;
}

// The residual r = (pi(k; R(aa) X + t) - u) / sigma_px and, where asked, its derivatives:
// jacobian_pose 2x6 (angle-axis, t), jacobian_point 2x3, jacobian_intrinsics 2x9 (fx fy cx cy k1
// k2 p1 p2 k3), each row-major as Ceres stores them. False (nothing written) if the point is not
// in front of the camera.
//
// Derivation (the chain rule through project(), geometry/camera_model.hpp):
//   q = R(aa) X,  p = q + t,  (x, y) = (p0 / p2, p1 / p2),  (x'', y'') = distortion of (x, y),
//   u = fx x'' + s y'' + cx,  v = fy y'' + cy.
//   d p / d X = R,  d p / d t = I,
//   d p / d aa = -[q]x J_l(aa)  with the left Jacobian of SO(3)
//     J_l(w) = I + (1 - cos th) / th^2 [w]x + (th - sin th) / th^3 [w]x^2,  th = |w|
//   (Barfoot, "State Estimation for Robotics", 2017, eq. 7.86: R(w + dw) = Exp(J_l(w) dw) R(w)),
//   whose coefficients are replaced by their Taylor series 1/2 - th^2/24 and 1/6 - th^2/120
//   for th^2 < 1e-8.
//   d (x, y) / d p = [1/p2 0 -x/p2; 0 1/p2 -y/p2],
//   with r2 = x^2 + y^2, L = 1 + k1 r2 + k2 r2^2 + k3 r2^3, L' = k1 + 2 k2 r2 + 3 k3 r2^2:
//   d x'' / d x = L + 2 x^2 L' + 2 p1 y + 6 p2 x,    d x'' / d y = 2 x y L' + 2 p1 x + 2 p2 y,
//   d y'' / d x = 2 x y L' + 2 p1 x + 2 p2 y,        d y'' / d y = L + 2 y^2 L' + 6 p1 y + 2 p2 x,
//   d (x'', y'') / d (k1, k2, k3) = (x, y) (r2, r2^2, r2^3),
//   d x'' / d (p1, p2) = (2 x y, r2 + 2 x^2),  d y'' / d (p1, p2) = (r2 + 2 y^2, 2 x y).
bool reprojection_with_jacobians(double skew, const double* intrinsics, const double* pose, const double* point,
                                 double u_px, double v_px, double inv_sigma, double* residual,
                                 double* jacobian_pose, double* jacobian_point, double* jacobian_intrinsics);

// ReprojectionError's residual (intrinsics held fixed, read from the camera it points to).
class AnalyticReprojectionError final : public ceres::SizedCostFunction<2, 6, 3> {
 public:
  AnalyticReprojectionError(const geometry::CameraModel* camera, double u_px, double v_px, double sigma_px)
      : camera_(camera), u_(u_px), v_(v_px), inv_sigma_(1.0 / sigma_px) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  const geometry::CameraModel* camera_;
  double u_, v_, inv_sigma_;
};

// ReprojectionErrorWithIntrinsics<9>'s residual (self-calibration of the five-coefficient model).
class AnalyticReprojectionErrorWithIntrinsics final : public ceres::SizedCostFunction<2, 6, 3, 9> {
 public:
  AnalyticReprojectionErrorWithIntrinsics(double skew, double u_px, double v_px, double sigma_px)
      : skew_(skew), u_(u_px), v_(v_px), inv_sigma_(1.0 / sigma_px) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double skew_, u_, v_, inv_sigma_;
};

}  // namespace photomill::triangulate
