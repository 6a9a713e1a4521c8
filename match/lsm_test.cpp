// Least-squares matching against images with a known affine relation: the reference is a
// speckle texture, the search image the same texture mapped by a known affine transformation
// (plus brightness, contrast and noise), so the true search point of every reference point is known.
#include "match/lsm.hpp"

#include <cmath>
#include <iostream>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

namespace photomill::match {
namespace {

// A continuous random texture: a sum of plane waves of wavelengths 6..20 px with random
// directions and phases (band-limited, so point samples of it are exact images of it).
struct Texture {
  std::vector<Eigen::Vector3d> waves;  // kx, ky, phase
  explicit Texture(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int k = 0; k < 48; ++k) {
      const double wavelength = 6 + 14 * u(rng), dir = 2 * M_PI * u(rng);
      waves.emplace_back(2 * M_PI / wavelength * std::cos(dir), 2 * M_PI / wavelength * std::sin(dir), 2 * M_PI * u(rng));
    }
  }
  double at(const Eigen::Vector2d& p) const {
    double v = 0;
    for (const auto& w : waves) v += std::cos(w.x() * p.x() + w.y() * p.y() + w.z());
    return 128 + 12 * v;
  }
};

struct Warp {
  Eigen::Matrix2d A;
  Eigen::Vector2d c;  // search = A (ref - c) + c + shift + bend (d = ref - c)
  Eigen::Vector2d shift;
  // Second-order part, as a curved surface seen from two places makes it:
  // bend(d) = (qx . (dx^2, dx dy, dy^2), qy . (dx^2, dx dy, dy^2)).
  Eigen::Vector3d qx = Eigen::Vector3d::Zero(), qy = Eigen::Vector3d::Zero();
  Eigen::Vector2d bend(const Eigen::Vector2d& d) const {
    const Eigen::Vector3d m(d.x() * d.x(), d.x() * d.y(), d.y() * d.y());
    return {qx.dot(m), qy.dot(m)};
  }
  Eigen::Vector2d map(const Eigen::Vector2d& p) const { return A * (p - c) + c + shift + bend(p - c); }
  // The map's derivative at p: its local affine part.
  Eigen::Matrix2d jacobian(const Eigen::Vector2d& p) const {
    const Eigen::Vector2d d = p - c;
    Eigen::Matrix2d J = A;
    J.row(0) += Eigen::RowVector2d(2 * qx[0] * d.x() + qx[1] * d.y(), qx[1] * d.x() + 2 * qx[2] * d.y());
    J.row(1) += Eigen::RowVector2d(2 * qy[0] * d.x() + qy[1] * d.y(), qy[1] * d.x() + 2 * qy[2] * d.y());
    return J;
  }
  // The inverse by Newton's method from the affine inverse.
  Eigen::Vector2d unmap(const Eigen::Vector2d& q) const {
    Eigen::Vector2d p = A.inverse() * (q - c - shift) + c;
    for (int it = 0; it < 20 && (qx.any() || qy.any()); ++it) p -= jacobian(p).inverse() * (map(p) - q);
    return p;
  }
};

cv::Mat render(const Texture& t, int w, int h, const Warp* warp = nullptr, double gain = 1, double offset = 0,
               double noise = 0, unsigned seed = 1) {
  cv::Mat im(h, w, CV_32F);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise > 0 ? noise : 1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d q(x, y);
      im.at<float>(y, x) = static_cast<float>(gain * t.at(warp ? warp->unmap(q) : q) + offset + (noise > 0 ? noise * n(rng) : 0));
    }
  }
  return im;
}

struct Case {
  const char* name;
  double angle_deg, zoom, shear, gain, offset, noise;
};

class LsmAccuracy : public ::testing::TestWithParam<Case> {};

TEST_P(LsmAccuracy, RecoversTheSearchPointToHundredthsOfAPixel) {
  const Case& k = GetParam();
  const Texture tex(7);
  const cv::Mat f = render(tex, 400, 400);
  Warp w;
  const double a = k.angle_deg * M_PI / 180;
  w.A = k.zoom * (Eigen::Matrix2d() << std::cos(a), -std::sin(a), std::sin(a), std::cos(a)).finished() *
        (Eigen::Matrix2d() << 1, k.shear, 0, 1).finished();
  w.c = {200, 200};
  w.shift = {3.3, -2.7};
  const cv::Mat g = render(tex, 400, 400, &w, k.gain, k.offset, k.noise, 11);
  LsmOptions o;
  double sum = 0;
  int n = 0;
  for (int i = 0; i < 25; ++i) {
    const Eigen::Vector2d ref(140 + 30 * (i % 5) + 0.37, 140 + 30 * (i / 5) + 0.61);
    const Eigen::Vector2d truth = w.map(ref);
    // Start as SIFT would leave it: about a pixel off, rotation and zoom roughly right.
    const Eigen::Vector2d start = truth + Eigen::Vector2d(0.8, -0.6);
    const Eigen::Matrix2d A0 = k.zoom * Eigen::Rotation2Dd(a + 0.1).toRotationMatrix();
    LsmFailure why = LsmFailure::None;
    const auto r = lsm_align(f, ref, 10, g, A0, start, o, &why);
    ASSERT_TRUE(r.has_value()) << k.name << " point " << i << ": " << to_string(why);
    const double e = (r->point_px - truth).norm();
    sum += e * e;
    ++n;
    EXPECT_GT(r->correlation, 0.95);
    EXPECT_LT((r->affine - w.A).norm(), 0.02) << r->affine;
  }
  const double rms = std::sqrt(sum / n);
  EXPECT_LT(rms, k.noise > 0 ? 0.03 : 0.01) << k.name;
}

INSTANTIATE_TEST_SUITE_P(Warps, LsmAccuracy,
                         ::testing::Values(Case{"shift", 0, 1, 0, 1, 0, 0}, Case{"rotated", 25, 1, 0, 1, 0, 0},
                                           Case{"zoomed_sheared", -10, 1.3, 0.25, 1, 0, 0},
                                           Case{"radiometry_noise", 5, 0.9, 0.1, 0.7, 25, 2.0}),
                         [](const auto& info) { return std::string(info.param.name); });

// A map with second-order terms (0.0015/px: about what a 4 mm shoulder seen from two photos 40
// degrees apart gives at 5 px/mm): the affine model's point is off by the bend's mean over the
// window, the quadratic model's is not.
TEST(Lsm, QuadraticModelTakesOutTheBendOfACurvedSurface) {
  const Texture tex(5);
  const cv::Mat f = render(tex, 400, 400);
  Warp w;
  w.A = Eigen::Rotation2Dd(0.2).toRotationMatrix() * 1.1;
  w.c = {200, 200};
  w.shift = {2.1, -1.4};
  w.qx = {0.0015, 0.0005, 0.0015};
  w.qy = {-0.0005, 0.001, 0.0010};
  const cv::Mat g = render(tex, 400, 400, &w, 0.9, 10, 0, 3);
  const auto rms_error = [&](bool quadratic) {
    LsmOptions o;
    o.quadratic = quadratic;
    double sum = 0;
    int n = 0;
    for (int i = 0; i < 25; ++i) {
      const Eigen::Vector2d ref(140 + 30 * (i % 5) + 0.37, 140 + 30 * (i / 5) + 0.61);
      const Eigen::Vector2d truth = w.map(ref);
      // The start: the map's local affine part at ref, a pixel off.
      LsmFailure why = LsmFailure::None;
      const auto r = lsm_align(f, ref, 12, g, w.jacobian(ref), truth + Eigen::Vector2d(0.7, 0.5), o, &why);
      EXPECT_TRUE(r.has_value()) << (quadratic ? "quadratic" : "affine") << " point " << i << ": " << to_string(why);
      if (!r) continue;
      sum += (r->point_px - truth).squaredNorm();
      ++n;
    }
    return n ? std::sqrt(sum / n) : INFINITY;
  };
  const double affine = rms_error(false), quadratic = rms_error(true);
  std::cout << "[ lsm      ] point error with a bend: affine model " << affine << " px, quadratic " << quadratic << " px\n";
  EXPECT_GT(affine, 0.05);
  EXPECT_LT(quadratic, 0.01);
}

TEST(Lsm, RefusesFlatWindowsOtherTextureAndTheBorder) {
  const cv::Mat f = render(Texture(3), 200, 200);
  const cv::Mat other = render(Texture(99), 200, 200);
  const cv::Mat flat(200, 200, CV_32F, cv::Scalar(128));
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
  const LsmOptions o;
  LsmFailure why = LsmFailure::None;
  EXPECT_FALSE(lsm_align(f, {100, 100}, 8, flat, I, {100, 100}, o, &why));
  EXPECT_EQ(why, LsmFailure::Singular);
  EXPECT_FALSE(lsm_align(f, {100, 100}, 8, other, I, {100, 100}, o, &why));
  EXPECT_TRUE(why == LsmFailure::Correlation || why == LsmFailure::Shift || why == LsmFailure::NotConverged ||
              why == LsmFailure::Zoom)
      << to_string(why);
  EXPECT_FALSE(lsm_align(f, {4, 100}, 8, f, I, {4, 100}, o, &why));
  EXPECT_EQ(why, LsmFailure::Border);
  // The same image aligns onto itself at once.
  const auto r = lsm_align(f, {100.25, 99.5}, 8, f, I, {100.25, 99.5}, o, &why);
  ASSERT_TRUE(r);
  EXPECT_LT((r->point_px - Eigen::Vector2d(100.25, 99.5)).norm(), 1e-6);
  EXPECT_NEAR(r->correlation, 1.0, 1e-9);
}

TEST(Lsm, HalfWindowFollowsTheFeatureSizeWithinLimits) {
  LsmOptions o;
  EXPECT_EQ(half_window_for(2.0, o), o.min_half_window_px);
  EXPECT_EQ(half_window_for(8.4, o), 8);
  EXPECT_EQ(half_window_for(80, o), o.max_half_window_px);
}

}  // namespace
}  // namespace photomill::match
