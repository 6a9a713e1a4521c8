// Unit tests of match's parts: union-find tracks that refuse two features of one image, pairwise
// track voting, the pair-selection rule, and the epipolar geometry (F from poses, the Sampson
// distance, robust F on scenes with a dominant plane).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "match/epipolar.hpp"
#include "match/match.hpp"
#include "match/tracks.hpp"

namespace photomill::match {
namespace {

// RootSIFT bytes: 512 sqrt(v / |v|_1) per value, so each row's squared values sum to ~512^2; a
// row with one bin of everything clamps at 255; an empty row stays empty.
TEST(RootSift, ScalesTheSquareRootOfTheL1NormalisedDescriptor) {
  std::vector<std::uint8_t> d(3 * 4, 0);
  for (int k = 0; k < 4; ++k) d[static_cast<std::size_t>(k)] = 25;  // row 0: four equal values
  d[4] = 90, d[5] = 10;                                                 // row 1: 0.9 and 0.1 of the mass
  const auto r = root_sift(d, 4);
  ASSERT_EQ(r.size(), d.size());
  for (int k = 0; k < 4; ++k) EXPECT_EQ(r[static_cast<std::size_t>(k)], 255) << "512 * sqrt(1/4) = 256, clamped";
  EXPECT_EQ(r[4], 255);                                     // 512 * sqrt(0.9) = 485.7
  EXPECT_EQ(r[5], static_cast<std::uint8_t>(std::lround(512 * std::sqrt(0.1))));  // 161.9 -> 162
  EXPECT_EQ(r[6], 0);
  for (std::size_t k = 8; k < 12; ++k) EXPECT_EQ(r[k], 0);
  // A SIFT-like row of 128 values: unit L2 norm times 512, to the rounding.
  std::vector<std::uint8_t> s(128);
  for (std::size_t k = 0; k < s.size(); ++k) s[k] = static_cast<std::uint8_t>((k * 37) % 97);
  const auto rs = root_sift(s, 128);
  double sum2 = 0;
  for (auto v : rs) sum2 += static_cast<double>(v) * v;
  EXPECT_NEAR(std::sqrt(sum2), 512, 2);
}

TEST(BuildTracks, JoinsChainsAndRefusesTwoFeaturesOfOneImage) {
  // a0-b0-c0 chain; c0-a1 would put a0 and a1 (image 0) into one track: refused, the weaker edge.
  const std::vector<MatchEdge> edges{{{0, 0}, {1, 0}, 0.2}, {{1, 0}, {2, 0}, 0.3}, {{2, 0}, {0, 1}, 0.6},
                                     {{3, 5}, {4, 7}, 0.1}};
  UnionStats stats;
  const auto tracks = build_tracks(edges, 2, &stats);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0], (std::vector<FeatureRef>{{0, 0}, {1, 0}, {2, 0}}));
  EXPECT_EQ(tracks[1], (std::vector<FeatureRef>{{3, 5}, {4, 7}}));
  EXPECT_EQ(stats.edges, 4u);
  EXPECT_EQ(stats.conflicts, 1u);
  EXPECT_EQ(stats.joined, 3u);
}

TEST(BuildTracks, BestEdgesWinAConflict) {
  // a1-c0 is the better match: it is taken first, and a0-b0-c0 then keeps a0 out.
  const std::vector<MatchEdge> edges{{{0, 0}, {1, 0}, 0.5}, {{1, 0}, {2, 0}, 0.5}, {{2, 0}, {0, 1}, 0.1}};
  const auto tracks = build_tracks(edges, 2);
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0], (std::vector<FeatureRef>{{0, 0}, {1, 0}}));
  EXPECT_EQ(tracks[1], (std::vector<FeatureRef>{{0, 1}, {2, 0}}));
}

TEST(BuildTracks, MinimumLength) {
  const std::vector<MatchEdge> edges{{{0, 0}, {1, 0}, 0.2}, {{1, 0}, {2, 0}, 0.3}, {{3, 1}, {4, 1}, 0.1}};
  EXPECT_EQ(build_tracks(edges, 3).size(), 1u);
  EXPECT_EQ(build_tracks(edges, 2).size(), 2u);
}

// Observations with a "true position" each; they agree when the positions are equal.
std::vector<std::size_t> vote(const std::vector<int>& where, std::vector<bool>* verified = nullptr,
                              const std::vector<std::pair<std::size_t, std::size_t>>& unknown = {}) {
  return vote_track(
      where.size(),
      [&](std::size_t i, std::size_t j) -> std::optional<bool> {
        for (const auto& [a, b] : unknown) {
          if ((a == i && b == j) || (a == j && b == i)) return std::nullopt;
        }
        return where[i] == where[j];
      },
      verified);
}

TEST(VoteTrack, RemovesTheOddOneOut) {
  EXPECT_EQ(vote({1, 1, 7, 1}), (std::vector<std::size_t>{0, 1, 3}));
  EXPECT_EQ(vote({1, 1, 7, 1, 8}), (std::vector<std::size_t>{0, 1, 3}));
  EXPECT_EQ(vote({1, 1, 1}), (std::vector<std::size_t>{0, 1, 2}));
}

TEST(VoteTrack, TwoThatDisagreeAreBothDropped) {
  EXPECT_TRUE(vote({1, 2}).empty());
  EXPECT_TRUE(vote({1, 2, 3}).empty());
}

TEST(VoteTrack, UncheckablePairsNeitherVerifyNorRemove) {
  std::vector<bool> verified;
  const auto kept = vote({1, 1, 1}, &verified, {{0, 2}, {1, 2}});
  EXPECT_EQ(kept, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(verified, (std::vector<bool>{true, true, false}));
}

TEST(FeaturePairs, ExhaustiveForSmallSetsThenNeighboursAndCodedOverlap) {
  MatchOptions o;
  o.exhaustive_max_images = 5;
  o.sequence_neighbours = 1;
  o.coded_neighbours = 1;
  const auto none = [](std::size_t, std::size_t) { return 0; };
  EXPECT_EQ(feature_pairs(5, o, none).size(), 10u);
  // 8 images: successors only, plus the image sharing most coded points (7 with 0).
  const auto pairs = feature_pairs(8, o, [](std::size_t a, std::size_t b) { return a + b == 7 ? 10 : 0; });
  const std::vector<std::pair<std::size_t, std::size_t>> expected{{0, 1}, {0, 7}, {1, 2}, {1, 6}, {2, 3}, {2, 5},
                                                                   {3, 4}, {4, 5}, {5, 6}, {6, 7}};
  EXPECT_EQ(pairs, expected);
}

// Two cameras looking at the origin from 500 mm.
struct TwoViews {
  Eigen::Matrix3d K;
  Pose a, b;
  Eigen::Vector2d project(const Pose& p, const Eigen::Vector3d& X) const {
    return (K * (p.rotation() * X + p.cam_from_world_translation_mm)).hnormalized();
  }
};

Pose look_from(const Eigen::Vector3d& centre) {
  const Eigen::Vector3d z = (-centre).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitZ().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = z;
  Pose p;
  p.cam_from_world_rotation = Eigen::Quaterniond(R);
  p.cam_from_world_translation_mm = -R * centre;
  return p;
}

TwoViews two_views() {
  TwoViews v;
  v.K << 1200, 0, 499.5, 0, 1200, 374.5, 0, 0, 1;
  v.a = look_from({400, -100, 300});
  v.b = look_from({250, 300, 350});
  return v;
}

TEST(Epipolar, FundamentalFromPosesHoldsForProjectedPoints) {
  const TwoViews v = two_views();
  const Eigen::Matrix3d F = fundamental_from_poses(v.K, v.a, v.b);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-80, 80);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Vector3d X(u(rng), u(rng), u(rng) / 4);
    const Eigen::Vector2d xa = v.project(v.a, X), xb = v.project(v.b, X);
    EXPECT_LT(sampson_distance_px(F, xa, xb), 1e-9);
    // Moving x_b one pixel across its epipolar line costs about 1/sqrt(2) px of Sampson distance
    // (the error is shared between the two images), and never more than 1 px.
    const Eigen::Vector3d line = F * xa.homogeneous();
    const Eigen::Vector2d normal = line.head<2>().normalized();
    const double d = sampson_distance_px(F, xa, xb + normal);
    EXPECT_GT(d, 0.5);
    EXPECT_LE(d, 1.0 + 1e-9);
  }
}

// A plate (z = 0) seen by both views, with a few points off it and wrong matches.
struct PlaneScene {
  std::vector<Eigen::Vector2d> a, b;
  std::vector<bool> off_plane, outlier;
};

PlaneScene plane_scene(unsigned seed, int on_plane, int off, int wrong) {
  const TwoViews v = two_views();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-150, 150), h(5, 30), px(0, 1000), noise(-0.2, 0.2);
  PlaneScene s;
  for (int k = 0; k < on_plane + off + wrong; ++k) {
    const bool is_off = k >= on_plane && k < on_plane + off;
    const Eigen::Vector3d X(u(rng) / 2, u(rng) / 3, is_off ? h(rng) : 0.0);
    Eigen::Vector2d xa = v.project(v.a, X) + Eigen::Vector2d(noise(rng), noise(rng));
    Eigen::Vector2d xb = v.project(v.b, X) + Eigen::Vector2d(noise(rng), noise(rng));
    if (k >= on_plane + off) xb = Eigen::Vector2d(px(rng), px(rng) * 0.75);
    s.a.push_back(xa);
    s.b.push_back(xb);
    s.off_plane.push_back(is_off);
    s.outlier.push_back(k >= on_plane + off);
  }
  return s;
}

class DominantPlane : public ::testing::TestWithParam<unsigned> {};

TEST_P(DominantPlane, RobustFKeepsThePointsOffThePlane) {
  const PlaneScene s = plane_scene(GetParam(), 600, 25, 150);
  const auto fit = estimate_fundamental(s.a, s.b, {});
  ASSERT_TRUE(fit.has_value());
  int off_kept = 0, off = 0, wrong_kept = 0;
  for (std::size_t k = 0; k < s.a.size(); ++k) {
    off += s.off_plane[k] ? 1 : 0;
    off_kept += s.off_plane[k] && fit->inliers[k] ? 1 : 0;
    // A wrong match may land on its epipolar line by chance; the test counts those it keeps
    // beyond what the true F would keep.
    if (s.outlier[k] && fit->inliers[k] &&
        sampson_distance_px(fundamental_from_poses(two_views().K, two_views().a, two_views().b), s.a[k], s.b[k]) > 1) {
      ++wrong_kept;
    }
  }
  EXPECT_EQ(off_kept, off);
  EXPECT_LE(wrong_kept, 2);
}

INSTANTIATE_TEST_SUITE_P(Seeds, DominantPlane, ::testing::Values(1u, 2u, 3u, 4u, 5u));

TEST(Epipolar, TooFewOrDegenerateCorrespondencesGiveNoF) {
  const std::vector<Eigen::Vector2d> few(7, Eigen::Vector2d(1, 2));
  EXPECT_FALSE(estimate_fundamental(few, few, {}).has_value());
  const std::vector<Eigen::Vector2d> same(20, Eigen::Vector2d(5, 5));
  EXPECT_FALSE(estimate_fundamental(same, same, {}).has_value());
}

TEST(Epipolar, UndistorterInvertsOpenCVsModel) {
  Camera c;
  c.image_width_px = 1000;
  c.image_height_px = 750;
  c.camera_matrix << 1200, 0, 499.5, 0, 1200, 374.5, 0, 0, 1;
  c.distortion = {-0.08, 0.06, 0.0004, -0.0003, 0};
  const Undistorter u(c);
  // Distort an ideal point by OpenCV's model and undistort it back.
  const Eigen::Vector2d ideal(900, 100);
  const Eigen::Vector2d xn((ideal.x() - 499.5) / 1200, (ideal.y() - 374.5) / 1200);
  const double r2 = xn.squaredNorm(), radial = 1 - 0.08 * r2 + 0.06 * r2 * r2;
  const Eigen::Vector2d xd(xn.x() * radial + 2 * 0.0004 * xn.x() * xn.y() - 0.0003 * (r2 + 2 * xn.x() * xn.x()),
                           xn.y() * radial + 0.0004 * (r2 + 2 * xn.y() * xn.y()) - 2 * 0.0003 * xn.x() * xn.y());
  const Eigen::Vector2d observed(1200 * xd.x() + 499.5, 1200 * xd.y() + 374.5);
  EXPECT_LT((u.apply({observed})[0] - ideal).norm(), 1e-6);
  EXPECT_FALSE(Undistorter().active());
  EXPECT_EQ(Undistorter().apply({observed})[0], observed);
}

}  // namespace
}  // namespace photomill::match
