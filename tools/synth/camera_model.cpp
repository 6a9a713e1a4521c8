// Pinhole + OpenCV distortion, forwards and inverted (see camera_model.hpp).
#include "tools/synth/camera_model.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

namespace photomill::synth {
namespace {

struct Distortion {
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};

Distortion coefficients(const Camera& c) {
  Distortion d;
  const auto& v = c.distortion;
  if (v.size() >= 4) {
    d.k1 = v[0];
    d.k2 = v[1];
    d.p1 = v[2];
    d.p2 = v[3];
  }
  if (v.size() >= 5) d.k3 = v[4];
  return d;
}

// OpenCV's model, as in cv::projectPoints:
//   r^2 = x^2 + y^2, radial = 1 + k1 r^2 + k2 r^4 + k3 r^6,
//   x' = x radial + 2 p1 x y + p2 (r^2 + 2 x^2),
//   y' = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y.
// Returns (x', y') and, if J is given, the Jacobian d(x', y') / d(x, y).
Eigen::Vector2d distort(const Distortion& d, const Eigen::Vector2d& p, Eigen::Matrix2d* J) {
  const double x = p.x(), y = p.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  const Eigen::Vector2d out(x * radial + 2 * d.p1 * x * y + d.p2 * (r2 + 2 * x * x),
                            y * radial + d.p1 * (r2 + 2 * y * y) + 2 * d.p2 * x * y);
  if (J) {
    // d radial / d(r^2)
    const double dr = d.k1 + r2 * (2 * d.k2 + 3 * r2 * d.k3);
    (*J)(0, 0) = radial + x * dr * 2 * x + 2 * d.p1 * y + d.p2 * 6 * x;
    (*J)(0, 1) = x * dr * 2 * y + 2 * d.p1 * x + d.p2 * 2 * y;
    (*J)(1, 0) = y * dr * 2 * x + d.p1 * 2 * x + 2 * d.p2 * y;
    (*J)(1, 1) = radial + y * dr * 2 * y + d.p1 * 6 * y + 2 * d.p2 * x;
  }
  return out;
}

}  // namespace

Eigen::Vector2d distort_to_pixel(const Camera& camera, const Eigen::Vector2d& normalised) {
  const Eigen::Vector2d p = distort(coefficients(camera), normalised, nullptr);
  const Eigen::Matrix3d& K = camera.camera_matrix;
  return {K(0, 0) * p.x() + K(0, 1) * p.y() + K(0, 2), K(1, 1) * p.y() + K(1, 2)};
}

std::optional<Eigen::Vector2d> pixel_to_normalised(const Camera& camera,
                                                   const Eigen::Vector2d& uv) {
  const Eigen::Matrix3d& K = camera.camera_matrix;
  const double yd = (uv.y() - K(1, 2)) / K(1, 1);
  const double xd = (uv.x() - K(0, 2) - K(0, 1) * yd) / K(0, 0);
  const Eigen::Vector2d target(xd, yd);
  const Distortion d = coefficients(camera);
  Eigen::Vector2d p = target;
  // Converged when the pixel residual is below 1e-12 px (1e-12 / f in normalised units).
  const double tol = 1e-12 / std::max(K(0, 0), K(1, 1));
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix2d J;
    const Eigen::Vector2d r = distort(d, p, &J) - target;
    if (r.lpNorm<Eigen::Infinity>() < tol) return p;
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-12)) return std::nullopt;
    p -= J.inverse() * r;
    if (!p.allFinite()) return std::nullopt;
  }
  const Eigen::Vector2d r = distort(d, p, nullptr) - target;
  if (r.lpNorm<Eigen::Infinity>() < 1e3 * tol) return p;
  return std::nullopt;
}

std::optional<Eigen::Vector2d> project(const Camera& camera, const Pose& pose,
                                       const Eigen::Vector3d& world_mm) {
  const Eigen::Vector3d c = pose.rotation() * world_mm + pose.cam_from_world_translation_mm;
  if (!(c.z() > 0)) return std::nullopt;
  return distort_to_pixel(camera, {c.x() / c.z(), c.y() / c.z()});
}

Pose look_at(const std::string& image, const Eigen::Vector3d& centre_mm,
             const Eigen::Vector3d& target_mm, const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target_mm - centre_mm).normalized();
  Eigen::Vector3d x = z.cross(up);
  if (!(x.norm() > 1e-9)) throw std::invalid_argument("look_at: viewing direction parallel to up");
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  Pose pose;
  pose.image = image;
  pose.cam_from_world_rotation = Eigen::Quaterniond(R).normalized();
  // Canonical sign (qw >= 0) so files are reproducible and readable.
  if (pose.cam_from_world_rotation.w() < 0) {
    pose.cam_from_world_rotation.coeffs() *= -1;
  }
  pose.cam_from_world_translation_mm = -(pose.rotation() * centre_mm);
  return pose;
}

void validate_synth_camera(const Camera& camera) {
  if (camera.image_width_px <= 0 || camera.image_height_px <= 0) {
    throw std::invalid_argument("image size must be positive");
  }
  const Eigen::Matrix3d& K = camera.camera_matrix;
  if (!K.allFinite() || !(K(0, 0) > 0) || !(K(1, 1) > 0)) {
    throw std::invalid_argument("focal lengths must be positive and finite");
  }
  if (K(0, 1) != 0 || K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1) {
    throw std::invalid_argument("camera matrix must be [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  const auto n = camera.distortion.size();
  if (n != 0 && n != 4 && n != 5) {
    throw std::invalid_argument("synth supports 0, 4 or 5 distortion coefficients (k1 k2 p1 p2 k3)");
  }
  for (double v : camera.distortion) {
    if (!std::isfinite(v)) throw std::invalid_argument("distortion coefficients must be finite");
  }
  // Invertible at the image border (where distortion is strongest) and on an interior grid, and
  // one-to-one: the Jacobian keeps a positive determinant.
  const Distortion d = coefficients(camera);
  const double w = camera.image_width_px, h = camera.image_height_px;
  const int steps = 32;
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      const Eigen::Vector2d uv(-0.5 + w * i / steps, -0.5 + h * j / steps);
      const auto p = pixel_to_normalised(camera, uv);
      Eigen::Matrix2d J;
      if (p) distort(d, *p, &J);
      if (!p || !(J.determinant() > 0)) {
        throw std::invalid_argument("the distortion cannot be inverted over the image (at pixel " +
                                    std::to_string(uv.x()) + ", " + std::to_string(uv.y()) +
                                    "); use smaller coefficients");
      }
    }
  }
}

}  // namespace photomill::synth
