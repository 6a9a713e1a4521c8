// Multi-view triangulation on exact and noisy synthetic views: the linear estimate, its
// normalisation, the checks (angle, cheirality, reprojection error) and the refinement.
#include <random>

#include <gtest/gtest.h>

#include "triangulate/pose.hpp"
#include "triangulate/triangulation.hpp"

namespace photomill::triangulate {
namespace {

CameraModel test_camera() {
  Camera c;
  c.image_width_px = 2000;
  c.image_height_px = 1500;
  c.camera_matrix << 2400, 0, 999.5, 0, 2400, 749.5, 0, 0, 1;
  c.distortion = {-0.08, 0.06, 0.0004, -0.0003, 0};
  return to_camera_model(c, "test");
}

// Cameras on a circle of radius `radius` around `target`, looking at it, `spread_deg` apart.
std::vector<PoseBlock> ring(int n, const Eigen::Vector3d& target, double radius, double spread_deg) {
  std::vector<PoseBlock> poses;
  for (int k = 0; k < n; ++k) {
    const double a = (k - (n - 1) / 2.0) * spread_deg * M_PI / 180;
    const Eigen::Vector3d centre = target + radius * Eigen::Vector3d(std::sin(a), -0.3, -std::cos(a)).normalized();
    const Eigen::Vector3d z = (target - centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    Eigen::Matrix3d R;
    R.row(0) = x.transpose();
    R.row(1) = z.cross(x).transpose();
    R.row(2) = z.transpose();
    poses.push_back(make_pose(R, -R * centre));
  }
  return poses;
}

std::vector<PointView> views_for(const CameraModel& cam, const std::vector<PoseBlock>& poses, const Eigen::Vector3d& X,
                                 double noise_px, std::mt19937& rng) {
  std::normal_distribution<double> noise(0, noise_px);
  std::vector<PointView> views;
  for (const PoseBlock& p : poses) {
    PointView v;
    v.cam_from_world = &p;
    v.R = rotation_of(p);
    v.t = translation_of(p);
    v.centre_mm = centre_of(p);
    v.uv_px = *project_point(cam, p.data(), X) + Eigen::Vector2d(noise(rng), noise(rng));
    v.xy = *undistort(cam, v.uv_px);
    views.push_back(v);
  }
  return views;
}

struct ExactCase {
  int views;
  double offset_mm;  // distance of the whole scene from the world origin
};

class ExactViews : public ::testing::TestWithParam<ExactCase> {};

TEST_P(ExactViews, LinearEstimateIsExact) {
  const CameraModel cam = test_camera();
  const Eigen::Vector3d offset = Eigen::Vector3d(1, -2, 0.5).normalized() * GetParam().offset_mm;
  const Eigen::Vector3d X = offset + Eigen::Vector3d(12.5, -7.25, 30);
  const auto poses = ring(GetParam().views, offset, 450, 20);
  std::mt19937 rng(1);
  const auto views = views_for(cam, poses, X, 0, rng);
  const auto linear = triangulate_linear(views);
  ASSERT_TRUE(linear.has_value());
  // Relative to the distance to the cameras: normalisation keeps this independent of the offset.
  EXPECT_LT((*linear - X).norm(), 1e-9 * 450) << "offset " << GetParam().offset_mm;
  const PointEstimate e = triangulate_point(cam, views, {});
  EXPECT_EQ(e.status, TriangulationStatus::Ok);
  EXPECT_LT((e.xyz_mm - X).norm(), 1e-9 * 450);
}

INSTANTIATE_TEST_SUITE_P(Triangulate, ExactViews,
                         ::testing::Values(ExactCase{2, 0}, ExactCase{3, 0}, ExactCase{12, 0}, ExactCase{12, 1e5},
                                           ExactCase{2, 1e6}));

TEST(Triangulation, RefinementLowersReprojectionError) {
  const CameraModel cam = test_camera();
  const auto poses = ring(6, Eigen::Vector3d::Zero(), 450, 15);
  std::mt19937 rng(7);
  double linear_sum = 0, refined_sum = 0;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d X(trial - 25.0, 0.5 * trial - 10, 20);
    const auto views = views_for(cam, poses, X, 0.5, rng);
    const Eigen::Vector3d lin = *triangulate_linear(views);
    const Eigen::Vector3d ref = refine_point(cam, views, lin, {});
    for (const auto& v : views) {
      linear_sum += (*project_point(cam, v.cam_from_world->data(), lin) - v.uv_px).squaredNorm();
      refined_sum += (*project_point(cam, v.cam_from_world->data(), ref) - v.uv_px).squaredNorm();
    }
  }
  // The refinement minimises exactly this sum, so it can only be lower.
  EXPECT_LT(refined_sum, linear_sum);
}

TEST(Triangulation, SmallAngleIsRejected) {
  const CameraModel cam = test_camera();
  const auto poses = ring(3, Eigen::Vector3d::Zero(), 450, 0.5);  // rays meet at 1 degree at most
  std::mt19937 rng(1);
  const auto views = views_for(cam, poses, Eigen::Vector3d(5, 5, 5), 0, rng);
  EXPECT_EQ(triangulate_point(cam, views, {}).status, TriangulationStatus::SmallAngle);
  TriangulationOptions lenient;
  lenient.min_angle_deg = 0.5;
  EXPECT_EQ(triangulate_point(cam, views, lenient).status, TriangulationStatus::Ok);
}

TEST(Triangulation, PointBehindCamerasIsRejected) {
  const CameraModel cam = test_camera();
  const auto poses = ring(4, Eigen::Vector3d::Zero(), 450, 15);
  // The cameras look towards the origin; X lies on the far side of them. Its algebraic projection
  // (x/z, y/z with z < 0) is a valid-looking image point, and the rays (as lines) meet at X.
  Eigen::Vector3d mean_centre = Eigen::Vector3d::Zero();
  for (const auto& p : poses) mean_centre += centre_of(p) / 4;
  const Eigen::Vector3d X = 2 * mean_centre;
  std::vector<PointView> views;
  for (const PoseBlock& p : poses) {
    PointView v;
    v.cam_from_world = &p;
    v.R = rotation_of(p);
    v.t = translation_of(p);
    v.centre_mm = centre_of(p);
    const Eigen::Vector3d xc = v.R * X + v.t;
    ASSERT_LT(xc.z(), 0);
    v.xy = xc.head<2>() / xc.z();
    distort_to_pixel(shape_of(cam), cam.params.data(), v.xy.x(), v.xy.y(), &v.uv_px.x(), &v.uv_px.y());
    views.push_back(v);
  }
  const auto linear = triangulate_linear(views);
  ASSERT_TRUE(linear.has_value());
  EXPECT_LT((*linear - X).norm(), 1e-6);
  EXPECT_EQ(triangulate_point(cam, views, {}).status, TriangulationStatus::BehindCamera);
}

TEST(Triangulation, OutlyingViewIsDropped) {
  const CameraModel cam = test_camera();
  const auto poses = ring(6, Eigen::Vector3d::Zero(), 450, 12);
  std::mt19937 rng(3);
  const Eigen::Vector3d X(10, -5, 15);
  auto views = views_for(cam, poses, X, 0.05, rng);
  views[4].uv_px += Eigen::Vector2d(15, -10);
  views[4].xy = *undistort(cam, views[4].uv_px);
  const PointEstimate e = triangulate_point(cam, views, {});
  ASSERT_EQ(e.status, TriangulationStatus::Ok);
  ASSERT_EQ(e.dropped.size(), 1u);
  EXPECT_EQ(e.dropped[0], 4u);
  EXPECT_LT((e.xyz_mm - X).norm(), 0.01);
}

TEST(Collinearity, DetectsPointsOnALine) {
  std::vector<Eigen::Vector3d> line, plane;
  for (int i = 0; i < 10; ++i) {
    line.push_back(Eigen::Vector3d(1, 2, 3) + i * Eigen::Vector3d(0.5, -1, 2));
    plane.push_back(Eigen::Vector3d(i % 3, i / 3, 0));
  }
  EXPECT_TRUE(collinear(line, 1e-3));
  EXPECT_FALSE(collinear(plane, 1e-3));
  EXPECT_TRUE(collinear(std::vector<Eigen::Vector3d>{{0, 0, 0}, {1, 1, 1}}, 1e-3));
}

}  // namespace
}  // namespace photomill::triangulate
