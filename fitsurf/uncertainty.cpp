#include "fitsurf/uncertainty.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/LU>  // determinant()
#include <Eigen/QR>
#include <queue>
#include <string>

#include "formats/error.hpp"

namespace photomill::fitsurf {
namespace {

// The points in x, y, in square buckets, for nearest-neighbour queries.
class Buckets {
public:
  explicit Buckets(const std::vector<Eigen::Vector2d>& p) : p_(p) {
    Eigen::Vector2d lo = p.front(), hi = p.front();
    for (const auto& q : p) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
    lo_ = lo;
    const double area = std::max((hi - lo).prod(), 1e-12);
    // About 2 points per bucket, at most 4 million buckets.
    cell_ = std::max(std::sqrt(area / static_cast<double>(p.size()) * 2), std::max((hi - lo).maxCoeff() / 2000, 1e-9));
    nx_ = static_cast<long>((hi.x() - lo.x()) / cell_) + 1;
    ny_ = static_cast<long>((hi.y() - lo.y()) / cell_) + 1;
    b_.resize(static_cast<std::size_t>(nx_ * ny_));
    for (std::size_t k = 0; k < p.size(); ++k) b_[index(cx(p[k].x()), cy(p[k].y()))].push_back(k);
  }

  // The n nearest points' indices and squared distances, nearest first (`skip` left out).
  void nearest(const Eigen::Vector2d& q, std::size_t n, std::size_t skip, std::vector<std::pair<double, std::size_t>>& out) const {
    std::priority_queue<std::pair<double, std::size_t>> heap;  // the n best so far, worst on top
    const long ix = cx(q.x()), iy = cy(q.y());
    // A query outside the box: the ring distance counts from the box's nearest bucket.
    const double outside = std::max({lo_.x() - q.x(), q.x() - (lo_.x() + static_cast<double>(nx_) * cell_),
                                     lo_.y() - q.y(), q.y() - (lo_.y() + static_cast<double>(ny_) * cell_), 0.0});
    const long rings = std::max(nx_, ny_) + 1;
    for (long r = 0; r <= rings; ++r) {
      const double reach = std::max(outside, static_cast<double>(r - 1) * cell_);  // no point of ring r is nearer
      if (heap.size() == n && r > 0 && reach > 0 && reach * reach > heap.top().first) break;
      for (long j = iy - r; j <= iy + r; ++j) {
        if (j < 0 || j >= ny_) continue;
        const bool edge_row = j == iy - r || j == iy + r;
        for (long i = ix - r; i <= ix + r; i += edge_row ? 1 : 2 * r) {
          if (i >= 0 && i < nx_) {
            for (std::size_t k : b_[index(i, j)]) {
              if (k == skip) continue;
              const double d2 = (p_[k] - q).squaredNorm();
              if (heap.size() < n) heap.emplace(d2, k);
              else if (d2 < heap.top().first) heap.pop(), heap.emplace(d2, k);
            }
          }
          if (r == 0) break;
        }
      }
    }
    out.clear();
    while (!heap.empty()) out.push_back(heap.top()), heap.pop();
    std::reverse(out.begin(), out.end());
  }

  // How many points lie within radius r of q.
  std::size_t count_within(const Eigen::Vector2d& q, double r) const {
    const long i0 = cx(q.x() - r), i1 = cx(q.x() + r), j0 = cy(q.y() - r), j1 = cy(q.y() + r);
    std::size_t n = 0;
    for (long j = j0; j <= j1; ++j) {
      for (long i = i0; i <= i1; ++i) {
        for (std::size_t k : b_[index(i, j)]) n += (p_[k] - q).squaredNorm() <= r * r;
      }
    }
    return n;
  }

private:
  long cx(double x) const { return std::clamp(static_cast<long>(std::floor((x - lo_.x()) / cell_)), 0L, nx_ - 1); }
  long cy(double y) const { return std::clamp(static_cast<long>(std::floor((y - lo_.y()) / cell_)), 0L, ny_ - 1); }
  std::size_t index(long i, long j) const { return static_cast<std::size_t>(j * nx_ + i); }
  const std::vector<Eigen::Vector2d>& p_;
  Eigen::Vector2d lo_;
  double cell_ = 1;
  long nx_ = 1, ny_ = 1;
  std::vector<std::vector<std::size_t>> b_;
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::min(q * static_cast<double>(v.size()), static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

UncertaintyGrid surface_uncertainty(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& residual_mm,
                                    const std::vector<double>& weight, const std::vector<double>& point_sigma_mm,
                                    const std::vector<double>& point_window_mm, const UncertaintyOptions& options,
                                    UncertaintySummary* summary) {
  if (!(options.cell_mm > 0) || !std::isfinite(options.cell_mm)) throw UsageError("uncertainty: the cell must be a positive length");
  if (!(options.residual_floor_mm >= 0) || !std::isfinite(options.residual_floor_mm)) throw UsageError("uncertainty: the residual floor must not be negative");
  if (!(options.resolution_mm >= 0) || !std::isfinite(options.resolution_mm)) throw UsageError("uncertainty: the resolution must not be negative");
  if (options.neighbours < 1 || options.neighbours > 1000) throw UsageError("uncertainty: neighbours must be 1-1000");
  if (!(options.loo_max_extrapolation > 0) || !std::isfinite(options.loo_max_extrapolation)) {
    throw UsageError("uncertainty: the leave-one-out extrapolation limit must be positive");
  }
  if (!(options.loo_max_noise_gain >= 1) || !std::isfinite(options.loo_max_noise_gain)) {
    throw UsageError("uncertainty: the leave-one-out noise gain limit must be at least 1");
  }
  if (residual_mm.size() != points.size() || (!weight.empty() && weight.size() != points.size()) ||
      (!point_sigma_mm.empty() && point_sigma_mm.size() != points.size()) ||
      (!point_window_mm.empty() && point_window_mm.size() != points.size())) {
    throw UsageError("uncertainty: one residual, weight, sigma and window per point");
  }
  std::vector<Eigen::Vector2d> xy;
  std::vector<double> r2, s2, z, w;  // per kept point: residual^2, sigma^2, height, window
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (!weight.empty() && !(weight[k] > 0)) continue;
    if (!points[k].allFinite() || !std::isfinite(residual_mm[k])) continue;
    xy.push_back(points[k].head<2>());
    z.push_back(points[k].z());
    r2.push_back(std::max(residual_mm[k] * residual_mm[k], options.residual_floor_mm * options.residual_floor_mm));
    const double s = point_sigma_mm.empty() ? 0 : point_sigma_mm[k];
    s2.push_back(std::isfinite(s) && s > 0 ? s * s : 0);
    const double wk = point_window_mm.empty() ? 0 : point_window_mm[k];
    w.push_back(std::isfinite(wk) && wk > 0 ? wk : 0);
  }
  if (xy.size() < 2) throw GeometryError("uncertainty: fewer than 2 fitted points that are not outliers");
  const Buckets buckets(xy);
  std::vector<std::pair<double, std::size_t>> near;

  // h: the median nearest-neighbour distance (over at most 20 000 points, evenly picked).
  std::vector<double> nn;
  const std::size_t every = std::max<std::size_t>(1, xy.size() / 20000);
  for (std::size_t k = 0; k < xy.size(); k += every) {
    buckets.nearest(xy[k], 1, k, near);
    if (!near.empty()) nn.push_back(std::sqrt(near.front().first));
  }
  double h = percentile(nn, 0.5);
  if (!(h > 0)) h = options.cell_mm;  // coincident points: the grid's own scale
  const double rho = options.resolution_mm > 0 ? options.resolution_mm : 3 * h;

  // Leave-one-out: each point's height predicted from its n nearest others by a least-squares
  // quadratic in x, y (a plane with fewer than 9 of them); e2[k] = (z_k - prediction)^2. The
  // prediction's noise is the neighbours' times g = sqrt([(A^T A)^-1]_00) (A the design matrix,
  // its first column the constant: the intercept's variance factor, as a regression's leverage);
  // a model whose g exceeds loo_max_noise_gain falls back to the plane, then to the mean. Dense
  // points lie in rows (a photo's pixel rows on the surface): 12 neighbours in two rows nearly
  // satisfy a quadratic equation of their own, and the quadratic's intercept there is noise
  // amplified 10 to 2 000 times (one point 8.7 mm off on the 2026 saddle's blend); a sparse
  // cloud's quadratics reach gains of 3-10 where they are right (docs/fitsurf.md). e is the
  // error expected between points: a point its neighbours do not surround (the Mahalanobis
  // distance of their centroid from it, under their covariance, above loo_max_extrapolation; a
  // marker corner densify writes across a masked marker, beside one row of points) would be
  // extrapolated to, its error the reach of the data, which the gap term d / rho covers: its e is 0.
  std::vector<double> e2(xy.size(), 0);
  const std::size_t n_loo = std::min(options.neighbours, xy.size() - 1);
  for (std::size_t k = 0; k < xy.size(); ++k) {
    buckets.nearest(xy[k], n_loo, k, near);
    if (near.size() < 3) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& nb : near) mean += xy[nb.second] - xy[k];
    mean /= static_cast<double>(near.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& nb : near) {
      const Eigen::Vector2d q = xy[nb.second] - xy[k] - mean;
      cov += q * q.transpose();
    }
    cov /= static_cast<double>(near.size());
    // mean' cov^-1 mean > L^2, written without the inverse: mean' adj(cov) mean > L^2 det(cov).
    const double det = cov.determinant();
    const double quad = mean.x() * mean.x() * cov(1, 1) - 2 * mean.x() * mean.y() * cov(0, 1) + mean.y() * mean.y() * cov(0, 0);
    if (!(quad <= options.loo_max_extrapolation * options.loo_max_extrapolation * det)) continue;
    Eigen::MatrixXd full(static_cast<Eigen::Index>(near.size()), 6);
    Eigen::VectorXd b(static_cast<Eigen::Index>(near.size()));
    for (std::size_t r = 0; r < near.size(); ++r) {
      const Eigen::Vector2d q = xy[near[r].second] - xy[k];
      full.row(static_cast<Eigen::Index>(r)) << 1, q.x(), q.y(), q.x() * q.x(), q.x() * q.y(), q.y() * q.y();
      b(static_cast<Eigen::Index>(r)) = z[near[r].second] - z[k];
    }
    double e = 0;  // prediction minus z_k at the point itself
    for (const int terms : {6, 3, 1}) {
      if (static_cast<int>(near.size()) < (terms == 6 ? 9 : terms == 3 ? 4 : 1)) continue;
      const Eigen::MatrixXd a = full.leftCols(terms);
      const Eigen::MatrixXd normal = a.transpose() * a;
      const double gain2 = normal.inverse()(0, 0);
      if (terms > 1 && !(gain2 <= options.loo_max_noise_gain * options.loo_max_noise_gain)) continue;
      const Eigen::VectorXd coef = a.colPivHouseholderQr().solve(b);
      e = std::isfinite(coef(0)) ? coef(0) : 0;
      break;
    }
    e2[k] = e * e;
  }

  Eigen::Vector2d lo = xy.front(), hi = xy.front();
  for (const auto& q : xy) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  UncertaintyGrid g;
  g.step_mm = options.cell_mm;
  g.x0_mm = lo.x(), g.y0_mm = lo.y();
  const double fx = std::ceil((hi.x() - lo.x()) / g.step_mm) + 1, fy = std::ceil((hi.y() - lo.y()) / g.step_mm) + 1;
  if (!(fx * fy <= static_cast<double>(kMaxUncertaintyNodes))) {
    throw UsageError("uncertainty: a grid of " + std::to_string(static_cast<long long>(fx * fy)) +
                     " nodes is too many (at most " + std::to_string(kMaxUncertaintyNodes) + "): give a larger cell");
  }
  g.nx = static_cast<std::size_t>(fx), g.ny = static_cast<std::size_t>(fy);
  g.sigma_mm.resize(g.nx * g.ny);
  const std::size_t n = std::min(options.neighbours, xy.size());
  for (std::size_t j = 0; j < g.ny; ++j) {
    for (std::size_t i = 0; i < g.nx; ++i) {
      const Eigen::Vector2d c(g.x0_mm + static_cast<double>(i) * g.step_mm, g.y0_mm + static_cast<double>(j) * g.step_mm);
      buckets.nearest(c, n, xy.size(), near);
      double sr = 0, ss = 0, se = 0, sw = 0;
      for (const auto& [d2, k] : near) sr += r2[k], ss += s2[k], se += e2[k], sw += w[k];
      const double s2_loc = std::max({sr, ss, se}) / static_cast<double>(near.size());
      const double d = std::sqrt(near.front().first);
      double m = static_cast<double>(std::max<std::size_t>(1, buckets.count_within(c, rho)));
      // Overlapping windows: the windows of mean half-width w that tile the disc of radius rho.
      const double wm = sw / static_cast<double>(near.size());
      if (wm > 0) m = std::min(m, std::max(1.0, M_PI * rho * rho / (4 * wm * wm)));
      g.sigma_mm[j * g.nx + i] = std::sqrt(s2_loc * (1 / m + (d / rho) * (d / rho)));
    }
  }
  if (summary != nullptr) {
    summary->spacing_mm = h;
    summary->resolution_mm = rho;
    summary->min_mm = *std::min_element(g.sigma_mm.begin(), g.sigma_mm.end());
    summary->max_mm = *std::max_element(g.sigma_mm.begin(), g.sigma_mm.end());
    summary->median_mm = percentile(g.sigma_mm, 0.5);
    summary->p95_mm = percentile(g.sigma_mm, 0.95);
  }
  return g;
}

}  // namespace photomill::fitsurf
