// Steps 4/7 (CC -> CL) and the drop cutter: exact on planes, never below any surface point on
// curved test surfaces, and gouges flagged where the surface is concave tighter than the ball.
#include "toolpath/cutter.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "formats/bspline.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

TEST(CcToCl, BallTouchesATiltedPlaneAtTheContactPoint) {
  // z = 20 + 0.3 y: n = (0, -0.3, 1) / sqrt(1.09).
  const BSplineSurface s = test::cylinder_surface(0, true);
  const DropCutter drop(s, 3.0, 0.5);
  for (double u : {0.2, 0.5, 0.8}) {
    for (double v : {0.3, 0.6}) {
      const PassFrame f = pass_frame(s, PassDirection::U, u, v);
      const CutterLocation cl = cc_to_cl(f, drop, {});
      const Eigen::Vector3d n = Eigen::Vector3d(0, -0.3, 1) / std::sqrt(1.09);
      EXPECT_NEAR((cl.normal - n).norm(), 0, 1e-12);
      EXPECT_NEAR((cl.centre - (cl.cc + 3.0 * n)).norm(), 0, 1e-12);
      EXPECT_NEAR((cl.tip - (cl.centre - Eigen::Vector3d(0, 0, 3))).norm(), 0, 1e-15);
      EXPECT_FALSE(cl.gouge);
      EXPECT_LT(cl.gouge_depth_mm, 1e-9);
    }
  }
}

TEST(CcToCl, StockRaisesTheBallAlongTheNormal) {
  const BSplineSurface s = test::cylinder_surface(0, true);
  CutterOptions o;
  o.stock_mm = 0.5;
  const DropCutter drop(s, 3.5, 0.5);
  const PassFrame f = pass_frame(s, PassDirection::U, 0.5, 0.5);
  const CutterLocation cl = cc_to_cl(f, drop, o);
  EXPECT_NEAR((cl.centre - (f.p + 3.5 * f.normal)).norm(), 0, 1e-12);
  EXPECT_NEAR(cl.tip.z(), cl.centre.z() - 3.0, 1e-12);
}

TEST(DropCutter, OnAPlaneIsTheClosedForm) {
  // Ball of radius r over z = 20 + 0.3 y: centre z = 20 + 0.3 y + r sqrt(1.09).
  const BSplineSurface s = test::cylinder_surface(0, true);
  const DropCutter drop(s, 3.0, 0.5);
  for (double x : {10.0, 33.3}) {
    for (double y : {8.0, 15.5, 22.0}) {
      const DropCutter::Contact c = drop.drop({x, y});
      ASSERT_TRUE(c.hit);
      EXPECT_NEAR(c.centre_z, 20 + 0.3 * y + 3 * std::sqrt(1.09), 1e-9);
    }
  }
  EXPECT_FALSE(drop.drop({-50, -50}).hit);
}

class DropCutterOn : public ::testing::TestWithParam<const char*> {};

// The defining property: at the height found, no point of the surface is inside the ball, and
// the ball touches it (a dense independent sampling finds nothing higher than the answer and
// something within the sampling error of it).
TEST_P(DropCutterOn, NeverBelowAnySurfacePointAndTouching) {
  const BSplineSurface s = test::named_surface(GetParam());
  const double r = 3.0;
  const DropCutter drop(s, r, 0.5);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(10, 140), uy(10, 90);
  const auto [u0, u1] = domain_u(s);
  const auto [v0, v1] = domain_v(s);
  for (int trial = 0; trial < 25; ++trial) {
    const Eigen::Vector2d xy(ux(rng), uy(rng));
    const DropCutter::Contact c = drop.drop(xy);
    ASSERT_TRUE(c.hit);
    // x, y are linear in u, v on these surfaces: sample the ball's footprint densely (0.02 mm).
    double highest = -1e300;
    const double du = 0.02 / 150 * (u1 - u0), dv = 0.02 / 100 * (v1 - v0);
    const double uc = (xy.x() / 150) * (u1 - u0) + u0, vc = (xy.y() / 100) * (v1 - v0) + v0;
    for (double u = uc - r / 150 * (u1 - u0); u <= uc + r / 150 * (u1 - u0); u += du) {
      for (double v = vc - r / 100 * (v1 - v0); v <= vc + r / 100 * (v1 - v0); v += dv) {
        const Eigen::Vector3d p = surface_point(s, u, v);
        const double d2 = (p.head<2>() - xy).squaredNorm();
        if (d2 < r * r) highest = std::max(highest, p.z() + std::sqrt(r * r - d2));
      }
    }
    EXPECT_GE(c.centre_z, highest - 1e-9) << "a surface point is inside the ball at " << xy.transpose();
    EXPECT_LE(c.centre_z, highest + 1e-3) << "the ball floats above the surface at " << xy.transpose();
    // The reported contact is on the ball.
    EXPECT_NEAR((c.point - Eigen::Vector3d(xy.x(), xy.y(), c.centre_z)).norm(), r, 1e-6);
  }
}

INSTANTIATE_TEST_SUITE_P(Surfaces, DropCutterOn, ::testing::Values("bumps", "wave", "groove"));

TEST(Gouge, ConcaveTighterThanTheBallIsFlaggedAndLifted) {
  // Concave trough of radius 2.2 mm (< R = 3) across y: a tangent ball cuts both flanks.
  const BSplineSurface s = test::trough_surface(2.2);
  const DropCutter drop(s, 3.0, 0.25);
  const PassFrame f = pass_frame(s, PassDirection::U, 0.5, 0.5);  // the trough's bottom
  CutterOptions o;
  const CutterLocation lifted = cc_to_cl(f, drop, o);
  EXPECT_TRUE(lifted.gouge);
  EXPECT_TRUE(lifted.lifted);
  EXPECT_NEAR(lifted.concave_radius_mm, 2.2, 0.01);
  EXPECT_GT(lifted.gouge_depth_mm, 0.1);
  EXPECT_GT((lifted.contact - lifted.cc).norm(), 0.5) << "the ball rests on the flanks, not the bottom";
  o.lift = false;
  const CutterLocation reported = cc_to_cl(f, drop, o);
  EXPECT_TRUE(reported.gouge);
  EXPECT_FALSE(reported.lifted);
  EXPECT_NEAR(reported.gouge_depth_mm, lifted.gouge_depth_mm, 1e-12);
  EXPECT_NEAR(reported.centre.z() + reported.gouge_depth_mm, lifted.centre.z(), 1e-12);
}

TEST(Gouge, OpenConcaveIsNotAGouge) {
  const BSplineSurface s = test::cylinder_surface(20, false);
  const DropCutter drop(s, 3.0, 0.5);
  const CutterLocation cl = cc_to_cl(pass_frame(s, PassDirection::U, 0.5, 0.5), drop, {});
  EXPECT_FALSE(cl.gouge);
  EXPECT_LT(cl.gouge_depth_mm, 1e-9);
  EXPECT_NEAR(cl.concave_radius_mm, 20, 0.01);
}

}  // namespace
}  // namespace photomill::toolpath
