// Cross-validated net growth for --tolerance (tolerance.hpp).
#include "fitsurf/tolerance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "fitsurf/numbers.hpp"
#include "geometry/parallel.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::fitsurf {
namespace {


std::uint64_t hash(std::size_t k, std::uint64_t seed) {
  std::uint64_t x = static_cast<std::uint64_t>(k) + seed * 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

int fold_of(std::size_t k, std::uint64_t seed, int folds) {
  return static_cast<int>(hash(k, seed) % static_cast<std::uint64_t>(folds));
}

// |d| of the points of fold f projected onto the surface fitted to the other folds; counts those
// beyond the training fit's robust cutoff.
void cross_validate_fold(const std::vector<Eigen::Vector3d>& points, const FitOptions& o, const ToleranceOptions& t,
                         int f, std::vector<double>& abs_d, std::size_t& outliers) {
  std::vector<Eigen::Vector3d> train, test;
  for (std::size_t k = 0; k < points.size(); ++k) (fold_of(k, t.seed, t.folds) == f ? test : train).push_back(points[k]);
  const FitResult fit = fit_surface(train, o);
  std::vector<double> d(test.size());
  geometry::parallel_blocks(test.size(), o.threads, 512, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t k = b; k < e; ++k) {
      Eigen::Vector2d uv0 = fit.box.to_uv(fit.frame.to_local(test[k]));
      d[k] = project_point(fit.local_surface, fit.frame.to_local(test[k]), uv0, o.projection).signed_distance_mm;
    }
  });
  for (double x : d) abs_d.push_back(std::abs(x));
  if (fit.robust_applied) {
    for (double x : d) outliers += std::abs(x) > fit.robust_cutoff_mm;
  }
}

}  // namespace

std::string to_string(ToleranceStat s) {
  switch (s) {
    case ToleranceStat::Rms: return "rms";
    case ToleranceStat::P90: return "p90";
    case ToleranceStat::P95: return "p95";
    case ToleranceStat::P99: return "p99";
    case ToleranceStat::Max: return "max";
  }
  return "?";
}

double deviation_statistic(std::vector<double> a, ToleranceStat stat) {
  if (a.empty()) return 0;
  if (stat == ToleranceStat::Rms) {
    double s = 0;
    for (double x : a) s += x * x;
    return std::sqrt(s / static_cast<double>(a.size()));
  }
  if (stat == ToleranceStat::Max) return *std::max_element(a.begin(), a.end());
  const double p = stat == ToleranceStat::P90 ? 0.90 : stat == ToleranceStat::P95 ? 0.95 : 0.99;
  const std::size_t rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(a.size())));
  const auto it = a.begin() + static_cast<std::ptrdiff_t>(std::clamp<std::size_t>(rank, 1, a.size()) - 1);
  std::nth_element(a.begin(), it, a.end());
  return *it;
}

ToleranceSearch choose_net(const std::vector<Eigen::Vector3d>& points, const FitOptions& base,
                           const ToleranceOptions& t) {
  if (!(t.tolerance_mm > 0) || !std::isfinite(t.tolerance_mm)) throw UsageError("--tolerance must be a positive length in mm");
  if (t.folds < 2) throw UsageError("--cv-folds must be >= 2");
  if (!(t.growth > 1)) throw UsageError("net growth must be > 1");
  if (t.max_poles < std::max(base.degree_u, base.degree_v) + 1) throw UsageError("--max-poles is below the degree + 1");
  validate(base);
  std::vector<Eigen::Vector3d> cv_points;
  if (points.size() > t.cv_max_points) {
    // An even subsample: keep point k when its hash falls below the wanted fraction.
    const double keep = static_cast<double>(t.cv_max_points) / static_cast<double>(points.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
      if (static_cast<double>(hash(k, t.seed + 1) >> 11) * 0x1.0p-53 < keep) cv_points.push_back(points[k]);
    }
  }
  const std::vector<Eigen::Vector3d>& cv_set = cv_points.empty() ? points : cv_points;
  FitOptions cv_base = base;
  cv_base.max_rounds = std::min(base.max_rounds, t.cv_max_rounds);
  // The data's extent in the parameter plane decides the aspect of the net.
  const PlaneFrame frame = parameter_frame(points, base.plane, base.frame);
  std::vector<Eigen::Vector3d> local(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) local[k] = frame.to_local(points[k]);
  const ParameterBox box = parameter_box(local);
  const double lu = box.length_u_mm(), lv = box.length_v_mm();
  const std::size_t train_size = cv_set.size() - cv_set.size() / static_cast<std::size_t>(t.folds);

  ToleranceSearch search;
  double best = std::numeric_limits<double>::infinity();
  ToleranceStep best_step;
  double noise_mm = 0, outlier_fraction = 0;
  int stall = 0;
  std::string why;
  for (double h = 0.25 * std::max(lu, lv);; h /= t.growth) {
    FitOptions o = cv_base;
    o.poles_u = std::max(base.degree_u + 1, static_cast<int>(std::ceil(lu / h - 1e-9)) + base.degree_u);
    o.poles_v = std::max(base.degree_v + 1, static_cast<int>(std::ceil(lv / h - 1e-9)) + base.degree_v);
    if (!search.steps.empty() && o.poles_u == search.steps.back().poles_u && o.poles_v == search.steps.back().poles_v) continue;
    if (o.poles_u > t.max_poles || o.poles_v > t.max_poles) {
      why = "the net reached --max-poles " + std::to_string(t.max_poles);
      break;
    }
    if (static_cast<long long>(o.poles_u) * o.poles_v > base.max_net_poles) {
      why = "the net reached the work limit --max-net-poles " + std::to_string(base.max_net_poles);
      break;
    }
    if (static_cast<std::size_t>(o.poles_u) * static_cast<std::size_t>(o.poles_v) > train_size) {
      why = "the net would have more poles than there are points";
      break;
    }
    std::vector<double> abs_d;
    std::size_t outliers = 0;
    for (int f = 0; f < t.folds; ++f) cross_validate_fold(cv_set, o, t, f, abs_d, outliers);
    const double cv = deviation_statistic(abs_d, t.stat);
    search.steps.push_back({o.poles_u, o.poles_v, cv});
    log::debug("tolerance: net " + std::to_string(o.poles_u) + "x" + std::to_string(o.poles_v) + ": cross-validated " +
               to_string(t.stat) + " " + sig(cv, 4) + " mm");
    if (cv <= t.tolerance_mm) {
      search.poles_u = o.poles_u;
      search.poles_v = o.poles_v;
      search.cv_mm = cv;
      return search;
    }
    stall = cv < best * (1 - t.min_gain) ? 0 : stall + 1;
    if (cv < best) {
      best = cv;
      best_step = search.steps.back();
      noise_mm = deviation_statistic(abs_d, ToleranceStat::Rms);
      outlier_fraction = static_cast<double>(outliers) / static_cast<double>(std::max<std::size_t>(1, abs_d.size()));
    }
    if (stall >= t.patience) {
      why = "the cross-validated " + to_string(t.stat) + " stopped improving (the noise of the data)";
      break;
    }
  }
  if (search.steps.empty()) throw GeometryError("--tolerance: no net could be tried: " + why);
  std::string hint;
  if (outlier_fraction > 0.001 && t.stat == ToleranceStat::Rms) {
    hint = "; " + fixed(100 * outlier_fraction, 1) +
           " % of the points are outliers, which an RMS counts: --tolerance-stat p95 or p99 ignores them";
  }
  throw GeometryError("tolerance " + sig(t.tolerance_mm, 4) + " mm (" + to_string(t.stat) +
                      ") cannot be met: " + why + "; the best is " + sig(best_step.cv_mm, 4) + " mm with a " +
                      std::to_string(best_step.poles_u) + "x" + std::to_string(best_step.poles_v) + " net" +
                      (t.stat == ToleranceStat::Rms ? std::string()
                                                    : " (cross-validated RMS distance " + sig(noise_mm, 4) + " mm)") +
                      "; ask for " +
                      sig(best_step.cv_mm * 1.05, 4) + " mm or more" + hint);
}

}  // namespace photomill::fitsurf
