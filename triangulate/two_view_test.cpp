// Two-view points (issue 24): the check against the neighbours (two_view.hpp) on hand-made
// clouds, and through reconstruct() on the synthetic scene: a wrong match along the epipolar
// line triangulates to a wrong depth with no reprojection error; its sigma (the covariance's
// largest axis) is large and it is removed, while a true two-view point among its neighbours is
// kept.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "triangulate/covariance.hpp"
#include "triangulate/reconstruct.hpp"
#include "triangulate/test_scene.hpp"
#include "triangulate/two_view.hpp"

namespace photomill::triangulate {
namespace {

// A gently curved surface z = 0.002 (x^2 + y^2) sampled every `step` mm over [-20, 20]^2, seen in
// `views` views, with covariance sigma^2 I.
std::vector<CheckedPoint> surface(double step, std::size_t views, double sigma_mm) {
  std::vector<CheckedPoint> pts;
  for (double x = -20; x <= 20; x += step) {
    for (double y = -20; y <= 20; y += step) {
      CheckedPoint p;
      p.xyz_mm = {x, y, 0.002 * (x * x + y * y)};
      p.views = views;
      p.covariance_mm2 = sigma_mm * sigma_mm * Eigen::Matrix3d::Identity();
      pts.push_back(p);
    }
  }
  return pts;
}

CheckedPoint two_view_at(const Eigen::Vector3d& x, double sigma_mm = 0.01) {
  CheckedPoint p;
  p.xyz_mm = x;
  p.views = 2;
  p.covariance_mm2 = sigma_mm * sigma_mm * Eigen::Matrix3d::Identity();
  return p;
}

TEST(TwoViewCheck, KeepsPointsOnTheSurfaceAndRemovesPointsOffIt) {
  std::vector<CheckedPoint> pts = surface(1.0, 5, 0.01);
  const std::size_t on = pts.size();
  pts.push_back(two_view_at({3.3, -4.6, 0.002 * (3.3 * 3.3 + 4.6 * 4.6) + 0.02}));  // on it, within noise
  const std::size_t above = pts.size();
  pts.push_back(two_view_at({-7.2, 5.1, 0.002 * (7.2 * 7.2 + 5.1 * 5.1) + 1.5}));   // 1.5 mm above it
  const std::size_t far = pts.size();
  pts.push_back(two_view_at({0, 0, 120}));                                            // far from everything
  const std::size_t edge = pts.size();
  pts.push_back(two_view_at({20.4, 0, 0.002 * 20.4 * 20.4}));                          // just beyond the edge, on it
  const TwoViewCheck c = check_two_view_points(pts, {});
  ASSERT_TRUE(c.ran);
  EXPECT_EQ(c.reference_points, on);
  EXPECT_EQ(c.checked, 4u);
  // 16 neighbours on a 1 mm grid: the 16th is sqrt(5) mm away.
  EXPECT_NEAR(c.spacing_mm, std::sqrt(5.0), 0.01);
  EXPECT_EQ(c.verdict[on], TwoViewVerdict::Kept) << c.distance_mm[on] << " allowed " << c.allowed_mm[on];
  EXPECT_EQ(c.verdict[above], TwoViewVerdict::OffNeighbours);
  EXPECT_NEAR(c.distance_mm[above], 1.5, 0.05);
  EXPECT_EQ(c.verdict[far], TwoViewVerdict::Unsupported);
  EXPECT_EQ(c.verdict[edge], TwoViewVerdict::Kept) << c.distance_mm[edge] << " allowed " << c.allowed_mm[edge];
  EXPECT_EQ(c.verdict[0], TwoViewVerdict::NotChecked);
  EXPECT_EQ(c.unsupported, 1u);
  EXPECT_EQ(c.off_neighbours, 1u);
}

TEST(TwoViewCheck, APointsOwnSigmaAlongTheNormalWidensItsBound) {
  std::vector<CheckedPoint> pts = surface(1.0, 5, 0.01);
  // 0.5 mm above, known to 0.2 mm along z (its rays nearly vertical and close): within 5 sigma.
  CheckedPoint p = two_view_at({2.5, 2.5, 0.002 * 12.5 + 0.5});
  p.covariance_mm2 = Eigen::Vector3d(1e-4, 1e-4, 0.04).asDiagonal();
  pts.push_back(p);
  // The same offset, uncertain only across the normal: removed.
  CheckedPoint q = two_view_at({-2.5, -2.5, 0.002 * 12.5 + 0.5});
  q.covariance_mm2 = Eigen::Vector3d(0.04, 0.04, 1e-4).asDiagonal();
  pts.push_back(q);
  const TwoViewCheck c = check_two_view_points(pts, {});
  EXPECT_EQ(c.verdict[pts.size() - 2], TwoViewVerdict::Kept);
  EXPECT_EQ(c.verdict[pts.size() - 1], TwoViewVerdict::OffNeighbours);
}

TEST(TwoViewCheck, ACurvedSurfaceIsNotTakenForAnOffset) {
  // A bump of 20 mm radius of curvature at its top, sampled every 2 mm: over the neighbourhood
  // (about 5 mm) its sagitta is 0.6 mm, far beyond the noise; points on it agree, a point 0.5 mm
  // above it does not.
  std::vector<CheckedPoint> pts;
  const auto z = [](double x, double y) { return 10 - (x * x + y * y) / 40; };
  for (double x = -16; x <= 16; x += 2) {
    for (double y = -16; y <= 16; y += 2) {
      CheckedPoint p;
      p.xyz_mm = {x, y, z(x, y)};
      p.views = 4;
      p.covariance_mm2 = 1e-4 * Eigen::Matrix3d::Identity();
      pts.push_back(p);
    }
  }
  const std::size_t first = pts.size();
  for (const auto& [x, y] : {std::pair{1.0, 1.0}, std::pair{-5.0, 7.0}, std::pair{9.0, -3.0}}) pts.push_back(two_view_at({x, y, z(x, y)}));
  pts.push_back(two_view_at({3, -3, z(3, -3) + 0.5}));
  const TwoViewCheck c = check_two_view_points(pts, {});
  for (std::size_t i = first; i < first + 3; ++i) {
    EXPECT_EQ(c.verdict[i], TwoViewVerdict::Kept) << i - first << ": " << c.distance_mm[i] << " allowed " << c.allowed_mm[i];
  }
  EXPECT_EQ(c.verdict.back(), TwoViewVerdict::OffNeighbours) << c.distance_mm.back() << " allowed " << c.allowed_mm.back();
  EXPECT_NEAR(c.distance_mm.back(), 0.5, 0.05);
}

TEST(TwoViewCheck, OptionsGovernTheBounds) {
  std::vector<CheckedPoint> pts = surface(1.0, 5, 0.01);
  pts.push_back(two_view_at({1.5, 1.5, 0.002 * 4.5 + 0.3}));  // 0.3 mm above
  pts.push_back(two_view_at({30, 0, 0.002 * 900}));           // 10 mm beyond the edge
  const std::size_t above = pts.size() - 2, beyond = pts.size() - 1;
  const TwoViewCheck defaults = check_two_view_points(pts, {});
  EXPECT_EQ(defaults.verdict[above], TwoViewVerdict::OffNeighbours);
  EXPECT_EQ(defaults.verdict[beyond], TwoViewVerdict::Unsupported);
  TwoViewOptions loose;
  loose.tolerance_mm = 0.4;
  loose.reach = 20;
  const TwoViewCheck c = check_two_view_points(pts, loose);
  EXPECT_EQ(c.verdict[above], TwoViewVerdict::Kept);
  EXPECT_NE(c.verdict[beyond], TwoViewVerdict::Unsupported);
  TwoViewOptions off;
  off.enabled = false;
  const TwoViewCheck none = check_two_view_points(pts, off);
  EXPECT_FALSE(none.ran);
  EXPECT_EQ(none.verdict[above], TwoViewVerdict::Kept);
  EXPECT_EQ(none.verdict[beyond], TwoViewVerdict::Kept);
}

TEST(TwoViewCheck, NeedsPointsSeenThriceNotControlPointsAlone) {
  // Two photos only: every point is a two-view point; nothing can be checked, all are kept.
  std::vector<CheckedPoint> pts = surface(2.0, 2, 0.01);
  pts.push_back(two_view_at({0, 0, 50}));
  TwoViewCheck c = check_two_view_points(pts, {});
  EXPECT_FALSE(c.ran);
  EXPECT_TRUE(std::all_of(c.verdict.begin(), c.verdict.end(), [](TwoViewVerdict v) { return v == TwoViewVerdict::Kept; }));
  // Control points on a plate are no evidence about a part above it.
  std::vector<CheckedPoint> plate = surface(4.0, 2, 0);
  for (CheckedPoint& p : plate) p.control = true;
  plate.push_back(two_view_at({0, 0, 30}));
  c = check_two_view_points(plate, {});
  EXPECT_FALSE(c.ran);
  EXPECT_EQ(c.verdict.back(), TwoViewVerdict::Kept);
  // Empty input.
  EXPECT_TRUE(check_two_view_points({}, {}).verdict.empty());
}

TEST(Covariance, SigmaIsTheLargestAxis) {
  // An ellipsoid 0.1 x 0.02 x 0.01 mm, turned: sigma_mm is its semi-major axis, 0.1 mm, where
  // the RMS per axis sqrt(trace / 3) says 0.059.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Matrix3d cov = R * Eigen::Vector3d(1e-2, 4e-4, 1e-4).asDiagonal() * R.transpose();
  EXPECT_NEAR(largest_axis_sigma_mm(cov), 0.1, 1e-12);
  EXPECT_EQ(largest_axis_sigma_mm(Eigen::Matrix3d::Zero()), 0);
  EXPECT_TRUE(std::isnan(largest_axis_sigma_mm(Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN()))));
}

TEST(Reconstruct, AWrongTwoViewMatchHasALargeSigmaAndIsRemoved) {
  test::SceneOptions so;
  so.random_part_points = 1500;  // seen in every view that sees them: the references
  const test::SceneTruth truth = test::make_scene(so);
  test::SceneTruth scene = truth;
  // Two neighbouring views (30 degrees apart on the ring, at 35 and 55 degrees elevation).
  const std::size_t a = 0, b = 1;
  const Pose& pa = truth.poses[a];
  // A true point of the part seen in two views only.
  test::add_two_view_track(scene, 900001, a, b, {10.3, -7.9, test::part_height_mm(so, 10.3, -7.9)}, 0);
  // A wrong match: in view b the feature belongs to the point 6 mm farther along a's ray through
  // X (so it lies on X's epipolar line in b): the two rays meet there, inside the part (1.9 mm
  // under its top, which falls away along the ray), with no reprojection error at all.
  const Eigen::Vector3d wrong =
      test::add_two_view_track(scene, 900002, a, b, {3.1, -2.4, test::part_height_mm(so, 3.1, -2.4)}, 6.0);
  ReconstructInput in;
  in.tracks = scene.tracks;
  in.camera = truth.camera;
  in.control_points = truth.plate_points;
  // The same without the check: both kept, for the sigma comparison.
  ReconstructOptions keep;
  keep.two_view.enabled = false;
  const Reconstruction all = reconstruct(in, keep);
  const auto index = [&](const Reconstruction& r, TrackId id) { return *r.scene.find_track(id); };
  const std::size_t tw = index(all, 900002), tg = index(all, 900001);
  ASSERT_TRUE(all.in_result[tw] && all.in_result[tg]);
  EXPECT_LT((all.scene.tracks[tw].xyz_mm - wrong).norm(), 0.05) << "triangulated at the wrong depth";
  // Its sigma is the covariance's largest axis, along the rays: several times the RMS per axis
  // and far above a point seen in every view.
  const Eigen::Matrix3d& cov = all.covariance_mm2[tw];
  EXPECT_DOUBLE_EQ(all.sigma_mm[tw], largest_axis_sigma_mm(cov));
  EXPECT_GT(all.sigma_mm[tw], 1.5 * std::sqrt(cov.trace() / 3));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d major = eig.eigenvectors().col(2);
  const Eigen::Vector3d ray = (all.scene.tracks[tw].xyz_mm - pa.centre_mm()).normalized();
  const Eigen::Vector3d ray_b = (all.scene.tracks[tw].xyz_mm - truth.poses[b].centre_mm()).normalized();
  EXPECT_GT(std::abs(major.dot((ray + ray_b).normalized())), 0.95) << "the major axis bisects the two rays";
  std::vector<double> multi;
  for (std::size_t t = 0; t < all.scene.tracks.size(); ++t) {
    if (all.in_result[t] && !all.scene.tracks[t].at_control && all.scene.active_observations(t).size() >= 6) {
      multi.push_back(all.sigma_mm[t]);
    }
  }
  ASSERT_FALSE(multi.empty());
  std::nth_element(multi.begin(), multi.begin() + static_cast<std::ptrdiff_t>(multi.size() / 2), multi.end());
  EXPECT_GT(all.sigma_mm[tw], 3 * multi[multi.size() / 2]);

  // With the check (the default): the wrong one removed, the good one kept.
  const Reconstruction r = reconstruct(in, {});
  EXPECT_TRUE(r.in_result[index(r, 900001)]);
  EXPECT_FALSE(r.in_result[index(r, 900002)]);
  EXPECT_TRUE(r.report.two_view.ran);
  EXPECT_EQ(r.report.two_view.checked, 2u);
  ASSERT_EQ(r.report.two_view.removed.size(), 1u);
  EXPECT_EQ(r.report.two_view.removed[0].track_id, 900002);
  EXPECT_EQ(r.report.two_view.removed[0].reason, "off_neighbours");
  EXPECT_GT(r.report.two_view.removed[0].distance_mm, 1.0);
  EXPECT_GT(r.report.two_view.removed[0].distance_mm, r.report.two_view.removed[0].allowed_mm);
  EXPECT_EQ(r.report.tracks_dropped.at("two_view_off_neighbours"), 1u);
  EXPECT_EQ(r.report.points + 1, all.report.points);
  ASSERT_FALSE(r.report.warnings.empty());
  EXPECT_NE(r.report.warnings.back().find("--two-view-sigmas"), std::string::npos) << r.report.warnings.back();
  const PointCloud cloud = make_point_cloud(r);
  EXPECT_EQ(cloud.points_mm.size(), r.report.points);
}

}  // namespace
}  // namespace photomill::triangulate
