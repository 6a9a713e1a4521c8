// Nelder-Mead on functions with known minima: Rosenbrock (the classic curved valley) and an
// ill-conditioned quadratic in tens of dimensions (the regime of a calibration).
#include <gtest/gtest.h>

#include <cmath>

#include "calib/simplex.hpp"

namespace photomill::calib {
namespace {

struct SimplexCase {
  const char* name;
  int dim;
  bool adaptive;
};

void PrintTo(const SimplexCase& c, std::ostream* os) { *os << c.name; }

class SimplexTest : public ::testing::TestWithParam<SimplexCase> {};

// f(x) = sum_i (i + 1)^2 (x_i - c_i)^2 with c_i = i / 10: condition number dim^2, minimum 0 at c.
TEST_P(SimplexTest, FindsTheMinimumOfAnIllConditionedQuadratic) {
  const auto& p = GetParam();
  Eigen::VectorXd c(p.dim);
  for (int i = 0; i < p.dim; ++i) c(i) = i / 10.0;
  auto f = [&](const Eigen::VectorXd& x) {
    double s = 0;
    for (int i = 0; i < p.dim; ++i) s += (i + 1.0) * (i + 1.0) * (x(i) - c(i)) * (x(i) - c(i));
    return s;
  };
  SimplexOptions o;
  o.adaptive = p.adaptive;
  o.ftol = 1e-14;
  const auto r = minimize_simplex(f, Eigen::VectorXd::Ones(p.dim), Eigen::VectorXd::Constant(p.dim, 0.5), o);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.f, 1e-10);
  EXPECT_LT((r.x - c).cwiseAbs().maxCoeff(), 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Dimensions, SimplexTest,
                         ::testing::Values(SimplexCase{"dim2_classic", 2, false}, SimplexCase{"dim10_adaptive", 10, true},
                                           SimplexCase{"dim30_adaptive", 30, true}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(Simplex, Rosenbrock) {
  auto f = [](const Eigen::VectorXd& x) { return 100 * std::pow(x(1) - x(0) * x(0), 2) + std::pow(1 - x(0), 2); };
  const auto r = minimize_simplex(f, Eigen::Vector2d(-1.2, 1), Eigen::Vector2d(0.1, 0.1), {});
  EXPECT_NEAR(r.x(0), 1, 1e-5);
  EXPECT_NEAR(r.x(1), 1, 1e-5);
  EXPECT_GT(r.evaluations, 0);
}

TEST(Simplex, StopsAtTheEvaluationLimit) {
  auto f = [](const Eigen::VectorXd& x) { return x.squaredNorm(); };
  SimplexOptions o;
  o.max_evaluations = 50;
  const auto r = minimize_simplex(f, Eigen::VectorXd::Ones(8), Eigen::VectorXd::Constant(8, 0.1), o);
  EXPECT_FALSE(r.converged);
  EXPECT_LE(r.evaluations, 50 + 8 + 2);  // the budget is checked once per step
}

TEST(Simplex, NonFiniteValuesCountAsWorst) {
  // log is -inf/NaN for x <= 0: the simplex must stay on the finite side and find x = 1.
  auto f = [](const Eigen::VectorXd& x) { return std::pow(std::log(x(0)), 2); };
  const auto r = minimize_simplex(f, Eigen::VectorXd::Constant(1, 3.0), Eigen::VectorXd::Constant(1, 5.0), {});
  EXPECT_NEAR(r.x(0), 1, 1e-5);
}

}  // namespace
}  // namespace photomill::calib
