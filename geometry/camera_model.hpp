// photomill's one camera model: a pinhole with OpenCV's distortion (all 14 coefficients), in a
// flat parameter block for Ceres, with a templated projection (for automatic differentiation)
// and its inverse (pixel -> undistorted normalised coordinates) by Newton's method. calib,
// match and triangulate evaluate cameras only through this header; synth keeps an independent
// copy as the oracle (tools/synth, checked against cv::projectPoints).
// Pixel convention: OpenCV's (centre of the top-left pixel at (0, 0)).
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "formats/camera.hpp"
#include "geometry/rotation.hpp"

namespace photomill::geometry {

// Layout of the intrinsics parameter block (OpenCV's model, coefficients in OpenCV's order
// after the four linear terms). Coefficients missing from camera.yaml are zero.
enum IntrinsicIndex : int {
  kFx = 0, kFy, kCx, kCy,              // pixels
  kK1, kK2, kP1, kP2, kK3,             // radial k1 k2 k3, tangential p1 p2
  kK4, kK5, kK6,                       // rational model denominator
  kS1, kS2, kS3, kS4,                  // thin prism
  kTauX, kTauY,                        // tilted sensor (rad)
  kIntrinsicCount
};
using Intrinsics = std::array<double, kIntrinsicCount>;

// The block index of each of camera.yaml's distortion coefficients, in OpenCV's order
// (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tau_x tau_y).
inline constexpr std::array<int, 14> kDistortionSlot = {kK1, kK2, kP1, kP2, kK3, kK4, kK5,
                                                        kK6, kS1, kS2, kS3, kS4, kTauX, kTauY};

// A camera as the stages use it: the parameter block, the skew (constant; OpenCV's own
// functions ignore it and its calibration never sets it) and the image size.
struct CameraModel {
  Intrinsics params{};
  double skew = 0;                 // camera_matrix(0, 1), pixels
  int width_px = 0;
  int height_px = 0;
  int distortion_count = 0;        // how many coefficients camera.yaml gave (0, 4, 5, 8, 12, 14)
};

// Which groups of distortion terms the model evaluates. Decided by the number of coefficients
// camera.yaml gave (not by their values, so that self-calibration can move a zero one):
// rational k4..k6 with 8 or more, thin prism s1..s4 with 12 or more, the tilt with 14. Skipping
// absent groups is exact (their coefficients are zero) and saves work in every residual.
struct ModelShape {
  double skew = 0;
  bool rational = false;
  bool thin_prism = false;
  bool tilted = false;
};
inline ModelShape shape_of_count(int distortion_count, double skew = 0) {
  return {skew, distortion_count >= 8, distortion_count >= 12, distortion_count >= 14};
}
inline ModelShape shape_of(const CameraModel& m) { return shape_of_count(m.distortion_count, m.skew); }

// Converts camera.yaml's camera (validated first: throws InputError(source, 0, ...)).
CameraModel to_camera_model(const Camera& camera, const std::string& source);
// Back to camera.yaml's form (same number of distortion coefficients as read).
Camera to_camera(const CameraModel& model, const Camera& original);

// OpenCV's sensor tilt (calib3d, computeTiltProjectionMatrix; Louhichi et al. 2007): with
//   Rxy = Ry(tau_y) Rx(tau_x),  Rx = [1 0 0; 0 c_x s_x; 0 -s_x c_x],  Ry = [c_y 0 -s_y; 0 1 0; s_y 0 c_y]
//   T = [Rxy22 0 -Rxy02; 0 Rxy22 -Rxy12; 0 0 1] Rxy
// the distorted point (x'', y'') maps to (q0 / q2, q1 / q2), q = T (x'', y'', 1).
template <typename T, typename P>
void apply_tilt(const P& tau_x, const P& tau_y, T* x, T* y) {
  using std::cos;
  using std::sin;
  const P cx = cos(tau_x), sx = sin(tau_x), cy = cos(tau_y), sy = sin(tau_y);
  // Rxy = Ry Rx, row by row.
  const P r00 = cy, r01 = sy * sx, r02 = -sy * cx;
  const P r10 = P(0.0), r11 = cx, r12 = sx;
  const P r20 = sy, r21 = -cy * sx, r22 = cy * cx;
  // T = Pz Rxy with Pz = [r22 0 -r02; 0 r22 -r12; 0 0 1].
  const P t00 = r22 * r00 - r02 * r20, t01 = r22 * r01 - r02 * r21, t02 = r22 * r02 - r02 * r22;
  const P t10 = r22 * r10 - r12 * r20, t11 = r22 * r11 - r12 * r21, t12 = r22 * r12 - r12 * r22;
  const T q0 = t00 * *x + t01 * *y + t02;
  const T q1 = t10 * *x + t11 * *y + t12;
  const T q2 = r20 * *x + r21 * *y + r22;
  *x = q0 / q2;
  *y = q1 / q2;
}

// OpenCV's distortion and projection (cv::projectPoints, docs of calib3d), for a point (x, y)
// in normalised camera coordinates (X/Z, Y/Z):
//   r^2 = x^2 + y^2
//   radial = (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
//   x'' = x radial + 2 p1 x y + p2 (r^2 + 2 x^2) + s1 r^2 + s2 r^4
//   y'' = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y + s3 r^2 + s4 r^4
//   (x'', y'') <- tilt(tau_x, tau_y) of (x'', y'')           (apply_tilt, 14 coefficients)
//   u = fx x'' + skew y'' + cx,   v = fy y'' + cy
// `k` is the parameter block (IntrinsicIndex layout), double or a Jet for self-calibration.
template <typename T, typename P>
void distort_to_pixel(const ModelShape& shape, const P* k, const T& x, const T& y, T* u, T* v) {
  const T r2 = x * x + y * y;
  const T r4 = r2 * r2;
  T radial = T(1.0) + k[kK1] * r2 + k[kK2] * r4 + k[kK3] * (r4 * r2);
  if (shape.rational) radial /= T(1.0) + k[kK4] * r2 + k[kK5] * r4 + k[kK6] * (r4 * r2);
  const T xy = x * y;
  T xd = x * radial + T(2.0) * k[kP1] * xy + k[kP2] * (r2 + T(2.0) * x * x);
  T yd = y * radial + k[kP1] * (r2 + T(2.0) * y * y) + T(2.0) * k[kP2] * xy;
  if (shape.thin_prism) {
    xd += k[kS1] * r2 + k[kS2] * r4;
    yd += k[kS3] * r2 + k[kS4] * r4;
  }
  if (shape.tilted) apply_tilt(k[kTauX], k[kTauY], &xd, &yd);
  *u = k[kFx] * xd + k[kCx];
  if (shape.skew != 0) *u += T(shape.skew) * yd;
  *v = k[kFy] * yd + k[kCy];
}

// Projection of a world point with pose cam_from_world = [angle-axis (3, rad), t (3, mm)]:
//   x_cam = R(aa) X + t  (the paper's x_cam = R X + T, section 3.2), then distort_to_pixel.
// Returns false (outputs untouched) if the point is not in front of the camera (z <= 0).
template <typename T, typename P>
bool project(const ModelShape& shape, const P* intrinsics, const T* cam_from_world, const T* point_mm, T* uv) {
  T p[3];
  transform_point(cam_from_world, point_mm, p);
  if (!(p[2] > T(0.0))) return false;
  distort_to_pixel(shape, intrinsics, p[0] / p[2], p[1] / p[2], &uv[0], &uv[1]);
  return true;
}

struct UndistortOptions {
  int max_iterations = 50;          // Newton steps
  double tolerance_px = 1e-10;      // stop when the pixel residual is below this
};

// Inverse of distort_to_pixel: the normalised (x, y) whose distorted pixel is uv, by Newton's
// method from the undistorted guess K^-1 uv. nullopt if it does not converge (the distortion
// folds over there, or the pixel lies far outside the calibrated field).
std::optional<Eigen::Vector2d> undistort(const CameraModel& camera, const Eigen::Vector2d& uv_px,
                                         const UndistortOptions& options = {});

// The pixel of the ideal pinhole camera with the same K (no distortion) that sees what uv_px
// sees: K (undistort(uv), 1), as OpenCV's undistortPoints with P = K; nullopt where undistort is.
std::optional<Eigen::Vector2d> undistort_to_ideal_pixel(const CameraModel& camera, const Eigen::Vector2d& uv_px,
                                                        const UndistortOptions& options = {});

// Pixel of a world point for a pose given as [angle-axis, t]; nullopt behind the camera.
std::optional<Eigen::Vector2d> project_point(const CameraModel& camera, const double* cam_from_world,
                                             const Eigen::Vector3d& point_mm);

}  // namespace photomill::geometry
