// The kernel interpolation of fitsurf's prefit (kernel.hpp): Rippa's leave-one-out residuals
// against explicit refits, interpolation, reproduction of the trend, the choice, and degenerate
// input.
#include "fitsurf/kernel.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "fitsurf/test_shapes.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {

// gtest's name for a parameter (found by argument-dependent lookup, so beside KernelModel).
void PrintTo(const KernelModel& m, std::ostream* os);
void PrintTo(const KernelModel& m, std::ostream* os) { *os << to_string(m); }

namespace {

struct Sample {
  std::vector<Eigen::Vector2d> xy;
  std::vector<double> z;
};

Sample sample(const std::string& shape, std::size_t n, double sigma_mm, std::uint64_t seed) {
  Sample s;
  for (const auto& p : test::sample(test::shape(shape), n, sigma_mm, seed)) {
    s.xy.push_back(p.head<2>());
    s.z.push_back(p.z());
  }
  return s;
}

class EveryKernel : public ::testing::TestWithParam<KernelModel> {};

// e_k = c_k / (A^-1)_kk (Rippa 1999) is the error of predicting point k from the others: the
// same as solving again without it.
TEST_P(EveryKernel, LeaveOneOutMatchesARefitWithoutThePoint) {
  const Sample s = sample("bumps", 60, 0.0, 61);
  const KernelInterpolant all = fit_kernel_model(s.xy, s.z, GetParam());
  for (std::size_t k : {0u, 17u, 42u, 59u}) {
    Sample rest = s;
    rest.xy.erase(rest.xy.begin() + static_cast<std::ptrdiff_t>(k));
    rest.z.erase(rest.z.begin() + static_cast<std::ptrdiff_t>(k));
    const KernelInterpolant without = fit_kernel_model(rest.xy, rest.z, GetParam());
    const double e = s.z[k] - without(s.xy[k]);
    EXPECT_NEAR(all.loo_residual_mm()[k], e, 1e-6 * std::max(1.0, std::abs(e))) << "point " << k;
  }
}

// The interpolant passes through the points: exactly (to rounding) for the polyharmonic kernels,
// within a micrometre for the positive definite ones, whose ridge (1e-8 of phi(0)) moves f(x_k)
// by 1e-8 c_k.
TEST_P(EveryKernel, InterpolatesThePoints) {
  const Sample s = sample("wave", 80, 0.0, 62);
  const KernelInterpolant k = fit_kernel_model(s.xy, s.z, GetParam());
  double worst = 0;
  for (std::size_t i = 0; i < s.z.size(); ++i) worst = std::max(worst, std::abs(k(s.xy[i]) - s.z[i]));
  std::printf("%s: largest |f(x_k) - z_k| %.3g mm\n", to_string(GetParam()).c_str(), worst);
  EXPECT_LT(worst, is_polyharmonic(GetParam().shape) ? 1e-5 : 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Models, EveryKernel,
                         ::testing::Values(KernelModel{KernelShape::Gaussian, 1, 20}, KernelModel{KernelShape::Gaussian, 2, 30},
                                           KernelModel{KernelShape::Matern32, 1, 40}, KernelModel{KernelShape::Matern52, 2, 40},
                                           KernelModel{KernelShape::Matern72, 1, 30}, KernelModel{KernelShape::Polyharmonic3, 2, 0},
                                           KernelModel{KernelShape::Polyharmonic4, 3, 0},
                                           KernelModel{KernelShape::Polyharmonic5, 4, 0}));

// Heights on a quadratic: every kernel whose trend holds quadratics reproduces it exactly, so
// the search finds a leave-one-out RMS of (nearly) zero and the interpolant is the quadratic
// between the points as well.
TEST(Kernel, ReproducesAQuadraticTrendExactly) {
  auto f = [](const Eigen::Vector2d& x) { return 20 + 0.1 * x.x() - 0.05 * x.y() + 0.002 * x.x() * x.x() - 0.003 * x.x() * x.y(); };
  Sample s = sample("dome", 50, 0.0, 63);
  for (std::size_t i = 0; i < s.z.size(); ++i) s.z[i] = f(s.xy[i]);
  const KernelInterpolant k = fit_kernel(s.xy, s.z);
  EXPECT_LT(k.loo_rms_mm(), 1e-6) << to_string(k.model());
  for (const auto& x : {Eigen::Vector2d(0, 0), Eigen::Vector2d(-30, 17), Eigen::Vector2d(55, -40)}) {
    EXPECT_NEAR(k(x), f(x), 1e-6) << x.transpose();
  }
  EXPECT_GT(k.candidates().size(), 100u);
}

// The chosen candidate is the one of smallest leave-one-out RMS, and it is what the result says.
TEST(Kernel, ChoosesTheSmallestLeaveOneOutError) {
  const Sample s = sample("bumps", 120, 0.01, 64);
  const KernelInterpolant k = fit_kernel(s.xy, s.z);
  double best = INFINITY;
  for (const auto& c : k.candidates()) best = std::min(best, c.loo_rms_mm);
  EXPECT_EQ(k.loo_rms_mm(), best);
  double sum2 = 0;
  for (double e : k.loo_residual_mm()) sum2 += e * e;
  EXPECT_NEAR(std::sqrt(sum2 / 120), k.loo_rms_mm(), 1e-12);
}

TEST(Kernel, DegenerateInputIsAGeometryError) {
  const Sample s = sample("dome", 3, 0.0, 66);
  EXPECT_THROW(fit_kernel(s.xy, s.z), GeometryError);
  const std::vector<Eigen::Vector2d> same(10, Eigen::Vector2d(1, 2));
  try {
    fit_kernel(same, std::vector<double>(10, 3.0));
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("coincide"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace photomill::fitsurf
