// densify's tests: a small camera and views looking at the origin.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "densify/patch.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::densify::test {

// 480 x 360 px, f 800 px; with `distortion`, k1 -0.06, k2 0.02.
inline geometry::CameraModel small_camera(bool distortion) {
  geometry::CameraModel c;
  c.width_px = 480;
  c.height_px = 360;
  c.params[geometry::kFx] = 800;
  c.params[geometry::kFy] = 800;
  c.params[geometry::kCx] = 239.5;
  c.params[geometry::kCy] = 179.5;
  if (distortion) {
    c.params[geometry::kK1] = -0.06;
    c.params[geometry::kK2] = 0.02;
    c.distortion_count = 5;
  }
  return c;
}

// A view from centre C looking at the origin, its x axis horizontal (cam_from_world; no photo).
inline PatchView look_at_origin_from(const Eigen::Vector3d& C) {
  const Eigen::Vector3d z = (-C).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  PatchView v;
  v.rotation.row(0) = x;
  v.rotation.row(1) = y;
  v.rotation.row(2) = z;
  v.translation_mm = -v.rotation * C;
  return v;
}

}  // namespace photomill::densify::test
