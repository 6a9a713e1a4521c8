// The camera model against OpenCV's projectPoints (same pixel convention, same distortion) and
// its inverse against the forward model.
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "tools/synth/camera_model.hpp"
#include "tools/synth/random.hpp"
#include "tools/synth/test_scene.hpp"

namespace photomill::synth {
namespace {

TEST(CameraModel, ProjectionEqualsOpenCvProjectPoints) {
  const Camera cam = test::small_camera();
  const Pose pose = look_at("a", {300, -200, 350}, {5, 10, 8}, Eigen::Vector3d::UnitZ());
  Rng rng(5);
  std::vector<cv::Point3d> world;
  for (int k = 0; k < 200; ++k) world.emplace_back(rng.uniform(-120, 120), rng.uniform(-100, 100), rng.uniform(0, 40));
  cv::Mat K(3, 3, CV_64F), dist(1, 5, CV_64F), rvec, tvec(3, 1, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = cam.camera_matrix(r, c);
  for (int k = 0; k < 5; ++k) dist.at<double>(0, k) = cam.distortion[k];
  cv::Mat R(3, 3, CV_64F);
  const Eigen::Matrix3d Re = pose.rotation();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R.at<double>(r, c) = Re(r, c);
    tvec.at<double>(r) = pose.cam_from_world_translation_mm[r];
  }
  cv::Rodrigues(R, rvec);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(world, rvec, tvec, K, dist, expected);
  for (std::size_t k = 0; k < world.size(); ++k) {
    const auto uv = project(cam, pose, {world[k].x, world[k].y, world[k].z});
    ASSERT_TRUE(uv);
    EXPECT_NEAR(uv->x(), expected[k].x, 1e-8);
    EXPECT_NEAR(uv->y(), expected[k].y, 1e-8);
  }
}

TEST(CameraModel, PixelToNormalisedInvertsTheDistortion) {
  const Camera cam = test::small_camera();
  for (double u = -0.5; u <= cam.image_width_px; u += 37.3) {
    for (double v = -0.5; v <= cam.image_height_px; v += 29.1) {
      const auto xy = pixel_to_normalised(cam, {u, v});
      ASSERT_TRUE(xy);
      const Eigen::Vector2d back = distort_to_pixel(cam, *xy);
      EXPECT_NEAR(back.x(), u, 1e-9);
      EXPECT_NEAR(back.y(), v, 1e-9);
    }
  }
}

TEST(CameraModel, LookAtPutsTheTargetOnTheOpticalAxisWithUpUp) {
  const Pose pose = look_at("a", {100, 200, 300}, {0, 0, 10}, Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d c = pose.rotation() * Eigen::Vector3d(0, 0, 10) + pose.cam_from_world_translation_mm;
  EXPECT_NEAR(c.x(), 0, 1e-9);
  EXPECT_NEAR(c.y(), 0, 1e-9);
  EXPECT_GT(c.z(), 0);
  EXPECT_TRUE(pose.centre_mm().isApprox(Eigen::Vector3d(100, 200, 300), 1e-12));
  // A point above the target appears above it in the image (smaller v).
  const Eigen::Vector3d above = pose.rotation() * Eigen::Vector3d(0, 0, 20) + pose.cam_from_world_translation_mm;
  EXPECT_LT(above.y(), 0);
  EXPECT_GE(pose.cam_from_world_rotation.w(), 0);
  EXPECT_THROW(look_at("a", {0, 0, 100}, {0, 0, 0}, Eigen::Vector3d::UnitZ()), std::invalid_argument);
}

TEST(CameraModel, ValidateRejectsUnusableCameras) {
  EXPECT_NO_THROW(validate_synth_camera(test::small_camera()));
  Camera strong = test::small_camera();
  strong.distortion = {-2.0, 0.0, 0, 0, 0};  // folds over inside the image
  EXPECT_THROW(validate_synth_camera(strong), std::invalid_argument);
  Camera eight = test::small_camera();
  eight.distortion.resize(8, 0.0);
  EXPECT_THROW(validate_synth_camera(eight), std::invalid_argument);
  Camera skew = test::small_camera();
  skew.camera_matrix(0, 1) = 0.5;
  EXPECT_THROW(validate_synth_camera(skew), std::invalid_argument);
  Camera zero = test::small_camera();
  zero.camera_matrix(0, 0) = 0;
  EXPECT_THROW(validate_synth_camera(zero), std::invalid_argument);
}

}  // namespace
}  // namespace photomill::synth
