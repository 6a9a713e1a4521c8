// The least-squares core against dense references: Gauss-Legendre exactness, the banded normal
// equations against a dense A^T W A, thread-count invariance, the sparse assembly, and the
// thin-plate energy of polynomials it must reproduce exactly.
#include "fitsurf/normal_equations.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "formats/error.hpp"

#include "fitsurf/fit.hpp"
#include "fitsurf/test_shapes.hpp"

namespace photomill::fitsurf {
namespace {

class GaussLegendre : public ::testing::TestWithParam<int> {};

TEST_P(GaussLegendre, IntegratesPolynomialsUpToDegree2nMinus1Exactly) {
  const int n = GetParam();
  std::vector<double> x, w;
  gauss_legendre(n, x, w);
  for (int k = 0; k <= 2 * n - 1; ++k) {
    double sum = 0;
    for (int i = 0; i < n; ++i) sum += w[static_cast<std::size_t>(i)] * std::pow(x[static_cast<std::size_t>(i)], k);
    const double exact = k % 2 ? 0.0 : 2.0 / (k + 1);
    EXPECT_NEAR(sum, exact, 1e-14) << "n " << n << " k " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(Orders, GaussLegendre, ::testing::Values(1, 2, 3, 4, 6, 9, 26));

SplineSpace small_space() {
  SplineSpace s;
  s.p = 3;
  s.q = 2;
  s.nu = 7;
  s.nv = 6;
  s.U = {0, 0, 0, 0, 0.2, 0.45, 0.7, 1, 1, 1, 1};
  s.V = {0, 0, 0, 0.3, 0.5, 0.8, 1, 1, 1};
  return s;
}

struct RandomData {
  std::vector<Eigen::Vector2d> uv;
  std::vector<Eigen::Vector3d> q;
  std::vector<double> w;
};

RandomData random_data(std::size_t n, std::uint64_t seed) {
  test::Rng rng(seed);
  RandomData d;
  for (std::size_t k = 0; k < n; ++k) {
    d.uv.emplace_back(rng.uniform(), rng.uniform());
    d.q.emplace_back(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 40));
    d.w.push_back(k % 7 == 0 ? 0.0 : rng.uniform(0.1, 2.0));
  }
  return d;
}

// Dense A (points x poles) with A[k][g] = N_i(u_k) N_j(v_k), from the shared basis functions.
Eigen::MatrixXd dense_collocation(const SplineSpace& s, const std::vector<Eigen::Vector2d>& uv) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(uv.size()), s.num_poles());
  for (std::size_t k = 0; k < uv.size(); ++k) {
    const BasisRow bu = basis_row(s.nu - 1, s.p, uv[k].x(), s.U);
    const BasisRow bv = basis_row(s.nv - 1, s.q, uv[k].y(), s.V);
    for (int a = 0; a <= s.p; ++a) {
      for (int b = 0; b <= s.q; ++b) {
        A(static_cast<Eigen::Index>(k), (bu.first + a) * s.nv + bv.first + b) =
            bu.values[static_cast<std::size_t>(a)] * bv.values[static_cast<std::size_t>(b)];
      }
    }
  }
  return A;
}

class Accumulation : public ::testing::TestWithParam<int> {};

TEST_P(Accumulation, EqualsDenseNormalEquationsWhateverTheThreadCount) {
  const SplineSpace s = small_space();
  const RandomData d = random_data(5000, 11);
  const DataNormalEquations ne = accumulate_normal_equations(s, d.uv, d.q, d.w, GetParam());
  const Eigen::MatrixXd A = dense_collocation(s, d.uv);
  const Eigen::VectorXd w = Eigen::Map<const Eigen::VectorXd>(d.w.data(), static_cast<Eigen::Index>(d.w.size()));
  const Eigen::MatrixXd AtWA = A.transpose() * w.asDiagonal() * A;
  Eigen::MatrixXd Q(static_cast<Eigen::Index>(d.q.size()), 3);
  for (std::size_t k = 0; k < d.q.size(); ++k) Q.row(static_cast<Eigen::Index>(k)) = d.q[k].transpose();
  const Eigen::MatrixXd AtWQ = A.transpose() * w.asDiagonal() * Q;
  const double scale = AtWA.cwiseAbs().maxCoeff();
  for (int g = 0; g < s.num_poles(); ++g) {
    for (int g2 = 0; g2 < s.num_poles(); ++g2) {
      ASSERT_NEAR(ne.matrix.entry(g, g2), AtWA(g, g2), 1e-12 * scale) << g << "," << g2;
    }
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(ne.rhs[static_cast<std::size_t>(g)][c], AtWQ(g, c), 1e-10 * AtWQ.cwiseAbs().maxCoeff());
    }
  }
  EXPECT_NEAR(ne.weight_sum, w.sum(), 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Threads, Accumulation, ::testing::Values(1, 2, 3, 8));

TEST(AssembleSparse, IsTheSymmetricSumOfBothStencils) {
  const SplineSpace s = small_space();
  const RandomData d = random_data(2000, 5);
  const DataNormalEquations ne = accumulate_normal_equations(s, d.uv, d.q, d.w, 1);
  const BandedSymmetric K = thin_plate_matrix(s, 150, 100);
  const Eigen::SparseMatrix<double> M = assemble_sparse(ne.matrix, 0.5, K, 3.0);
  const Eigen::MatrixXd dense(M);
  EXPECT_LT((dense - dense.transpose()).cwiseAbs().maxCoeff(), 1e-15 * dense.cwiseAbs().maxCoeff());
  for (int g = 0; g < s.num_poles(); ++g) {
    for (int g2 = 0; g2 < s.num_poles(); ++g2) {
      EXPECT_NEAR(dense(g, g2), 0.5 * ne.matrix.entry(g, g2) + 3.0 * K.entry(g, g2), 1e-14 * dense.cwiseAbs().maxCoeff());
    }
  }
}

// z = a x^2 + b x y + c y^2 + e x^3 + f x^2 y + g x y^2 + h y^3 (x, y affine in u, v) lies in the
// spline space of any degree >= 3 (>= 2 without the cubic terms), so a fit without smoothing
// reproduces it. Its energies per unit area are then exact: order 3 (third derivatives 6e, 2f, 2g,
// 6h, constant) (6e)^2 + 3 (2f)^2 + 3 (2g)^2 + (6h)^2, whatever the quadratic part (the null space of
// order 3 is the quadrics); order 2, for the quadratic part alone, (2a)^2 + 2 b^2 + (2c)^2. The
// affine x(u,v), y(u,v) have neither.
struct Polynomial {
  double a, b, c;     // quadratic part
  double e, f, g, h;  // cubic part
  int degree;
};

class SmoothingEnergy : public ::testing::TestWithParam<Polynomial> {};

TEST_P(SmoothingEnergy, ReproducesPolynomialsAndTheirEnergy) {
  const Polynomial pd = GetParam();
  const bool cubic = pd.e != 0 || pd.f != 0 || pd.g != 0 || pd.h != 0;
  std::vector<Eigen::Vector3d> pts;
  test::Rng rng(3);
  for (int k = 0; k < 4000; ++k) {
    const double x = k < 4 ? (k % 2 ? 75.0 : -75.0) : rng.uniform(-75, 75);
    const double y = k < 4 ? (k / 2 ? 50.0 : -50.0) : rng.uniform(-50, 50);
    pts.emplace_back(x, y, pd.a * x * x + pd.b * x * y + pd.c * y * y + pd.e * x * x * x + pd.f * x * x * y +
                               pd.g * x * y * y + pd.h * y * y * y);
  }
  FitOptions o;
  o.degree_u = o.degree_v = pd.degree;
  o.poles_u = 9;
  o.poles_v = 7;
  o.plane = PlaneChoice::Xy;
  o.smoothing_mm4 = 0;
  o.parameter_correction = false;
  o.robust = RobustLoss::None;
  const FitResult fit = fit_surface(pts, o);
  double worst = 0;
  for (double r : fit.residual_mm) worst = std::max(worst, std::abs(r));
  EXPECT_LT(worst, 1e-9);

  SplineSpace s;
  s.p = s.q = pd.degree;
  s.nu = 9;
  s.nv = 7;
  s.U = fit.local_surface.knots_u;
  s.V = fit.local_surface.knots_v;
  for (int order : {2, 3}) {
    if (order == 2 && cubic) continue;  // its second derivatives vary: no closed form here
    const BandedSymmetric K = thin_plate_matrix(s, fit.box.length_u_mm(), fit.box.length_v_mm(), order);
    for (int c = 0; c < 3; ++c) {
      double energy = 0;
      for (int g = 0; g < s.num_poles(); ++g) {
        for (int g2 = 0; g2 < s.num_poles(); ++g2) {
          energy += fit.local_surface.poles_mm[static_cast<std::size_t>(g)][c] * K.entry(g, g2) *
                    fit.local_surface.poles_mm[static_cast<std::size_t>(g2)][c];
        }
      }
      const double expected = c != 2       ? 0.0
                              : order == 2 ? 4 * pd.a * pd.a + 2 * pd.b * pd.b + 4 * pd.c * pd.c
                                           : 36 * pd.e * pd.e + 12 * pd.f * pd.f + 12 * pd.g * pd.g + 36 * pd.h * pd.h;
      EXPECT_NEAR(energy, expected, 1e-9 * std::max(1.0, expected)) << "order " << order << ", coordinate " << c;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Polynomials, SmoothingEnergy,
                         ::testing::Values(Polynomial{0.01, 0, 0, 0, 0, 0, 0, 3}, Polynomial{0, 0.02, 0, 0, 0, 0, 0, 3},
                                           Polynomial{0, 0, -0.015, 0, 0, 0, 0, 3},
                                           Polynomial{0.004, -0.01, 0.007, 0, 0, 0, 0, 3},
                                           Polynomial{0.004, -0.01, 0.007, 0, 0, 0, 0, 2},
                                           Polynomial{0.004, -0.01, 0.007, 0, 0, 0, 0, 5},
                                           Polynomial{0.004, -0.01, 0.007, 1e-4, 0, 0, 0, 3},
                                           Polynomial{0, 0, 0, 0, -2e-4, 0, 0, 3}, Polynomial{0, 0, 0, 0, 0, 3e-4, 0, 3},
                                           Polynomial{0.002, 0, -0.003, 1e-4, -2e-4, 3e-4, -1e-4, 3},
                                           Polynomial{0.002, 0, -0.003, 1e-4, -2e-4, 3e-4, -1e-4, 4}));

TEST(SmoothingEnergy, OrdersOtherThanTwoAndThreeAreRefused) {
  EXPECT_THROW(thin_plate_matrix(small_space(), 150, 100, 1), UsageError);
  EXPECT_THROW(thin_plate_matrix(small_space(), 150, 100, 4), UsageError);
}

}  // namespace
}  // namespace photomill::fitsurf
