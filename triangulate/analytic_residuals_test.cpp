// The hand-written reprojection derivatives (analytic_residuals.hpp) against Ceres' automatic
// differentiation of the same residual (residuals.hpp), over rotations from exactly zero (the
// Taylor branch) to near pi, with and without skew; and the choice of form by camera model.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "triangulate/analytic_residuals.hpp"
#include "triangulate/residuals.hpp"

namespace photomill::triangulate {
namespace {

struct Evaluation {
  bool ok = false;
  std::array<double, 2> residual{};
  std::vector<std::vector<double>> jacobians;
};

Evaluation evaluate(const ceres::CostFunction& cost, const std::vector<const double*>& blocks) {
  Evaluation e;
  std::vector<double*> pointers;
  for (int size : cost.parameter_block_sizes()) e.jacobians.emplace_back(static_cast<std::size_t>(2 * size), 0.0);
  for (auto& j : e.jacobians) pointers.push_back(j.data());
  e.ok = cost.Evaluate(blocks.data(), e.residual.data(), pointers.data());
  return e;
}

// Agreement to 1e-9 of the block's largest derivative (the automatic one is exact to rounding).
void expect_same(const Evaluation& analytic, const Evaluation& automatic, const char* what) {
  ASSERT_EQ(analytic.ok, automatic.ok) << what;
  if (!analytic.ok) return;
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(analytic.residual[static_cast<std::size_t>(i)], automatic.residual[static_cast<std::size_t>(i)],
                1e-12 * (1.0 + std::abs(automatic.residual[static_cast<std::size_t>(i)])))
        << what;
  }
  ASSERT_EQ(analytic.jacobians.size(), automatic.jacobians.size());
  for (std::size_t b = 0; b < automatic.jacobians.size(); ++b) {
    double scale = 0;
    for (double v : automatic.jacobians[b]) scale = std::max(scale, std::abs(v));
    ASSERT_GT(scale, 0.0) << what << " block " << b;
    for (std::size_t k = 0; k < automatic.jacobians[b].size(); ++k) {
      EXPECT_NEAR(analytic.jacobians[b][k], automatic.jacobians[b][k], 1e-9 * scale)
          << what << " block " << b << " entry " << k;
    }
  }
}

CameraModel five_coefficient_camera(double skew) {
  CameraModel c;
  c.params[geometry::kFx] = 3012.5;
  c.params[geometry::kFy] = 2987.25;
  c.params[geometry::kCx] = 1003.1;
  c.params[geometry::kCy] = 748.6;
  c.params[geometry::kK1] = -0.21;
  c.params[geometry::kK2] = 0.13;
  c.params[geometry::kP1] = 1.2e-3;
  c.params[geometry::kP2] = -8e-4;
  c.params[geometry::kK3] = 0.031;
  c.skew = skew;
  c.width_px = 2000;
  c.height_px = 1500;
  c.distortion_count = 5;
  return c;
}

TEST(AnalyticReprojection, DerivativesMatchAutomaticDifferentiation) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const std::array<double, 7> angles = {0.0, 1e-12, 1e-6, 1e-4, 0.3, 1.7, 3.1};
  int cases = 0;
  for (double skew : {0.0, 0.7}) {
    const CameraModel camera = five_coefficient_camera(skew);
    const ModelShape shape = shape_of(camera);
    for (double angle : angles) {
      for (int trial = 0; trial < 20; ++trial) {
        Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
        axis.normalize();
        PoseBlock pose{};
        for (int i = 0; i < 3; ++i) pose[static_cast<std::size_t>(i)] = axis[i] * angle;
        // A point in front of the camera, up to ~0.6 of the focal length off the axis (corners).
        const Eigen::Vector3d in_camera(unit(rng) * 300, unit(rng) * 300, 500 + 300 * std::abs(unit(rng)));
        const Eigen::Vector3d t(unit(rng) * 50, unit(rng) * 50, unit(rng) * 50);
        // X = R^T (p - t), so that R X + t = in_camera.
        const PoseBlock inverse = {-pose[0], -pose[1], -pose[2], 0, 0, 0};
        const Eigen::Vector3d shifted = in_camera - t;
        Eigen::Vector3d X;
        ceres::AngleAxisRotatePoint(inverse.data(), shifted.data(), X.data());
        for (int i = 0; i < 3; ++i) pose[static_cast<std::size_t>(3 + i)] = t[i];
        const Eigen::Vector2d uv(900 + 200 * unit(rng), 700 + 200 * unit(rng));
        const double sigma_px = 0.25;

        const std::unique_ptr<ceres::CostFunction> fixed_analytic(ReprojectionError::create(&camera, uv, sigma_px));
        const std::unique_ptr<ceres::CostFunction> fixed_automatic(ReprojectionError::create_automatic(&camera, uv, sigma_px));
        ASSERT_NE(dynamic_cast<AnalyticReprojectionError*>(fixed_analytic.get()), nullptr);
        expect_same(evaluate(*fixed_analytic, {pose.data(), X.data()}),
                    evaluate(*fixed_automatic, {pose.data(), X.data()}), "intrinsics fixed");

        const std::unique_ptr<ceres::CostFunction> self_analytic(
            reprojection_error_with_intrinsics(geometry::kK4, shape, uv, sigma_px));
        const std::unique_ptr<ceres::CostFunction> self_automatic(
            reprojection_error_with_intrinsics(geometry::kK4, shape, uv, sigma_px, true));
        ASSERT_NE(dynamic_cast<AnalyticReprojectionErrorWithIntrinsics*>(self_analytic.get()), nullptr);
        expect_same(evaluate(*self_analytic, {pose.data(), X.data(), camera.params.data()}),
                    evaluate(*self_automatic, {pose.data(), X.data(), camera.params.data()}), "self-calibration");
        ++cases;
      }
    }
  }
  EXPECT_EQ(cases, 2 * 7 * 20);
}

// Residual only (no Jacobians asked), and a point behind the camera fails as the automatic form does.
TEST(AnalyticReprojection, ResidualOnlyAndPointsBehindTheCamera) {
  const CameraModel camera = five_coefficient_camera(0);
  const PoseBlock pose = {0.1, -0.2, 0.05, 3, -4, 20};
  const std::unique_ptr<ceres::CostFunction> cost(ReprojectionError::create(&camera, {1000, 750}, 1.0));
  const std::unique_ptr<ceres::CostFunction> automatic(ReprojectionError::create_automatic(&camera, {1000, 750}, 1.0));
  const Eigen::Vector3d front(10, -5, 400);
  const double* blocks[] = {pose.data(), front.data()};
  double r[2] = {0, 0}, r_automatic[2] = {0, 0};
  ASSERT_TRUE(cost->Evaluate(blocks, r, nullptr));
  ASSERT_TRUE(automatic->Evaluate(blocks, r_automatic, nullptr));
  EXPECT_DOUBLE_EQ(r[0], r_automatic[0]);
  EXPECT_DOUBLE_EQ(r[1], r_automatic[1]);

  const Eigen::Vector3d behind(10, -5, -400);
  const double* behind_blocks[] = {pose.data(), behind.data()};
  EXPECT_FALSE(cost->Evaluate(behind_blocks, r, nullptr));
  EXPECT_FALSE(automatic->Evaluate(behind_blocks, r_automatic, nullptr));
}

// Models with rational, thin-prism or tilt terms keep the automatic form; so does a block larger
// than the five coefficients'.
TEST(AnalyticReprojection, OtherModelsKeepAutomaticDifferentiation) {
  CameraModel rational = five_coefficient_camera(0);
  rational.distortion_count = 8;
  const std::unique_ptr<ceres::CostFunction> fixed(ReprojectionError::create(&rational, {1, 2}, 1.0));
  EXPECT_EQ(dynamic_cast<AnalyticReprojectionError*>(fixed.get()), nullptr);
  const std::unique_ptr<ceres::CostFunction> self(
      reprojection_error_with_intrinsics(geometry::kS1, shape_of(rational), {1, 2}, 1.0));
  EXPECT_EQ(dynamic_cast<AnalyticReprojectionErrorWithIntrinsics*>(self.get()), nullptr);
  const std::unique_ptr<ceres::CostFunction> larger_block(
      reprojection_error_with_intrinsics(geometry::kS1, shape_of(five_coefficient_camera(0)), {1, 2}, 1.0));
  EXPECT_EQ(dynamic_cast<AnalyticReprojectionErrorWithIntrinsics*>(larger_block.get()), nullptr);
  EXPECT_FALSE(analytic_projection_applies(geometry::shape_of_count(14)));
  EXPECT_TRUE(analytic_projection_applies(geometry::shape_of_count(4)));
}

}  // namespace
}  // namespace photomill::triangulate
