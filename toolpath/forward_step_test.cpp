// Steps 2 and 3: the chord length from the tolerance, the dense sub-curve maximum, and whole
// passes whose every segment is checked against the surface by an independent dense sampling.
#include "toolpath/forward_step.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/test_surfaces.hpp"

namespace photomill::toolpath {
namespace {

TEST(ChordLength, SagittaOfTheChordIsTheTolerance) {
  for (double rho : {0.5, 3.0, 20.0, 1000.0}) {
    for (double tol : {1e-4, 0.005, 0.1}) {
      const double L = chord_length_for_tolerance(rho, tol);
      if (tol >= rho) continue;
      EXPECT_NEAR(rho - std::sqrt(rho * rho - 0.25 * L * L), tol, 1e-12 * rho) << rho << " " << tol;
    }
  }
  EXPECT_TRUE(std::isinf(chord_length_for_tolerance(std::numeric_limits<double>::infinity(), 0.01)));
  EXPECT_DOUBLE_EQ(chord_length_for_tolerance(0.001, 0.01), 0.002);
}

TEST(ForwardParamStep, DividesByTheSpeed) {
  EXPECT_DOUBLE_EQ(forward_param_step(1.5, Eigen::Vector3d(0, 300, 400)), 1.5 / 500);
  EXPECT_TRUE(std::isinf(forward_param_step(1.5, Eigen::Vector3d::Zero())));
}

TEST(SubcurveMax, FindsAsymmetricAndDoubleBumps) {
  // Asymmetric bump: top at t = 0.9 (f = t^9 (1 - t)); a midpoint check sees 1/1024 of it.
  const auto skew = [](double t) { return std::pow(t, 9) * (1 - t); };
  const double top = std::pow(0.9, 9) * 0.1;
  const SubcurveMax m = max_over_subcurve(skew, 0, 1);
  EXPECT_NEAR(m.value, top, 1e-7 * top);
  EXPECT_NEAR(m.t, 0.9, 1e-3);
  // Two bumps of different height (an S-shaped sub-curve's distance from its chord).
  const auto twin = [](double t) { return std::abs(std::sin(2 * std::numbers::pi * t)) * (t < 0.5 ? 1.0 : 1.3); };
  EXPECT_NEAR(max_over_subcurve(twin, 0, 1).value, 1.3, 1e-6);
}

TEST(DistanceToSegment, ClampsToTheEnds) {
  const Eigen::Vector3d a(0, 0, 0), b(2, 0, 0);
  EXPECT_DOUBLE_EQ(distance_to_segment({1, 1, 0}, a, b), 1.0);
  EXPECT_DOUBLE_EQ(distance_to_segment({-3, 4, 0}, a, b), 5.0);
  EXPECT_DOUBLE_EQ(distance_to_segment({1, 0, 2}, a, a), std::sqrt(5.0));
}

// Independent dense check of one segment: 200 samples of the sub-curve against the chord.
double dense_chord_error(const IsoCurve& c, double t0, double t1) {
  const Eigen::Vector3d a = c.point(t0), b = c.point(t1);
  double worst = 0;
  for (int k = 1; k < 200; ++k) worst = std::max(worst, distance_to_segment(c.point(t0 + (t1 - t0) * k / 200.0), a, b));
  return worst;
}

struct MarchCase {
  const char* surface;
  PassDirection dir;
  double w;
  bool reverse;
};

class March : public ::testing::TestWithParam<MarchCase> {};

TEST_P(March, EverySegmentWithinTheChordToleranceAndNotWasteful) {
  const MarchCase& c = GetParam();
  const BSplineSurface s = test::named_surface(c.surface);
  const IsoCurve curve(s, c.dir, c.w);
  const DropCutter drop(s, 3.0, 0.5);
  CutterOptions co;
  ForwardStepOptions fo;
  const double t0 = c.reverse ? 1.0 : 0.0, t1 = 1.0 - t0;
  const MarchResult m = march_interval(curve, t0, t1, fo, 3.0, [&](const PassFrame& f) { return cc_to_cl(f, drop, co); });
  ASSERT_EQ(m.points.size(), m.ts.size());
  ASSERT_GE(m.points.size(), 10u);
  EXPECT_EQ(m.ts.front(), t0);
  EXPECT_EQ(m.ts.back(), t1);
  double worst = 0;
  for (std::size_t k = 1; k < m.ts.size(); ++k) {
    EXPECT_GT((m.ts[k] - m.ts[k - 1]) * (t1 - t0), 0) << "parameters must advance";
    const double err = dense_chord_error(curve, m.ts[k - 1], m.ts[k]);
    EXPECT_LE(err, fo.chord_tol_mm) << "segment " << k << " at t = " << m.ts[k];
    EXPECT_LE((m.points[k].cc - m.points[k - 1].cc).norm(), fo.max_step_mm * 1.01);
    worst = std::max(worst, err);
  }
  EXPECT_LE(m.max_chord_error_mm, fo.chord_tol_mm);
  EXPECT_LE(m.max_penetration_mm, fo.gouge_tol_mm);
  // The steps are as long as the tolerances allow somewhere (not a fixed tiny step).
  EXPECT_GT(std::max(worst, m.max_penetration_mm / fo.gouge_tol_mm * fo.chord_tol_mm), 0.5 * fo.aim * fo.chord_tol_mm);
}

INSTANTIATE_TEST_SUITE_P(Passes, March,
                         ::testing::Values(MarchCase{"bumps", PassDirection::U, 0.4, false},
                                           MarchCase{"bumps", PassDirection::V, 0.3, true},
                                           MarchCase{"wave", PassDirection::U, 0.27, false},
                                           MarchCase{"wave", PassDirection::V, 0.6, false}),
                         [](const auto& info) {
                           return std::string(info.param.surface) + (info.param.dir == PassDirection::U ? "_u" : "_v") +
                                  (info.param.reverse ? "_reversed" : "");
                         });

TEST(March, RequiredStepBelowTheMinimumIsAGeometryError) {
  const BSplineSurface s = test::wave_surface();
  const IsoCurve curve(s, PassDirection::U, 0.5);
  const DropCutter drop(s, 3.0, 0.5);
  ForwardStepOptions fo;
  fo.chord_tol_mm = 1e-6;
  fo.min_step_mm = 0.5;  // a chord of 0.5 mm on this wave deviates far more than 1e-6 mm
  EXPECT_THROW(march_interval(curve, 0, 1, fo, 3.0, [&](const PassFrame& f) { return cc_to_cl(f, drop, {}); }),
               GeometryError);
}

}  // namespace
}  // namespace photomill::toolpath

namespace photomill::toolpath {
namespace {

// Issue #25: on a sub-curve a few ulp long (nearly coincident knots at t = 0.5) the golden-section
// search aimed at a bracket of 1e-3 of it, narrower than double precision can make one, and never
// ended. It now stops at rounding; f counts its calls and gives up, so the old code fails here
// instead of hanging.
TEST(MaxOverSubcurve, EndsOnAnIntervalAFewUlpLong) {
  int calls = 0;
  const auto f = [&calls](double t) {
    if (++calls > 10'000) throw std::runtime_error("the search does not end");
    return -t;  // largest at the start: the bracket closes on t0, a few ulp wide
  };
  const SubcurveMax m = max_over_subcurve(f, 0.5, 0.5 + 1e-15);
  EXPECT_GE(m.t, 0.5);
  EXPECT_LE(m.t, 0.5 + 1e-15);
  EXPECT_LT(calls, 200);
}

}  // namespace
}  // namespace photomill::toolpath
