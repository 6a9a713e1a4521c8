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
  const Eigen::Vector3d r(pose[0], pose[1], pose[2]);
  const double theta = r.norm();
  if (theta < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(theta, r / theta).toRotationMatrix();
}

}  // namespace

std::vector<Eigen::Vector2d> view_residuals(const View& view, const Parameters& p, std::size_t v,
                                            const ModelOptions& model) {
  const Eigen::Matrix3d R = rotation(p.poses[v]);
  const Eigen::Vector3d t(p.poses[v][3], p.poses[v][4], p.poses[v][5]);
  std::vector<Eigen::Vector2d> out(view.world_mm.size());
  for (std::size_t i = 0; i < view.world_mm.size(); ++i) {
    const Eigen::Vector3d pc = R * view.world_mm[i] + t;
    double uv[2];
    project_camera_point(p.intrinsics.data(), p.distortion.data(), model.fix_aspect_ratio, pc.data(), uv);
    out[i] = Eigen::Vector2d(uv[0], uv[1]) - view.observed_px[i];
  }
  return out;
}

double sum_squared_error(const std::vector<View>& views, const Parameters& p, const ModelOptions& model) {
  // The simplex evaluates this millions of times: the same arithmetic as project_camera_point,
  // written out in scalars, with R built once per view. With k4 = k5 = k6 = 0 the rational
  // denominator is exactly 1, so skipping it changes no bit of the result.
  const double fx = p.intrinsics[0];
  const double fy = model.fix_aspect_ratio ? p.intrinsics[0] : p.intrinsics[1];
  const double cx = p.intrinsics[2];
  const double cy = p.intrinsics[3];
  const auto& d = p.distortion;
  const bool rational = d[5] != 0 || d[6] != 0 || d[7] != 0;
  double sse = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const Eigen::Matrix3d R = rotation(p.poses[v]);
    const double* t = p.poses[v].data() + 3;
    const auto& world = views[v].world_mm;
    const auto& observed = views[v].observed_px;
    for (std::size_t i = 0; i < world.size(); ++i) {
      const Eigen::Vector3d& X = world[i];
      const double zc = R(2, 0) * X.x() + R(2, 1) * X.y() + R(2, 2) * X.z() + t[2];
      const double x = (R(0, 0) * X.x() + R(0, 1) * X.y() + R(0, 2) * X.z() + t[0]) / zc;
      const double y = (R(1, 0) * X.x() + R(1, 1) * X.y() + R(1, 2) * X.z() + t[1]) / zc;
      const double r2 = x * x + y * y;
      const double r4 = r2 * r2;
      const double r6 = r4 * r2;
      double radial = 1 + d[0] * r2 + d[1] * r4 + d[4] * r6;
      if (rational) radial /= 1 + d[5] * r2 + d[6] * r4 + d[7] * r6;
      const double xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
      const double yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
      const double du = fx * xd + cx - observed[i].x();
      const double dv = fy * yd + cy - observed[i].y();
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
