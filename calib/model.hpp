// The camera model calib estimates (OpenCV's pinhole + radial/tangential/rational distortion), its
// parameter layout, and the reprojection residual shared by every optimiser (Ceres LM, the
// Nelder-Mead simplex, the covariance), so all of them minimise exactly the same cost.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"
#include "geometry/camera_model.hpp"
#include "geometry/rotation.hpp"

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

// K = [fx 0 cx; 0 fy cy; 0 0 1] from the intrinsics block (fx, fy, cx, cy).
Eigen::Matrix3d camera_matrix(const Parameters& p);

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

// calib's blocks in the layout of photomill's one camera model (geometry/camera_model.hpp, whose
// distort_to_pixel is OpenCV's projection): k = [fx, fy (= fx with fix_aspect_ratio), cx, cy,
// k1 k2 p1 p2 k3 k4 k5 k6, 0...]. The rational denominator is evaluated only for the rational
// model (k4..k6 are held at 0 otherwise, so skipping it is exact).
template <typename T>
void to_model_block(const T* intrinsics, const T* distortion, bool fix_aspect_ratio, T* k) {
  for (int i = 0; i < geometry::kIntrinsicCount; ++i) k[i] = T(0.0);
  k[geometry::kFx] = intrinsics[0];
  k[geometry::kFy] = fix_aspect_ratio ? intrinsics[0] : intrinsics[1];
  k[geometry::kCx] = intrinsics[2];
  k[geometry::kCy] = intrinsics[3];
  for (int i = 0; i < kDistortion; ++i) k[geometry::kDistortionSlot[static_cast<std::size_t>(i)]] = distortion[i];
}
inline geometry::ModelShape model_shape(const ModelOptions& model) { return {0, model.rational, false, false}; }

// The pixel of a point p in the camera's frame through calib's blocks (the projection of every
// calib residual: ReprojectionResidual below, the rig's in rig.cpp).
template <typename T>
void project_in_camera(const T* intrinsics, const T* distortion, const ModelOptions& model, const T* p, T* uv) {
  T k[geometry::kIntrinsicCount];
  to_model_block(intrinsics, distortion, model.fix_aspect_ratio, k);
  geometry::distort_to_pixel(model_shape(model), k, p[0] / p[2], p[1] / p[2], &uv[0], &uv[1]);
}

// Residual of one observation: r = project(K, d, R X + t) - (u, v), px. Parameter blocks:
// intrinsics[4], distortion[8], pose[6] (layout above). Used by Ceres (autodiff) and, with
// T = double, by the simplex and the reports.
struct ReprojectionResidual {
  Eigen::Vector3d world_mm;
  Eigen::Vector2d observed_px;
  ModelOptions model;

  template <typename T>
  bool operator()(const T* intrinsics, const T* distortion, const T* pose, T* residual) const {
    const T X[3] = {T(world_mm.x()), T(world_mm.y()), T(world_mm.z())};
    T p[3];
    geometry::transform_point(pose, X, p);
    T uv[2];
    project_in_camera(intrinsics, distortion, model, p, uv);
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
