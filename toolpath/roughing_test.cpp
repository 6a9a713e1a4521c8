// Roughing (roughing.hpp) and the general cutter sweep of the stock z-map (zmap.hpp): the swept
// flat and bull-nose bottoms against brute force; a roughed stock that never cuts into the
// allowance, leaves at most a step-down of stairs, never plunges or rapids into material, and
// mills in the direction asked.
#include "toolpath/roughing.hpp"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Brute force: the lowest of the cutter's bottoms at 20001 positions along the move, each the
// profile over the xy line's distance from the axis.
double brute_bottom(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Cutter& c, const Eigen::Vector2d& xy) {
  double best = kInf;
  constexpr int kN = 20000;
  const double R = c.radius_mm, rc = c.corner_radius_mm;
  for (int k = 0; k <= kN; ++k) {
    const Eigen::Vector3d t = a + (b - a) * (static_cast<double>(k) / kN);
    const double rho = (t.head<2>() - xy).norm();
    if (rho > R) continue;
    const double over = rho - (R - rc);
    const double lift = over <= 0 ? 0.0 : rc - std::sqrt(std::max(0.0, rc * rc - over * over));
    best = std::min(best, t.z() + lift);
  }
  return best;
}

TEST(SweptCutter, FlatBullNoseAndBallMatchBruteForce) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-10, 10), h(-4, 4);
  for (const Cutter c : {Cutter{3, 0}, Cutter{3, 1}, Cutter{3, 3}}) {
    int hits = 0;
    for (int m = 0; m < 30; ++m) {
      const Eigen::Vector3d a(u(rng), u(rng), h(rng));
      const Eigen::Vector3d b = m % 5 == 0 ? Eigen::Vector3d(a.x(), a.y(), h(rng)) : Eigen::Vector3d(u(rng), u(rng), h(rng));
      for (int k = 0; k < 20; ++k) {
        const Eigen::Vector2d xy = a.head<2>() + (b.head<2>() - a.head<2>()) * (k / 19.0) + Eigen::Vector2d(h(rng), h(rng));
        const double exact = swept_cutter_bottom(a, b, c, xy), brute = brute_bottom(a, b, c, xy);
        if (!std::isfinite(brute)) {
          EXPECT_FALSE(std::isfinite(exact)) << "r_c " << c.corner_radius_mm << " at " << xy.transpose();
          continue;
        }
        ++hits;
        EXPECT_LE(exact, brute + 1e-9) << "r_c " << c.corner_radius_mm << " at " << xy.transpose();
        EXPECT_NEAR(exact, brute, 2e-3) << "r_c " << c.corner_radius_mm << " at " << xy.transpose();
      }
    }
    EXPECT_GT(hits, 100);
  }
}

// A 60 x 60 mm plate at z = 0 with a dome in its middle (Gaussian, 12 mm high, sigma 8 mm).
BSplineSurface dome_surface() {
  return test::interpolate_height_field([](double x, double y) { return 12 * std::exp(-(x * x + y * y) / (2 * 64.0)); }, -30,
                                        30, -30, 30, 41, 41);
}

RoughingOptions quick_options() {
  RoughingOptions o;
  o.tool_diameter_mm = 6;
  o.step_down_mm = 2;
  o.allowance_mm = 0.5;
  o.cell_mm = 0.25;
  return o;
}

// Replays the CL data on a z-map of the stock: every move that descends more steeply than the
// ramp angle, and every rapid, must meet no material (above its lowest point, within the tool's
// reach). Returns the number of offending moves; `first` describes the first.
std::size_t plunges_into_material(const ClData& cl, const StockBox& stock, const Cutter& cutter, double ramp_angle_deg,
                                  std::string& first) {
  HeightGrid m;
  m.lo = stock.min_mm.head<2>() - Eigen::Vector2d::Constant(cutter.radius_mm + 1);
  m.cell_mm = 0.25;
  m.nx = static_cast<long>((stock.max_mm.x() - stock.min_mm.x() + 2 * cutter.radius_mm + 2) / m.cell_mm) + 1;
  m.ny = static_cast<long>((stock.max_mm.y() - stock.min_mm.y() + 2 * cutter.radius_mm + 2) / m.cell_mm) + 1;
  m.z.assign(static_cast<std::size_t>(m.nx * m.ny), -kInf);
  for (long j = 0; j < m.ny; ++j) {
    for (long i = 0; i < m.nx; ++i) {
      const Eigen::Vector2d p = m.node_xy(i, j);
      if (p.x() >= stock.min_mm.x() && p.x() <= stock.max_mm.x() && p.y() >= stock.min_mm.y() && p.y() <= stock.max_mm.y()) {
        m.z[static_cast<std::size_t>(j * m.nx + i)] = stock.max_mm.z();
      }
    }
  }
  const double slope = std::tan(ramp_angle_deg * 3.14159265358979 / 180) * 1.0001;
  std::size_t bad = 0;
  for (std::size_t k = 1; k < cl.moves.size(); ++k) {
    const Eigen::Vector3d& a = cl.moves[k - 1].tip_mm;
    const Eigen::Vector3d& b = cl.moves[k].tip_mm;
    const double run = (b.head<2>() - a.head<2>()).norm(), drop = a.z() - b.z();
    const bool rapid = cl.moves[k].kind == ClMove::Kind::Rapid;
    if (rapid || drop > slope * run + 1e-9) {
      // Would this move remove material? Sweep it on a copy of the nodes it reaches.
      for (long j = 0; j < m.ny; ++j) {
        for (long i = 0; i < m.nx; ++i) {
          const double top = m.z[static_cast<std::size_t>(j * m.nx + i)];
          if (!std::isfinite(top)) continue;
          const double z = swept_cutter_bottom(a, b, cutter, m.node_xy(i, j));
          if (z < top - 1e-6) {
            if (bad++ == 0) {
              first = std::string(rapid ? "rapid" : "feed") + " move " + std::to_string(k) + " to (" + std::to_string(b.x()) + ", " +
                      std::to_string(b.y()) + ", " + std::to_string(b.z()) + ") meets material at z " + std::to_string(top);
            }
            i = m.nx, j = m.ny;
          }
        }
      }
    }
    ClData one;
    one.moves = {cl.moves[k - 1], cl.moves[k]};
    cut_material(m, one, cutter, 1);
  }
  return bad;
}

TEST(Roughing, DomeIsClearedToTheAllowanceWithoutCuttingIntoIt) {
  const BSplineSurface dome = dome_surface();
  const RoughingOptions o = quick_options();
  const RoughingResult r = generate_roughing(dome, o);
  const RoughingStats& s = r.stats;
  // Default stock: the surface's box grown by 2 mm, its top 2 mm above the dome.
  EXPECT_NEAR(s.stock.min_mm.x(), -32, 0.6);
  EXPECT_NEAR(s.stock.max_mm.z(), 14, 0.05);
  EXPECT_GE(s.levels, 6u);
  // The last level: the plate plus the allowance, within the flat tolerance (0.1 mm).
  EXPECT_GE(s.bottom_level_mm, 0.5);
  EXPECT_LE(s.bottom_level_mm, 0.5 + o.flat_tol_mm + 1e-9);
  EXPECT_EQ(s.skipped_loops, 0u);
  EXPECT_GT(s.ramps + s.helices, 0u);
  const StockCheck c = check_stock(dome, s.stock, {{&r.cl, {3, 0}}}, o.allowance_mm, 0.1, 0);
  EXPECT_GT(c.nodes, 300000u);
  // The grid is conservative (each node the highest of its 3 x 3 neighbourhood): no cut below
  // surface + allowance beyond what sampling between 0.25 mm nodes allows.
  EXPECT_LT(c.max_into_allowance_mm, 0.01) << "at " << c.into_allowance_at.transpose();
  EXPECT_EQ(c.max_gouge_mm, 0.0);
  // Stairs: at most a step-down above surface + allowance, plus the slope (at most 0.91 on this
  // dome) times how far the grid keeps the tool from its limit: the 3 x 3 neighbourhood
  // (sqrt(2) cells), the contours' first offset d0 (one cell + the simplification, half a cell)
  // and the simplification itself: 0.91 x (0.354 + 0.375 + 0.125) = 0.78 mm.
  EXPECT_LT(c.max_left_mm, o.step_down_mm + 0.78);
  EXPECT_LT(c.p95_left_mm, o.step_down_mm + 0.2);
}

TEST(Roughing, NeverPlungesOrRapidsIntoMaterial) {
  const BSplineSurface dome = dome_surface();
  RoughingOptions o = quick_options();
  o.step_down_mm = 3;
  const RoughingResult r = generate_roughing(dome, o);
  std::string first;
  EXPECT_EQ(plunges_into_material(r.cl, r.stats.stock, {3, 0}, o.ramp_angle_deg, first), 0u) << first;
}

// Rest machining: after a 12 mm end mill, a 4 mm one clears only what the first left. Together
// they leave what the 4 mm tool alone leaves (its own stairs and corners), with a fraction of
// its path (rough_cli_test replays both in cutsim: no plunge, no rapid into material); after the
// same program with the same tool there is nothing left to clear.
TEST(Roughing, RestMachiningClearsOnlyWhatTheLargerToolLeft) {
  const BSplineSurface dome = dome_surface();
  RoughingOptions big = quick_options();
  big.tool_diameter_mm = 12;
  big.step_down_mm = 3;
  const RoughingResult first = generate_roughing(dome, big);
  RoughingOptions small = quick_options();
  small.tool_diameter_mm = 4;
  small.step_down_mm = 1;
  small.stock = first.stats.stock;
  const RoughingResult alone = generate_roughing(dome, small);
  small.rest_after.push_back({first.cl, {6, 0}});
  const RoughingResult rest = generate_roughing(dome, small);
  EXPECT_GT(rest.stats.rest_levels, 0u);
  EXPECT_LT(rest.stats.feed_length_mm, 0.6 * alone.stats.feed_length_mm);
  const StockCheck after_first = check_stock(dome, first.stats.stock, {{&first.cl, {6, 0}}}, 0.5, 0.25, 0);
  const StockCheck both = check_stock(dome, first.stats.stock, {{&first.cl, {6, 0}}, {&rest.cl, {2, 0}}}, 0.5, 0.25, 0);
  const StockCheck only_small = check_stock(dome, first.stats.stock, {{&alone.cl, {2, 0}}}, 0.5, 0.25, 0);
  EXPECT_LT(both.p95_left_mm, after_first.p95_left_mm - 0.5);
  EXPECT_NEAR(both.p95_left_mm, only_small.p95_left_mm, 0.1);
  EXPECT_LT(both.max_left_mm, only_small.max_left_mm + 0.25);
  EXPECT_LT(both.max_into_allowance_mm, 0.01);
  RoughingOptions again = big;
  again.rest_after.push_back({first.cl, {6, 0}});
  again.stock = first.stats.stock;
  try {
    generate_roughing(dome, again);
    ADD_FAILURE() << "the same tool after itself found material to cut";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("nothing left to cut"), std::string::npos) << e.what();
  }
  again.rest_min_mm = 0;
  EXPECT_THROW(validate(again), UsageError);
}

TEST(Roughing, BullNoseAndAGivenStock) {
  const BSplineSurface dome = dome_surface();
  RoughingOptions o = quick_options();
  o.corner_radius_mm = 1;
  o.stock = StockBox{{-20, -20, 0}, {20, 20, 13}};
  const RoughingResult r = generate_roughing(dome, o);
  EXPECT_DOUBLE_EQ(r.stats.stock.max_mm.z(), 13);
  EXPECT_DOUBLE_EQ(r.cl.tool_corner_radius_mm, 1);
  const StockCheck c = check_stock(dome, r.stats.stock, {{&r.cl, {3, 1}}}, o.allowance_mm, 0.1, 0);
  EXPECT_LT(c.max_into_allowance_mm, 0.01);
  EXPECT_LT(c.p95_left_mm, o.step_down_mm + 0.2);
  std::string first;
  EXPECT_EQ(plunges_into_material(r.cl, r.stats.stock, {3, 1}, o.ramp_angle_deg, first), 0u) << first;
}

// The winding of the constant-z feed moves round the dome's axis, summed over a level: climb
// milling (material on the cutter's right, M3) goes round an island clockwise (negative).
double winding_at_level(const ClData& cl, double z) {
  double turn = 0;
  for (std::size_t k = 1; k < cl.moves.size(); ++k) {
    const Eigen::Vector3d& a = cl.moves[k - 1].tip_mm;
    const Eigen::Vector3d& b = cl.moves[k].tip_mm;
    if (cl.moves[k].kind != ClMove::Kind::Feed || std::abs(a.z() - z) > 1e-9 || std::abs(b.z() - z) > 1e-9) continue;
    double d = std::atan2(b.y(), b.x()) - std::atan2(a.y(), a.x());
    if (d > 3.14159265358979) d -= 2 * 3.14159265358979;
    if (d < -3.14159265358979) d += 2 * 3.14159265358979;
    turn += d;
  }
  return turn;
}

TEST(Roughing, ClimbGoesRoundTheIslandClockwiseConventionalCounterClockwise) {
  const BSplineSurface dome = dome_surface();
  RoughingOptions o = quick_options();
  o.stock = StockBox{{-30, -30, 0}, {30, 30, 10}};
  for (const MillingDirection d : {MillingDirection::Climb, MillingDirection::Conventional}) {
    o.direction = d;
    const RoughingResult r = generate_roughing(dome, o);
    const double z = 10 - o.step_down_mm;  // the first level: the dome is an island there
    const double turn = winding_at_level(r.cl, z);
    if (d == MillingDirection::Climb) {
      EXPECT_LT(turn, -2 * 3.14159) << "climb";
    } else {
      EXPECT_GT(turn, 2 * 3.14159) << "conventional";
    }
  }
}

TEST(Roughing, OptionsOutOfRangeAreUsageErrors) {
  const auto bad = [](auto change) {
    RoughingOptions o = quick_options();
    change(o);
    EXPECT_THROW(validate(o), UsageError);
  };
  bad([](RoughingOptions& o) { o.tool_diameter_mm = 0; });
  bad([](RoughingOptions& o) { o.corner_radius_mm = 3.5; });
  bad([](RoughingOptions& o) { o.step_down_mm = -1; });
  bad([](RoughingOptions& o) { o.step_over_mm = 4; });
  bad([](RoughingOptions& o) { o.allowance_mm = std::nan(""); });
  bad([](RoughingOptions& o) { o.ramp_angle_deg = 45; });
  bad([](RoughingOptions& o) { o.clearance_mm = 6; });
  bad([](RoughingOptions& o) { o.cell_mm = 0; });
  bad([](RoughingOptions& o) { o.stock = StockBox{{0, 0, 0}, {10, -1, 5}}; });
  EXPECT_NO_THROW(validate(quick_options()));
}

TEST(Roughing, AStockBesideTheSurfaceIsRefused) {
  RoughingOptions o = quick_options();
  o.stock = StockBox{{100, 100, 0}, {120, 120, 10}};
  EXPECT_THROW(generate_roughing(dome_surface(), o), GeometryError);
}

TEST(Roughing, TheWorkLimitStopsARunawayInsteadOfGrowing) {
  RoughingOptions o = quick_options();
  o.max_moves = 100;
  try {
    generate_roughing(dome_surface(), o);
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("--max-moves"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace photomill::toolpath
