// Rig calibration on a synthetic stereo pair with exact ground truth: the cameras' relative pose
// within a few of its stated standard deviations, a frame whose board moved between the two shots
// left out and named, and the errors for photos no camera took or cameras that share no frame.
#include "calib/rig.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>

#include "calib/test_scene.hpp"
#include "formats/error.hpp"

namespace photomill::calib {
namespace {

struct StereoScene {
  test::Scene left;  // its poses are the rig's (camera 0 = the rig frame)
  Camera right_truth;
  Eigen::Isometry3d right_from_left = Eigen::Isometry3d::Identity();
  std::vector<Observation> observations;
};

// The left camera of make_scene; the right one 80 mm to its right, turned 3 degrees, with other
// intrinsics. Frame `moved` (if >= 0): the board moves 1.5 mm between the two shots.
StereoScene make_stereo(unsigned seed, int moved = -1) {
  test::SceneOptions o;
  o.views = 10;
  o.seed = seed;
  o.noise_px = 0.1;
  StereoScene s;
  s.left = test::make_scene(o);
  s.right_truth = s.left.truth;
  s.right_truth.camera_matrix << 1010, 0, 630.2, 0, 1012, 490.4, 0, 0, 1;
  s.right_truth.distortion = {-0.1, 0.03, -0.0004, 0.0002, 0};
  s.right_from_left.linear() = Eigen::AngleAxisd(3 * M_PI / 180, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  s.right_from_left.translation() = Eigen::Vector3d(-80, 1.5, -2);
  std::mt19937 rng(seed + 100);
  std::normal_distribution<double> noise(0, o.noise_px);
  const cv::Matx33d K(1010, 0, 630.2, 0, 1012, 490.4, 0, 0, 1);
  for (const Observation& ob : s.left.observations) {
    Observation l = ob;
    l.image = "L" + ob.image;
    s.observations.push_back(l);
  }
  for (std::size_t v = 0; v < s.left.poses.size(); ++v) {
    const Pose& p = s.left.poses[v];
    Eigen::Isometry3d left_from_world = Eigen::Isometry3d::Identity();
    left_from_world.linear() = p.rotation();
    left_from_world.translation() = p.cam_from_world_translation_mm;
    const Eigen::Isometry3d right_from_world = s.right_from_left * left_from_world;
    const Eigen::AngleAxisd aa(right_from_world.linear());
    const cv::Vec3d rvec(aa.angle() * aa.axis().x(), aa.angle() * aa.axis().y(), aa.angle() * aa.axis().z());
    const Eigen::Vector3d t = right_from_world.translation();
    std::vector<cv::Point3d> obj;
    for (const auto& c : s.left.control) {
      const Eigen::Vector3d x = c.xyz_mm + (static_cast<int>(v) == moved ? Eigen::Vector3d(1.5, 0, 0) : Eigen::Vector3d::Zero());
      obj.emplace_back(x.x(), x.y(), x.z());
    }
    std::vector<cv::Point2d> img;
    cv::projectPoints(obj, rvec, cv::Vec3d(t.x(), t.y(), t.z()), K, s.right_truth.distortion, img);
    for (std::size_t i = 0; i < img.size(); ++i) {
      if (img[i].x < 0 || img[i].y < 0 || img[i].x > 1279 || img[i].y > 959) continue;
      s.observations.push_back({"R" + p.image, s.left.control[i].point_id, img[i].x + noise(rng), img[i].y + noise(rng)});
    }
  }
  return s;
}

double angle_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle() * 180 / M_PI;
}

TEST(Rig, RecoversTheRelativePoseWithinItsSigma) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const StereoScene s = make_stereo(seed);
    const RigResult r = calibrate_rig(s.observations, s.left.control, {"L", "R"}, {s.left.size, s.left.size}, {}, "obs");
    ASSERT_EQ(r.rig.cameras.size(), 2u);
    const RigCamera& c = r.rig.cameras[1];
    ASSERT_TRUE(c.cam_from_rig_sigma);
    const auto& sigma = *c.cam_from_rig_sigma;
    const Eigen::Vector3d dt = c.cam_from_rig_translation_mm - s.right_from_left.translation();
    for (int i = 0; i < 3; ++i) EXPECT_LT(std::abs(dt[i]), 4 * sigma[3 + i]) << "seed " << seed << " axis " << i;
    const double da = angle_deg(c.cam_from_rig_rotation, s.right_from_left.linear());
    EXPECT_LT(da, 4 * sigma.head<3>().norm()) << "seed " << seed;
    // At 0.1 px of noise the baseline is good to ~0.01 %, and its sigma says so.
    EXPECT_LT(std::abs(c.cam_from_rig_translation_mm.norm() - s.right_from_left.translation().norm()),
              4 * r.baseline_sigma_mm[1]);
    EXPECT_LT(r.baseline_sigma_mm[1], 0.05);
    EXPECT_NEAR(r.sigma_px, 0.1, 0.02);
    EXPECT_EQ(r.rig.cameras[0].cam_from_rig_rotation, Eigen::Matrix3d::Identity());
    EXPECT_FALSE(r.rig.cameras[0].cam_from_rig_sigma);
  }
}

// Three cameras: a third one 60 mm above the first, seeing only some frames; its pose in the rig
// comes out as well as the second's, and each camera keeps its own intrinsics.
TEST(Rig, ThreeCameras) {
  const StereoScene s = make_stereo(6);
  std::vector<Observation> obs = s.observations;
  Eigen::Isometry3d up_from_left = Eigen::Isometry3d::Identity();
  up_from_left.linear() = Eigen::AngleAxisd(-2 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  up_from_left.translation() = Eigen::Vector3d(0, 60, 1);
  const cv::Matx33d K(990, 0, 650.5, 0, 991, 470.2, 0, 0, 1);
  const std::vector<double> dist{-0.11, 0.04, 0.0002, 0.0001, 0};
  std::mt19937 rng(77);
  std::normal_distribution<double> noise(0, 0.1);
  for (std::size_t v = 0; v < s.left.poses.size(); v += 2) {  // every other frame
    const Pose& p = s.left.poses[v];
    Eigen::Isometry3d left_from_world = Eigen::Isometry3d::Identity();
    left_from_world.linear() = p.rotation();
    left_from_world.translation() = p.cam_from_world_translation_mm;
    const Eigen::Isometry3d up_from_world = up_from_left * left_from_world;
    const Eigen::AngleAxisd aa(up_from_world.linear());
    const cv::Vec3d rvec(aa.angle() * aa.axis().x(), aa.angle() * aa.axis().y(), aa.angle() * aa.axis().z());
    const Eigen::Vector3d t = up_from_world.translation();
    std::vector<cv::Point3d> pts;
    for (const auto& c : s.left.control) pts.emplace_back(c.xyz_mm.x(), c.xyz_mm.y(), c.xyz_mm.z());
    std::vector<cv::Point2d> img;
    cv::projectPoints(pts, rvec, cv::Vec3d(t.x(), t.y(), t.z()), K, dist, img);
    for (std::size_t i = 0; i < img.size(); ++i) {
      if (img[i].x < 0 || img[i].y < 0 || img[i].x > 1279 || img[i].y > 959) continue;
      obs.push_back({"U" + p.image, s.left.control[i].point_id, img[i].x + noise(rng), img[i].y + noise(rng)});
    }
  }
  const RigResult r = calibrate_rig(obs, s.left.control, {"L", "R", "U"}, {s.left.size, s.left.size, s.left.size}, {},
                                    "obs");
  ASSERT_EQ(r.rig.cameras.size(), 3u);
  const RigCamera& right = r.rig.cameras[1];
  const RigCamera& up = r.rig.cameras[2];
  EXPECT_LT((right.cam_from_rig_translation_mm - s.right_from_left.translation()).norm(), 0.2);
  EXPECT_LT((up.cam_from_rig_translation_mm - up_from_left.translation()).norm(), 0.2);
  EXPECT_LT(angle_deg(up.cam_from_rig_rotation, up_from_left.linear()), 0.05);
  EXPECT_NEAR(up.camera.fx(), 990, 2);
  EXPECT_NEAR(right.camera.fx(), 1010, 2);
  EXPECT_NEAR(r.rig.cameras[0].camera.fx(), 1000, 2);
  int three = 0;
  for (const auto& f : r.frames) three += f.cameras == 3;
  EXPECT_EQ(three, 5);
}

TEST(Rig, LeavesOutAFrameWhoseBoardMoved) {
  const StereoScene s = make_stereo(4, 6);
  const RigResult r = calibrate_rig(s.observations, s.left.control, {"L", "R"}, {s.left.size, s.left.size}, {}, "obs");
  int left_out = 0;
  for (const auto& f : r.frames) {
    if (f.used) continue;
    ++left_out;
    EXPECT_EQ(f.frame, "view6.png");
    EXPECT_NE(f.reason.find("the board moved"), std::string::npos) << f.reason;
  }
  EXPECT_EQ(left_out, 1);
  const RigCamera& c = r.rig.cameras[1];
  EXPECT_LT((c.cam_from_rig_translation_mm - s.right_from_left.translation()).norm(), 0.2);
  EXPECT_LT(r.rms_px, 0.15);
}

TEST(Rig, RefusesPhotosNoCameraTookAndCamerasWithoutASharedFrame) {
  StereoScene s = make_stereo(5);
  auto obs = s.observations;
  obs.push_back({"Xview1.png", 0, 10, 10});
  try {
    calibrate_rig(obs, s.left.control, {"L", "R"}, {s.left.size, s.left.size}, {}, "obs.csv");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("obs.csv: image 'Xview1.png' starts with none of the rig's prefixes"),
              std::string::npos)
        << e.what();
  }
  // The right photos renamed so that no frame pairs them with a left one.
  obs = s.observations;
  for (auto& o : obs) {
    if (o.image[0] == 'R') o.image = "Rother_" + o.image.substr(1);
  }
  try {
    calibrate_rig(obs, s.left.control, {"L", "R"}, {s.left.size, s.left.size}, {}, "obs.csv");
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("camera 1 ('R') shares no frame with camera 0 ('L')"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace photomill::calib
