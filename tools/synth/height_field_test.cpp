// The height field against finite differences, its bounds against sampling, the shapes' sizes.
#include <array>
#include <cmath>

#include <gtest/gtest.h>

#include "tools/synth/height_field.hpp"
#include "tools/synth/random.hpp"

namespace photomill::synth {
namespace {

class Shape : public ::testing::TestWithParam<std::string> {};

TEST_P(Shape, GradientMatchesCentralDifferences) {
  const HeightField f = make_shape(GetParam(), 150, 100, 30, 20);
  Rng rng(3);
  const double h = 1e-5;
  for (int k = 0; k < 2000; ++k) {
    const double x = rng.uniform(-80, 80), y = rng.uniform(-55, 55);
    const Eigen::Vector2d g = f.gradient(x, y);
    const double gx = (f.height_mm(x + h, y) - f.height_mm(x - h, y)) / (2 * h);
    const double gy = (f.height_mm(x, y + h) - f.height_mm(x, y - h)) / (2 * h);
    EXPECT_NEAR(g.x(), gx, 1e-6) << x << ", " << y;
    EXPECT_NEAR(g.y(), gy, 1e-6) << x << ", " << y;
    // The normal is the unit upward normal, perpendicular to both tangents (1, 0, h_x), (0, 1, h_y).
    const Eigen::Vector3d n = f.normal(x, y);
    EXPECT_NEAR(n.norm(), 1, 1e-12);
    EXPECT_GT(n.z(), 0);
    EXPECT_NEAR(n.dot(Eigen::Vector3d(1, 0, gx)), 0, 1e-6);
    EXPECT_NEAR(n.dot(Eigen::Vector3d(0, 1, gy)), 0, 1e-6);
  }
}

TEST_P(Shape, BoundsHoldOnADenseSample) {
  const HeightField f = make_shape(GetParam(), 150, 100, 30, 20);
  double max_slope = 0, max_curv = 0, max_h = 0;
  const double d = 1e-4;
  for (double x = -76; x <= 76; x += 0.5) {
    for (double y = -51; y <= 51; y += 0.5) {
      max_h = std::max(max_h, std::abs(f.height_mm(x, y)));
      max_slope = std::max(max_slope, f.gradient(x, y).norm());
      // Hessian by differences of the exact gradient; its spectral norm.
      Eigen::Matrix2d H;
      H.col(0) = (f.gradient(x + d, y) - f.gradient(x - d, y)) / (2 * d);
      H.col(1) = (f.gradient(x, y + d) - f.gradient(x, y - d)) / (2 * d);
      const Eigen::Matrix2d S = 0.5 * (H + H.transpose());
      // Largest |eigenvalue| of a symmetric 2x2: |mean| + sqrt(((a - c)/2)^2 + b^2).
      const double mean = 0.5 * (S(0, 0) + S(1, 1));
      const double rad = std::hypot(0.5 * (S(0, 0) - S(1, 1)), S(0, 1));
      max_curv = std::max(max_curv, std::abs(mean) + rad);
    }
  }
  EXPECT_GE(f.slope_bound(), max_slope);
  EXPECT_GE(f.curvature_bound(), max_curv);
  EXPECT_GE(f.height_bound(), max_h);
  // Not uselessly loose either (the ray caster's speed depends on them).
  EXPECT_LT(f.slope_bound(), 6 * max_slope);
  EXPECT_LT(f.curvature_bound(), 20 * max_curv);
  // The shape is as high as asked and meets the plate at the rectangle's edge.
  EXPECT_NEAR(max_h, 30, 0.05);
  EXPECT_EQ(f.height_mm(-75, 0), 0);
  EXPECT_EQ(f.height_mm(0, 50), 0);
  EXPECT_EQ(f.height_mm(100, 0), 0);
  EXPECT_LT(std::abs(f.height_mm(-74.9, 0)), 1e-4);
}

TEST_P(Shape, IsNotALowDegreePolynomial) {
  // A cubic in x along a line would have a constant third difference; these shapes do not.
  const HeightField f = make_shape(GetParam(), 150, 100, 30, 20);
  const double s = 5;
  std::vector<double> third;
  for (double x = -40; x <= 25; x += s) {
    const double y = 3;
    third.push_back(f.height_mm(x + 3 * s, y) - 3 * f.height_mm(x + 2 * s, y) + 3 * f.height_mm(x + s, y) -
                    f.height_mm(x, y));
  }
  const auto [lo, hi] = std::minmax_element(third.begin(), third.end());
  EXPECT_GT(*hi - *lo, 0.05);
}

// A walled part (edge blend 0): its top is the shape itself up to the rectangle's edge, where
// vertical walls drop to the plate; the bounds hold for the top.
TEST_P(Shape, WalledPartStandsOnWallsAboveThePlate) {
  const HeightField f = make_shape(GetParam(), 150, 100, 30, 0);
  ASSERT_TRUE(f.walled());
  double max_slope = 0, max_h = 0, min_h = INFINITY;
  Rng rng(5);
  const double h = 1e-5;
  for (double x = -75; x <= 75; x += 0.5) {
    for (double y = -50; y <= 50; y += 0.5) {
      max_h = std::max(max_h, f.height_mm(x, y));
      min_h = std::min(min_h, f.height_mm(x, y));
      max_slope = std::max(max_slope, f.gradient(x, y).norm());
    }
  }
  EXPECT_NEAR(max_h, 30, 0.05);
  EXPECT_GT(min_h, 0);
  EXPECT_GE(f.slope_bound(), max_slope);
  EXPECT_LT(f.slope_bound(), 6 * max_slope);
  for (int k = 0; k < 500; ++k) {
    const double x = rng.uniform(-74.9, 74.9), y = rng.uniform(-49.9, 49.9);
    const Eigen::Vector2d g = f.gradient(x, y);
    EXPECT_NEAR(g.x(), (f.height_mm(x + h, y) - f.height_mm(x - h, y)) / (2 * h), 1e-6);
    EXPECT_NEAR(g.y(), (f.height_mm(x, y + h) - f.height_mm(x, y - h)) / (2 * h), 1e-6);
  }
  // The wall: the rim's height on the edge, the plate just outside it.
  for (const auto& [x, y, ox, oy] : {std::array<double, 4>{-75, 12, -75.001, 12}, {75, -3, 75.001, -3},
                                     {20, 50, 20, 50.001}, {-33, -50, -33, -50.001}}) {
    EXPECT_GT(f.height_mm(x, y), 0) << x << ", " << y;
    EXPECT_EQ(f.wall_top_mm(x, y), f.height_mm(x, y));
    EXPECT_EQ(f.wall_top_mm(ox, oy), f.height_mm(x, y));
    EXPECT_EQ(f.height_mm(ox, oy), 0);
  }
}

INSTANTIATE_TEST_SUITE_P(All, Shape, ::testing::ValuesIn(shape_names()));

TEST(HeightField, ValidateRejectsBadFields) {
  HeightField f = make_shape("bumps", 150, 100, 30, 20);
  EXPECT_NO_THROW(validate(f));
  HeightField wide = f;
  wide.edge_blend_mm = 60;
  EXPECT_THROW(validate(wide), std::invalid_argument);
  HeightField empty = f;
  empty.x_max_mm = empty.x_min_mm;
  EXPECT_THROW(validate(empty), std::invalid_argument);
  HeightField bad_term = f;
  bad_term.terms[0].s1_mm = 0;
  EXPECT_THROW(validate(bad_term), std::invalid_argument);
  HeightField nan = f;
  nan.base_mm = std::nan("");
  EXPECT_THROW(validate(nan), std::invalid_argument);
  EXPECT_THROW(make_shape("cube", 150, 100, 30, 20), std::invalid_argument);
  HeightField negative = f;
  negative.edge_blend_mm = -1;
  EXPECT_THROW(validate(negative), std::invalid_argument);
}

}  // namespace
}  // namespace photomill::synth
