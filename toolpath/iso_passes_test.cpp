// Steps 1, 5 and 6: iso-parametric curves, curvatures, the side step from the scallop height
// (against an independent construction of the cusp), its parameter conversion, boundary clipping
// and the pass plan.
#include "toolpath/iso_passes.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "formats/bspline.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

// Cusp height of two balls of radius R whose centres lie on a circle of radius A about the
// centre of curvature O, theta = g / rho apart, over a surface circle of radius rho: the point on
// the bisecting ray at distance R from a centre, found by bisection, measured from the stock
// surface (radius rho + a convex, rho - a concave) - a construction independent of the
// law-of-cosines formula in side_step_mm.
double cusp_by_construction(double R, double rho, double stock, double g, bool convex) {
  const double theta = g / rho;
  const double A = convex ? rho + stock + R : rho - stock - R;
  const Eigen::Vector2d c(A * std::sin(theta / 2), A * std::cos(theta / 2));  // bisector along +y
  const double surface = convex ? rho + stock : rho - stock;
  const double nearest = A * std::cos(theta / 2);  // closest point of the ray to the centre
  // Between the stock surface (outside the balls) and `nearest` (inside both) the distance to
  // the centre is monotonic.
  double outside = surface, inside = nearest;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (outside + inside);
    ((Eigen::Vector2d(0, mid) - c).norm() > R ? outside : inside) = mid;
  }
  const double t = 0.5 * (outside + inside);
  return std::abs(t - surface);
}

struct SideCase {
  const char* name;
  double radius_mm;  // 0 = flat
  bool convex;
  double stock_mm;
};

class SideStep : public ::testing::TestWithParam<SideCase> {};

TEST_P(SideStep, LeavesExactlyTheScallopHeight) {
  const SideCase& c = GetParam();
  const double R = 3, h = 0.01;
  const double kappa = c.radius_mm == 0 ? 0.0 : (c.convex ? -1.0 : 1.0) / c.radius_mm;
  const double g = side_step_mm(R, h, c.stock_mm, kappa);
  if (c.radius_mm == 0) {
    EXPECT_DOUBLE_EQ(g, 2 * std::sqrt(h * (2 * R - h)));
    return;
  }
  EXPECT_NEAR(cusp_by_construction(R, c.radius_mm, c.stock_mm, g, c.convex), h, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Curvatures, SideStep,
                         ::testing::Values(SideCase{"flat", 0, true, 0}, SideCase{"convex_r5", 5, true, 0},
                                           SideCase{"convex_r50", 50, true, 0}, SideCase{"concave_r8", 8, false, 0},
                                           SideCase{"concave_r100", 100, false, 0},
                                           SideCase{"convex_r20_stock", 20, true, 0.5},
                                           SideCase{"concave_r20_stock", 20, false, 0.5}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(SideStep, CurvatureCorrectionGoesTheRightWay) {
  const double R = 3, h = 0.01, flat = side_step_mm(R, h, 0, 0);
  EXPECT_LT(side_step_mm(R, h, 0, -1.0 / 10), flat);  // convex: passes closer
  EXPECT_GT(side_step_mm(R, h, 0, 1.0 / 10), flat);   // concave: further apart
  // Tighter than 2R concave: capped at the 2R value, never larger.
  EXPECT_DOUBLE_EQ(side_step_mm(R, h, 0, 1.0 / 4), side_step_mm(R, h, 0, 1.0 / 6));
  EXPECT_DOUBLE_EQ(side_step_mm(R, h, 0, 1.0 / 1), side_step_mm(R, h, 0, 1.0 / 6));
  EXPECT_TRUE(std::isfinite(side_step_mm(R, h, 0, -1e6)));
}

// Curvatures of the cylinder strips (radius 20 across y, straight along x) have known values.
struct CurvCase {
  const char* name;
  bool convex;
  PassDirection dir;
};

class Curvature : public ::testing::TestWithParam<CurvCase> {};

TEST_P(Curvature, MatchesTheCylinder) {
  const CurvCase& c = GetParam();
  const BSplineSurface s = test::cylinder_surface(20, c.convex);
  const double sign = c.convex ? -1.0 : 1.0;
  for (double v : {0.3, 0.5, 0.7}) {
    const PassFrame f = pass_frame(s, c.dir, 0.4, v);
    EXPECT_GT(f.normal.z(), 0);
    EXPECT_NEAR(f.normal.norm(), 1.0, 1e-12);
    // Along x the strip is straight; across (along y) it is the circle.
    const double along_x = c.dir == PassDirection::U ? along_curvature(f) : across_curvature(f);
    const double along_y = c.dir == PassDirection::U ? across_curvature(f) : along_curvature(f);
    EXPECT_NEAR(along_x, 0.0, 1e-6);
    EXPECT_NEAR(along_y, sign / 20, 2e-5);
    EXPECT_NEAR(max_concave_curvature(f), c.convex ? 0.0 : 1.0 / 20, 2e-5);
  }
}

INSTANTIATE_TEST_SUITE_P(Cylinders, Curvature,
                         ::testing::Values(CurvCase{"convex_u", true, PassDirection::U},
                                           CurvCase{"convex_v", true, PassDirection::V},
                                           CurvCase{"concave_u", false, PassDirection::U},
                                           CurvCase{"concave_v", false, PassDirection::V}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(AcrossParamStep, ConvertsMillimetresByTheSpeedAcrossThePass) {
  // Tilted plane z = 20 + 0.3 y over 60 x 30 mm, u -> x, v -> y: 30 sqrt(1.09) mm per unit v.
  const BSplineSurface s = test::cylinder_surface(0, true);
  const PassFrame f = pass_frame(s, PassDirection::U, 0.5, 0.5);
  EXPECT_NEAR(across_param_step(f, 0.5), 0.5 / (30 * std::sqrt(1.09)), 1e-12);
  const PassFrame fv = pass_frame(s, PassDirection::V, 0.5, 0.5);
  EXPECT_NEAR(across_param_step(fv, 0.5), 0.5 / 60, 1e-12);
}

TEST(IsoCurve, HoldsOneParameter) {
  const BSplineSurface s = test::bumps_surface();
  const IsoCurve cu(s, PassDirection::U, 0.25), cv(s, PassDirection::V, 0.25);
  EXPECT_EQ(cu.uv(0.6), Eigen::Vector2d(0.6, 0.25));
  EXPECT_EQ(cv.uv(0.6), Eigen::Vector2d(0.25, 0.6));
  EXPECT_EQ(cu.point(0.6), surface_point(s, 0.6, 0.25));
  EXPECT_EQ(cv.point(0.6), surface_point(s, 0.25, 0.6));
  // w at the end of the domain gives the boundary curve y = 0.
  EXPECT_NEAR(IsoCurve(s, PassDirection::U, 0.0).point(0.3).y(), 0.0, 1e-12);
}

struct ClipCase {
  const char* name;
  std::vector<Eigen::Vector2d> polygon;
  double w;
  std::vector<Interval> expected;
};

class Clip : public ::testing::TestWithParam<ClipCase> {};

TEST_P(Clip, IntervalsInsideThePolygon) {
  const ClipCase& c = GetParam();
  BSplineSurface s = test::cylinder_surface(0, true);
  s.boundary_uv = c.polygon;
  const auto got = clip_to_boundary(s, PassDirection::U, c.w);
  ASSERT_EQ(got.size(), c.expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_NEAR(got[k].t0, c.expected[k].t0, 1e-12);
    EXPECT_NEAR(got[k].t1, c.expected[k].t1, 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Polygons, Clip,
    ::testing::Values(
        ClipCase{"square", {{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.1, 0.9}}, 0.5, {{0.1, 0.9}}},
        ClipCase{"outside", {{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.1, 0.9}}, 0.95, {}},
        ClipCase{"triangle", {{0.0, 0.0}, {1.0, 0.0}, {0.5, 1.0}}, 0.5, {{0.25, 0.75}}},
        // A U shape: the line through both arms gives two pieces.
        ClipCase{"u_shape", {{0.1, 0.1}, {0.9, 0.1}, {0.9, 0.9}, {0.7, 0.9}, {0.7, 0.3}, {0.3, 0.3}, {0.3, 0.9}, {0.1, 0.9}},
                 0.5, {{0.1, 0.3}, {0.7, 0.9}}},
        // Beyond the domain: clipped to it.
        ClipCase{"wider", {{-0.5, 0.2}, {1.5, 0.2}, {1.5, 0.8}, {-0.5, 0.8}}, 0.5, {{0.0, 1.0}}}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Clip, NoPolygonIsTheWholeLine) {
  const BSplineSurface s = test::cylinder_surface(0, true);
  const auto got = clip_to_boundary(s, PassDirection::V, 0.3);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], (Interval{0.0, 1.0}));
}

TEST(CuspBudget, ConcaveAlongThePassLeavesRoomForTheChord) {
  // Concave trough radius 20 across y; passes along v (y) see it along their length.
  const BSplineSurface s = test::cylinder_surface(20, false);
  PassPlanOptions o;
  o.direction = PassDirection::V;
  const PassFrame f = pass_frame(s, o.direction, 0.5, 0.5);
  const double rho = 20, r = o.tool_radius_mm;
  EXPECT_NEAR(cusp_budget_mm(f, o), o.scallop_mm - o.chord_tol_mm * (rho - r) / rho, 2e-7);
  o.direction = PassDirection::U;  // straight along the pass: the whole h
  EXPECT_NEAR(cusp_budget_mm(pass_frame(s, o.direction, 0.5, 0.5), o), o.scallop_mm, 1e-9);
}

struct PlanCase {
  const char* name;
  double radius_mm;
  bool convex;
  PassDirection dir;
};

class Plan : public ::testing::TestWithParam<PlanCase> {};

// The lines cover the domain from edge to edge, and neighbouring lines are never further apart
// (measured along the surface, across the pass) than the side step allowed anywhere between them.
TEST_P(Plan, SpacingNeverExceedsTheAllowedSideStep) {
  const PlanCase& c = GetParam();
  const BSplineSurface s = test::cylinder_surface(c.radius_mm, c.convex);
  PassPlanOptions o;
  o.direction = c.dir;
  const auto lines = plan_passes(s, o);
  ASSERT_GE(lines.size(), 3u);
  const auto [w0, w1] = across_domain(s, c.dir);
  EXPECT_EQ(lines.front().w, w0);
  EXPECT_EQ(lines.back().w, w1);
  double worst = 0;
  for (std::size_t k = 0; k + 1 < lines.size(); ++k) {
    ASSERT_LT(lines[k].w, lines[k + 1].w);
    for (double t : {0.1, 0.5, 0.9}) {
      // Arc length across, by fine quadrature, against g at the midpoint.
      const IsoCurve across(s, c.dir == PassDirection::U ? PassDirection::V : PassDirection::U, t);
      double len = 0;
      constexpr int kN = 64;
      for (int i = 0; i < kN; ++i) {
        const double a = lines[k].w + (lines[k + 1].w - lines[k].w) * i / kN;
        const double b = lines[k].w + (lines[k + 1].w - lines[k].w) * (i + 1) / kN;
        len += (across.point(b) - across.point(a)).norm();
      }
      const PassFrame mid = pass_frame(s, c.dir, c.dir == PassDirection::U ? t : 0.5 * (lines[k].w + lines[k + 1].w),
                                       c.dir == PassDirection::U ? 0.5 * (lines[k].w + lines[k + 1].w) : t);
      const double g = side_step_mm(o.tool_radius_mm, cusp_budget_mm(mid, o), 0, across_curvature(mid));
      EXPECT_LE(len, g * (1 + 1e-3)) << "lines " << k << ", " << k + 1;
      worst = std::max(worst, len / g);
    }
  }
  // ... and not wastefully closer (the min over the line is the only slack here).
  EXPECT_GT(worst, 0.9);
}

INSTANTIATE_TEST_SUITE_P(Strips, Plan,
                         ::testing::Values(PlanCase{"plane_u", 0, true, PassDirection::U},
                                           PlanCase{"convex_u", 20, true, PassDirection::U},
                                           PlanCase{"concave_u", 20, false, PassDirection::U},
                                           PlanCase{"convex_v", 20, true, PassDirection::V}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Plan, PolygonLimitsTheLines) {
  BSplineSurface s = test::bumps_surface();
  s.boundary_uv = {{0.2, 0.3}, {0.8, 0.25}, {0.7, 0.7}, {0.3, 0.75}};
  PassPlanOptions o;
  o.scallop_mm = 0.05;
  o.chord_tol_mm = 0.01;
  const auto lines = plan_passes(s, o);
  EXPECT_EQ(lines.front().w, 0.25);
  EXPECT_EQ(lines.back().w, 0.75);
  for (const auto& line : lines) {
    for (const Interval& iv : line.intervals) {
      EXPECT_GE(iv.t0, 0.2 - 1e-9);
      EXPECT_LE(iv.t1, 0.8 + 1e-9);
    }
  }
}

}  // namespace
}  // namespace photomill::toolpath
