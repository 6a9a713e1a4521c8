// Z-map verification: the closed-form swept-ball bottom against brute force, and the simulation
// against cusps and gouges whose size is known in closed form on a plane.
#include "toolpath/zmap.hpp"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Brute force: the lowest of the sphere bottoms at 20001 positions along the move.
double brute_bottom(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double R, const Eigen::Vector2d& xy) {
  double best = kInf;
  constexpr int kN = 20000;
  for (int k = 0; k <= kN; ++k) {
    const Eigen::Vector3d c = a + (b - a) * (static_cast<double>(k) / kN);
    const double d2 = (c.head<2>() - xy).squaredNorm();
    if (d2 < R * R) best = std::min(best, c.z() - std::sqrt(R * R - d2));
  }
  return best;
}

struct SweepCase {
  const char* name;
  Eigen::Vector3d a, b;
};

void PrintTo(const SweepCase& c, std::ostream* os) { *os << c.name; }

class SweptBall : public ::testing::TestWithParam<SweepCase> {};

TEST_P(SweptBall, MatchesBruteForce) {
  const SweepCase& c = GetParam();
  const double R = 3;
  std::mt19937 rng(7);
  const Eigen::Vector2d lo = c.a.head<2>().cwiseMin(c.b.head<2>()), hi = c.a.head<2>().cwiseMax(c.b.head<2>());
  std::uniform_real_distribution<double> ux(lo.x() - R - 0.5, hi.x() + R + 0.5), uy(lo.y() - R - 0.5, hi.y() + R + 0.5);
  int hits = 0;
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector2d xy(ux(rng), uy(rng));
    const double exact = swept_ball_bottom(c.a, c.b, R, xy);
    const double brute = brute_bottom(c.a, c.b, R, xy);
    if (!std::isfinite(brute)) {
      EXPECT_FALSE(std::isfinite(exact)) << "at " << xy.transpose();
      continue;
    }
    ++hits;
    // The closed form is the true minimum: never above the sampled one, and close to it (the
    // sampling error of 20000 steps is below 1e-6 mm here).
    EXPECT_LE(exact, brute + 1e-12) << "at " << xy.transpose();
    EXPECT_NEAR(exact, brute, 2e-6) << "at " << xy.transpose();
  }
  EXPECT_GT(hits, 50);
}

INSTANTIATE_TEST_SUITE_P(
    Moves, SweptBall,
    ::testing::Values(SweepCase{"level", {0, 0, 10}, {10, 0, 10}}, SweepCase{"rising", {0, 0, 10}, {10, 1, 14}},
                      SweepCase{"falling", {0, 0, 14}, {10, -1, 9}}, SweepCase{"steep", {0, 0, 0}, {1, 0, 8}},
                      SweepCase{"vertical", {2, 1, 0}, {2, 1, 8}}, SweepCase{"point", {3, 0, 5}, {3, 0, 5}}),
    [](const auto& info) { return std::string(info.param.name); });

// A horizontal plane z = 0 over [0, 60] x [0, 30].
BSplineSurface plane() { return test::cylinder_surface(0, true); }

ClData passes_on_plane(const std::vector<double>& ys, const std::vector<double>& tip_z) {
  // Zig-zag: along x, across at the end, back along x.
  ClData cl;
  for (std::size_t k = 0; k < ys.size(); ++k) {
    const double xa = k % 2 == 0 ? 0 : 60, xb = 60 - xa;
    cl.moves.push_back({ClMove::Kind::Feed, {xa, ys[k], tip_z[k]}, std::nullopt, 1000});
    cl.moves.push_back({ClMove::Kind::Feed, {xb, ys[k], tip_z[k]}, std::nullopt, 1000});
  }
  return cl;
}

TEST(Zmap, CuspBetweenTwoPassesOnAPlaneIsTheCircleFormula) {
  // Tilted plane z = 20 + 0.3 y: passes along x, tips on the plane's offset so the balls touch it.
  // Between two passes g apart (measured along the surface) the cusp is R - sqrt(R^2 - (g/2)^2).
  const double R = 3, g = 0.8, slope = 0.3;
  const double c = std::sqrt(1 + slope * slope);  // along-surface length per unit y
  const double y0 = 12, y1 = y0 + g / c;
  // Tip for a ball touching the plane at y: centre = p + R n, n = (0, -slope, 1) / c.
  const auto tip = [&](double y) {
    const Eigen::Vector3d p(0, y, 20 + slope * y), n = Eigen::Vector3d(0, -slope, 1) / c;
    return (p + R * n - Eigen::Vector3d(0, 0, R)).eval();
  };
  const ClData cl = passes_on_plane({tip(y0).y(), tip(y1).y()}, {tip(y0).z(), tip(y1).z()});
  ZmapOptions o;
  o.cell_mm = 0.05;
  o.tool_radius_mm = R;
  const double yc = 0.5 * (y0 + y1);  // the cusp lies midway between the contact points
  o.window_min = Eigen::Vector2d(10, yc - 0.2);
  o.window_max = Eigen::Vector2d(50, yc + 0.2);
  const ZmapResult z = simulate_zmap(test::cylinder_surface(0, true), cl, o);
  const double cusp = R - std::sqrt(R * R - 0.25 * g * g);
  EXPECT_EQ(z.unmachined, 0u);
  EXPECT_LE(z.grid_max_scallop_mm, cusp + 1e-9);
  // Refinement between the nodes finds the ridge itself.
  EXPECT_NEAR(z.max_scallop_mm, cusp, 2e-6);
  EXPECT_LT(z.max_gouge_mm, 1e-9);
}

TEST(Zmap, DeepenedPassShowsItsGouge) {
  // Three passes on the plane z = 20 + 0.3 y; the middle one 0.02 mm too low (vertically).
  const double R = 3, slope = 0.3, c = std::sqrt(1 + slope * slope), dip = 0.02;
  std::vector<double> ys, zs;
  for (int k = 0; k < 3; ++k) {
    const double y = 10 + 0.4 * k;
    const Eigen::Vector3d p(0, y, 20 + slope * y), n = Eigen::Vector3d(0, -slope, 1) / c;
    const Eigen::Vector3d t = p + R * n - Eigen::Vector3d(0, 0, R);
    ys.push_back(t.y());
    zs.push_back(t.z() - (k == 1 ? dip : 0.0));
  }
  ZmapOptions o;
  o.cell_mm = 0.05;
  o.tool_radius_mm = R;
  o.window_min = Eigen::Vector2d(10, 9);
  o.window_max = Eigen::Vector2d(50, 11.5);
  const ZmapResult z = simulate_zmap(test::cylinder_surface(0, true), passes_on_plane(ys, zs), o);
  // A vertical dip d on a plane of normal n is a normal depth d n_z.
  EXPECT_NEAR(z.max_gouge_mm, dip / c, 1e-6);
  EXPECT_NEAR(z.max_gouge_at.y(), 10.4, 0.05);  // under the middle pass's contact line
}

TEST(Zmap, NodesNoBallReachesAreCounted) {
  ZmapOptions o;
  o.cell_mm = 0.25;
  // One pass at y = 5 on the 60 x 30 plane: everything beyond 3 mm of it stays unmachined.
  const ZmapResult z = simulate_zmap(plane(), passes_on_plane({5}, {20 + 0.3 * 5}), o);
  EXPECT_GT(z.nodes, 0u);
  EXPECT_GT(z.unmachined, z.nodes / 2);
  EXPECT_LT(z.unmachined, z.nodes);
}

TEST(Zmap, BadOptionsAndWindowsAreRejected) {
  ZmapOptions o;
  o.cell_mm = 0;
  EXPECT_THROW(simulate_zmap(plane(), passes_on_plane({5}, {21.5}), o), UsageError);
  o.cell_mm = 0.5;
  o.window_min = Eigen::Vector2d(100, 100);
  o.window_max = Eigen::Vector2d(120, 120);
  EXPECT_THROW(simulate_zmap(plane(), passes_on_plane({5}, {21.5}), o), GeometryError);
}

}  // namespace
}  // namespace photomill::toolpath
