// The whole fit against analytic ground truth (fitsurf/test_shapes.hpp): dense noisy clouds,
// parameter correction, sparse marker points, robust reweighting, --tolerance mode, exact
// reproduction, solvers and threads, knot placement, and degenerate input.
#include "fitsurf/fit.hpp"

#include <cmath>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "fitsurf/fitsurf.hpp"
#include "fitsurf/outline.hpp"
#include "fitsurf/synth_shapes.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::fitsurf {
namespace {

using test::cloud_of;

// Deviation from the truth inside the fitted surface's outline.
test::TruthDeviation truth(const BSplineSurface& s, const test::Shape& shape) { return test::truth_inside_outline(s, shape); }

class FitsurfFit : public ::testing::Test {
protected:
  void SetUp() override { log::set_level(log::Level::Quiet); }
};

// Done-when 1: 100 000 points with 0.01 mm noise, 30x30 cubic net, default method: the surface
// deviates from the truth by <= 0.01 mm RMS, and the residuals are the noise (its component
// along the normal: sigma).
// The same with smoothing of order 3 (--smoothing-order 3, same lambda 0.01 in mm^6).
class DenseAccuracy : public FitsurfFit, public ::testing::WithParamInterface<std::tuple<std::string, int>> {};

TEST_P(DenseAccuracy, HundredThousandNoisyPointsWithin10Micrometres) {
  const test::Shape shape = test::shape(std::get<0>(GetParam()));
  const double sigma = 0.01;
  Options o;
  o.fit.poles_u = o.fit.poles_v = 30;
  o.fit.smoothing_order = std::get<1>(GetParam());
  const Result r = fit_point_cloud(cloud_of(test::sample(shape, 100000, sigma, 21)), o);
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_GT(dev.samples, 10000u);
  EXPECT_LE(dev.rms_mm, 0.01) << "max " << dev.max_mm;
  EXPECT_GT(r.stats.rms_mm, 0.95 * sigma);
  EXPECT_LT(r.stats.rms_mm, 1.05 * sigma);
  EXPECT_LT(std::abs(r.stats.mean_mm), 0.1 * sigma) << "no bias above or below";
  EXPECT_EQ(r.fit.surface.num_poles_u, 30);
  EXPECT_FALSE(r.fit.surface.boundary_uv.empty());
}

INSTANTIATE_TEST_SUITE_P(Shapes, DenseAccuracy,
                         ::testing::Combine(::testing::Values("bumps", "saddle", "wave", "dome", "steep", "ridge"),
                                            ::testing::Values(2, 3)),
                         [](const auto& info) {
                           return std::get<0>(info.param) + "_order" + std::to_string(std::get<1>(info.param));
                         });

// synth's parts meet the plate through a 20 mm blend (the demo part is synth's bumps; synth_saddle,
// synth_wave, synth_dome are its other parts, synth::make_shape itself): uniform knots 5.6 mm
// apart leave 0.011-0.017 mm RMS at 30x30, knots placed by the shape of a first fit
// (adaptive_knots) bring them within 0.01 mm (0.004-0.0065), and keep every other shape within it
// (docs/measurements/fitsurf.md, dense accuracy). Done-when 1 on synth's true surfaces.
class DenseAdaptive : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(DenseAdaptive, HundredThousandNoisyPointsWithin10MicrometresAt30x30) {
  const test::Shape shape = test::shape_or_synth_part(GetParam());
  const PointCloud cloud = cloud_of(test::sample(shape, 100000, 0.01, 21));
  Options o;
  o.fit.poles_u = o.fit.poles_v = 30;
  o.fit.knots = KnotPlacement::Adaptive;
  const Result r = fit_point_cloud(cloud, o);
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_LE(dev.rms_mm, 0.01) << "max " << dev.max_mm;
  EXPECT_EQ(r.fit.surface.num_poles_u, 30);
  if (GetParam() == "demo") {
    o.fit.knots = KnotPlacement::Uniform;
    EXPECT_GT(truth(fit_point_cloud(cloud, o).fit.surface, shape).rms_mm, 0.011) << "uniform knots miss the blend";
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, DenseAdaptive,
                         ::testing::Values("bumps", "saddle", "wave", "dome", "steep", "ridge", "demo", "synth_saddle",
                                           "synth_wave", "synth_dome"));

// Adaptive knots crowd where the shape bends: on the demo part, the outer 20 mm of each side (the
// blend, 27 % of the length) get more of the knots than uniform ones would give them; the knots
// stay strictly increasing and clamped.
TEST_F(FitsurfFit, AdaptiveKnotsCrowdIntoTheBlend) {
  const test::Shape shape = test::shape("demo");
  Options o;
  o.fit.robust = RobustLoss::None;
  o.fit.plane = PlaneChoice::Xy;  // u along x, v along y
  const Result r = fit_point_cloud(cloud_of(test::sample(shape, 50000, 0.0, 22)), o);
  const auto U = adaptive_knots(r.fit.local_surface, 0, 30, 4.0, 1e-4);
  ASSERT_EQ(U.size(), 34u);
  for (int k = 0; k <= 3; ++k) {
    EXPECT_EQ(U[static_cast<std::size_t>(k)], 0.0);
    EXPECT_EQ(U[static_cast<std::size_t>(30 + k)], 1.0);
  }
  int in_blend = 0;
  for (std::size_t k = 4; k < 30; ++k) {
    EXPECT_GT(U[k], U[k - 1]);
    const double x = -75 + 150 * U[k];  // the data span x in [-75, 75]
    in_blend += std::abs(x) > 55;
  }
  EXPECT_GE(in_blend, 10) << "uniform: 7 of the 26 interior knots";
  Options plane = o;
  PointCloud flat;
  for (const auto& p : test::sample(shape, 5000, 0.0, 23)) flat.points_mm.emplace_back(p.x(), p.y(), 0.0);
  const Result f = fit_point_cloud(flat, plane);
  const auto P = adaptive_knots(f.fit.local_surface, 0, 30, 4.0, 1e-4);
  for (std::size_t k = 4; k < 30; ++k) EXPECT_NEAR(P[k], (k - 3) / 27.0, 1e-6) << "a plane: uniform (to 0.15 um over 150 mm)";
}

// Done-when 2: parameter correction beats plane projection alone where the net, not the noise,
// limits the accuracy: on the most curved shape (steep: 0.1 /mm at its top) with a 16x16 net and on
// the steepest (ridge: 74-degree sides) with 20x20. (With 30x30 both are limited by the noise and
// equal: docs/measurements/fitsurf.md.)
struct CorrectionCase {
  std::string shape;
  int net;
};

void PrintTo(const CorrectionCase& c, std::ostream* os) { *os << c.shape << " " << c.net; }

class Correction : public FitsurfFit, public ::testing::WithParamInterface<CorrectionCase> {};

TEST_P(Correction, BeatsPlaneProjectionWhereTheNetLimits) {
  const test::Shape shape = test::shape(GetParam().shape);
  const PointCloud cloud = cloud_of(test::sample(shape, 100000, 0.01, 22));
  Options o;
  o.fit.poles_u = o.fit.poles_v = GetParam().net;
  // The two parameterisations alone, without reweighting (which, where the net cannot follow the
  // shape, flags a few clean points: ridge 20x20 with the default reject, 0.00317 -> 0.00291 mm,
  // docs/measurements/fitsurf.md).
  o.fit.robust = RobustLoss::None;
  o.fit.parameter_correction = false;
  const Result plane = fit_point_cloud(cloud, o);
  o.fit.parameter_correction = true;
  const Result corrected = fit_point_cloud(cloud, o);
  const auto a = truth(plane.fit.surface, shape), b = truth(corrected.fit.surface, shape);
  EXPECT_LT(b.rms_mm, 0.9 * a.rms_mm) << "plane " << a.rms_mm << " corrected " << b.rms_mm;
  EXPECT_LE(b.max_mm, a.max_mm) << "plane " << a.max_mm << " corrected " << b.max_mm;
  EXPECT_LT(corrected.stats.rms_mm, plane.stats.rms_mm);
  EXPECT_GE(corrected.fit.round_rms_mm.size(), 3u);
}

INSTANTIATE_TEST_SUITE_P(Shapes, Correction, ::testing::Values(CorrectionCase{"steep", 16}, CorrectionCase{"ridge", 20}));

// The B-spline's own smoothing between sparse points, without the kernel prefit that fitsurf
// uses by default for them (SparseKernel below).
Options spline_only() {
  Options o;
  o.prefit.mode = Prefit::None;
  return o;
}

// Done-when 3: ~150 marker points (a jittered 15 x 10 grid, 0.01 mm noise) with the default
// smoothing: no wiggles (max curvature within 2x the truth's) on every shape; within 0.1 mm of
// the truth inside the points' hull on the shapes whose features are broad compared with the
// 10 mm marker spacing. (On bumps, wave and steep the features are as small as the spacing:
// SparseErrorIsSampling shows that error shrinks as markers are added.)
class SparseMarkers : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(SparseMarkers, SmoothWithoutWiggles) {
  const test::Shape shape = test::shape(GetParam());
  const Result r = fit_point_cloud(cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, 23)), spline_only());
  const auto hull = r.fit.surface.boundary_uv;  // convex: auto below 2000 points
  ASSERT_GE(hull.size(), 3u);
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_LE(dev.max_curvature, 2.0 * dev.true_max_curvature);
  if (GetParam() == "saddle" || GetParam() == "dome") {
    EXPECT_LE(dev.max_mm, 0.1);
  }
}

// Not the ridge: markers 10 mm apart across its 74-degree sides reach 2.5x its curvature (numbers
// in docs/measurements/fitsurf.md).
INSTANTIATE_TEST_SUITE_P(Shapes, SparseMarkers, ::testing::Values("bumps", "saddle", "wave", "dome", "steep"));

// Smoothing of order 3 (third derivatives: quadrics cost nothing) on the same ~150 markers: a
// gap between markers on a curved part is bridged along its curvature instead of being
// flattened towards a plane. No wiggles on every shape, the ridge included (thin plate: 2.1x its
// curvature), and within 0.1 mm of the truth on saddle, dome and steep (thin plate: steep
// 0.26 mm); never farther from the truth than the thin plate's fit, but on the demo part whose
// 4 mm shoulders fall between markers 10 mm apart (figures in docs/measurements/fitsurf.md).
class SparseMarkersOrder3 : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(SparseMarkersOrder3, FollowsTheCurvatureBetweenMarkers) {
  const test::Shape shape = test::shape(GetParam());
  const PointCloud cloud = cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, 23));
  Options o = spline_only();
  o.fit.fold.max_slope_deg = 90;  // the ridge's sides: measure, do not refuse
  const auto thin_plate = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  o.fit.smoothing_order = 3;
  const auto dev = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  EXPECT_LE(dev.max_curvature, 2.0 * dev.true_max_curvature);
  if (thin_plate.max_mm > 0.1) {
    EXPECT_LT(dev.max_mm, thin_plate.max_mm) << "order 3 " << dev.max_mm << " mm, thin plate " << thin_plate.max_mm;
  }
  if (GetParam() == "saddle" || GetParam() == "dome" || GetParam() == "steep") {
    EXPECT_LE(dev.max_mm, 0.1);
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, SparseMarkersOrder3,
                         ::testing::Values("bumps", "saddle", "wave", "dome", "steep", "ridge"));

// Points weighted by their own standard deviation (--weight-by-sigma, the cloud's sigma_mm):
// half the points 0.005 mm noisy, half 0.05 mm (a two-view point beside one seen in eight
// photos). Weighted by 1/sigma^2 the fit is about as close to the truth as the precise half
// alone; unweighted, more than twice as far.
TEST_F(FitsurfFit, WeightBySigmaFollowsThePreciseHalf) {
  const test::Shape shape = test::shape("dome");
  auto pts = test::sample(shape, 10000, 0.005, 51);
  const auto noisy = test::sample(shape, 10000, 0.05, 52);
  pts.insert(pts.end(), noisy.begin(), noisy.end());
  PointCloud cloud = cloud_of(pts);
  PointProperty& sigma = cloud.add_property("sigma_mm", PlyScalar::Float64);
  for (std::size_t k = 0; k < pts.size(); ++k) sigma.values[k] = k < 10000 ? 0.005 : 0.05;
  Options o;
  o.fit.poles_u = o.fit.poles_v = 20;
  const auto plain = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  o.weight_by_sigma = true;
  const Result r = fit_point_cloud(cloud, o);
  const auto weighted = truth(r.fit.surface, shape);
  EXPECT_LT(weighted.rms_mm, 0.5 * plain.rms_mm) << "weighted " << weighted.rms_mm << ", plain " << plain.rms_mm;
  // Only the precise half: about what 10 000 points of 0.005 mm alone give.
  Options alone = o;
  alone.weight_by_sigma = false;
  const auto precise = truth(fit_point_cloud(cloud_of(test::sample(shape, 10000, 0.005, 51)), alone).fit.surface, shape);
  EXPECT_LT(weighted.rms_mm, 1.3 * precise.rms_mm) << "weighted " << weighted.rms_mm << ", precise half alone " << precise.rms_mm;
}

// Issue 24: a few points off the surface that say they are uncertain (triangulate's sigma_mm is
// the largest axis of the point's covariance: a two-view point's depth along its rays) do not
// pull the fit with --weight-by-sigma even without the robust step; the same points claiming the
// precision of the others do, and then only the robust step (the default) keeps them out.
TEST_F(FitsurfFit, WeightBySigmaLetsUncertainPointsGo) {
  const test::Shape shape = test::shape("dome");
  auto pts = test::sample(shape, 3000, 0.01, 61);
  // A patch of 8 points 0.6 mm above the surface, about (10, 5).
  for (int k = 0; k < 8; ++k) {
    const double x = 10 + 0.8 * std::cos(k * 0.785), y = 5 + 0.8 * std::sin(k * 0.785);
    pts.push_back({x, y, shape.f(x, y) + 0.6});
  }
  auto run = [&](double patch_sigma_mm, RobustLoss robust) {
    PointCloud cloud = cloud_of(pts);
    PointProperty& sigma = cloud.add_property("sigma_mm", PlyScalar::Float64);
    for (std::size_t k = 0; k < pts.size(); ++k) sigma.values[k] = k < 3000 ? 0.01 : patch_sigma_mm;
    Options o;
    o.fit.poles_u = o.fit.poles_v = 20;
    o.weight_by_sigma = true;
    o.fit.robust = robust;
    const Result r = fit_point_cloud(cloud, o);
    double pull = 0;  // how far the surface came up to the patch: 0.6 - its mean residual
    for (std::size_t i = 0; i < r.selection.kept.size(); ++i) {
      if (r.selection.kept[i] >= 3000) pull += (0.6 - r.fit.residual_mm[i]) / 8;
    }
    return pull;
  };
  const double precise = run(0.01, RobustLoss::None), uncertain = run(0.2, RobustLoss::None);
  EXPECT_LT(uncertain, 0.02) << "the patch claiming 0.2 mm moved the surface by " << uncertain << " mm";
  EXPECT_GT(precise, 3 * uncertain) << "precise " << precise << ", uncertain " << uncertain;
  EXPECT_LT(run(0.01, RobustLoss::Reject), 0.02) << "rejected by the robust step";
}

TEST_F(FitsurfFit, WeightBySigmaNeedsAValidSigmaPerPoint) {
  PointCloud cloud = cloud_of(test::sample(test::shape("dome"), 2000, 0.01, 53));
  Options o;
  o.weight_by_sigma = true;
  auto message = [&] {
    try {
      fit_point_cloud(cloud, o, "cloud.ply");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message().find("cloud.ply: --weight-by-sigma: the cloud has no sigma_mm"), std::string::npos) << message();
  PointProperty& sigma = cloud.add_property("sigma_mm", PlyScalar::Float64);
  sigma.values.assign(cloud.points_mm.size(), 0.01);
  sigma.values[7] = -1;
  EXPECT_NE(message().find("point 8 has sigma_mm -1"), std::string::npos) << message();
  sigma.values[7] = 0;  // a control point: weighted as sigma_floor_mm
  EXPECT_EQ(message(), "no error");
  o.sigma_floor_mm = 0;
  EXPECT_THROW(fit_point_cloud(cloud, o, "cloud.ply"), UsageError);
}

// Denser noisy markers (a 30 x 20 grid, 5 mm apart) with the default tiny smoothing follow their
// noise; --noise-mm chooses the smoothing (Reinsch) so that the residuals match the noise: closer
// to the truth, no wiggles, and within 0.1 mm on the broad shapes.
class NoisyMarkers : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(NoisyMarkers, NoiseLevelChoosesTheSmoothing) {
  const test::Shape shape = test::shape(GetParam());
  const PointCloud cloud = cloud_of(test::sample_grid(shape, 30, 20, 1.5, 0.01, 23));
  Options o = spline_only();
  const auto plain = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  o.fit.noise_mm = 0.01;
  const Result r = fit_point_cloud(cloud, o);
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_LT(dev.rms_mm, plain.rms_mm);
  EXPECT_LE(dev.max_curvature, 2.0 * dev.true_max_curvature);
  EXPECT_NEAR(r.stats.rms_mm, 0.01, 0.0015);
  EXPECT_GT(r.fit.smoothing_mm4, o.fit.smoothing_mm4);
  if (GetParam() == "saddle" || GetParam() == "dome") {
    EXPECT_LE(dev.max_mm, 0.1);
  }
}

INSTANTIATE_TEST_SUITE_P(Shapes, NoisyMarkers, ::testing::Values("bumps", "saddle", "wave", "dome", "steep"));

TEST_F(FitsurfFit, SparseErrorIsSampling) {
  const test::Shape shape = test::shape("bumps");
  const auto coarse = truth(fit_point_cloud(cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.0, 24)), spline_only()).fit.surface, shape);
  const auto fine = truth(fit_point_cloud(cloud_of(test::sample_grid(shape, 30, 20, 1.5, 0.0, 24)), spline_only()).fit.surface, shape);
  // Halving the spacing divides the interpolation error by about 4 (second order).
  EXPECT_LT(fine.max_mm, 0.4 * coarse.max_mm) << coarse.max_mm << " -> " << fine.max_mm;
  EXPECT_LE(fine.max_mm, 0.1);
}

// Where the 0.1 mm bound is not met with 150 markers, the samples do not determine the surface to
// that: the thin-plate spline interpolant of the same points (the least-bending surface through
// them, a smooth plausible part with identical marker positions) lies more than 0.2 mm from the
// truth, so no fit can be within 0.1 mm of both. fitsurf's fit is about as close to the truth as
// that interpolant (figures in docs/measurements/fitsurf.md; the same points as fitsurf_bench's sparse table).
class SparseLimit : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(SparseLimit, SamplesCannotPinTheSurfaceTo100Micrometres) {
  const test::Shape shape = test::shape(GetParam());
  const PointCloud cloud = cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, 4));
  Options o = spline_only();
  o.fit.fold.max_slope_deg = 90;  // as the benchmark: measure, do not refuse
  const Result r = fit_point_cloud(cloud, o);
  const auto tps = test::thin_plate_interpolant(cloud.points_mm);
  double tps_max = 0;
  const auto& b = r.fit.surface.boundary_uv;
  for (int i = 0; i < 120; ++i) {
    for (int j = 0; j < 120; ++j) {
      const Eigen::Vector2d uv((i + 0.5) / 120, (j + 0.5) / 120);
      if (!point_in_polygon(b, uv)) continue;
      const Eigen::Vector3d x = surface_point(r.fit.surface, uv.x(), uv.y());
      tps_max = std::max(tps_max, test::distance_to_truth(shape, Eigen::Vector3d(x.x(), x.y(), tps(x.x(), x.y()))));
    }
  }
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_GT(tps_max, 0.2) << "two surfaces through the same markers differ by more than twice the bound";
  EXPECT_LT(dev.max_mm, 1.3 * tps_max) << "fit " << dev.max_mm << " mm, thin-plate interpolant " << tps_max << " mm";
}

INSTANTIATE_TEST_SUITE_P(Shapes, SparseLimit, ::testing::Values("wave", "steep", "ridge", "demo"));

// Done-when 3 with fitsurf's default for sparse clouds, the kernel prefit (fitsurf.hpp): the same
// ~150 markers interpolated by the kernel that predicts each of them best from the others, the
// net fitted to that. Within 0.1 mm of the truth inside the points' hull on the synth kinds of
// shape and the narrow bump, without wiggles, and closer than the spline's own smoothing of
// either order (docs/measurements/fitsurf.md, sparse markers: 6 jitter seeds, worst bumps 0.087, saddle
// 0.034, wave 0.098, dome 0.032, steep 0.054 mm).
using SparseSeed = std::tuple<std::string, std::uint64_t>;
class SparseKernel : public FitsurfFit, public ::testing::WithParamInterface<SparseSeed> {};

TEST_P(SparseKernel, WithinATenthOfAMillimetre) {
  const auto& [name, seed] = GetParam();
  const test::Shape shape = test::shape(name);
  const PointCloud cloud = cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, seed));
  Options defaults;
  defaults.fit.fold.max_slope_deg = 90;  // the ridge's sides: measure, do not refuse
  const Result r = fit_point_cloud(cloud, defaults);
  ASSERT_TRUE(r.prefit.has_value()) << "150 points for 900 poles: the kernel prefit by default";
  const auto dev = truth(r.fit.surface, shape);
  EXPECT_LE(dev.max_mm, 0.1) << to_string(r.prefit->model);
  EXPECT_LE(dev.max_curvature, 2.0 * dev.true_max_curvature);
  Options o = spline_only();
  o.fit.fold.max_slope_deg = 90;
  o.fit.smoothing_order = 3;
  EXPECT_LT(dev.max_mm, truth(fit_point_cloud(cloud, o).fit.surface, shape).max_mm);
}

INSTANTIATE_TEST_SUITE_P(Shapes, SparseKernel,
                         ::testing::Combine(::testing::Values("bumps", "saddle", "wave", "dome", "steep", "ridge"),
                                            ::testing::Values(std::uint64_t{4}, std::uint64_t{23})));

// Where 150 markers do not reach 0.1 mm with any of the fits (the demo part's blend down to the
// plate, 4 mm shoulders between markers 10 mm apart): the kernel prefit is still free of wiggles
// and closer to the truth over the points' hull than the spline's own smoothing of either order.
// (Not inside the demo part's blend, where its short length ripples between the markers:
// docs/measurements/fitsurf.md has the figures.)
class SparseKernelBeyond : public FitsurfFit, public ::testing::WithParamInterface<std::string> {};

TEST_P(SparseKernelBeyond, CloserThanTheSplineAlone) {
  const test::Shape shape = test::shape(GetParam());
  const PointCloud cloud = cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, 23));
  Options o;
  o.fit.fold.max_slope_deg = 90;  // measure, do not refuse (as the benchmark)
  const auto dev = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  EXPECT_LE(dev.max_curvature, 2.0 * dev.true_max_curvature);
  o.prefit.mode = Prefit::None;
  const auto thin_plate = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  o.fit.smoothing_order = 3;
  const auto order3 = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  EXPECT_LT(dev.max_mm, std::min(thin_plate.max_mm, order3.max_mm))
      << "kernel " << dev.max_mm << ", thin plate " << thin_plate.max_mm << ", order 3 " << order3.max_mm;
  EXPECT_LT(dev.rms_mm, std::min(thin_plate.rms_mm, order3.rms_mm));
}

INSTANTIATE_TEST_SUITE_P(Shapes, SparseKernelBeyond, ::testing::Values("demo"));

// A mismatched marker (1.5 mm off) and a misidentified one (4 mm off) among 150: both, and only
// they, are left out by their leave-one-out residuals, and the fit stays within 0.1 mm.
TEST_F(FitsurfFit, KernelPrefitLeavesOutMismatchedMarkers) {
  const test::Shape shape = test::shape("bumps");
  auto pts = test::sample_grid(shape, 15, 10, 3.0, 0.01, 23);
  pts[37].z() += 1.5;
  pts[102] += Eigen::Vector3d(0, 0, -4);
  const Result r = fit_point_cloud(cloud_of(pts), Options{});
  ASSERT_TRUE(r.prefit.has_value());
  EXPECT_EQ(r.fit.outliers, 2u);
  ASSERT_EQ(r.fit.outlier.size(), pts.size());
  EXPECT_TRUE(r.fit.outlier[37]);
  EXPECT_TRUE(r.fit.outlier[102]);
  EXPECT_EQ(r.fit.weight[37], 0.0);
  EXPECT_LE(truth(r.fit.surface, shape).max_mm, 0.1);
  EXPECT_NEAR(std::abs(r.fit.residual_mm[102]), 4.0, 0.2) << "the outlier's residual is its distance to the surface";
}

// Clean sparse points scattered at random (not on a grid: some far out on the hull's edge, some
// clustered) are not taken for outliers: each leave-one-out residual is judged against its own
// prediction's uncertainty. (Judged by the raw residuals, 8 of 600 such points on bumps and 27 on
// the ridge were rejected; docs/measurements/fitsurf.md.)
class SparseKernelClean : public FitsurfFit, public ::testing::WithParamInterface<SparseSeed> {};

TEST_P(SparseKernelClean, NoOutliersAmongCleanScatteredPoints) {
  const auto& [name, seed] = GetParam();
  const Result r = fit_point_cloud(cloud_of(test::sample(test::shape(name), 150, 0.01, seed)), Options{});
  ASSERT_TRUE(r.prefit.has_value());
  EXPECT_EQ(r.fit.outliers, 0u);
  EXPECT_LT(r.stats.max_abs_mm, 0.05) << "the surface passes through (near) every point";
}

INSTANTIATE_TEST_SUITE_P(Shapes, SparseKernelClean,
                         ::testing::Combine(::testing::Values("bumps", "wave", "steep"),
                                            ::testing::Values(std::uint64_t{1}, std::uint64_t{2})));

// When the prefit is used: auto for few points (<= 400) that are fewer than the net's poles, and
// never with --tolerance, --noise-mm or --weight-by-sigma (the kernel interpolates; the spline
// smooths to a noise level or by weights); --prefit kernel with any of them is a usage error.
TEST_F(FitsurfFit, KernelPrefitOnlyForSparseClouds) {
  const test::Shape shape = test::shape("dome");
  const PointCloud sparse = cloud_of(test::sample_grid(shape, 15, 10, 3.0, 0.01, 25));
  Options o;
  EXPECT_TRUE(fit_point_cloud(sparse, o).prefit.has_value());
  EXPECT_FALSE(fit_point_cloud(cloud_of(test::sample_grid(shape, 30, 20, 1.5, 0.01, 25)), o).prefit.has_value())
      << "600 points";
  Options small_net = o;
  small_net.fit.poles_u = small_net.fit.poles_v = 12;  // 144 poles, fewer than the 150 points
  EXPECT_FALSE(fit_point_cloud(sparse, small_net).prefit.has_value());
  Options kernel = small_net;
  kernel.prefit.mode = Prefit::Kernel;
  EXPECT_TRUE(fit_point_cloud(sparse, kernel).prefit.has_value());
  Options tol = o;
  tol.tolerance = ToleranceOptions{};
  tol.tolerance->tolerance_mm = 1.0;  // met by a 10x8 net on these 150 points
  EXPECT_FALSE(fit_point_cloud(sparse, tol).prefit.has_value());
  tol.prefit.mode = Prefit::Kernel;
  EXPECT_THROW(fit_point_cloud(sparse, tol), UsageError);
  Options noise = o;
  noise.fit.noise_mm = 0.01;
  EXPECT_FALSE(fit_point_cloud(sparse, noise).prefit.has_value());
  noise.prefit.mode = Prefit::Kernel;
  EXPECT_THROW(fit_point_cloud(sparse, noise), UsageError);
  PointCloud with_sigma = sparse;
  with_sigma.add_property("sigma_mm", PlyScalar::Float64).values.assign(with_sigma.points_mm.size(), 0.01);
  Options weighted = o;
  weighted.weight_by_sigma = true;
  EXPECT_FALSE(fit_point_cloud(with_sigma, weighted).prefit.has_value());
}

// Robust reweighting is on by default (--robust reject): a cloud with 1 % gross outliers (mismatched
// features 1-5 mm off) is fitted as if they were absent; a plain fit is pulled by over 1 mm.
TEST_F(FitsurfFit, DefaultRejectsGrossOutliers) {
  const test::Shape shape = test::shape("bumps");
  auto pts = test::sample(shape, 30000, 0.01, 37);
  test::Rng rng(38);
  for (std::size_t k = 0; k < pts.size(); k += 100) pts[k].z() += (k % 200 ? 1 : -1) * rng.uniform(1.0, 5.0);
  Options o;
  EXPECT_EQ(o.fit.robust, RobustLoss::Reject);
  o.fit.fold.max_slope_deg = 90;  // the plain fit may curl at the edge: measure it
  const auto robust = truth(fit_point_cloud(cloud_of(pts), o).fit.surface, shape);
  o.fit.robust = RobustLoss::None;
  const auto clean = truth(fit_point_cloud(cloud_of(test::sample(shape, 30000, 0.01, 37)), o).fit.surface, shape);
  EXPECT_LE(robust.max_mm, 1.5 * clean.max_mm) << "robust " << robust.max_mm << ", clean " << clean.max_mm;
  try {
    const auto plain = truth(fit_point_cloud(cloud_of(pts), o).fit.surface, shape);
    EXPECT_GT(plain.max_mm, 10 * robust.max_mm);
  } catch (const GeometryError&) {
    SUCCEED() << "the plain fit curls over at the edge";
  }
}

// A few mismatched points tens of mm above the part (two-view matches along an epipolar line, as
// in the demo chain without its marker mask) in a cloud with a fine net: each pulls a spike up to
// itself, parameter correction then finds it close to the spike's flank, and the surface folds.
// Screened first against a coarse fit, they are left out from the start. Here the net has under 3
// points per pole, so the reweighting is judged on a coarser net (robust_on_coarser_net); the
// screening comes first there too.
TEST_F(FitsurfFit, GrossOutliersAreScreenedBeforeTheFirstRound) {
  const test::Shape shape = test::shape("demo");
  auto pts = test::sample(shape, 7000, 0.01, 61);
  const auto clean_pts = pts;
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(-68.3, 0.0), Eigen::Vector2d(21.6, -35.7),
                                   Eigen::Vector2d(-60.5, -32.2), Eigen::Vector2d(50.4, 36.6)}) {
    pts.emplace_back(xy.x(), xy.y(), shape.f(xy.x(), xy.y()) + 40.0);
  }
  Options o;
  o.fit.poles_u = 75;
  o.fit.poles_v = 50;
  o.fit.smoothing_mm4 = 1;
  const Result r = fit_point_cloud(cloud_of(pts), o);
  EXPECT_EQ(r.fit.robust_poles_u * r.fit.robust_poles_v > 0, r.fit.robust_applied);
  EXPECT_LT(r.fit.robust_poles_u, 75) << "under 3 points per pole: judged on a coarser net";
  EXPECT_EQ(r.fit.gross_outliers, 4u);
  for (std::size_t k = clean_pts.size(); k < pts.size(); ++k) EXPECT_EQ(r.fit.weight[k], 0.0);
  const auto screened = truth(r.fit.surface, shape);
  const auto clean = truth(fit_point_cloud(cloud_of(clean_pts), o).fit.surface, shape);
  EXPECT_LE(screened.max_mm, 1.1 * clean.max_mm) << "screened " << screened.max_mm << ", clean " << clean.max_mm;
  // No screening: the spikes fold the surface (an error naming the fold), or, since parameter
  // correction stops before a round that curls the surface (stop_before_fold), they are left out
  // by the reweighting instead and none reaches the surface.
  o.fit.gross_threshold = 1e9;
  try {
    EXPECT_LE(truth(fit_point_cloud(cloud_of(pts), o).fit.surface, shape).max_mm, 1.1 * clean.max_mm);
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("folds"), std::string::npos) << e.what();
  }
}

// A net with ~2 points per pole (the demo chain's 75x50 on ~7 000 points) and 1 % of the points
// 0.2-0.3 mm off: too little for the gross screening (20 robust sigmas), too much to keep. The
// fine fit follows each nearly onto itself, so its own residuals cannot show them; judged on the
// coarser net that has 3 points per pole they stand out, and the fine net is fitted without them.
TEST_F(FitsurfFit, RobustWeightsComeFromACoarserNetWhenTheFineOneLacksPoints) {
  const test::Shape shape = test::shape("bumps");
  const auto clean_pts = test::sample(shape, 7000, 0.005, 71);
  auto pts = clean_pts;
  test::Rng rng(72);
  std::vector<std::size_t> injected;
  for (std::size_t k = 0; k < pts.size(); k += 100) {
    pts[k].z() += (k % 200 ? 1 : -1) * rng.uniform(0.2, 0.3);
    injected.push_back(k);
  }
  Options o;
  o.fit.poles_u = 75;
  o.fit.poles_v = 50;
  o.fit.smoothing_mm4 = 1;
  const Result r = fit_point_cloud(cloud_of(pts), o);
  ASSERT_TRUE(r.fit.robust_applied);
  // Both counts scaled by sqrt(n / (3 * 75 * 50)).
  const double f = std::sqrt(static_cast<double>(pts.size()) / (3.0 * 75 * 50));
  EXPECT_EQ(r.fit.robust_poles_u, static_cast<int>(std::floor(75 * f)));
  EXPECT_EQ(r.fit.robust_poles_v, static_cast<int>(std::floor(50 * f)));
  std::size_t caught = 0;
  for (std::size_t k : injected) caught += r.fit.outlier[k];
  EXPECT_GE(caught, injected.size() * 9 / 10) << caught << " of " << injected.size();
  EXPECT_LE(r.fit.outliers, injected.size() + pts.size() / 100) << "clean points rejected";
  const auto robust = truth(r.fit.surface, shape);
  const auto clean = truth(fit_point_cloud(cloud_of(clean_pts), o).fit.surface, shape);
  o.fit.robust_on_coarser_net = false;
  const Result off = fit_point_cloud(cloud_of(pts), o);
  EXPECT_FALSE(off.fit.robust_applied);
  const auto unjudged = truth(off.fit.surface, shape);
  // Measured 2026-11-24: RMS / max from the truth, clean 0.0032 / 0.051 mm, judged on the coarser
  // net 0.0036 / 0.051, not judged (gross screening only) 0.0094 / 0.112.
  EXPECT_LE(robust.rms_mm, 1.3 * clean.rms_mm) << "robust " << robust.rms_mm << ", clean " << clean.rms_mm;
  EXPECT_LE(robust.max_mm, 1.3 * clean.max_mm) << "robust " << robust.max_mm << ", clean " << clean.max_mm;
  EXPECT_GT(unjudged.rms_mm, 2 * clean.rms_mm) << "unjudged " << unjudged.rms_mm << ", clean " << clean.rms_mm;
}

// Robust reweighting: 2 % of the points are outliers 0.5-5 mm off the surface.
std::vector<Eigen::Vector3d> with_outliers(const test::Shape& s, std::size_t n, std::size_t& outliers) {
  auto pts = test::sample(s, n, 0.01, 25);
  test::Rng rng(26);
  outliers = 0;
  for (std::size_t k = 0; k < pts.size(); k += 50) {
    pts[k].z() += (k % 100 ? 1 : -1) * rng.uniform(0.5, 5.0);
    ++outliers;
  }
  return pts;
}

class RobustFit : public FitsurfFit, public ::testing::WithParamInterface<RobustLoss> {};

TEST_P(RobustFit, IgnoresOutliersThatPullAPlainFit) {
  const test::Shape shape = test::shape("bumps");
  std::size_t injected = 0;
  const PointCloud cloud = cloud_of(with_outliers(shape, 100000, injected));
  Options o;
  o.fit.robust = GetParam();
  const Result robust = fit_point_cloud(cloud, o);
  o.fit.robust = RobustLoss::None;
  o.fit.fold.max_slope_deg = 90;  // outliers near the edge curl a plain fit there: measure, do not refuse
  const Result plain = fit_point_cloud(cloud, o);
  const auto a = truth(robust.fit.surface, shape), b = truth(plain.fit.surface, shape);
  EXPECT_LE(a.rms_mm, 0.01);
  EXPECT_GT(b.rms_mm, 2 * a.rms_mm) << "the outliers do pull a plain fit";
  EXPECT_GE(robust.fit.outliers, injected);
  EXPECT_LT(robust.fit.outliers, injected + injected / 10);
  EXPECT_NEAR(robust.stats.inlier_rms_mm, 0.01, 0.001);
  // The residual cloud marks them: weight 0 for the injected ones.
  std::size_t zero = 0;
  for (std::size_t k = 0; k < robust.fit.weight.size(); k += 50) zero += robust.fit.weight[k] == 0.0;
  EXPECT_EQ(zero, injected);
}

INSTANTIATE_TEST_SUITE_P(Losses, RobustFit, ::testing::Values(RobustLoss::Reject, RobustLoss::Tukey),
                         [](const auto& info) { return info.param == RobustLoss::Reject ? "reject" : "tukey"; });

// On clean noisy data rejection changes next to nothing: the same fit as no reweighting.
TEST_F(FitsurfFit, RejectLeavesCleanDataAlone) {
  const PointCloud cloud = cloud_of(test::sample(test::shape("wave"), 30000, 0.01, 36));
  Options o;
  o.fit.robust = RobustLoss::Reject;
  const Result a = fit_point_cloud(cloud, o);
  o.fit.robust = RobustLoss::None;
  const Result b = fit_point_cloud(cloud, o);
  EXPECT_LE(a.fit.outliers, 2u);
  EXPECT_LT(std::abs(a.stats.rms_mm - b.stats.rms_mm), 1e-5);
}

TEST_F(FitsurfFit, HuberLimitsTheirPull) {
  const test::Shape shape = test::shape("bumps");
  std::size_t injected = 0;
  const PointCloud cloud = cloud_of(with_outliers(shape, 50000, injected));
  Options o;
  o.fit.robust = RobustLoss::Huber;
  const auto a = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  o.fit.robust = RobustLoss::None;
  const auto b = truth(fit_point_cloud(cloud, o).fit.surface, shape);
  EXPECT_LT(a.rms_mm, 0.5 * b.rms_mm);
}

// --tolerance: grows the net until the cross-validated RMS meets it, or says it cannot.
TEST_F(FitsurfFit, ToleranceModeChoosesTheSmallestNetThatMeetsIt) {
  const test::Shape shape = test::shape("bumps");
  const PointCloud cloud = cloud_of(test::sample(shape, 20000, 0.01, 27));
  Options o;
  o.tolerance = ToleranceOptions{};
  o.tolerance->tolerance_mm = 0.02;
  const Result r = fit_point_cloud(cloud, o);
  ASSERT_TRUE(r.tolerance.has_value());
  ASSERT_GE(r.tolerance->steps.size(), 2u);
  EXPECT_LE(r.tolerance->cv_mm, 0.02);
  for (std::size_t k = 0; k + 1 < r.tolerance->steps.size(); ++k) EXPECT_GT(r.tolerance->steps[k].cv_mm, 0.02);
  EXPECT_EQ(r.fit.surface.num_poles_u, r.tolerance->poles_u);
  EXPECT_LE(r.stats.rms_mm, 0.02);
  EXPECT_LE(truth(r.fit.surface, shape).rms_mm, 0.02);
}

TEST_F(FitsurfFit, ToleranceBelowTheNoiseCannotBeMet) {
  const PointCloud cloud = cloud_of(test::sample(test::shape("saddle"), 20000, 0.01, 28));
  Options o;
  o.tolerance = ToleranceOptions{};
  o.tolerance->tolerance_mm = 0.005;
  try {
    fit_point_cloud(cloud, o);
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("cannot be met"), std::string::npos) << m;
    EXPECT_NE(m.find("stopped improving"), std::string::npos) << m;
  }
}

// The least-squares machinery reproduces a B-spline surface exactly from its own samples
// (same knots, parameters known: the xy plane and poles at the Greville abscissae make the
// plane projection the true parameterisation).
TEST_F(FitsurfFit, ReproducesABSplineSurfaceFromItsSamples) {
  BSplineSurface truth_s;
  truth_s.degree_u = truth_s.degree_v = 3;
  truth_s.num_poles_u = 12;
  truth_s.num_poles_v = 9;
  truth_s.knots_u = clamped_uniform_knots(12, 3);
  truth_s.knots_v = clamped_uniform_knots(9, 3);
  auto greville = [](const std::vector<double>& U, int i, int p) {
    double s = 0;
    for (int k = 1; k <= p; ++k) s += U[static_cast<std::size_t>(i + k)];
    return s / p;
  };
  test::Rng rng(29);
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 9; ++j) {
      truth_s.poles_mm.emplace_back(150 * greville(truth_s.knots_u, i, 3), 100 * greville(truth_s.knots_v, j, 3),
                                    rng.uniform(20, 40));
    }
  }
  std::vector<Eigen::Vector3d> pts;
  for (int a = 0; a <= 120; ++a) {
    for (int b = 0; b <= 80; ++b) pts.push_back(surface_point(truth_s, a / 120.0, b / 80.0));
  }
  FitOptions o;
  o.poles_u = 12;
  o.poles_v = 9;
  o.plane = PlaneChoice::Xy;
  o.smoothing_mm4 = 0;
  o.parameter_correction = false;
  o.robust = RobustLoss::None;
  const FitResult fit = fit_surface(pts, o);
  EXPECT_EQ(fit.surface.knots_u, truth_s.knots_u);
  EXPECT_EQ(fit.surface.knots_v, truth_s.knots_v);
  for (std::size_t k = 0; k < truth_s.poles_mm.size(); ++k) {
    EXPECT_LT((fit.surface.poles_mm[k] - truth_s.poles_mm[k]).norm(), 1e-8) << k;
  }
}

TEST_F(FitsurfFit, ConjugateGradientsAgreeWithCholesky) {
  const PointCloud cloud = cloud_of(test::sample(test::shape("wave"), 20000, 0.01, 30));
  Options o;
  o.fit.poles_u = o.fit.poles_v = 20;
  const Result a = fit_point_cloud(cloud, o);
  o.fit.solver = LinearSolver::Cg;
  const Result b = fit_point_cloud(cloud, o);
  ASSERT_EQ(a.fit.surface.poles_mm.size(), b.fit.surface.poles_mm.size());
  for (std::size_t k = 0; k < a.fit.surface.poles_mm.size(); ++k) {
    EXPECT_LT((a.fit.surface.poles_mm[k] - b.fit.surface.poles_mm[k]).norm(), 1e-6);
  }
}

TEST_F(FitsurfFit, ThreadCountChangesNothingButRounding) {
  const PointCloud cloud = cloud_of(test::sample(test::shape("dome"), 30000, 0.01, 31));
  Options o;
  o.fit.threads = 1;
  const Result a = fit_point_cloud(cloud, o);
  o.fit.threads = 3;
  const Result b = fit_point_cloud(cloud, o);
  ASSERT_EQ(a.fit.round_rms_mm.size(), b.fit.round_rms_mm.size());
  for (std::size_t k = 0; k < a.fit.surface.poles_mm.size(); ++k) {
    EXPECT_LT((a.fit.surface.poles_mm[k] - b.fit.surface.poles_mm[k]).norm(), 1e-9);
  }
  EXPECT_EQ(a.fit.surface.boundary_uv.size(), b.fit.surface.boundary_uv.size());
}

TEST(AveragedKnots, FollowTheDataAndStayValid) {
  // 80 % of the parameters in [0, 0.3].
  test::Rng rng(32);
  std::vector<double> u;
  for (int k = 0; k < 10000; ++k) u.push_back(k % 5 ? rng.uniform(0, 0.3) : rng.uniform(0.3, 1));
  const auto U = averaged_knots(u, 20, 3);
  ASSERT_EQ(U.size(), 24u);
  for (int k = 0; k <= 3; ++k) {
    EXPECT_EQ(U[static_cast<std::size_t>(k)], 0.0);
    EXPECT_EQ(U[static_cast<std::size_t>(20 + k)], 1.0);
  }
  for (std::size_t k = 4; k < 20; ++k) EXPECT_GT(U[k], U[k - 1]);
  int below = 0;
  for (std::size_t k = 4; k < 20; ++k) below += U[k] < 0.3;
  EXPECT_GE(below, 12) << "about 80 % of the 16 interior knots where 80 % of the data are";
  // Ties everywhere: still strictly increasing.
  const auto T = averaged_knots(std::vector<double>(1000, 0.5), 12, 3);
  for (std::size_t k = 4; k < 12; ++k) EXPECT_GT(T[k], T[k - 1]);
}

// A gap across the data (no points for |x| < 20 mm) leaves uniform knot spans without data: without
// smoothing the system is singular. Averaged knots put a span across the gap and fit.
TEST_F(FitsurfFit, AveragedKnotsBridgeAGapWithoutSmoothing) {
  const test::Shape shape = test::shape("bumps");
  std::vector<Eigen::Vector3d> pts;
  for (const auto& p : test::sample(shape, 60000, 0.01, 33)) {
    if (std::abs(p.x()) > 20) pts.push_back(p);
  }
  Options o;
  o.fit.smoothing_mm4 = 0;
  o.outline.method = OutlineMethod::None;
  EXPECT_THROW(fit_point_cloud(cloud_of(pts), o), GeometryError);
  o.fit.knots = KnotPlacement::Averaged;
  const Result r = fit_point_cloud(cloud_of(pts), o);
  const auto dev = test::compare_with_truth(r.fit.surface, shape, 120, [&](const Eigen::Vector2d& uv) {
    return std::abs(surface_point(r.fit.surface, uv.x(), uv.y()).x()) > 22;
  });
  EXPECT_LE(dev.rms_mm, 0.01);
}

TEST_F(FitsurfFit, ResidualsArePositiveAboveTheSurface) {
  const test::Shape shape = test::shape("dome");
  auto pts = test::sample(shape, 20000, 0.0, 34);
  for (std::size_t k = 0; k < pts.size(); ++k) pts[k].z() += k % 2 ? 0.02 : -0.02;
  Options o;
  o.fit.robust = RobustLoss::None;
  const Result r = fit_point_cloud(cloud_of(pts), o);
  std::size_t right = 0;
  for (std::size_t k = 0; k < pts.size(); ++k) right += (r.fit.residual_mm[k] > 0) == (k % 2 == 1);
  EXPECT_GT(right, pts.size() * 99 / 100);
}

TEST(ResidualStats, NearestRankPercentilesOfTheAbsoluteResiduals) {
  std::vector<double> d;
  for (int k = 100; k >= 1; --k) d.push_back(k % 2 ? -k : k);  // |d| = 1..100, shuffled signs
  FitResult fit;
  const ResidualStats s = residual_stats(d, fit);
  EXPECT_EQ(s.count, 100u);
  EXPECT_EQ(s.p50_mm, 50);
  EXPECT_EQ(s.p90_mm, 90);
  EXPECT_EQ(s.p95_mm, 95);
  EXPECT_EQ(s.p99_mm, 99);
  EXPECT_EQ(s.max_abs_mm, 100);
  EXPECT_NEAR(s.rms_mm, std::sqrt(101.0 * 201.0 / 6.0), 1e-12);  // sqrt(mean k^2)
  EXPECT_NEAR(s.mean_mm, 0.5, 1e-12);                            // pairs (2j, -(2j-1)) sum to 1
  EXPECT_EQ(s.inliers, 100u);
}

// Degenerate input: a clear GeometryError naming the problem, never a surface.
struct DegenerateCase {
  std::string name;
  std::function<std::vector<Eigen::Vector3d>()> points;
  std::function<void(Options&)> configure;
  std::string message;
};

void PrintTo(const DegenerateCase& c, std::ostream* os) { *os << c.name; }

class DegenerateInput : public FitsurfFit, public ::testing::WithParamInterface<DegenerateCase> {};

TEST_P(DegenerateInput, SaysWhatIsWrong) {
  const DegenerateCase& c = GetParam();
  Options o;
  c.configure(o);
  try {
    fit_point_cloud(cloud_of(c.points()), o);
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
  }
}

// Points on a cylinder of radius 40 mm over 270 degrees around the x axis: the part folds over
// any plane.
std::vector<Eigen::Vector3d> folded(std::size_t n) {
  test::Rng rng(35);
  std::vector<Eigen::Vector3d> pts;
  for (std::size_t k = 0; k < n; ++k) {
    const double a = rng.uniform(-0.75, 0.75) * std::numbers::pi;
    pts.emplace_back(rng.uniform(-75, 75), 40 * std::sin(a), 40 * std::cos(a));
  }
  return pts;
}

std::vector<DegenerateCase> degenerate_cases() {
  auto none = [](Options&) {};
  return {
      {"too_few", [] { return test::sample(test::shape("dome"), 12, 0, 1); }, none, "too few"},
      {"too_few_for_degree_5", [] { return test::sample(test::shape("dome"), 30, 0, 1); },
       [](Options& o) { o.fit.degree_u = o.fit.degree_v = 5; }, "at least 36"},
      {"collinear",
       [] {
         std::vector<Eigen::Vector3d> p;
         for (int k = 0; k < 100; ++k) p.emplace_back(k, 2.0 * k, 30);
         return p;
       },
       none, "line"},
      {"coincident", [] { return std::vector<Eigen::Vector3d>(100, Eigen::Vector3d(1, 2, 3)); }, none, "coincide"},
      {"folded_dense", [] { return folded(20000); }, none, "folds over"},
      {"folded_sparse", [] { return folded(100); }, none, "folds over"},
      {"empty_cells_without_smoothing", [] { return test::sample_grid(test::shape("dome"), 6, 5, 1.0, 0, 2); },
       [](Options& o) {
         o.fit.smoothing_mm4 = 0;
         o.prefit.mode = Prefit::None;  // the kernel's samples would fill the cells
       },
       "singular"},
      {"flat_plate_only",
       [] {
         auto p = test::sample(test::shape("dome"), 2000, 0, 3);
         for (auto& x : p) x.z() = 0.01 * x.x();
         return p;
       },
       [](Options& o) { o.select.drop_plane = true; }, "the cloud is flat"},
  };
}

INSTANTIATE_TEST_SUITE_P(Cases, DegenerateInput, ::testing::ValuesIn(degenerate_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace
}  // namespace photomill::fitsurf
