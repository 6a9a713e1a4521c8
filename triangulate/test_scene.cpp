// Synthetic ground truth (see test_scene.hpp).
#include "triangulate/test_scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <map>
#include <random>
#include <set>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "triangulate/reconstruct.hpp"

namespace photomill::triangulate::test {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

Pose look_at(const std::string& name, const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  // Camera frame: z forward, x right, y down; world z up appears upwards in the image.
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  Pose p;
  p.image = name;
  p.cam_from_world_rotation = Eigen::Quaterniond(R).normalized();
  p.cam_from_world_translation_mm = -R * centre;
  return p;
}

}  // namespace

double part_height_mm(const SceneOptions& o, double x, double y) {
  const double u = 2 * x / o.part_x_mm, v = 2 * y / o.part_y_mm;
  if (std::abs(u) >= 1 || std::abs(v) >= 1) return 0;
  const double cu = std::cos(u * std::numbers::pi / 2), cv = std::cos(v * std::numbers::pi / 2);
  return o.part_height_mm * cu * cu * cv * cv * (0.8 + 0.2 * std::sin(3 * u + 1.3 * v));
}

SceneTruth make_scene(const SceneOptions& o) {
  SceneTruth s;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0, o.noise_px);
  std::uniform_real_distribution<double> unit(0, 1);

  Camera& c = s.camera;
  c.image_width_px = o.width_px;
  c.image_height_px = o.height_px;
  c.camera_matrix << o.focal_px, 0, (o.width_px - 1) / 2.0 + 3.5, 0, o.focal_px * 1.0005, (o.height_px - 1) / 2.0 - 2.25, 0, 0, 1;
  c.distortion = o.distortion;

  for (int k = 0; k < o.views; ++k) {
    const double az = (10 + 360.0 * k / o.views + 8 * (unit(rng) - 0.5)) * kDeg;
    const double el = (o.elevations_deg[static_cast<std::size_t>(k) % o.elevations_deg.size()] + 4 * (unit(rng) - 0.5)) * kDeg;
    const double dist = o.distance_mm * (1 + 0.1 * (unit(rng) - 0.5));
    const Eigen::Vector3d target(20 * (unit(rng) - 0.5), 20 * (unit(rng) - 0.5), o.part_height_mm / 3);
    Eigen::Vector3d centre = target + dist * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    if (o.one_centre) {
      centre = Eigen::Vector3d(0, -o.distance_mm * 0.6, o.distance_mm * 0.8);
      const Eigen::Vector3d aim(60 * std::cos(az), 40 * std::sin(az), 0);
      s.poses.push_back(look_at(std::string("view_") + std::to_string(100 + k) + ".png", centre, aim));
      continue;
    }
    char name[32];
    std::snprintf(name, sizeof name, "view_%03d.png", k);
    s.poses.push_back(look_at(name, centre, target));
  }

  PointId marker = 0;
  for (int j = 0; j < o.plate_points_y; ++j) {
    for (int i = 0; i < o.plate_points_x; ++i) {
      const double x = -o.plate_x_mm / 2 + o.plate_x_mm * i / std::max(1, o.plate_points_x - 1);
      const double y = -o.plate_y_mm / 2 + o.plate_y_mm * j / std::max(1, o.plate_points_y - 1);
      if (std::abs(x) < o.part_x_mm / 2 + 5 && std::abs(y) < o.part_y_mm / 2 + 5) continue;  // under the part
      if (o.plate_marker_side_mm > 0) {
        const double sd = o.plate_marker_side_mm;
        const Eigen::Vector3d corners[4] = {{x, y, 0}, {x + sd, y, 0}, {x + sd, y - sd, 0}, {x, y - sd, 0}};
        for (int k = 0; k < 4; ++k) s.plate_points.push_back({marker * 4 + k, corners[k], std::nullopt});
        ++marker;
      } else {
        s.plate_points.push_back({static_cast<PointId>(s.plate_points.size()), Eigen::Vector3d(x, y, 0), std::nullopt});
      }
    }
  }
  auto add_part_point = [&](double x, double y) {
    const PointId id = o.part_id_offset + static_cast<PointId>(s.part_points.size());
    s.part_points.push_back({id, Eigen::Vector3d(x, y, part_height_mm(o, x, y)), std::nullopt});
  };
  if (o.random_part_points > 0) {
    for (std::size_t k = 0; k < o.random_part_points; ++k) {
      add_part_point(0.9 * o.part_x_mm * (unit(rng) - 0.5), 0.9 * o.part_y_mm * (unit(rng) - 0.5));
    }
  } else {
    for (int j = 0; j < o.part_points_y; ++j) {
      for (int i = 0; i < o.part_points_x; ++i) {
        add_part_point(0.9 * o.part_x_mm * ((i + 0.5) / o.part_points_x - 0.5),
                       0.9 * o.part_y_mm * ((j + 0.5) / o.part_points_y - 0.5));
      }
    }
  }

  std::vector<ControlPoint> all = s.plate_points;
  all.insert(all.end(), s.part_points.begin(), s.part_points.end());
  std::vector<cv::Point3d> object;
  for (const auto& p : all) object.emplace_back(p.xyz_mm.x(), p.xyz_mm.y(), p.xyz_mm.z());
  cv::Mat K, dist(1, static_cast<int>(o.distortion.size()), CV_64F);
  cv::eigen2cv(c.camera_matrix, K);
  for (std::size_t i = 0; i < o.distortion.size(); ++i) dist.at<double>(static_cast<int>(i)) = o.distortion[i];

  // Per point, the views that see it (in front, inside the image).
  std::vector<std::vector<std::pair<std::size_t, cv::Point2d>>> seen(all.size());
  for (std::size_t v = 0; v < s.poses.size(); ++v) {
    const Pose& pose = s.poses[v];
    const Eigen::AngleAxisd aa(pose.rotation());
    const Eigen::Vector3d rv = aa.angle() * aa.axis();
    const cv::Mat rvec = (cv::Mat_<double>(3, 1) << rv.x(), rv.y(), rv.z());
    const Eigen::Vector3d& t = pose.cam_from_world_translation_mm;
    const cv::Mat tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
    std::vector<cv::Point2d> uv;
    cv::projectPoints(object, rvec, tvec, K, dist, uv);
    for (std::size_t p = 0; p < all.size(); ++p) {
      const double depth = (pose.rotation() * all[p].xyz_mm + t).z();
      if (depth <= 0 || uv[p].x < 0 || uv[p].y < 0 || uv[p].x > o.width_px - 1 || uv[p].y > o.height_px - 1) continue;
      seen[p].push_back({v, uv[p]});
    }
  }
  for (std::size_t p = 0; p < all.size(); ++p) {
    auto& views = seen[p];
    if (o.max_track_length > 0 && views.size() > o.max_track_length) {
      std::shuffle(views.begin(), views.end(), rng);
      views.resize(o.max_track_length);
      std::sort(views.begin(), views.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    }
    for (const auto& [v, uv] : views) {
      TrackObservation t{all[p].point_id, s.poses[v].image, uv.x + noise(rng), uv.y + noise(rng)};
      if (o.outlier_fraction > 0 && unit(rng) < o.outlier_fraction) {
        const double a = 2 * std::numbers::pi * unit(rng);
        t.u_px += o.outlier_px * std::cos(a);
        t.v_px += o.outlier_px * std::sin(a);
        s.outliers.push_back(t);
      }
      s.tracks.push_back(t);
    }
  }
  return s;
}

Eigen::Vector2d project(const SceneTruth& truth, std::size_t view, const Eigen::Vector3d& X) {
  const Pose& pose = truth.poses[view];
  const Eigen::AngleAxisd aa(pose.rotation());
  const Eigen::Vector3d rv = aa.angle() * aa.axis();
  const cv::Mat rvec = (cv::Mat_<double>(3, 1) << rv.x(), rv.y(), rv.z());
  const Eigen::Vector3d& t = pose.cam_from_world_translation_mm;
  const cv::Mat tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
  cv::Mat K, dist(1, static_cast<int>(truth.camera.distortion.size()), CV_64F);
  cv::eigen2cv(truth.camera.camera_matrix, K);
  for (std::size_t i = 0; i < truth.camera.distortion.size(); ++i) dist.at<double>(static_cast<int>(i)) = truth.camera.distortion[i];
  std::vector<cv::Point2d> uv;
  cv::projectPoints(std::vector<cv::Point3d>{{X.x(), X.y(), X.z()}}, rvec, tvec, K, dist, uv);
  return {uv[0].x, uv[0].y};
}

Eigen::Vector3d add_two_view_track(SceneTruth& truth, TrackId id, std::size_t a, std::size_t b, const Eigen::Vector3d& X,
                                   double depth_mm) {
  const Eigen::Vector3d there = X + depth_mm * (X - truth.poses[a].centre_mm()).normalized();
  const Eigen::Vector2d ua = project(truth, a, X), ub = project(truth, b, there);
  truth.tracks.push_back({id, truth.poses[a].image, ua.x(), ua.y()});
  truth.tracks.push_back({id, truth.poses[b].image, ub.x(), ub.y()});
  return there;
}

RigSceneTruth make_rig_scene(int frames, double noise_px, unsigned seed) {
  SceneOptions o;
  o.views = 2 * frames;
  o.noise_px = 0;
  o.seed = seed;
  const SceneTruth base = make_scene(o);
  RigSceneTruth s;
  RigCamera left{"left_", base.camera, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), std::nullopt};
  RigCamera right = left;
  right.prefix = "right_";
  right.camera.camera_matrix(0, 0) = right.camera.camera_matrix(1, 1) = 2600;
  right.camera.distortion = {-0.05, 0.03, -0.0002, 0.0003, 0.0};
  right.cam_from_rig_rotation = Eigen::AngleAxisd(6 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  right.cam_from_rig_translation_mm = -right.cam_from_rig_rotation * Eigen::Vector3d(80, 0, 0);
  s.rig.cameras = {left, right};
  // world_new = T0 world_old, T0 the rig's pose at frame 00 (camera 0's).
  const Eigen::Matrix3d R0 = base.poses[0].rotation();
  const Eigen::Vector3d t0 = base.poses[0].cam_from_world_translation_mm;
  for (const auto* in : {&base.plate_points, &base.part_points}) {
    auto& out = in == &base.plate_points ? s.plate_points : s.part_points;
    for (ControlPoint p : *in) {
      p.xyz_mm = R0 * p.xyz_mm + t0;
      out.push_back(p);
    }
  }
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  for (int f = 0; f < frames; ++f) {
    const Pose& frame = base.poses[static_cast<std::size_t>(2 * f)];
    // rig_from_world_new = rig_from_world_old T0^-1.
    const Eigen::Matrix3d Rf = frame.rotation() * R0.transpose();
    const Eigen::Vector3d tf = frame.cam_from_world_translation_mm - Rf * t0;
    for (const RigCamera& cam : s.rig.cameras) {
      char name[32];
      std::snprintf(name, sizeof name, "%s%02d.png", cam.prefix.c_str(), f);
      Pose pose;
      pose.image = name;
      const Eigen::Matrix3d R = cam.cam_from_rig_rotation * Rf;
      pose.cam_from_world_rotation = Eigen::Quaterniond(R).normalized();
      pose.cam_from_world_translation_mm = cam.cam_from_rig_rotation * tf + cam.cam_from_rig_translation_mm;
      s.poses.push_back(pose);
      const Eigen::AngleAxisd aa(pose.rotation());
      const Eigen::Vector3d rv = aa.angle() * aa.axis();
      const Eigen::Vector3d& t = pose.cam_from_world_translation_mm;
      const cv::Mat rvec = (cv::Mat_<double>(3, 1) << rv.x(), rv.y(), rv.z());
      const cv::Mat tvec = (cv::Mat_<double>(3, 1) << t.x(), t.y(), t.z());
      cv::Mat K, dist(1, static_cast<int>(cam.camera.distortion.size()), CV_64F);
      cv::eigen2cv(cam.camera.camera_matrix, K);
      for (std::size_t i = 0; i < cam.camera.distortion.size(); ++i) dist.at<double>(static_cast<int>(i)) = cam.camera.distortion[i];
      for (const auto* points : {&s.plate_points, &s.part_points}) {
        for (const ControlPoint& p : *points) {
          std::vector<cv::Point2d> uv;
          cv::projectPoints(std::vector<cv::Point3d>{{p.xyz_mm.x(), p.xyz_mm.y(), p.xyz_mm.z()}}, rvec, tvec, K, dist, uv);
          const double depth = (pose.rotation() * p.xyz_mm + t).z();
          if (depth <= 0 || uv[0].x < 0 || uv[0].y < 0 || uv[0].x > cam.camera.image_width_px - 1 ||
              uv[0].y > cam.camera.image_height_px - 1) {
            continue;
          }
          s.tracks.push_back({p.point_id, pose.image, uv[0].x + noise(rng), uv[0].y + noise(rng)});
        }
      }
    }
  }
  return s;
}

Accuracy evaluate(const Reconstruction& r, const SceneTruth& truth, bool similarity) {
  std::map<PointId, Eigen::Vector3d> true_points;
  for (const auto& p : truth.plate_points) true_points[p.point_id] = p.xyz_mm;
  std::set<PointId> part;
  for (const auto& p : truth.part_points) {
    true_points[p.point_id] = p.xyz_mm;
    part.insert(p.point_id);
  }
  std::vector<Eigen::Vector3d> est, tru;
  std::vector<char> is_part;
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    const auto it = true_points.find(r.scene.tracks[t].id);
    if (it == true_points.end()) continue;
    est.push_back(r.scene.tracks[t].xyz_mm);
    tru.push_back(it->second);
    is_part.push_back(part.count(r.scene.tracks[t].id) ? 1 : 0);
  }
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  if (similarity && est.size() >= 3) {
    Eigen::Matrix3Xd a(3, static_cast<Eigen::Index>(est.size())), b(3, static_cast<Eigen::Index>(est.size()));
    for (std::size_t k = 0; k < est.size(); ++k) {
      a.col(static_cast<Eigen::Index>(k)) = est[k];
      b.col(static_cast<Eigen::Index>(k)) = tru[k];
    }
    M = Eigen::umeyama(a, b, true);
  }
  const Eigen::Matrix3d sR = M.topLeftCorner<3, 3>();
  const Eigen::Vector3d T = M.topRightCorner<3, 1>();
  Accuracy acc;
  acc.scale = std::cbrt(sR.determinant());
  double sum = 0;
  for (std::size_t k = 0; k < est.size(); ++k) {
    if (!is_part[k]) continue;
    const double e = (sR * est[k] + T - tru[k]).norm();
    sum += e * e;
    acc.part_max_mm = std::max(acc.part_max_mm, e);
    ++acc.part_points;
  }
  acc.part_rms_mm = acc.part_points ? std::sqrt(sum / static_cast<double>(acc.part_points)) : 0;
  std::map<std::string, Eigen::Vector3d> true_centres;
  for (const Pose& p : truth.poses) true_centres[p.image] = p.centre_mm();
  sum = 0;
  for (const Pose& p : registered_poses(r)) {
    const double e = (sR * p.centre_mm() + T - true_centres.at(p.image)).norm();
    sum += e * e;
    acc.centre_max_mm = std::max(acc.centre_max_mm, e);
    ++acc.cameras;
  }
  acc.centre_rms_mm = acc.cameras ? std::sqrt(sum / static_cast<double>(acc.cameras)) : 0;
  return acc;
}

void give_sizes_spoil_large(std::vector<TrackObservation>& tracks) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 0.6);
  std::size_t k = 0;
  for (auto& t : tracks) {
    const bool big = (k++ % 3) == 0;
    t.size_px = big ? 12.0 : 1.0;
    if (big) {
      t.u_px += n(rng);
      t.v_px += n(rng);
    }
  }
}

}  // namespace photomill::triangulate::test
