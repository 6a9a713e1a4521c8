// Rigid transforms as the stages store them: a pose block [angle-axis r (3, rad, |r| = angle),
// t (3, mm)] with x_cam = R(r) X + t (cam_from_world; the paper's x_cam = R X + T, section 3.2).
// The angle-axis convention is Rodrigues' (cv::Rodrigues, ceres/rotation.h), evaluated through
// Ceres so the templated forms differentiate exactly (Jets) and stay finite near r = 0.
#pragma once

#include <array>

#include <Eigen/Core>
#include <ceres/rotation.h>

namespace photomill::geometry {

using PoseBlock = std::array<double, 6>;

// out = R(pose[0..2]) X + pose[3..5]; double or Jet.
template <typename T>
void transform_point(const T* pose, const T* X, T* out) {
  ceres::AngleAxisRotatePoint(pose, X, out);
  out[0] += pose[3];
  out[1] += pose[4];
  out[2] += pose[5];
}

inline Eigen::Matrix3d rotation_of(const PoseBlock& pose) {
  Eigen::Matrix3d R;
  ceres::AngleAxisToRotationMatrix(pose.data(), ceres::ColumnMajorAdapter3x3(R.data()));
  return R;
}

inline Eigen::Vector3d translation_of(const PoseBlock& pose) { return {pose[3], pose[4], pose[5]}; }

// The camera centre in the world: C = -R^T t.
inline Eigen::Vector3d centre_of(const PoseBlock& pose) { return -rotation_of(pose).transpose() * translation_of(pose); }

inline PoseBlock make_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  PoseBlock p{};
  ceres::RotationMatrixToAngleAxis(ceres::ColumnMajorAdapter3x3(R.data()), p.data());
  p[3] = t.x();
  p[4] = t.y();
  p[5] = t.z();
  return p;
}

// a_from_c = a_from_b * b_from_c: R = R_ab R_bc, t = R_ab t_bc + t_ab.
inline PoseBlock compose(const PoseBlock& a_from_b, const PoseBlock& b_from_c) {
  const Eigen::Matrix3d R = rotation_of(a_from_b);
  return make_pose(R * rotation_of(b_from_c), R * translation_of(b_from_c) + translation_of(a_from_b));
}

// b_from_a of a_from_b: R^T, -R^T t.
inline PoseBlock inverse(const PoseBlock& a_from_b) {
  const Eigen::Matrix3d Rt = rotation_of(a_from_b).transpose();
  return make_pose(Rt, -Rt * translation_of(a_from_b));
}

}  // namespace photomill::geometry
