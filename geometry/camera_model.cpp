// The camera model (see camera_model.hpp).
#include "geometry/camera_model.hpp"

#include <cmath>

#include <ceres/jet.h>
#include <Eigen/LU>

#include "formats/error.hpp"

namespace photomill::geometry {

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
  for (std::size_t i = 0; i < d.size() && i < kDistortionSlot.size(); ++i) {
    m.params[static_cast<std::size_t>(kDistortionSlot[i])] = d[i];
  }
  return m;
}

Camera to_camera(const CameraModel& m, const Camera& original) {
  Camera c = original;
  c.camera_matrix << m.params[kFx], m.skew, m.params[kCx], 0, m.params[kFy], m.params[kCy], 0, 0, 1;
  for (std::size_t i = 0; i < c.distortion.size() && i < kDistortionSlot.size(); ++i) {
    c.distortion[i] = m.params[static_cast<std::size_t>(kDistortionSlot[i])];
  }
  return c;
}

// Newton's method on f(x, y) = distort_to_pixel(x, y) - uv, with the 2x2 Jacobian J from dual
// numbers (ceres::Jet): (x, y) <- (x, y) - J^-1 f. A root where det J has not the sign it has at
// the principal point lies beyond a fold of the distortion (the polynomial maps a ray from the
// other side of the field onto uv there): no camera sees that pixel so, and it is refused.
std::optional<Eigen::Vector2d> undistort(const CameraModel& camera, const Eigen::Vector2d& uv_px,
                                         const UndistortOptions& options) {
  using J = ceres::Jet<double, 2>;
  const auto& k = camera.params;
  const ModelShape shape = shape_of(camera);
  auto evaluate = [&](double x, double y, Eigen::Vector2d& f, Eigen::Matrix2d& jac) {
    J u, v;
    distort_to_pixel(shape, k.data(), J(x, 0), J(y, 1), &u, &v);
    f = Eigen::Vector2d(u.a - uv_px.x(), v.a - uv_px.y());
    jac << u.v[0], u.v[1], v.v[0], v.v[1];
  };
  Eigen::Vector2d f;
  Eigen::Matrix2d jac;
  evaluate(0, 0, f, jac);
  const double centre_det = jac.determinant();
  // Start from the pinhole inverse: y = (v - cy) / fy, x = (u - cx - skew y) / fx.
  double y = (uv_px.y() - k[kCy]) / k[kFy];
  double x = (uv_px.x() - k[kCx] - camera.skew * y) / k[kFx];
  for (int it = 0; it < options.max_iterations; ++it) {
    evaluate(x, y, f, jac);
    if (!f.allFinite() || !jac.allFinite()) return std::nullopt;
    const double det = jac.determinant();
    if (f.norm() < options.tolerance_px) {
      if (!(det * centre_det > 0)) return std::nullopt;
      return Eigen::Vector2d(x, y);
    }
    if (!(std::abs(det) > 0)) return std::nullopt;
    const Eigen::Vector2d step = jac.inverse() * f;
    x -= step.x();
    y -= step.y();
  }
  return std::nullopt;
}

std::optional<Eigen::Vector2d> undistort_to_ideal_pixel(const CameraModel& camera, const Eigen::Vector2d& uv_px,
                                                        const UndistortOptions& options) {
  const auto xy = undistort(camera, uv_px, options);
  if (!xy) return std::nullopt;
  const auto& k = camera.params;
  return Eigen::Vector2d(k[kFx] * xy->x() + camera.skew * xy->y() + k[kCx], k[kFy] * xy->y() + k[kCy]);
}

std::optional<Eigen::Vector2d> project_point(const CameraModel& camera, const double* cam_from_world,
                                             const Eigen::Vector3d& point_mm) {
  Eigen::Vector2d uv;
  if (!project(shape_of(camera), camera.params.data(), cam_from_world, point_mm.data(), uv.data())) return std::nullopt;
  return uv;
}

}  // namespace photomill::geometry
