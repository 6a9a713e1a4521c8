// The camera model (see camera_model.hpp).
#include "triangulate/camera_model.hpp"

#include <cmath>

#include <ceres/jet.h>
#include <Eigen/LU>

#include "formats/error.hpp"

namespace photomill::triangulate {

CameraModel to_camera_model(const Camera& camera, const std::string& source) {
  validate_camera(camera, source);
  CameraModel m;
  m.params.fill(0);
  m.params[kFx] = camera.fx();
  m.params[kFy] = camera.fy();
  m.params[kCx] = camera.cx();
  m.params[kCy] = camera.cy();
  m.skew = camera.camera_matrix(0, 1);
  m.width_px = camera.image_width_px;
  m.height_px = camera.image_height_px;
  const auto& d = camera.distortion;
  m.distortion_count = static_cast<int>(d.size());
  // OpenCV order k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 tx ty -> our layout.
  static constexpr int kSlot[] = {kK1, kK2, kP1, kP2, kK3, kK4, kK5, kK6, kS1, kS2, kS3, kS4};
  for (std::size_t i = 0; i < d.size() && i < 12; ++i) m.params[static_cast<std::size_t>(kSlot[i])] = d[i];
  if (d.size() == 14 && (d[12] != 0 || d[13] != 0)) {
    throw InputError(source, 0,
                     "tilted-sensor distortion (tau_x, tau_y non-zero) is not supported by triangulate");
  }
  return m;
}

Camera to_camera(const CameraModel& m, const Camera& original) {
  Camera c = original;
  c.camera_matrix << m.params[kFx], m.skew, m.params[kCx], 0, m.params[kFy], m.params[kCy], 0, 0, 1;
  static constexpr int kSlot[] = {kK1, kK2, kP1, kP2, kK3, kK4, kK5, kK6, kS1, kS2, kS3, kS4};
  for (std::size_t i = 0; i < c.distortion.size() && i < 12; ++i) {
    c.distortion[i] = m.params[static_cast<std::size_t>(kSlot[i])];
  }
  return c;
}

// Newton's method on f(x, y) = distort_to_pixel(x, y) - uv, with the 2x2 Jacobian from dual
// numbers (ceres::Jet): (x, y) <- (x, y) - J^-1 f.
std::optional<Eigen::Vector2d> undistort(const CameraModel& camera, const Eigen::Vector2d& uv_px,
                                         const UndistortOptions& options) {
  using J = ceres::Jet<double, 2>;
  const auto& k = camera.params;
  const ModelShape shape = shape_of(camera);
  // Start from the pinhole inverse: y = (v - cy) / fy, x = (u - cx - skew y) / fx.
  double y = (uv_px.y() - k[kCy]) / k[kFy];
  double x = (uv_px.x() - k[kCx] - camera.skew * y) / k[kFx];
  for (int it = 0; it < options.max_iterations; ++it) {
    J u, v;
    distort_to_pixel(shape, k.data(), J(x, 0), J(y, 1), &u, &v);
    const Eigen::Vector2d f(u.a - uv_px.x(), v.a - uv_px.y());
    if (!f.allFinite()) return std::nullopt;
    if (f.norm() < options.tolerance_px) return Eigen::Vector2d(x, y);
    Eigen::Matrix2d jac;
    jac << u.v[0], u.v[1], v.v[0], v.v[1];
    const double det = jac.determinant();
    if (!(std::abs(det) > 0)) return std::nullopt;
    const Eigen::Vector2d step = jac.inverse() * f;
    x -= step.x();
    y -= step.y();
  }
  return std::nullopt;
}

std::optional<Eigen::Vector2d> project_point(const CameraModel& camera, const double* cam_from_world,
                                             const Eigen::Vector3d& point_mm) {
  Eigen::Vector2d uv;
  if (!project(shape_of(camera), camera.params.data(), cam_from_world, point_mm.data(), uv.data())) return std::nullopt;
  return uv;
}

}  // namespace photomill::triangulate
