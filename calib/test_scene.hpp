// Test helper: a synthetic calibration scene with exact ground truth. Known control points (a
// board on z = 0 or a cloud of points in a box) are projected by a known camera with
// cv::projectPoints and perturbed by seeded Gaussian noise.
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>

#include "formats/camera.hpp"
#include "formats/tables.hpp"

namespace photomill::calib::test {

struct SceneOptions {
  bool planar = true;       // a 9x7 board of 30 mm squares, else 80 points in a 300x240x150 mm box
  int views = 8;
  double noise_px = 0.1;    // standard deviation per coordinate
  double min_tilt_deg = 15;  // angle between the viewing direction and the board normal (or +z)
  double max_tilt_deg = 40;
  double distance_mm = 0;   // camera to aim point; 0: 450 (board) or 600 (points)
  double aim_jitter_mm = 70;  // the aim point moves this far so the points reach the image corners
  unsigned seed = 1;
};

struct Scene {
  Camera truth;
  cv::Size size;
  std::vector<ControlPoint> control;
  std::vector<Observation> observations;
  std::vector<Pose> poses;
};

inline Scene make_scene(const SceneOptions& o) {
  Scene s;
  s.size = {1280, 960};
  s.truth.image_width_px = s.size.width;
  s.truth.image_height_px = s.size.height;
  s.truth.camera_matrix << 1000, 0, 645.3, 0, 1003, 478.9, 0, 0, 1;
  s.truth.distortion = {-0.12, 0.05, 0.0005, -0.0003, 0};
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> uni(0, 1);
  std::normal_distribution<double> noise(0, o.noise_px);
  Eigen::Vector3d centre;
  if (o.planar) {
    for (int r = 0; r < 7; ++r) {
      for (int c = 0; c < 9; ++c) s.control.push_back({r * 9 + c, Eigen::Vector3d(30.0 * c, 30.0 * r, 0), {}});
    }
    centre = {120, 90, 0};
  } else {
    for (int i = 0; i < 80; ++i) {
      s.control.push_back({100 + i, Eigen::Vector3d(300 * uni(rng), 240 * uni(rng), 150 * uni(rng)), {}});
    }
    centre = {150, 120, 75};
  }
  const cv::Matx33d K(s.truth.camera_matrix(0, 0), 0, s.truth.camera_matrix(0, 2), 0, s.truth.camera_matrix(1, 1),
                      s.truth.camera_matrix(1, 2), 0, 0, 1);
  for (int v = 0; v < o.views; ++v) {
    // Camera centre on a cone around +z (the board normal), looking at the centre, random roll.
    const double tilt = (o.min_tilt_deg + (o.max_tilt_deg - o.min_tilt_deg) * uni(rng)) * std::numbers::pi / 180;
    const double azimuth = 2 * std::numbers::pi * (v + 0.3 * uni(rng)) / o.views;
    const double roll = (uni(rng) - 0.5) * 0.6;
    const Eigen::Vector3d dir(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth), std::cos(tilt));
    const double distance = o.distance_mm > 0 ? o.distance_mm : o.planar ? 450 : 600;
    const Eigen::Vector3d aim = centre + o.aim_jitter_mm * Eigen::Vector3d(2 * uni(rng) - 1, 2 * uni(rng) - 1, 0);
    const Eigen::Vector3d C = aim + distance * (0.9 + 0.2 * uni(rng)) * dir;
    const Eigen::Vector3d z = (aim - C).normalized();
    Eigen::Vector3d x = Eigen::Vector3d::UnitX().cross(z).cross(z).normalized() * -1;
    x = Eigen::AngleAxisd(roll, z) * x;
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d R;  // cam_from_world: rows are the camera axes in the world
    R.row(0) = x.transpose();
    R.row(1) = y.transpose();
    R.row(2) = z.transpose();
    const Eigen::Vector3d t = -R * C;
    Pose pose;
    pose.image = "view" + std::to_string(v) + ".png";
    pose.cam_from_world_rotation = Eigen::Quaterniond(R);
    pose.cam_from_world_translation_mm = t;
    s.poses.push_back(pose);
    std::vector<cv::Point3d> obj;
    for (const auto& c : s.control) obj.emplace_back(c.xyz_mm.x(), c.xyz_mm.y(), c.xyz_mm.z());
    const Eigen::AngleAxisd aa(R);
    const cv::Vec3d rvec(aa.angle() * aa.axis().x(), aa.angle() * aa.axis().y(), aa.angle() * aa.axis().z());
    std::vector<cv::Point2d> img;
    cv::projectPoints(obj, rvec, cv::Vec3d(t.x(), t.y(), t.z()), K, s.truth.distortion, img);
    for (std::size_t i = 0; i < img.size(); ++i) {
      if (img[i].x < 0 || img[i].y < 0 || img[i].x > s.size.width - 1 || img[i].y > s.size.height - 1) continue;
      s.observations.push_back({pose.image, s.control[i].point_id, img[i].x + noise(rng), img[i].y + noise(rng)});
    }
  }
  return s;
}

}  // namespace photomill::calib::test
