// The camera model against OpenCV's own projection (cv::projectPoints) for every supported
// distortion length, and undistortion as its exact inverse.
#include <random>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "formats/error.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::geometry {
namespace {

Camera camera_with(const std::vector<double>& distortion) {
  Camera c;
  c.image_width_px = 2000;
  c.image_height_px = 1500;
  c.camera_matrix << 2400, 0, 1003.5, 0, 2401.2, 747.25, 0, 0, 1;
  c.distortion = distortion;
  return c;
}

class DistortionModels : public ::testing::TestWithParam<std::vector<double>> {};

TEST_P(DistortionModels, ProjectionMatchesOpenCV) {
  const Camera cam = camera_with(GetParam());
  const CameraModel model = to_camera_model(cam, "test");
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> xy(-0.35, 0.35), depth(300, 600);
  const PoseBlock pose{0.1, -0.2, 0.05, 5, -3, 20};
  std::vector<cv::Point3d> points;
  for (int i = 0; i < 200; ++i) {
    const double z = depth(rng);
    // Points in front of the camera, spread over the field of view, expressed in the world.
    const Eigen::Vector3d cam_point(xy(rng) * z, xy(rng) * z, z);
    const Eigen::Vector3d world = rotation_of(pose).transpose() * (cam_point - translation_of(pose));
    points.emplace_back(world.x(), world.y(), world.z());
  }
  const cv::Mat rvec = (cv::Mat_<double>(3, 1) << pose[0], pose[1], pose[2]);
  const cv::Mat tvec = (cv::Mat_<double>(3, 1) << pose[3], pose[4], pose[5]);
  const cv::Mat K = (cv::Mat_<double>(3, 3) << 2400, 0, 1003.5, 0, 2401.2, 747.25, 0, 0, 1);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, rvec, tvec, K, cam.distortion, expected);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto uv = project_point(model, pose.data(), Eigen::Vector3d(points[i].x, points[i].y, points[i].z));
    ASSERT_TRUE(uv.has_value());
    EXPECT_NEAR(uv->x(), expected[i].x, 1e-8);
    EXPECT_NEAR(uv->y(), expected[i].y, 1e-8);
  }
}

TEST_P(DistortionModels, UndistortInvertsProjection) {
  const CameraModel model = to_camera_model(camera_with(GetParam()), "test");
  const ModelShape shape = shape_of(model);
  for (double u = 0; u <= 1999; u += 111) {
    for (double v = 0; v <= 1499; v += 83) {
      const auto xy = undistort(model, {u, v});
      ASSERT_TRUE(xy.has_value()) << u << " " << v;
      double uu = 0, vv = 0;
      distort_to_pixel(shape, model.params.data(), xy->x(), xy->y(), &uu, &vv);
      EXPECT_NEAR(uu, u, 1e-9);
      EXPECT_NEAR(vv, v, 1e-9);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Geometry, DistortionModels,
    ::testing::Values(std::vector<double>{}, std::vector<double>{-0.08, 0.06, 0.0004, -0.0003},
                      std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02},
                      std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02, 0.01, -0.005, 0.002},
                      std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02, 0.01, -0.005, 0.002, 0.001, -0.0005,
                                          0.0007, 0.0002},
                      // The tilted sensor (Scheimpflug cameras), 14 coefficients.
                      std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02, 0.01, -0.005, 0.002, 0.001, -0.0005,
                                          0.0007, 0.0002, 0.012, -0.008},
                      std::vector<double>{0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -0.03, 0.05}));

TEST(CameraModel, RejectsAnInvalidCameraNamingTheFile) {
  Camera c = camera_with({});
  c.camera_matrix(0, 0) = -1;
  try {
    (void)to_camera_model(c, "cam.yaml");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam.yaml"), std::string::npos);
  }
}

TEST(CameraModel, UndistortToIdealPixelIsThePinholeOfTheUndistortedRay) {
  const CameraModel model = to_camera_model(camera_with({-0.08, 0.06, 0.0004, -0.0003, -0.02}), "test");
  const auto xy = undistort(model, {1800, 200});
  const auto ideal = undistort_to_ideal_pixel(model, {1800, 200});
  ASSERT_TRUE(xy && ideal);
  EXPECT_NEAR(ideal->x(), 2400 * xy->x() + 1003.5, 1e-9);
  EXPECT_NEAR(ideal->y(), 2401.2 * xy->y() + 747.25, 1e-9);
  // Without distortion the ideal pixel is the pixel itself.
  const CameraModel pinhole = to_camera_model(camera_with({}), "test");
  const auto same = undistort_to_ideal_pixel(pinhole, {123.25, 456.5});
  ASSERT_TRUE(same);
  EXPECT_NEAR(same->x(), 123.25, 1e-9);
  EXPECT_NEAR(same->y(), 456.5, 1e-9);
}

TEST(CameraModel, UndistortSaysWhenItCannot) {
  // k1 = -1 folds the image over beyond r = 1/sqrt(3): a pixel far out has no ray.
  const CameraModel folded = to_camera_model(camera_with({-1, 0, 0, 0}), "test");
  EXPECT_FALSE(undistort(folded, {1003.5 + 3 * 2400, 747.25}).has_value());
}

TEST(CameraModel, RoundTripsToCamera) {
  for (const auto& d : {std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02},
                        std::vector<double>{-0.08, 0.06, 0.0004, -0.0003, -0.02, 0.01, -0.005, 0.002, 0.001,
                                            -0.0005, 0.0007, 0.0002, 0.012, -0.008}}) {
    const Camera cam = camera_with(d);
    EXPECT_EQ(to_camera(to_camera_model(cam, "test"), cam), cam);
  }
}

}  // namespace
}  // namespace photomill::geometry
