// Ceres residuals of triangulate's adjustments, each with its formula and parameter layout.
// Ceres' cost functions are handed over by raw pointer: the Problem takes ownership.
// Every residual is whitened (divided by its standard deviation), so reprojection errors,
// control-point priors and scale bars add up to one chi-square-like cost (Triggs et al.,
// "Bundle adjustment - a modern synthesis", 2000, sec. 3-4; Ceres examples/bundle_adjuster.cc).
#pragma once

#include <array>

#include <ceres/ceres.h>

#include "triangulate/analytic_residuals.hpp"
#include "triangulate/scene.hpp"

namespace photomill::triangulate {

// Reprojection error with the intrinsics held fixed (stored in the functor).
//   r = (pi(K, d; R(aa) X + t) - u) / sigma_px                               (2 values)
// Parameters: pose[0..2] = angle-axis (rad), pose[3..5] = t (mm), cam_from_world;
//             point[0..2] = X (mm, world).
// pi is geometry/camera_model.hpp's project() (the paper's x_cam = R X + T, section 3.2, then OpenCV's
// distortion). A point behind the camera makes the evaluation fail (Ceres rejects the step).
struct ReprojectionError {
  ReprojectionError(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera(camera), shape(shape_of(*camera)), u(uv_px.x()), v(uv_px.y()), inv_sigma(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, T* r) const {
    T uv[2];
    if (!project(shape, camera->params.data(), pose, point, uv)) return false;
    r[0] = (uv[0] - u) * inv_sigma;
    r[1] = (uv[1] - v) * inv_sigma;
    return true;
  }

  // The analytic form (analytic_residuals.hpp) where it covers the camera's model.
  static ceres::CostFunction* create(const CameraModel* camera, const Eigen::Vector2d& uv_px, double sigma_px) {
    if (analytic_projection_applies(shape_of(*camera))) {
      return new AnalyticReprojectionError(camera, uv_px.x(), uv_px.y(), sigma_px);
    }
    return create_automatic(camera, uv_px, sigma_px);
  }
  static ceres::CostFunction* create_automatic(const CameraModel* camera, const Eigen::Vector2d& uv_px,
                                               double sigma_px) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 6, 3>(
        new ReprojectionError(camera, uv_px, sigma_px));
  }

  const CameraModel* camera;
  ModelShape shape;
  double u, v, inv_sigma;
};

// Reprojection error with the intrinsics as a parameter block (self-calibration).
//   r = (pi(k; R(aa) X + t) - u) / sigma_px                                  (2 values)
// Parameters: pose[0..5] and point[0..2] as above; k[0..N-1] = the first N intrinsics in
// geometry/camera_model.hpp's IntrinsicIndex layout (fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6 s1 s2
// s3 s4 tau_x tau_y), the skew fixed. N is the number the camera's model reads (9 for OpenCV's
// 5 coefficients, 12 rational, 16 with the thin prism, 18 tilted: intrinsics_block_size), so the
// block holds nothing the projection ignores: automatic differentiation carries 9 + N derivatives
// per value, and with all 18 in every block the demo's adjustments spent a third of their time
// on derivatives of coefficients its model does not have.
template <int N>
struct ReprojectionErrorWithIntrinsics {
  ReprojectionErrorWithIntrinsics(const ModelShape& shape, const Eigen::Vector2d& uv_px, double sigma_px)
      : shape(shape), u(uv_px.x()), v(uv_px.y()), inv_sigma(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* pose, const T* point, const T* intrinsics, T* r) const {
    T uv[2];
    if (!project(shape, intrinsics, pose, point, uv)) return false;
    r[0] = (uv[0] - u) * inv_sigma;
    r[1] = (uv[1] - v) * inv_sigma;
    return true;
  }

  ModelShape shape;
  double u, v, inv_sigma;
};

// The intrinsics a camera model's projection reads: the first this many of IntrinsicIndex.
constexpr int intrinsics_read(const ModelShape& shape) {
  return shape.tilted ? kIntrinsicCount : shape.thin_prism ? kTauX : shape.rational ? kS1 : kK4;
}

// make.template operator()<N>() for the intrinsics block size N (9, 12, 16, else 18): the cost
// functions' sizes are template arguments.
template <class Make>
ceres::CostFunction* by_block_size(int block_size, Make make) {
  switch (block_size) {
    case kK4: return make.template operator()<kK4>();
    case kS1: return make.template operator()<kS1>();
    case kTauX: return make.template operator()<kTauX>();
    default: return make.template operator()<kIntrinsicCount>();
  }
}

// ReprojectionErrorWithIntrinsics<block_size>, block_size one of 9, 12, 16, 18 and at least
// intrinsics_read(shape); the analytic form (analytic_residuals.hpp) where it covers the model
// and the block, unless `automatic`.
inline ceres::CostFunction* reprojection_error_with_intrinsics(int block_size, const ModelShape& shape,
                                                               const Eigen::Vector2d& uv_px, double sigma_px,
                                                               bool automatic = false) {
  if (!automatic && block_size == kK4 && analytic_projection_applies(shape)) {
    return new AnalyticReprojectionErrorWithIntrinsics(shape.skew, uv_px.x(), uv_px.y(), sigma_px);
  }
  return by_block_size(block_size, [&]<int N>() -> ceres::CostFunction* {
    return new ceres::AutoDiffCostFunction<ReprojectionErrorWithIntrinsics<N>, 2, 6, 3, N>(
        new ReprojectionErrorWithIntrinsics<N>(shape, uv_px, sigma_px));
  });
}

// aa(R R0^T): the angle-axis vector of the rotation from R0 (the unit quaternion q0) to the
// rotation of pose[0..2], for the pose priors below.
template <typename T>
void rotation_from(const T* pose, const std::array<double, 4>& q0, T* aa) {
  T q[4], q0_inverse[4], dq[4];
  ceres::AngleAxisToQuaternion(pose, q);
  q0_inverse[0] = T(q0[0]);
  for (int i = 1; i < 4; ++i) q0_inverse[i] = T(-q0[static_cast<std::size_t>(i)]);
  ceres::QuaternionProduct(q, q0_inverse, dq);
  ceres::QuaternionToAngleAxis(dq, aa);
}

// Reprojection error of a photo taken with a rig (scene.hpp, SceneRig): the camera's pose is the
// rig's pose in the frame composed with the camera's pose in the rig,
//   x_rig = R(a) X + s,  x_cam = R(b) x_rig + t,
//   r = (pi(k; x_cam) - u) / sigma_px                                        (2 values)
// Parameters: rig_from_world[0..5] = (a, s), cam_from_rig[0..5] = (b, t) (angle-axis rad, mm),
// point[0..2] = X (mm, world), and with `N` > 0 the first N intrinsics (as in
// ReprojectionErrorWithIntrinsics); with N = 0 the camera's intrinsics are constants. The pose
// blocks follow COLMAP's rig model (cam_from_rig x rig_from_world); derivatives are automatic.
template <int N>
struct RigReprojectionError {
  RigReprojectionError(const CameraModel* camera, const ModelShape& shape, const Eigen::Vector2d& uv_px, double sigma_px)
      : camera(camera), shape(shape), u(uv_px.x()), v(uv_px.y()), inv_sigma(1.0 / sigma_px) {}

  template <typename T>
  bool evaluate(const T* rig_from_world, const T* cam_from_rig, const T* point, const T* intrinsics, T* r) const {
    T x_rig[3];
    geometry::transform_point(rig_from_world, point, x_rig);
    T uv[2];
    const bool in_front = intrinsics ? project(shape, intrinsics, cam_from_rig, x_rig, uv)
                                     : project(shape, camera->params.data(), cam_from_rig, x_rig, uv);
    if (!in_front) return false;
    r[0] = (uv[0] - u) * inv_sigma;
    r[1] = (uv[1] - v) * inv_sigma;
    return true;
  }
  template <typename T>
  bool operator()(const T* rig_from_world, const T* cam_from_rig, const T* point, T* r) const {
    return evaluate<T>(rig_from_world, cam_from_rig, point, nullptr, r);
  }
  template <typename T>
  bool operator()(const T* rig_from_world, const T* cam_from_rig, const T* point, const T* intrinsics, T* r) const {
    return evaluate<T>(rig_from_world, cam_from_rig, point, intrinsics, r);
  }

  const CameraModel* camera;  // N = 0: the intrinsics
  ModelShape shape;
  double u, v, inv_sigma;
};

// RigReprojectionError with the camera's intrinsics constant (block_size 0) or its first
// block_size intrinsics a parameter block (reprojection_error_with_intrinsics' sizes).
inline ceres::CostFunction* rig_reprojection_error(const CameraModel& camera, int block_size, const Eigen::Vector2d& uv_px,
                                                   double sigma_px) {
  const ModelShape shape = shape_of(camera);
  if (block_size == 0) {
    return new ceres::AutoDiffCostFunction<RigReprojectionError<0>, 2, 6, 6, 3>(
        new RigReprojectionError<0>(&camera, shape, uv_px, sigma_px));
  }
  return by_block_size(block_size, [&]<int N>() -> ceres::CostFunction* {
    return new ceres::AutoDiffCostFunction<RigReprojectionError<N>, 2, 6, 6, 3, N>(
        new RigReprojectionError<N>(&camera, shape, uv_px, sigma_px));
  });
}

// Prior on a camera's pose in the rig, as the rig's calibration measured it (rig.yaml's
// cam_from_rig and its sigma: rotation about the camera's x, y, z axes, then translation):
//   r[0..2] = aa(R R0^T) / sigma_rad[0..2],   r[3..5] = (t - t0) / sigma_mm[0..2]      (6 values)
// R R0^T is the rotation between the two seen from the camera (left of cam_from_rig), so its
// components are about the camera's axes, as the calibration's covariance gives them.
// Parameters: cam_from_rig[0..5].
struct RigPosePrior {
  RigPosePrior(const PoseBlock& given, const Eigen::Matrix<double, 6, 1>& sigma_deg_mm) {
    ceres::AngleAxisToQuaternion(given.data(), q0.data());
    for (int i = 0; i < 3; ++i) {
      t0[static_cast<std::size_t>(i)] = given[static_cast<std::size_t>(3 + i)];
      inv_sigma[static_cast<std::size_t>(i)] = 180.0 / (3.14159265358979323846 * sigma_deg_mm[i]);
      inv_sigma[static_cast<std::size_t>(3 + i)] = 1.0 / sigma_deg_mm[3 + i];
    }
  }

  template <typename T>
  bool operator()(const T* pose, T* r) const {
    T aa[3];
    rotation_from(pose, q0, aa);
    for (int i = 0; i < 3; ++i) {
      r[i] = aa[i] * inv_sigma[static_cast<std::size_t>(i)];
      r[3 + i] = (pose[3 + i] - t0[static_cast<std::size_t>(i)]) * inv_sigma[static_cast<std::size_t>(3 + i)];
    }
    return true;
  }

  static ceres::CostFunction* create(const PoseBlock& given, const Eigen::Matrix<double, 6, 1>& sigma_deg_mm) {
    return new ceres::AutoDiffCostFunction<RigPosePrior, 6, 6>(new RigPosePrior(given, sigma_deg_mm));
  }

  std::array<double, 4> q0{};
  std::array<double, 3> t0{};
  std::array<double, 6> inv_sigma{};
};

// Prior on a control point with known coordinates X0 and standard deviation sigma per axis:
//   r = (X - X0) / sigma_mm                                                   (3 values)
// Parameters: point[0..2] = X (mm, world).
struct ControlPointPrior {
  ControlPointPrior(const Eigen::Vector3d& known_mm, double sigma_mm) : known(known_mm), inv_sigma(1.0 / sigma_mm) {}

  template <typename T>
  bool operator()(const T* point, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = (point[i] - known[i]) * inv_sigma;
    return true;
  }

  static ceres::CostFunction* create(const Eigen::Vector3d& known_mm, double sigma_mm) {
    return new ceres::AutoDiffCostFunction<ControlPointPrior, 3, 3>(new ControlPointPrior(known_mm, sigma_mm));
  }

  Eigen::Vector3d known;
  double inv_sigma;
};

// Prior on a camera pose known to sigma_rad in rotation and sigma_mm in position (a turntable,
// a robot, another tool's orientation), with known pose (R0, C0) and C = -R^T t:
//   r[0..2] = aa(R R0^T) / sigma_rad,   r[3..5] = (C - C0) / sigma_mm              (6 values)
// aa() the angle-axis vector of the rotation (its norm is the angle between R and R0, so the
// prior is isotropic in rotation); the position prior is on the centre, not on t, so that the
// two sigmas mean what a user measures (degrees of the camera's attitude, mm of its position).
// Parameters: pose[0..5] as in ReprojectionError.
struct PosePrior {
  PosePrior(const PoseBlock& known, double sigma_mm, double sigma_rad)
      : inv_sigma_mm(1.0 / sigma_mm), inv_sigma_rad(1.0 / sigma_rad) {
    ceres::AngleAxisToQuaternion(known.data(), q0.data());
    const Eigen::Vector3d c = centre_of(known);
    for (int i = 0; i < 3; ++i) c0[static_cast<std::size_t>(i)] = c[i];
  }

  template <typename T>
  bool operator()(const T* pose, T* r) const {
    T aa[3];
    rotation_from(pose, q0, aa);
    // C = -R^T t: rotate t by the inverse rotation (-aa).
    const T inverse[3] = {-pose[0], -pose[1], -pose[2]};
    T rt[3];
    ceres::AngleAxisRotatePoint(inverse, pose + 3, rt);
    for (int i = 0; i < 3; ++i) {
      r[i] = aa[i] * inv_sigma_rad;
      r[3 + i] = (-rt[i] - c0[static_cast<std::size_t>(i)]) * inv_sigma_mm;
    }
    return true;
  }

  static ceres::CostFunction* create(const PoseBlock& known, double sigma_mm, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<PosePrior, 6, 6>(new PosePrior(known, sigma_mm, sigma_rad));
  }

  std::array<double, 4> q0{};
  std::array<double, 3> c0{};
  double inv_sigma_mm, inv_sigma_rad;
};

// Scale bar: a known distance d (standard deviation sigma) between two points A and B:
//   r = (|A - B| - d) / sigma_mm                                              (1 value)
// Parameters: a[0..2] = A, b[0..2] = B (mm, world). This is the datum of a reconstruction
// without control points: the adjustment itself fixes the scale, rather than a rescale afterwards.
struct ScaleBarError {
  ScaleBarError(double distance_mm, double sigma_mm) : distance(distance_mm), inv_sigma(1.0 / sigma_mm) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    const T dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    const T squared = dx * dx + dy * dy + dz * dz;
    if (!(squared > T(0.0))) return false;  // coincident points: the distance is not differentiable
    r[0] = (ceres::sqrt(squared) - distance) * inv_sigma;
    return true;
  }

  static ceres::CostFunction* create(double distance_mm, double sigma_mm) {
    return new ceres::AutoDiffCostFunction<ScaleBarError, 1, 3, 3>(new ScaleBarError(distance_mm, sigma_mm));
  }

  double distance, inv_sigma;
};

}  // namespace photomill::triangulate
