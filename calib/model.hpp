// The camera model calib estimates (OpenCV's pinhole + radial/tangential/rational distortion), its
// parameter layout, and the reprojection residual shared by every optimiser (Ceres LM, the
// Nelder-Mead simplex, the covariance), so all of them minimise exactly the same cost.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"

namespace photomill::calib {

// Which parameters are estimated; the rest are held at fixed values. The names are OpenCV's
// calibrateCamera flags.
struct ModelOptions {
  bool fix_aspect_ratio = false;     // CALIB_FIX_ASPECT_RATIO: fx = fy (square pixels)
  bool fix_principal_point = false;  // CALIB_FIX_PRINCIPAL_POINT: cx, cy at the image centre
  bool zero_tangent = false;         // CALIB_ZERO_TANGENT_DIST: p1 = p2 = 0
  bool fix_k3 = false;               // CALIB_FIX_K3: k3 = 0
  bool rational = false;             // CALIB_RATIONAL_MODEL: k4, k5, k6 estimated (else 0)
};

// Parameter blocks (the layout every optimiser uses):
//   intrinsics[4] = fx, fy, cx, cy (px; with fix_aspect_ratio fy is ignored and fx used for both)
//   distortion[8] = k1, k2, p1, p2, k3, k4, k5, k6 (OpenCV order)
//   pose[6]       = angle-axis r (rad, |r| = angle), t (mm): x_cam = R(r) * X + t (cam_from_world)
constexpr int kIntrinsics = 4;
constexpr int kDistortion = 8;
constexpr int kPose = 6;

struct Parameters {
  std::array<double, kIntrinsics> intrinsics{};
  std::array<double, kDistortion> distortion{};
  std::vector<std::array<double, kPose>> poses;  // one per view
};

// Which elements of each block are free under `model` (the rest are constant).
std::array<bool, kIntrinsics> free_intrinsics(const ModelOptions& model);
std::array<bool, kDistortion> free_distortion(const ModelOptions& model);
// Names for reports: "fx", "fy", "cx", "cy", "k1", ... "k6".
const std::array<std::string, kIntrinsics>& intrinsic_names();
const std::array<std::string, kDistortion>& distortion_names();

// The points of one view: control points (world frame, mm) and where they were observed (px).
struct View {
  std::string image;
  std::vector<PointId> ids;
  std::vector<Eigen::Vector3d> world_mm;
  std::vector<Eigen::Vector2d> observed_px;
};

// OpenCV's projection (calib3d docs, "Detailed description"): with (x', y') = (X_c/Z_c, Y_c/Z_c),
// r^2 = x'^2 + y'^2,
//   x'' = x' (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6) + 2 p1 x'y' + p2 (r^2 + 2x'^2)
//   y'' = y' (same radial factor) + p1 (r^2 + 2y'^2) + 2 p2 x'y'
//   u = fx x'' + cx,  v = fy y'' + cy    (OpenCV pixel convention).
template <typename T>
void project_camera_point(const T* intrinsics, const T* d, bool fix_aspect_ratio, const T* p_cam, T* uv) {
  const T x = p_cam[0] / p_cam[2];
  const T y = p_cam[1] / p_cam[2];
  const T r2 = x * x + y * y;
  const T r4 = r2 * r2;
  const T r6 = r4 * r2;
  const T radial = (T(1) + d[0] * r2 + d[1] * r4 + d[4] * r6) / (T(1) + d[5] * r2 + d[6] * r4 + d[7] * r6);
  const T xd = x * radial + T(2) * d[2] * x * y + d[3] * (r2 + T(2) * x * x);
  const T yd = y * radial + d[2] * (r2 + T(2) * y * y) + T(2) * d[3] * x * y;
  const T fy = fix_aspect_ratio ? intrinsics[0] : intrinsics[1];
  uv[0] = intrinsics[0] * xd + intrinsics[2];
  uv[1] = fy * yd + intrinsics[3];
}

// Rotates by the angle-axis vector r (Rodrigues' formula), the convention of ceres/rotation.h and
// cv::Rodrigues; a first-order form near zero keeps derivatives finite.
template <typename T>
void angle_axis_rotate(const T* r, const T* p, T* out) {
  const T theta2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
  const T cross[3] = {r[1] * p[2] - r[2] * p[1], r[2] * p[0] - r[0] * p[2], r[0] * p[1] - r[1] * p[0]};
  if (theta2 > T(1e-30)) {
    using std::cos;
    using std::sin;
    using std::sqrt;
    const T theta = sqrt(theta2);
    const T c = cos(theta);
    const T s = sin(theta);
    const T w[3] = {r[0] / theta, r[1] / theta, r[2] / theta};
    const T wp[3] = {cross[0] / theta, cross[1] / theta, cross[2] / theta};
    const T dot = (w[0] * p[0] + w[1] * p[1] + w[2] * p[2]) * (T(1) - c);
    for (int i = 0; i < 3; ++i) out[i] = p[i] * c + wp[i] * s + w[i] * dot;
  } else {
    for (int i = 0; i < 3; ++i) out[i] = p[i] + cross[i];
  }
}

// Residual of one observation: r = project(K, d, R X + t) - (u, v), px. Parameter blocks:
// intrinsics[4], distortion[8], pose[6] (layout above). Used by Ceres (autodiff) and, with
// T = double, by the simplex and the reports.
struct ReprojectionResidual {
  Eigen::Vector3d world_mm;
  Eigen::Vector2d observed_px;
  bool fix_aspect_ratio = false;

  template <typename T>
  bool operator()(const T* intrinsics, const T* distortion, const T* pose, T* residual) const {
    const T X[3] = {T(world_mm.x()), T(world_mm.y()), T(world_mm.z())};
    T p[3];
    angle_axis_rotate(pose, X, p);
    p[0] += pose[3];
    p[1] += pose[4];
    p[2] += pose[5];
    T uv[2];
    project_camera_point(intrinsics, distortion, fix_aspect_ratio, p, uv);
    residual[0] = uv[0] - T(observed_px.x());
    residual[1] = uv[1] - T(observed_px.y());
    return true;
  }
};

// Residual vectors (model minus observation, px) of every point of view `v`.
std::vector<Eigen::Vector2d> view_residuals(const View& view, const Parameters& p, std::size_t v,
                                            const ModelOptions& model);
// Sum of squared residuals over all views (the cost every optimiser minimises, px^2).
double sum_squared_error(const std::vector<View>& views, const Parameters& p, const ModelOptions& model);
std::size_t point_count(const std::vector<View>& views);

}  // namespace photomill::calib
