// Nelder-Mead downhill simplex (see simplex.hpp for the sources).
#include "calib/simplex.hpp"

#include <cmath>
#include <limits>
#include <vector>

namespace photomill::calib {
namespace {

struct Coefficients {
  double reflect, expand, contract, shrink;
};

// Nelder-Mead's classic coefficients, or Gao-Han's for dimension n: 1, 1 + 2/n, 3/4 - 1/(2n), 1 - 1/n.
Coefficients coefficients(long n, bool adaptive) {
  if (!adaptive || n < 2) return {1, 2, 0.5, 0.5};
  const double dn = static_cast<double>(n);
  return {1, 1 + 2 / dn, 0.75 - 1 / (2 * dn), 1 - 1 / dn};
}

// One Nelder-Mead run from a fresh simplex around x0. Returns when the vertex values agree to
// ftol or the evaluation budget is spent.
void run_once(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x0,
              const Eigen::VectorXd& step, const SimplexOptions& o, SimplexResult& r) {
  const long n = x0.size();
  const Coefficients c = coefficients(n, o.adaptive);
  std::vector<Eigen::VectorXd> x(n + 1, x0);
  std::vector<double> fx(n + 1);
  auto eval = [&](const Eigen::VectorXd& p) {
    ++r.evaluations;
    const double v = f(p);
    return std::isfinite(v) ? v : std::numeric_limits<double>::infinity();
  };
  fx[0] = eval(x[0]);
  for (long i = 0; i < n; ++i) {
    x[i + 1](i) += step(i);
    fx[i + 1] = eval(x[i + 1]);
  }
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(n);
  for (const auto& v : x) sum += v;
  r.converged = false;
  while (true) {
    long lo = 0;
    long hi = 0;
    for (long i = 1; i <= n; ++i) {
      if (fx[i] < fx[lo]) lo = i;
      if (fx[i] > fx[hi]) hi = i;
    }
    long nhi = lo;
    for (long i = 0; i <= n; ++i) {
      if (i != hi && fx[i] > fx[nhi]) nhi = i;
    }
    const double spread = 2 * std::abs(fx[hi] - fx[lo]) / (std::abs(fx[hi]) + std::abs(fx[lo]) + o.tiny);
    if (spread < o.ftol) {
      r.converged = true;
      break;
    }
    if (r.evaluations >= o.max_evaluations) break;
    ++r.iterations;
    const Eigen::VectorXd centroid = (sum - x[hi]) / static_cast<double>(n);
    auto replace_worst = [&](const Eigen::VectorXd& p, double fp) {
      sum += p - x[hi];
      x[hi] = p;
      fx[hi] = fp;
    };
    const Eigen::VectorXd xr = centroid + c.reflect * (centroid - x[hi]);
    const double fr = eval(xr);
    if (fr < fx[lo]) {
      const Eigen::VectorXd xe = centroid + c.expand * (xr - centroid);
      const double fe = eval(xe);
      if (fe < fr) {
        replace_worst(xe, fe);
      } else {
        replace_worst(xr, fr);
      }
      continue;
    }
    if (fr < fx[nhi]) {
      replace_worst(xr, fr);
      continue;
    }
    // Contract: outside (towards the reflected point) if it was better than the worst vertex,
    // inside (towards the worst vertex) otherwise.
    const bool outside = fr < fx[hi];
    const Eigen::VectorXd xc = outside ? Eigen::VectorXd(centroid + c.contract * (xr - centroid))
                                       : Eigen::VectorXd(centroid + c.contract * (x[hi] - centroid));
    const double fc = eval(xc);
    if (outside ? fc <= fr : fc < fx[hi]) {
      replace_worst(xc, fc);
      continue;
    }
    // Shrink every vertex towards the best one.
    for (long i = 0; i <= n; ++i) {
      if (i == lo) continue;
      x[i] = x[lo] + c.shrink * (x[i] - x[lo]);
      fx[i] = eval(x[i]);
    }
    sum.setZero();
    for (const auto& v : x) sum += v;
  }
  long best = 0;
  for (long i = 1; i <= n; ++i) {
    if (fx[i] < fx[best]) best = i;
  }
  r.x = x[best];
  r.f = fx[best];
}

}  // namespace

SimplexResult minimize_simplex(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& step, const SimplexOptions& options) {
  SimplexResult r;
  run_once(f, x0, step, options, r);
  while (r.converged && r.restarts < options.max_restarts && r.evaluations < options.max_evaluations) {
    const double before = r.f;
    const Eigen::VectorXd x_before = r.x;
    run_once(f, x_before, step, options, r);
    ++r.restarts;
    if (r.f > before) {  // a restart never loses the best point found so far
      r.f = before;
      r.x = x_before;
    }
    if (before - r.f <= options.restart_improvement * std::abs(before) + options.tiny) break;
  }
  return r;
}

}  // namespace photomill::calib
