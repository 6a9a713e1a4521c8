// fitsurf's library entry point (fitsurf.hpp).
#include "fitsurf/fitsurf.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>

#include "fitsurf/numbers.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::fitsurf {

ResidualStats residual_stats(const std::vector<double>& d, const FitResult& fit) {
  ResidualStats s;
  s.count = d.size();
  if (d.empty()) return s;
  std::vector<double> a(d.size());
  double sum2 = 0, sum = 0, in2 = 0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    a[k] = std::abs(d[k]);
    sum2 += d[k] * d[k];
    sum += d[k];
    const bool inlier = fit.outlier.empty() || !fit.outlier[k];
    if (inlier) {
      ++s.inliers;
      in2 += d[k] * d[k];
    }
  }
  const double n = static_cast<double>(d.size());
  s.rms_mm = std::sqrt(sum2 / n);
  s.mean_mm = sum / n;
  s.inlier_rms_mm = s.inliers ? std::sqrt(in2 / static_cast<double>(s.inliers)) : 0.0;
  s.max_abs_mm = *std::max_element(a.begin(), a.end());
  // Nearest-rank percentiles, in increasing order so each nth_element works on what is left.
  auto pct = [&](double p, std::vector<double>::iterator from) {
    const std::size_t rank = static_cast<std::size_t>(std::ceil(p * n));
    const auto it = a.begin() + static_cast<std::ptrdiff_t>(std::clamp<std::size_t>(rank, 1, a.size()) - 1);
    std::nth_element(from, it, a.end());
    return it;
  };
  auto it = pct(0.50, a.begin());
  s.p50_mm = *it;
  it = pct(0.90, it);
  s.p90_mm = *it;
  it = pct(0.95, it);
  s.p95_mm = *it;
  it = pct(0.99, it);
  s.p99_mm = *it;
  return s;
}

namespace {

// 1 / max(sigma_k, floor)^2 of the kept points, scaled to mean 1 (so lambda keeps its meaning).
std::vector<double> sigma_weights(const PointCloud& cloud, const std::vector<std::size_t>& kept, double floor_mm,
                                  const std::string& source) {
  const PointProperty* sigma = cloud.find("sigma_mm");
  if (!sigma) {
    throw InputError(source, 0, "--weight-by-sigma: the cloud has no sigma_mm property (triangulate writes one)");
  }
  std::vector<double> w(kept.size());
  double sum = 0;
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const double s = sigma->values[kept[i]];
    if (!(s >= 0) || !std::isfinite(s)) {
      throw InputError(source, 0, "--weight-by-sigma: point " + std::to_string(kept[i] + 1) + " has sigma_mm " + sig(s, 6) +
                                      " (must be finite and >= 0)");
    }
    const double m = std::max(s, floor_mm);
    w[i] = 1.0 / (m * m);
    sum += w[i];
  }
  if (sum > 0) {
    for (double& x : w) x *= static_cast<double>(w.size()) / sum;
  }
  return w;
}

double median_abs(std::vector<double> v) {
  for (double& x : v) x = std::abs(x);
  return median(std::move(v));
}

// The kernel prefit (PrefitOptions): heights over the points' parameter plane interpolated by
// the kernel that predicts each point best from the others, outliers by that prediction left
// out, the interpolant sampled on a grid inside the points' hull, the B-spline fitted to the
// samples; then the points' own foot points, residuals and weights on that surface, so the
// outline, report and residual cloud describe the points, not the samples.
FitResult kernel_prefit_fit(const std::vector<Eigen::Vector3d>& points, const FitOptions& fit_options,
                            const PrefitOptions& po, PrefitSummary& summary) {
  require_points(points.size(), fit_options);  // the same minimum as without the prefit
  const PlaneFrame frame = parameter_frame(points, fit_options.plane, fit_options.frame);
  std::vector<Eigen::Vector2d> xy(points.size());
  std::vector<double> z(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d l = frame.to_local(points[k]);
    xy[k] = l.head<2>();
    z[k] = l.z();
  }
  KernelOptions ko = po.kernel;
  if (ko.threads == 0) ko.threads = fit_options.threads;
  // Outliers: the worst leave-one-out residual beyond the cutoff is left out and the same kernel
  // solved again, until none is (an outlier spoils its neighbours' predictions, so one at a
  // time); then the kernel is chosen again and the points judged again, until a choice finds
  // none; at most max_outlier_fraction of the points.
  std::vector<std::size_t> kept(points.size());
  for (std::size_t k = 0; k < kept.size(); ++k) kept[k] = k;
  std::vector<std::uint8_t> outlier(points.size(), 0);
  auto subset = [&](const auto& all) {
    std::remove_cvref_t<decltype(all)> out;
    out.reserve(kept.size());
    for (std::size_t k : kept) out.push_back(all[k]);
    return out;
  };
  KernelInterpolant kernel = fit_kernel(subset(xy), subset(z), ko);
  const bool screen = fit_options.robust != RobustLoss::None;
  double cutoff = 0;
  // Judged by the standardised residuals t_k (kernel.hpp), against their robust scale
  // s = 1.4826 MAD(t): in mm, point k's scale is s |e_k| / |t_k|, at least robust_min_scale_mm.
  // Returns the index (in kept) of the worst outlier, or kept.size() when there is none.
  auto worst_outlier = [&] {
    const auto& e = kernel.loo_residual_mm();
    const auto& t = kernel.loo_standardised();
    const double s_t = 1.4826 * median_abs(t);
    const double floor_cut = po.outlier_threshold * fit_options.robust_min_scale_mm;
    std::size_t worst = e.size();
    cutoff = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < e.size(); ++i) {
      if (t[i] == 0) continue;
      cutoff = std::min(cutoff, std::max(po.outlier_threshold * s_t * std::abs(e[i] / t[i]), floor_cut));
      if (std::abs(t[i]) > po.outlier_threshold * s_t && std::abs(e[i]) > floor_cut &&
          (worst == e.size() || std::abs(t[i]) > std::abs(t[worst]))) {
        worst = i;
      }
    }
    if (!std::isfinite(cutoff)) cutoff = floor_cut;
    return worst;
  };
  bool capped = false;
  while (screen && !capped) {
    bool removed = false;
    for (std::size_t worst = worst_outlier(); worst < kept.size(); worst = worst_outlier()) {
      if (static_cast<double>(points.size() - kept.size() + 1) > po.max_outlier_fraction * static_cast<double>(points.size())) {
        log::warn("kernel prefit: more than " + sig(100 * po.max_outlier_fraction, 3) +
                  " % of the points look like outliers; the rest are kept");
        capped = true;
        break;
      }
      outlier[kept[worst]] = 1;
      kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(worst));
      kernel = fit_kernel_model(subset(xy), subset(z), kernel.model(), ko);
      removed = true;
    }
    if (!removed) break;
    kernel = fit_kernel(subset(xy), subset(z), ko);
  }

  // Samples: a grid of po.samples_per_span per knot span of the net in each direction over the
  // kept points' box, inside their convex hull grown by one (the longer) grid step.
  const std::vector<Eigen::Vector2d> kept_xy = subset(xy);
  const std::vector<Eigen::Vector2d> hull = convex_hull(kept_xy);
  Eigen::Vector2d lo = kept_xy.front(), hi = kept_xy.front();
  for (const auto& p : kept_xy) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector2d extent = hi - lo;
  const double spans_u = std::max(1, fit_options.poles_u - fit_options.degree_u);
  const double spans_v = std::max(1, fit_options.poles_v - fit_options.degree_v);
  const int nu = static_cast<int>(std::ceil(spans_u * po.samples_per_span));
  const int nv = static_cast<int>(std::ceil(spans_v * po.samples_per_span));
  if (!(extent.minCoeff() > 0)) throw GeometryError("the kernel prefit's points span no area in their plane");
  const double step = std::max(extent.x() / nu, extent.y() / nv);
  auto near_hull = [&](const Eigen::Vector2d& x) {
    return (hull.size() >= 3 && point_in_polygon(hull, x)) || boundary_distance(hull, x) <= step;
  };
  std::vector<Eigen::Vector3d> samples;
  for (int i = 0; i <= nu; ++i) {
    for (int j = 0; j <= nv; ++j) {
      const Eigen::Vector2d x = lo + Eigen::Vector2d(extent.x() * i / nu, extent.y() * j / nv);
      if (near_hull(x)) samples.push_back(frame.to_world(Eigen::Vector3d(x.x(), x.y(), kernel(x))));
    }
  }
  FitOptions so = fit_options;
  so.robust = RobustLoss::None;  // the samples are exact: the kernel's screening took the outliers
  FitResult fit = fit_surface(samples, so);

  // The points' own foot points and residuals on the surface.
  std::vector<Eigen::Vector2d> uv(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    uv[k] = fit.box.to_uv(fit.frame.to_local(points[k])).cwiseMax(0.0).cwiseMin(1.0);
  }
  std::vector<double> d;
  project_points(fit.surface, points, uv, d, fit_options.projection, fit_options.threads);
  fit.uv = std::move(uv);
  fit.residual_mm = std::move(d);
  fit.weight.assign(points.size(), 1.0);
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (outlier[k]) fit.weight[k] = 0;
  }
  fit.robust_applied = screen;
  fit.outliers = points.size() - kept.size();
  fit.outlier = screen ? outlier : std::vector<std::uint8_t>{};
  fit.robust_cutoff_mm = cutoff;
  fit.robust_scale_mm = screen ? cutoff / po.outlier_threshold : 0;
  fit.robust_poles_u = fit.robust_poles_v = 0;
  fit.gross_outliers = 0;

  summary.model = kernel.model();
  summary.loo_rms_mm = kernel.loo_rms_mm();
  summary.candidates = kernel.candidates().size();
  summary.samples = samples.size();
  summary.outliers = fit.outliers;
  summary.outlier_cutoff_mm = cutoff;
  return fit;
}

bool use_kernel_prefit(const Options& o, std::size_t points, const FitOptions& fit) {
  const bool noisy = o.weight_by_sigma || fit.noise_mm > 0;
  switch (o.prefit.mode) {
    case Prefit::None: return false;
    case Prefit::Kernel:
      if (o.tolerance) {
        throw UsageError("--prefit kernel and --tolerance exclude each other (the net would be chosen for the kernel's "
                         "samples, not the points)");
      }
      if (noisy) {
        throw UsageError("--prefit kernel interpolates the points: --noise-mm and --weight-by-sigma smooth them with "
                         "--prefit none");
      }
      return true;
    case Prefit::Auto:
      return !o.tolerance && !noisy && points <= o.prefit.auto_max_points &&
             points < static_cast<std::size_t>(fit.poles_u) * static_cast<std::size_t>(fit.poles_v);
  }
  return false;
}

}  // namespace

Result fit_point_cloud(const PointCloud& cloud, const Options& options, const std::string& source) {
  if (!(options.sigma_floor_mm > 0) || !std::isfinite(options.sigma_floor_mm)) {
    throw UsageError("--sigma-floor-mm must be positive");
  }
  const auto t0 = std::chrono::steady_clock::now();
  Result r;
  r.input_points = cloud.points_mm.size();
  r.units = cloud.units;
  if (cloud.points_mm.empty()) throw GeometryError("no points to fit: the input holds none");
  {
    Eigen::Vector3d lo = cloud.points_mm.front(), hi = lo;
    for (const auto& p : cloud.points_mm) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    r.extent = (hi - lo).maxCoeff();
  }
  std::optional<log::Step> step(std::in_place, "selecting the part's points among " + std::to_string(cloud.points_mm.size()));
  // The cloud's own normals (densify writes them) decide which points are on walls.
  std::vector<Eigen::Vector3d> normals;
  {
    const PointProperty *nx = cloud.find("nx"), *ny = cloud.find("ny"), *nz = cloud.find("nz");
    if (nx && ny && nz) {
      normals.resize(cloud.points_mm.size());
      for (std::size_t i = 0; i < normals.size(); ++i) normals[i] = {nx->values[i], ny->values[i], nz->values[i]};
    }
  }
  r.selection = select_part(cloud.points_mm, options.select, normals);
  std::vector<Eigen::Vector3d> points;
  points.reserve(r.selection.kept.size());
  for (std::size_t k : r.selection.kept) points.push_back(cloud.points_mm[k]);

  std::vector<double> weights;
  if (options.weight_by_sigma) weights = sigma_weights(cloud, r.selection.kept, options.sigma_floor_mm, source);
  validate(options.fit);
  double pca_slope_deg = -1, xy_slope_deg = -1;
  FitOptions fit_options = with_plane_chosen(points, options.fit, pca_slope_deg, xy_slope_deg);
  if (!(options.prefit.samples_per_span > 0) || !(options.prefit.outlier_threshold > 0)) {
    throw UsageError("the prefit's samples per span and outlier threshold must be positive");
  }
  step.emplace("fitting " + std::to_string(points.size()) + " points");
  if (use_kernel_prefit(options, points.size(), fit_options)) {
    r.prefit.emplace();
    r.fit = kernel_prefit_fit(points, fit_options, options.prefit, *r.prefit);
  } else {
    if (options.tolerance) {
      step.emplace("choosing the net for a tolerance of " + sig(options.tolerance->tolerance_mm, 3) + " mm");
      r.tolerance = choose_net(points, fit_options, *options.tolerance);
      step.emplace("fitting " + std::to_string(points.size()) + " points, net " + std::to_string(r.tolerance->poles_u) +
                   "x" + std::to_string(r.tolerance->poles_v));
      fit_options.poles_u = r.tolerance->poles_u;
      fit_options.poles_v = r.tolerance->poles_v;
    }
  }
  // fit_surface stops the parameter correction before a round too steep at the foot points'
  // cells (FitOptions::stop_before_fold); the outline can hold places between them that were
  // not looked at. Then the fit is repeated with one round fewer, down to the first.
  auto fit_and_check = [&](FitOptions fo) {
    FitResult f = r.prefit ? std::move(r.fit) : fit_surface(points, fo, weights);
    step.emplace("the data's outline and the fold check");
    for (;;) {
      try {
        f.surface.boundary_uv = data_outline(f.uv, f.weight, f.box.length_u_mm(), f.box.length_v_mm(), options.outline);
        f.local_surface.boundary_uv = f.surface.boundary_uv;
        check_no_fold(f, f.surface.boundary_uv, fo.fold);
        break;
      } catch (const GeometryError& e) {
        const int rounds = static_cast<int>(f.round_rms_mm.size());
        if (r.prefit || !fo.stop_before_fold || !fo.parameter_correction || rounds <= 1) throw;
        log::debug(std::string("fitted again with ") + std::to_string(rounds - 1) + " rounds: " + e.what());
        fo.max_rounds = rounds - 1;
        f = fit_surface(points, fo, weights);
        // Stopped: by this fit's own check, or by the outline's check of the longer one.
        if (f.stopped_at_round == 0) f.stopped_at_round = static_cast<int>(f.round_rms_mm.size());
      }
    }
    f.pca_slope_deg = pca_slope_deg;
    f.xy_slope_deg = xy_slope_deg;
    return f;
  };
  // The smoothing ladder (Options::max_smoothing_factor): not with a tolerance, whose net was
  // chosen and cross-validated at the smoothing given, nor where the smoothing is not the user's
  // to raise (none, or chosen for --noise-mm), nor for the kernel prefit.
  const bool ladder_allowed = !r.prefit && !options.tolerance && fit_options.noise_mm == 0 &&
                              fit_options.smoothing_mm4 > 0 && options.max_smoothing_factor > 1;
  std::optional<CurlError> curled;  // the given smoothing's fit curled already in its first round
  try {
    r.fit = fit_and_check(fit_options);
  } catch (const CurlError& e) {
    if (!ladder_allowed) throw;
    curled = e;
  }
  if (ladder_allowed && (curled || r.fit.stopped_at_round > 0)) {
    // Each fit is scored by the RMS of its orthogonal distances over the points the first fit
    // that worked kept (weight > 0), so that all are judged on the same points and none scores
    // better by rejecting more of them.
    std::vector<double> reference_weight;
    auto score = [&](const FitResult& f) {
      if (reference_weight.empty()) reference_weight = f.weight;
      double sum = 0;
      std::size_t n = 0;
      for (std::size_t k = 0; k < f.residual_mm.size(); ++k) {
        if (reference_weight[k] > 0) sum += f.residual_mm[k] * f.residual_mm[k], ++n;
      }
      return n ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
    };
    double best = std::numeric_limits<double>::infinity();
    if (curled) {
      r.smoothing_ladder.push_back({fit_options.smoothing_mm4, 0, true, 0, curled->what()});
    } else {
      best = score(r.fit);
      r.smoothing_ladder.push_back({r.fit.smoothing_mm4, static_cast<int>(r.fit.round_rms_mm.size()), true, best, ""});
    }
    bool found = !curled;
    for (int k = 1; std::pow(10.0, 0.5 * k) <= options.max_smoothing_factor * (1 + 1e-9); ++k) {
      const double factor = std::pow(10.0, 0.5 * k);  // sqrt(10)^k: exactly 10 and 100 at k = 2 and 4
      FitOptions fo = fit_options;
      fo.smoothing_mm4 = fit_options.smoothing_mm4 * factor;
      step.emplace("the surface curled: fitting again with smoothing " + sig(fo.smoothing_mm4, 4));
      SmoothingTrial trial{fo.smoothing_mm4, 0, false, 0, ""};
      try {
        FitResult f = fit_and_check(fo);
        trial.rounds = static_cast<int>(f.round_rms_mm.size());
        trial.stopped = f.stopped_at_round > 0;
        trial.score_rms_mm = score(f);
        if (trial.score_rms_mm < best) {
          best = trial.score_rms_mm;
          r.fit = std::move(f);
          found = true;
        }
      } catch (const GeometryError& e) {
        trial.refused = e.what();
        log::debug("smoothing " + sig(fo.smoothing_mm4, 4) + " refused: " + e.what());
      }
      r.smoothing_ladder.push_back(trial);
      // A fit whose correction ran its course: a stiffer surface would only be farther from the data.
      if (trial.refused.empty() && !trial.stopped) break;
    }
    const std::string given = sig(fit_options.smoothing_mm4, 4);
    if (!found) {
      throw CurlError(std::string(curled->what()) + " (the smoothing raised up to " +
                      sig(fit_options.smoothing_mm4 * options.max_smoothing_factor, 4) + " did not keep it flat either)");
    }
    std::string tried;
    for (std::size_t k = 1; k < r.smoothing_ladder.size(); ++k) {
      const SmoothingTrial& t = r.smoothing_ladder[k];
      tried += (k > 1 ? ", " : "") + sig(t.smoothing, 4) +
               (t.refused.empty() ? " (" + sig(t.score_rms_mm, 4) + " mm" + (t.stopped ? ", stopped" : "") + ")" : " (refused)");
    }
    const std::string kept = "; kept smoothing " + sig(r.fit.smoothing_mm4, 4) + " (--max-smoothing-factor 1: keep the smoothing given)";
    if (curled) {
      // The smoothing asked for gave no surface: the one delivered is stiffer than asked, say so.
      log::warn("at smoothing " + given + " the surface curled in its first round (" + curled->what() +
                "); fitted again with " + tried + kept);
    } else {
      log::info("parameter correction stopped before a curl at smoothing " + given + " (RMS " +
                sig(r.smoothing_ladder.front().score_rms_mm, 4) + " mm); fitted again with " + tried + kept);
    }
  }
  const bool ladder = !r.smoothing_ladder.empty();
  if (r.fit.stopped_at_round > 0) {
    log::warn("parameter correction stopped after round " + std::to_string(r.fit.stopped_at_round) +
              ": the next round's surface was steeper than the data allow (it curls over the plane where the points "
              "slide along a steep flank); fitted RMS " + sig(r.fit.round_rms_mm.back(), 4) + " mm" +
              (ladder ? " at smoothing " + sig(r.fit.smoothing_mm4, 4) + ", the closest of the smoothing ladder"
                      : ". A larger --smoothing lets the correction go further"));
  }
  step.reset();
  // A surface holds mm or the arbitrary unit of a reconstruction without a datum: a cloud in any
  // unit but mm (only triangulate --arbitrary-scale writes one) gives a surface that is not in mm.
  r.fit.surface.units = r.fit.local_surface.units = cloud.units == kSurfaceUnitMm ? kSurfaceUnitMm : kSurfaceUnitArbitrary;
  r.stats = residual_stats(r.fit.residual_mm, r.fit);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

PointCloud residual_cloud(const PointCloud& input, const Result& result) {
  PointCloud out;
  out.xyz_type = input.xyz_type;
  out.units = input.units;
  const auto& kept = result.selection.kept;
  out.points_mm.reserve(kept.size());
  for (std::size_t k : kept) out.points_mm.push_back(input.points_mm[k]);
  for (const auto& prop : input.properties) {
    // replaced below (older files: without the prefix)
    if (prop.name == "scalar_residual_mm" || prop.name == "scalar_weight" || prop.name == "residual_mm" || prop.name == "weight") continue;
    PointProperty p{prop.name, prop.type, {}};
    p.values.reserve(kept.size());
    for (std::size_t k : kept) p.values.push_back(prop.values[k]);
    out.properties.push_back(std::move(p));
  }
  // "scalar_": the prefix CloudCompare needs to load a scalar field (docs/formats.md).
  out.properties.push_back({"scalar_residual_mm", PlyScalar::Float64, result.fit.residual_mm});
  out.properties.push_back({"scalar_weight", PlyScalar::Float64, result.fit.weight});
  return out;
}

}  // namespace photomill::fitsurf
