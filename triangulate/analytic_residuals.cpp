#include "triangulate/analytic_residuals.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include <ceres/rotation.h>

namespace photomill::triangulate {
namespace {

// A pose's rotation R(w) (row-major) and the left Jacobian J_l(w) of SO(3) (see the header),
// for its angle-axis w.
struct PoseRotation {
  double w[3] = {0, 0, 0};
  double R[9];
  double jl[9];
  const double* key = nullptr;
};

void compute_rotation(const double* w, PoseRotation& r) {
  r.w[0] = w[0];
  r.w[1] = w[1];
  r.w[2] = w[2];
  ceres::AngleAxisToRotationMatrix(w, ceres::RowMajorAdapter3x3(r.R));
  // J_l(w) = I + a W + b W^2, W = [w]x, W^2 = w w^T - th^2 I.
  const double w0 = w[0], w1 = w[1], w2 = w[2];
  const double th2 = w0 * w0 + w1 * w1 + w2 * w2;
  double a, b;
  if (th2 < 1e-8) {
    a = 0.5 - th2 / 24.0;
    b = 1.0 / 6.0 - th2 / 120.0;
  } else {
    const double th = std::sqrt(th2);
    a = (1.0 - std::cos(th)) / th2;
    b = (th - std::sin(th)) / (th2 * th);
  }
  const double jl[9] = {1.0 + b * (w0 * w0 - th2), -a * w2 + b * w0 * w1,      a * w1 + b * w0 * w2,
                        a * w2 + b * w1 * w0,      1.0 + b * (w1 * w1 - th2), -a * w0 + b * w1 * w2,
                        -a * w1 + b * w2 * w0,     a * w0 + b * w2 * w1,      1.0 + b * (w2 * w2 - th2)};
  std::copy(jl, jl + 9, r.jl);
}

// R and J_l of the pose block at `pose`, from a small per-thread table keyed by the block's
// address and checked against its values: every observation of a photo needs the same ones, and
// computing them (two sine/cosine pairs and a square root) for each was ~8 % of the demo's
// adjustments.
const PoseRotation& pose_rotation(const double* pose) {
  constexpr std::size_t kSlots = 64;
  thread_local std::array<PoseRotation, kSlots> table;
  // Pose blocks are 6 doubles apart in an array: consecutive blocks take consecutive slots.
  PoseRotation& r = table[(reinterpret_cast<std::uintptr_t>(pose) / (6 * sizeof(double))) % kSlots];
  if (r.key != pose || r.w[0] != pose[0] || r.w[1] != pose[1] || r.w[2] != pose[2]) {
    compute_rotation(pose, r);
    r.key = pose;
  }
  return r;
}

}  // namespace

bool reprojection_with_jacobians(double skew, const double* k, const double* pose, const double* point,
                                 double u_px, double v_px, double inv_sigma, double* residual,
                                 double* jacobian_pose, double* jacobian_point, double* jacobian_intrinsics) {
  using geometry::kCx;
  using geometry::kCy;
  using geometry::kFx;
  using geometry::kFy;
  using geometry::kK1;
  using geometry::kK2;
  using geometry::kK3;
  using geometry::kP1;
  using geometry::kP2;
  // geometry::project()'s evaluation, with the rotation applied as its matrix (the same to
  // rounding as the angle-axis formula project() uses).
  const PoseRotation& rot = pose_rotation(pose);
  const double* R = rot.R;
  const double q[3] = {R[0] * point[0] + R[1] * point[1] + R[2] * point[2],
                       R[3] * point[0] + R[4] * point[1] + R[5] * point[2],
                       R[6] * point[0] + R[7] * point[1] + R[8] * point[2]};
  const double p[3] = {q[0] + pose[3], q[1] + pose[4], q[2] + pose[5]};
  if (!(p[2] > 0.0)) return false;
  const double x = p[0] / p[2], y = p[1] / p[2];
  const double r2 = x * x + y * y;
  const double r4 = r2 * r2;
  const double radial = 1.0 + k[kK1] * r2 + k[kK2] * r4 + k[kK3] * (r4 * r2);
  const double xy = x * y;
  const double xd = x * radial + 2.0 * k[kP1] * xy + k[kP2] * (r2 + 2.0 * x * x);
  const double yd = y * radial + k[kP1] * (r2 + 2.0 * y * y) + 2.0 * k[kP2] * xy;
  double u = k[kFx] * xd + k[kCx];
  if (skew != 0) u += skew * yd;
  const double v = k[kFy] * yd + k[kCy];
  residual[0] = (u - u_px) * inv_sigma;
  residual[1] = (v - v_px) * inv_sigma;
  if (jacobian_pose == nullptr && jacobian_point == nullptr && jacobian_intrinsics == nullptr) return true;

  const double fx = k[kFx] * inv_sigma, fy = k[kFy] * inv_sigma, s = skew * inv_sigma;
  if (jacobian_intrinsics != nullptr) {
    double* ju = jacobian_intrinsics;
    double* jv = jacobian_intrinsics + 9;
    const double r6 = r4 * r2;
    const double dxd[5] = {x * r2, x * r4, 2.0 * xy, r2 + 2.0 * x * x, x * r6};  // k1 k2 p1 p2 k3
    const double dyd[5] = {y * r2, y * r4, r2 + 2.0 * y * y, 2.0 * xy, y * r6};
    ju[kFx] = xd * inv_sigma;
    ju[kFy] = 0.0;
    ju[kCx] = inv_sigma;
    ju[kCy] = 0.0;
    jv[kFx] = 0.0;
    jv[kFy] = yd * inv_sigma;
    jv[kCx] = 0.0;
    jv[kCy] = inv_sigma;
    for (int i = 0; i < 5; ++i) {
      ju[kK1 + i] = fx * dxd[i] + s * dyd[i];
      jv[kK1 + i] = fy * dyd[i];
    }
  }
  if (jacobian_pose == nullptr && jacobian_point == nullptr) return true;

  // d(u, v) / d(x, y), whitened.
  const double dl = k[kK1] + 2.0 * k[kK2] * r2 + 3.0 * k[kK3] * r4;
  const double dxd_dx = radial + 2.0 * x * x * dl + 2.0 * k[kP1] * y + 6.0 * k[kP2] * x;
  const double dxd_dy = 2.0 * xy * dl + 2.0 * k[kP1] * x + 2.0 * k[kP2] * y;
  const double dyd_dx = dxd_dy;
  const double dyd_dy = radial + 2.0 * y * y * dl + 6.0 * k[kP1] * y + 2.0 * k[kP2] * x;
  const double a00 = fx * dxd_dx + s * dyd_dx, a01 = fx * dxd_dy + s * dyd_dy;
  const double a10 = fy * dyd_dx, a11 = fy * dyd_dy;
  // d(u, v) / d p = A [1/p2 0 -x/p2; 0 1/p2 -y/p2].
  const double iz = 1.0 / p[2];
  const double c[2][3] = {{a00 * iz, a01 * iz, -(a00 * x + a01 * y) * iz},
                          {a10 * iz, a11 * iz, -(a10 * x + a11 * y) * iz}};
  if (jacobian_point != nullptr) {
    for (int row = 0; row < 2; ++row) {
      for (int col = 0; col < 3; ++col) {
        jacobian_point[row * 3 + col] = c[row][0] * R[col] + c[row][1] * R[3 + col] + c[row][2] * R[6 + col];
      }
    }
  }
  if (jacobian_pose != nullptr) {
    const double(&jl)[9] = rot.jl;
    // M = -[q]x J_l, with -[q]x = [0 q2 -q1; -q2 0 q0; q1 -q0 0].
    const double mq[3][3] = {{0.0, q[2], -q[1]}, {-q[2], 0.0, q[0]}, {q[1], -q[0], 0.0}};
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) m[i][j] = mq[i][0] * jl[j] + mq[i][1] * jl[3 + j] + mq[i][2] * jl[6 + j];
    }
    for (int row = 0; row < 2; ++row) {
      for (int col = 0; col < 3; ++col) {
        jacobian_pose[row * 6 + col] = c[row][0] * m[0][col] + c[row][1] * m[1][col] + c[row][2] * m[2][col];
        jacobian_pose[row * 6 + 3 + col] = c[row][col];
      }
    }
  }
  return true;
}

bool AnalyticReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                         double** jacobians) const {
  return reprojection_with_jacobians(camera_->skew, camera_->params.data(), parameters[0], parameters[1], u_, v_,
                                     inv_sigma_, residuals, jacobians ? jacobians[0] : nullptr,
                                     jacobians ? jacobians[1] : nullptr, nullptr);
}

bool AnalyticReprojectionErrorWithIntrinsics::Evaluate(double const* const* parameters, double* residuals,
                                                       double** jacobians) const {
  return reprojection_with_jacobians(skew_, parameters[2], parameters[0], parameters[1], u_, v_, inv_sigma_,
                                     residuals, jacobians ? jacobians[0] : nullptr,
                                     jacobians ? jacobians[1] : nullptr, jacobians ? jacobians[2] : nullptr);
}

}  // namespace photomill::triangulate
