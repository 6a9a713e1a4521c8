// The data outline in (u,v): convex hull for sparse data, occupancy-grid concave outline for
// dense data with notches.
#include "fitsurf/outline.hpp"

#include <gtest/gtest.h>

#include "fitsurf/test_shapes.hpp"

namespace photomill::fitsurf {
namespace {

TEST(ConvexHull, OfAGridIsItsCornersCounterClockwise) {
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i <= 10; ++i) {
    for (int j = 0; j <= 5; ++j) pts.emplace_back(i, j);
  }
  const auto hull = convex_hull(pts);
  ASSERT_EQ(hull.size(), 4u);
  EXPECT_DOUBLE_EQ(signed_area(hull), 50.0);
  EXPECT_TRUE(is_simple_polygon(hull));
}

TEST(OutlinePolygon, InsideTestAndSimplicity) {
  const std::vector<Eigen::Vector2d> square{{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  EXPECT_TRUE(point_in_polygon(square, {0.5, 0.5}));
  EXPECT_FALSE(point_in_polygon(square, {1.5, 0.5}));
  const std::vector<Eigen::Vector2d> bow{{0, 0}, {1, 1}, {1, 0}, {0, 1}};
  EXPECT_FALSE(is_simple_polygon(bow));
  EXPECT_TRUE(is_simple_polygon(square));
}

// Points uniform over an L: [0,1]^2 minus the corner square [0.5,1] x [0.5,1], in a 150 x 100 mm
// parameter rectangle.
std::vector<Eigen::Vector2d> l_shape(std::size_t n, std::uint64_t seed) {
  test::Rng rng(seed);
  std::vector<Eigen::Vector2d> uv;
  while (uv.size() < n) {
    const Eigen::Vector2d p(rng.uniform(), rng.uniform());
    if (!(p.x() > 0.5 && p.y() > 0.5)) uv.push_back(p);
  }
  return uv;
}

void expect_valid(const std::vector<Eigen::Vector2d>& poly) {
  ASSERT_GE(poly.size(), 3u);
  EXPECT_GT(signed_area(poly), 0.0) << "counter-clockwise";
  EXPECT_TRUE(is_simple_polygon(poly));
  for (const auto& p : poly) {
    EXPECT_GE(p.x(), 0.0);
    EXPECT_LE(p.x(), 1.0);
    EXPECT_GE(p.y(), 0.0);
    EXPECT_LE(p.y(), 1.0);
  }
}

class ConcaveOutline : public ::testing::TestWithParam<std::size_t> {};

TEST_P(ConcaveOutline, FollowsTheNotchOfAnLShape) {
  const auto uv = l_shape(GetParam(), 3);
  OutlineOptions o;
  o.method = OutlineMethod::Concave;
  const auto poly = data_outline(uv, {}, 150, 100, o);
  expect_valid(poly);
  EXPECT_FALSE(point_in_polygon(poly, {0.8, 0.8})) << "the notch is outside";
  EXPECT_TRUE(point_in_polygon(poly, {0.25, 0.25}));
  EXPECT_TRUE(point_in_polygon(poly, {0.9, 0.2}));
  EXPECT_TRUE(point_in_polygon(poly, {0.2, 0.9}));
  // Its area is the L's (0.75) up to a band about one cell wide along the border.
  const double cell_u = 3 * std::sqrt(0.75 * 150 * 100 / static_cast<double>(uv.size())) / 100;
  EXPECT_NEAR(signed_area(poly), 0.75, 4 * cell_u);
  std::size_t outside = 0;
  for (const auto& p : uv) outside += !point_in_polygon(poly, p);
  EXPECT_LT(static_cast<double>(outside), 0.01 * static_cast<double>(uv.size()));
}

INSTANTIATE_TEST_SUITE_P(Densities, ConcaveOutline, ::testing::Values(3000, 30000, 300000));

TEST(ConvexOutline, OfSparsePointsLiesInsideTheirHull) {
  const auto uv = l_shape(150, 4);
  OutlineOptions o;  // auto: convex below 2000 points
  const auto poly = data_outline(uv, {}, 150, 100, o);
  expect_valid(poly);
  const auto hull = convex_hull(uv);
  EXPECT_LE(signed_area(poly), signed_area(hull) + 1e-15);
  EXPECT_GT(signed_area(poly), 0.95 * signed_area(hull));
  for (const auto& p : poly) {
    double nearest = 1;
    for (const auto& q : uv) nearest = std::min(nearest, (p - q).norm());
    EXPECT_LT(nearest, 1e-12) << "vertices are data points";
  }
}

TEST(DataOutline, ZeroWeightsAreLeftOutAndNoneGivesNothing) {
  auto uv = l_shape(3000, 5);
  std::vector<double> w(uv.size(), 1.0);
  uv.emplace_back(0.99, 0.99);  // an outlier in the notch
  w.push_back(0.0);
  OutlineOptions o;
  o.method = OutlineMethod::Concave;
  EXPECT_FALSE(point_in_polygon(data_outline(uv, w, 150, 100, o), {0.8, 0.8}));
  o.method = OutlineMethod::None;
  EXPECT_TRUE(data_outline(uv, w, 150, 100, o).empty());
}

}  // namespace
}  // namespace photomill::fitsurf
