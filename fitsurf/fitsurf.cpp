// fitsurf's library entry point (fitsurf.hpp).
#include "fitsurf/fitsurf.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "fitsurf/numbers.hpp"
#include "formats/error.hpp"

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

}  // namespace

Result fit_point_cloud(const PointCloud& cloud, const Options& options, const std::string& source) {
  if (!(options.sigma_floor_mm > 0) || !std::isfinite(options.sigma_floor_mm)) {
    throw UsageError("--sigma-floor-mm must be positive");
  }
  const auto t0 = std::chrono::steady_clock::now();
  Result r;
  r.input_points = cloud.points_mm.size();
  if (cloud.points_mm.empty()) throw GeometryError("no points to fit: the input holds none");
  r.selection = select_part(cloud.points_mm, options.select);
  std::vector<Eigen::Vector3d> points;
  points.reserve(r.selection.kept.size());
  for (std::size_t k : r.selection.kept) points.push_back(cloud.points_mm[k]);

  std::vector<double> weights;
  if (options.weight_by_sigma) weights = sigma_weights(cloud, r.selection.kept, options.sigma_floor_mm, source);
  FitOptions fit_options = options.fit;
  if (options.tolerance) {
    r.tolerance = choose_net(points, options.fit, *options.tolerance);
    fit_options.poles_u = r.tolerance->poles_u;
    fit_options.poles_v = r.tolerance->poles_v;
  }
  r.fit = fit_surface(points, fit_options, weights);
  r.fit.surface.boundary_uv = data_outline(r.fit.uv, r.fit.weight, r.fit.box.length_u_mm(),
                                           r.fit.box.length_v_mm(), options.outline);
  r.fit.local_surface.boundary_uv = r.fit.surface.boundary_uv;
  check_no_fold(r.fit, r.fit.surface.boundary_uv, fit_options.fold);
  r.stats = residual_stats(r.fit.residual_mm, r.fit);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

PointCloud residual_cloud(const PointCloud& input, const Result& result) {
  PointCloud out;
  out.xyz_type = input.xyz_type;
  const auto& kept = result.selection.kept;
  out.points_mm.reserve(kept.size());
  for (std::size_t k : kept) out.points_mm.push_back(input.points_mm[k]);
  for (const auto& prop : input.properties) {
    if (prop.name == "residual_mm" || prop.name == "weight") continue;  // replaced below
    PointProperty p{prop.name, prop.type, {}};
    p.values.reserve(kept.size());
    for (std::size_t k : kept) p.values.push_back(prop.values[k]);
    out.properties.push_back(std::move(p));
  }
  out.properties.push_back({"residual_mm", PlyScalar::Float64, result.fit.residual_mm});
  out.properties.push_back({"weight", PlyScalar::Float64, result.fit.weight});
  return out;
}

}  // namespace photomill::fitsurf
