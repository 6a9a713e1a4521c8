// The data's slope per cell and the choice of parameter plane by it (slope.hpp); the fold check
// relative to the data and the parameter correction stopped before a round that curls the surface
// (fit.hpp, FoldOptions and FitOptions::stop_before_fold).
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "fitsurf/fitsurf.hpp"
#include "fitsurf/slope.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::fitsurf {
namespace {

constexpr double kPi = std::numbers::pi;

// A ramp rising at 0.4 (21.8 degrees over xy) that ends in a falling edge: past x = 38 mm the
// height loses 0.3 (x - 38)^2, down to the edge's end where it falls at edge_deg over xy.
// Its best-fit plane tilts with the ramp, so over it the edge is steeper by the ramp's tilt:
// past 90 degrees for an edge at 75 over xy, as a body scan's flank turns past its plane.
double ramp_end_x(double edge_deg) { return 38 + (0.4 + std::tan(edge_deg * kPi / 180)) / 0.6; }
double ramp_z(double x) { return 0.4 * x - (x > 38 ? 0.3 * (x - 38) * (x - 38) : 0.0); }
std::vector<Eigen::Vector3d> ramp(double edge_deg, std::size_t n, std::uint64_t seed, double noise_mm = 0) {
  test::Rng rng(seed);
  std::vector<Eigen::Vector3d> pts;
  const double x1 = ramp_end_x(edge_deg);
  for (std::size_t k = 0; k < n; ++k) {
    const double x = rng.uniform(-50, x1), y = rng.uniform(0, 60);
    pts.emplace_back(x, y, ramp_z(x) + noise_mm * rng.normal());
  }
  return pts;
}

class DataSlopes : public ::testing::Test {
protected:
  void SetUp() override { log::set_level(log::Level::Quiet); }
};

TEST_F(DataSlopes, ATiltedPlaneHasItsTiltOverXyAndNoneOverItsOwnPlane) {
  // z = 0.5 x: 26.57 degrees over xy.
  test::Rng rng(3);
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < 20000; ++k) {
    const double x = rng.uniform(-50, 50), y = rng.uniform(-30, 30);
    pts.emplace_back(x, y, 0.5 * x);
  }
  double pca = -1, xy = -1;
  EXPECT_EQ(choose_plane(pts, {}, {}, 1.0, &pca, &xy), PlaneChoice::Pca);
  EXPECT_NEAR(xy, std::atan(0.5) * 180 / kPi, 0.01);
  EXPECT_LT(pca, 0.01);
}

TEST_F(DataSlopes, AnEdgeThatTurnsPastTheBestFitPlaneIsHeldByXy) {
  const auto pts = ramp(75, 40000, 5);
  double pca = -1, xy = -1;
  EXPECT_EQ(choose_plane(pts, {}, {}, 1.0, &pca, &xy), PlaneChoice::Xy) << "pca " << pca << ", xy " << xy;
  EXPECT_LT(xy, 75.5);
  EXPECT_GT(pca, xy + 1);
  const PlaneFrame f = parameter_frame(pts, PlaneChoice::Xy);
  std::vector<Eigen::Vector3d> local;
  for (const auto& p : pts) local.push_back(f.to_local(p));
  const DataSlope s = data_slope(local, parameter_box(local));
  EXPECT_LE(s.max_deg, 75.5);
  EXPECT_GT(s.max_at.x() + f.origin_mm.x(), 38) << "the steepest cells are on the edge";
  // On the ramp the data are at 21.8 degrees, on the edge's end at 60-75.
  EXPECT_NEAR(s.near(0 - f.origin_mm.x(), 30 - f.origin_mm.y()), std::atan(0.4) * 180 / kPi, 1.0);
  EXPECT_GT(s.near(ramp_end_x(75) - 0.5 - f.origin_mm.x(), 30 - f.origin_mm.y()), 60);
}

TEST_F(DataSlopes, AScanLineHasNoSlope) {
  // Points on one line in each cell (x fixed per column of cells): no plane, so no slope.
  std::vector<Eigen::Vector3d> local;
  for (int i = 0; i < 50; ++i) {
    for (int j = 0; j < 200; ++j) local.emplace_back(i * 10.0, j * 0.05, 0.1 * j);
  }
  const DataSlope s = data_slope(local, parameter_box(local));
  EXPECT_EQ(s.cells, 0u);
  EXPECT_LT(s.near(5, 5), 0);
}

// With the default options the ramp's edge is fitted over xy: 0.0145 mm RMS (0.01 mm noise), where
// over its best-fit plane, over which the edge is no height field, the fit stays 0.19 mm off.
TEST_F(DataSlopes, AnEdgeSteeperThanThePlaneIsFittedWithTheDefaultOptions) {
  const auto pts = ramp(75, 40000, 7, 0.01);
  Options o;
  o.fit.poles_u = o.fit.poles_v = 30;
  const Result r = fit_point_cloud(test::cloud_of(pts), o);
  EXPECT_EQ(r.fit.plane, PlaneChoice::Xy);
  EXPECT_LT(r.stats.rms_mm, 0.03);
  o.fit.plane = PlaneChoice::Pca;
  const Result p = fit_point_cloud(test::cloud_of(pts), o);
  EXPECT_LT(3 * r.stats.rms_mm, p.stats.rms_mm) << "xy " << r.stats.rms_mm << " rounds " << r.fit.round_rms_mm.size()
                                            << ", pca " << p.stats.rms_mm << " rounds " << p.fit.round_rms_mm.size();
}

// The ramp with its edge at 80 degrees, on an 8 x 8 net: round 8 of the correction curls the
// surface at the edge beyond what the data allow, so it is undone and the correction stops after
// round 7, with a result that passes the fold check; without the stop the same fit is refused.
TEST_F(DataSlopes, NoRoundSteeperThanAllowedIsKept) {
  const auto pts = ramp(80, 20000, 9, 0.05);
  Options o;
  o.fit.poles_u = o.fit.poles_v = 8;
  o.fit.plane = PlaneChoice::Xy;
  const Result r = fit_point_cloud(test::cloud_of(pts), o);
  EXPECT_NO_THROW(check_no_fold(r.fit, r.fit.surface.boundary_uv, o.fit.fold));
  EXPECT_GT(r.fit.stopped_at_round, 0);
  EXPECT_LT(r.fit.stopped_at_round, o.fit.max_rounds);
  EXPECT_EQ(static_cast<int>(r.fit.round_rms_mm.size()), r.fit.stopped_at_round);
  o.fit.stop_before_fold = false;
  EXPECT_THROW(fit_point_cloud(test::cloud_of(pts), o), GeometryError);
}

}  // namespace
}  // namespace photomill::fitsurf
