// B-spline evaluation against closed forms: partition of unity, polynomial reproduction,
// an exact rational circle, and derivatives against central differences.
#include "formats/bspline.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace photomill {
namespace {

BSplineSurface wavy_surface(bool rational) {
  BSplineSurface s;
  s.degree_u = 3;
  s.degree_v = 2;
  s.num_poles_u = 7;
  s.num_poles_v = 5;
  s.knots_u = {0, 0, 0, 0, 0.2, 0.5, 0.5, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0.3, 0.6, 1, 1, 1};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> z(-5, 5), w(0.5, 2.0);
  for (int i = 0; i < 7; ++i) {
    for (int j = 0; j < 5; ++j) s.poles_mm.emplace_back(20.0 * i, 15.0 * j + 2 * i, z(rng));
  }
  if (rational) {
    for (int k = 0; k < 35; ++k) s.weights.push_back(w(rng));
  }
  return s;
}

TEST(FindSpan, CoversTheDomainIncludingItsEnds) {
  const std::vector<double> U{0, 0, 0, 0, 0.2, 0.5, 0.5, 1, 1, 1, 1};
  const int n = 6, p = 3;
  EXPECT_EQ(find_span(n, p, 0.0, U), 3);
  EXPECT_EQ(find_span(n, p, 0.1, U), 3);
  EXPECT_EQ(find_span(n, p, 0.2, U), 4);
  EXPECT_EQ(find_span(n, p, 0.5, U), 6);
  EXPECT_EQ(find_span(n, p, 0.99, U), 6);
  EXPECT_EQ(find_span(n, p, 1.0, U), 6);
  EXPECT_EQ(find_span(n, p, 7.0, U), 6);
  EXPECT_EQ(find_span(n, p, -1.0, U), 3);
}

TEST(BasisFuns, PartitionOfUnityAndDerivativesSumToZero) {
  const std::vector<double> U{0, 0, 0, 0, 0.2, 0.5, 0.5, 1, 1, 1, 1};
  for (double u = 0; u <= 1.0; u += 0.01) {
    const int span = find_span(6, 3, u, U);
    double ders[3 * 4];
    ders_basis_funs(span, u, 3, 2, U, ders);
    double N[4];
    basis_funs(span, u, 3, U, N);
    double s0 = 0, s1 = 0, s2 = 0;
    for (int j = 0; j < 4; ++j) {
      EXPECT_NEAR(ders[j], N[j], 1e-15);
      EXPECT_GE(N[j], -1e-15);
      s0 += ders[j];
      s1 += ders[4 + j];
      s2 += ders[8 + j];
    }
    EXPECT_NEAR(s0, 1.0, 1e-14);
    EXPECT_NEAR(s1, 0.0, 1e-10);
    EXPECT_NEAR(s2, 0.0, 1e-8);
  }
}

TEST(SurfacePoint, ReproducesABicubicPolynomialExactly) {
  // Single-span Bezier patch whose poles are the Bernstein coefficients of z = x^3 (x = 3u):
  // with poles at x_i = i on [0, 3], z-coefficients of t^3 are (0, 0, 0, 1) times 27.
  BSplineSurface s;
  s.num_poles_u = s.num_poles_v = 4;
  s.knots_u = s.knots_v = clamped_uniform_knots(4, 3);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) s.poles_mm.emplace_back(i, j, i == 3 ? 27.0 : 0.0);
  }
  for (double u : {0.0, 0.25, 0.6, 1.0}) {
    for (double v : {0.0, 0.5, 1.0}) {
      const Eigen::Vector3d p = surface_point(s, u, v);
      EXPECT_NEAR(p.x(), 3 * u, 1e-13);
      EXPECT_NEAR(p.y(), 3 * v, 1e-13);
      EXPECT_NEAR(p.z(), 27 * u * u * u, 1e-12);
    }
  }
}

TEST(SurfacePoint, RationalQuarterCylinderIsExact) {
  // Quarter circle of radius 50 in x-z (degree 2, weights 1, sqrt(2)/2, 1), extruded along y.
  BSplineSurface s;
  s.degree_u = 2;
  s.degree_v = 1;
  s.num_poles_u = 3;
  s.num_poles_v = 2;
  s.knots_u = {0, 0, 0, 1, 1, 1};
  s.knots_v = {0, 0, 1, 1};
  const double R = 50;
  for (const Eigen::Vector2d& xz : {Eigen::Vector2d(R, 0), Eigen::Vector2d(R, R), Eigen::Vector2d(0, R)}) {
    for (double y : {0.0, 100.0}) s.poles_mm.emplace_back(xz.x(), y, xz.y());
  }
  s.weights = {1, 1, std::sqrt(0.5), std::sqrt(0.5), 1, 1};
  for (double u = 0; u <= 1.0; u += 0.05) {
    const auto d = surface_derivatives(s, u, 0.3);
    EXPECT_NEAR(std::hypot(d.p.x(), d.p.z()), R, 1e-11);
    EXPECT_NEAR(d.p.y(), 30.0, 1e-11);
    // The normal of a cylinder is radial.
    const Eigen::Vector3d radial = Eigen::Vector3d(d.p.x(), 0, d.p.z()).normalized();
    EXPECT_NEAR(std::abs(d.normal().dot(radial)), 1.0, 1e-12);
    EXPECT_NEAR((surface_point(s, u, 0.3) - d.p).norm(), 0.0, 1e-12);
  }
}

class DerivativesTest : public ::testing::TestWithParam<bool> {};

TEST_P(DerivativesTest, MatchCentralDifferences) {
  const BSplineSurface s = wavy_surface(GetParam());
  const double h = 1e-5;
  // Stay off the knot lines, where second derivatives jump.
  for (double u : {0.1, 0.33, 0.72, 0.9}) {
    for (double v : {0.15, 0.45, 0.8}) {
      const auto d = surface_derivatives(s, u, v);
      const auto P = [&](double a, double b) { return surface_point(s, a, b); };
      EXPECT_LT((d.p - P(u, v)).norm(), 1e-12);
      EXPECT_LT((d.su - (P(u + h, v) - P(u - h, v)) / (2 * h)).norm(), 1e-5 * (1 + d.su.norm()));
      EXPECT_LT((d.sv - (P(u, v + h) - P(u, v - h)) / (2 * h)).norm(), 1e-5 * (1 + d.sv.norm()));
      const double g = 1e-4;
      EXPECT_LT((d.suu - (P(u + g, v) - 2 * P(u, v) + P(u - g, v)) / (g * g)).norm(), 1e-3 * (1 + d.suu.norm()));
      EXPECT_LT((d.svv - (P(u, v + g) - 2 * P(u, v) + P(u, v - g)) / (g * g)).norm(), 1e-3 * (1 + d.svv.norm()));
      EXPECT_LT((d.suv - (P(u + g, v + g) - P(u + g, v - g) - P(u - g, v + g) + P(u - g, v - g)) / (4 * g * g)).norm(),
                1e-3 * (1 + d.suv.norm()));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(PolynomialAndRational, DerivativesTest, ::testing::Bool());

TEST(ClampedUniformKnots, HaveTheRightShape) {
  EXPECT_EQ(clamped_uniform_knots(6, 3), (std::vector<double>{0, 0, 0, 0, 1.0 / 3, 2.0 / 3, 1, 1, 1, 1}));
  EXPECT_EQ(clamped_uniform_knots(4, 3, -1, 1), (std::vector<double>{-1, -1, -1, -1, 1, 1, 1, 1}));
}

}  // namespace
}  // namespace photomill
