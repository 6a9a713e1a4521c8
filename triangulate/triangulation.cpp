// Multi-view triangulation (see triangulation.hpp).
#include "triangulate/triangulation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <ceres/jet.h>
#include <Eigen/Cholesky>

#include "geometry/linear_algebra.hpp"
#include "geometry/parallel.hpp"

namespace photomill::triangulate {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

bool in_front_of_all(const std::vector<PointView>& views, const Eigen::Vector3d& X) {
  for (const PointView& v : views) {
    if (!((v.R * X + v.t).z() > 0)) return false;
  }
  return true;
}

// Reprojection error (pixels) of X in each view; infinity behind a camera.
std::vector<double> reprojection_errors(const CameraModel& camera, const std::vector<PointView>& views,
                                        const Eigen::Vector3d& X) {
  std::vector<double> e;
  e.reserve(views.size());
  for (const PointView& v : views) {
    const auto uv = project_point(v.camera ? *v.camera : camera, v.cam_from_world->data(), X);
    e.push_back(uv ? (*uv - v.uv_px).norm() : std::numeric_limits<double>::infinity());
  }
  return e;
}

}  // namespace

std::optional<Eigen::Vector3d> triangulate_linear(const std::vector<PointView>& views) {
  if (views.size() < 2) return std::nullopt;
  // Normalising similarity: X = c + s X~.
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const PointView& v : views) c += v.centre_mm;
  c /= static_cast<double>(views.size());
  double ms = 0;
  for (const PointView& v : views) ms += (v.centre_mm - c).squaredNorm();
  const double s = std::sqrt(ms / static_cast<double>(views.size()));
  if (!(s > 0)) return std::nullopt;  // all centres coincide: no baseline
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() *= s;
  T.topRightCorner<3, 1>() = c;

  Eigen::MatrixXd A(2 * views.size(), 4);
  for (std::size_t j = 0; j < views.size(); ++j) {
    const PointView& v = views[j];
    Eigen::Matrix<double, 3, 4> P;
    P << v.R, v.t;
    const Eigen::Matrix<double, 3, 4> Pn = P * T;
    Eigen::Matrix<double, 2, 4> rows;
    rows.row(0) = v.xy.x() * Pn.row(2) - Pn.row(0);
    rows.row(1) = v.xy.y() * Pn.row(2) - Pn.row(1);
    const double norm = rows.norm();
    if (norm > 0) rows /= norm;
    A.block<2, 4>(static_cast<Eigen::Index>(2 * j), 0) = rows;
  }
  const Eigen::Vector4d Xh = T * geometry::svd(A, Eigen::ComputeFullV).V.col(3);
  if (!(std::abs(Xh(3)) > 1e-12 * Xh.head<3>().norm())) return std::nullopt;
  const Eigen::Vector3d X = Xh.head<3>() / Xh(3);
  if (!X.allFinite()) return std::nullopt;
  return X;
}

double max_intersection_angle_deg(const std::vector<PointView>& views, const Eigen::Vector3d& X) {
  double best_cos = 1;
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(views.size());
  for (const PointView& v : views) rays.push_back((X - v.centre_mm).normalized());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) best_cos = std::min(best_cos, rays[i].dot(rays[j]));
  }
  return std::acos(std::clamp(best_cos, -1.0, 1.0)) * kRadToDeg;
}

// Gauss-Newton: X <- X - (J^T J)^-1 J^T r, r = stacked pi_j(X) - uv_j, J = dr/dX (2n x 3).
Eigen::Vector3d refine_point(const CameraModel& camera, const std::vector<PointView>& views,
                             Eigen::Vector3d X, const TriangulationOptions& options) {
  using J3 = ceres::Jet<double, 3>;
  for (int it = 0; it < options.refine_iterations; ++it) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Jtr = Eigen::Vector3d::Zero();
    const J3 Xj[3] = {J3(X.x(), 0), J3(X.y(), 1), J3(X.z(), 2)};
    for (const PointView& v : views) {
      J3 pose[6];
      for (int k = 0; k < 6; ++k) pose[k] = J3((*v.cam_from_world)[static_cast<std::size_t>(k)]);
      J3 uv[2];
      const CameraModel& cam = v.camera ? *v.camera : camera;
      if (!project(shape_of(cam), cam.params.data(), pose, Xj, uv)) return X;  // left to the checks
      Eigen::Matrix<double, 2, 3> J;
      J.row(0) = uv[0].v.transpose();
      J.row(1) = uv[1].v.transpose();
      const Eigen::Vector2d r(uv[0].a - v.uv_px.x(), uv[1].a - v.uv_px.y());
      JtJ += J.transpose() * J;
      Jtr += J.transpose() * r;
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(JtJ);
    if (ldlt.info() != Eigen::Success) return X;
    const Eigen::Vector3d step = ldlt.solve(Jtr);
    if (!step.allFinite()) return X;
    X -= step;
    const double scale = (X - views.front().centre_mm).norm();
    if (step.norm() <= options.refine_step_tolerance * scale) break;
  }
  return X;
}

PointEstimate triangulate_point(const CameraModel& camera, std::vector<PointView> views,
                                const TriangulationOptions& options) {
  PointEstimate out;
  std::vector<std::size_t> index(views.size());
  for (std::size_t i = 0; i < index.size(); ++i) index[i] = i;
  while (true) {
    if (views.size() < 2) {
      out.status = TriangulationStatus::TooFewViews;
      return out;
    }
    const auto linear = triangulate_linear(views);
    if (!linear) {
      out.status = TriangulationStatus::Degenerate;
      return out;
    }
    out.max_angle_deg = max_intersection_angle_deg(views, *linear);
    if (out.max_angle_deg < options.min_angle_deg) {
      out.status = TriangulationStatus::SmallAngle;
      return out;
    }
    if (!in_front_of_all(views, *linear)) {
      out.status = TriangulationStatus::BehindCamera;
      return out;
    }
    const Eigen::Vector3d X = refine_point(camera, views, *linear, options);
    if (!X.allFinite() || !in_front_of_all(views, X)) {
      out.status = TriangulationStatus::BehindCamera;
      return out;
    }
    const std::vector<double> errors = reprojection_errors(camera, views, X);
    const auto worst = std::max_element(errors.begin(), errors.end());
    if (*worst <= options.max_reproj_px) {
      out.status = TriangulationStatus::Ok;
      out.xyz_mm = X;
      out.max_angle_deg = max_intersection_angle_deg(views, X);
      return out;
    }
    if (views.size() <= 2) {
      out.status = TriangulationStatus::LargeError;
      return out;
    }
    const auto k = static_cast<std::size_t>(worst - errors.begin());
    out.dropped.push_back(index[k]);
    out.dropped_error_px.push_back(*worst);
    views.erase(views.begin() + static_cast<std::ptrdiff_t>(k));
    index.erase(index.begin() + static_cast<std::ptrdiff_t>(k));
  }
}

std::vector<PointView> views_of(const Scene& scene, const std::vector<std::size_t>& observations) {
  std::vector<PointView> views;
  views.reserve(observations.size());
  for (std::size_t o : observations) {
    const ObservationRef& ob = scene.observations[o];
    const SceneImage& im = scene.images[ob.image];
    PointView v;
    v.cam_from_world = &im.cam_from_world;
    v.camera = &scene.cameras[im.camera];
    v.R = rotation_of(im.cam_from_world);
    v.t = translation_of(im.cam_from_world);
    v.centre_mm = -v.R.transpose() * v.t;
    v.xy = ob.xy;
    v.uv_px = ob.uv_px;
    views.push_back(v);
  }
  return views;
}

std::size_t triangulate_tracks(Scene& scene, const TriangulationOptions& options, int threads,
                               bool retriangulate) {
  std::vector<char> newly(scene.tracks.size(), 0);
  geometry::parallel_blocks(scene.tracks.size(), threads, 64, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t t = begin; t < end; ++t) {
      SceneTrack& track = scene.tracks[t];
      if (track.state == TrackState::Rejected || track.at_control) continue;
      if (track.state == TrackState::Triangulated && !retriangulate) continue;
      const std::vector<std::size_t> obs = scene.active_observations(t);
      if (obs.size() < 2) {
        track.issue = TrackIssue::NotRegistered;
        continue;
      }
      const PointEstimate e = triangulate_point(scene.cameras.front(), views_of(scene, obs), options);
      switch (e.status) {
        case TriangulationStatus::Ok:
          for (std::size_t k = 0; k < e.dropped.size(); ++k) {
            ObservationRef& ob = scene.observations[obs[e.dropped[k]]];
            ob.inlier = false;
            ob.removed_round = -1;
            ob.removed_residual_px = e.dropped_error_px[k];
          }
          newly[t] = track.state != TrackState::Triangulated;
          track.state = TrackState::Triangulated;
          track.issue = TrackIssue::None;
          track.xyz_mm = e.xyz_mm;
          continue;
        case TriangulationStatus::TooFewViews: track.issue = TrackIssue::NotRegistered; break;
        case TriangulationStatus::Degenerate:
        case TriangulationStatus::SmallAngle: track.issue = TrackIssue::SmallAngle; break;
        case TriangulationStatus::BehindCamera: track.issue = TrackIssue::BehindCamera; break;
        case TriangulationStatus::LargeError: track.issue = TrackIssue::LargeError; break;
      }
      track.state = TrackState::Pending;
    }
  });
  std::size_t n = 0;
  for (char c : newly) n += c ? 1 : 0;
  return n;
}

}  // namespace photomill::triangulate
