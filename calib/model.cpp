// Camera model bookkeeping and the double-precision cost (see model.hpp).
#include "calib/model.hpp"

#include <cmath>

#include <Eigen/Geometry>

namespace photomill::calib {

std::array<bool, kIntrinsics> free_intrinsics(const ModelOptions& m) {
  return {true, !m.fix_aspect_ratio, !m.fix_principal_point, !m.fix_principal_point};
}

std::array<bool, kDistortion> free_distortion(const ModelOptions& m) {
  return {true, true, !m.zero_tangent, !m.zero_tangent, !m.fix_k3, m.rational, m.rational, m.rational};
}

Eigen::Matrix3d camera_matrix(const Parameters& p) {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = p.intrinsics[0];
  K(1, 1) = p.intrinsics[1];
  K(0, 2) = p.intrinsics[2];
  K(1, 2) = p.intrinsics[3];
  return K;
}

const std::array<std::string, kIntrinsics>& intrinsic_names() {
  static const std::array<std::string, kIntrinsics> names{"fx", "fy", "cx", "cy"};
  return names;
}

const std::array<std::string, kDistortion>& distortion_names() {
  static const std::array<std::string, kDistortion> names{"k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"};
  return names;
}

namespace {

// R(r) as a matrix, so a view's points are rotated without recomputing sin and cos per point.
Eigen::Matrix3d rotation(const std::array<double, kPose>& pose) {
  return geometry::rotation_of({pose[0], pose[1], pose[2], pose[3], pose[4], pose[5]});
}

// Pixel of the camera point pc (the residual's arithmetic, with R built once per view).
Eigen::Vector2d pixel(const Parameters& p, const ModelOptions& model, const Eigen::Vector3d& pc) {
  double k[geometry::kIntrinsicCount];
  to_model_block(p.intrinsics.data(), p.distortion.data(), model.fix_aspect_ratio, k);
  Eigen::Vector2d uv;
  geometry::distort_to_pixel(model_shape(model), k, pc.x() / pc.z(), pc.y() / pc.z(), &uv.x(), &uv.y());
  return uv;
}

}  // namespace

std::vector<Eigen::Vector2d> view_residuals(const View& view, const Parameters& p, std::size_t v,
                                            const ModelOptions& model) {
  const Eigen::Matrix3d R = rotation(p.poses[v]);
  const Eigen::Vector3d t(p.poses[v][3], p.poses[v][4], p.poses[v][5]);
  std::vector<Eigen::Vector2d> out(view.world_mm.size());
  for (std::size_t i = 0; i < view.world_mm.size(); ++i) {
    const Eigen::Vector3d pc = R * view.world_mm[i] + t;
    out[i] = pixel(p, model, pc) - view.observed_px[i];
  }
  return out;
}

double sum_squared_error(const std::vector<View>& views, const Parameters& p, const ModelOptions& model) {
  // The simplex evaluates this millions of times: the block is built once, R once per view.
  double k[geometry::kIntrinsicCount];
  to_model_block(p.intrinsics.data(), p.distortion.data(), model.fix_aspect_ratio, k);
  const geometry::ModelShape shape = model_shape(model);
  double sse = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const Eigen::Matrix3d R = rotation(p.poses[v]);
    const Eigen::Vector3d t(p.poses[v][3], p.poses[v][4], p.poses[v][5]);
    const auto& world = views[v].world_mm;
    const auto& observed = views[v].observed_px;
    for (std::size_t i = 0; i < world.size(); ++i) {
      const Eigen::Vector3d pc = R * world[i] + t;
      double u = 0, w = 0;
      geometry::distort_to_pixel(shape, k, pc.x() / pc.z(), pc.y() / pc.z(), &u, &w);
      const double du = u - observed[i].x();
      const double dv = w - observed[i].y();
      sse += du * du + dv * dv;
    }
  }
  return sse;
}

std::size_t point_count(const std::vector<View>& views) {
  std::size_t n = 0;
  for (const auto& v : views) n += v.world_mm.size();
  return n;
}

}  // namespace photomill::calib
