// --tolerance mode: the smallest control net whose fit meets a deviation tolerance, judged by
// k-fold cross-validation so that the net does not grow to chase the noise.
//
// Net sizes grow geometrically with square cells in mm: cell h_0 = a quarter of the longer side
// of the data, h_{k+1} = h_k / growth, poles = ceil(L / h) + degree per direction. For each size the
// points are split into `folds` groups (by a hash of their index); each group is left out in
// turn, the surface fitted to the others (the full method of fit.hpp) and the left-out points
// projected onto it. The statistic (RMS, a percentile or the maximum of |d|) over all left-out
// points is compared with the tolerance (outliers count: with a few per cent of them, a
// percentile is the statistic that can be met):
// - at or below it: that net is chosen;
// - improving by less than min_gain over `patience` steps: the cross-validated error has reached
//   the noise of the data (or the method's limit); the tolerance cannot be met, and the error
//   says what can be.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/fit.hpp"

namespace photomill::fitsurf {

enum class ToleranceStat { Rms, P90, P95, P99, Max };
std::string to_string(ToleranceStat stat);

struct ToleranceOptions {
  double tolerance_mm = 0.05;
  ToleranceStat stat = ToleranceStat::Rms;
  int folds = 4;
  double growth = 1.3;
  double min_gain = 0.02;
  int patience = 3;
  int max_poles = 200;              // per direction
  // The cross-validation fits use at most this many points (an even subsample by index hash)
  // and this many rounds: they only rank net sizes; the final fit uses everything.
  std::size_t cv_max_points = 50000;
  int cv_max_rounds = 3;
  std::uint64_t seed = 1;           // fold assignment
};

struct ToleranceStep {
  int poles_u = 0, poles_v = 0;
  double cv_mm = 0;             // cross-validated statistic
};

struct ToleranceSearch {
  std::vector<ToleranceStep> steps;  // in the order tried
  int poles_u = 0, poles_v = 0;      // the chosen net
  double cv_mm = 0;                  // its cross-validated statistic
};

// The statistic of |d| (nearest-rank percentiles).
double deviation_statistic(std::vector<double> abs_d, ToleranceStat stat);

// Chooses the net for `base` (its poles_u/poles_v are ignored). Throws GeometryError when the
// tolerance cannot be met, naming the best cross-validated value and its net; UsageError for
// bad options.
ToleranceSearch choose_net(const std::vector<Eigen::Vector3d>& points, const FitOptions& base,
                           const ToleranceOptions& options);

}  // namespace photomill::fitsurf
