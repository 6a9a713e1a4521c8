// The downhill simplex method of Nelder and Mead (1965), as in Numerical Recipes' `amoeba`
// (Press et al., 3rd ed., sec. 10.5), with the dimension-adaptive coefficients of Gao and Han
// (2012, "Implementing the Nelder-Mead simplex algorithm with adaptive parameters") that keep it
// moving in the tens-to-hundreds of dimensions of a calibration, and restarts from the best vertex
// (NR's advice: "restart ... at a point where it claims to have found a minimum").
#pragma once

#include <functional>

#include <Eigen/Core>

namespace photomill::calib {

struct SimplexOptions {
  // A run stops when the spread of the vertex values is small, NR's test:
  // 2 |f_max - f_min| / (|f_max| + |f_min| + tiny) < ftol; `tiny` (NR's TINY) makes the test
  // absolute for a minimum value near 0.
  double ftol = 1e-12;
  double tiny = 1e-10;
  // The whole minimisation (all restarts) stops after this many function evaluations.
  long max_evaluations = 4'000'000;
  // Restarts stop when one improves the best value by less than this fraction (plus tiny).
  double restart_improvement = 1e-10;
  int max_restarts = 200;
  bool adaptive = true;  // Gao-Han coefficients; false: the classic 1, 2, 0.5, 0.5
};

struct SimplexResult {
  Eigen::VectorXd x;
  double f = 0;
  long evaluations = 0;
  long iterations = 0;  // reflections/expansions/contractions/shrinks over all restarts
  int restarts = 0;
  bool converged = false;  // false: stopped by max_evaluations
};

// Minimises f from x0; the initial simplex is x0 plus step(i) along each axis i (so `step` sets
// the scale of each parameter).
SimplexResult minimize_simplex(const std::function<double(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x0,
                               const Eigen::VectorXd& step, const SimplexOptions& options);

}  // namespace photomill::calib
