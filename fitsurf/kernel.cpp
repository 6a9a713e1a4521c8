// Kernel interpolation with leave-one-out selection (kernel.hpp).
#include "fitsurf/kernel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <numbers>

#include <Eigen/LU>

#include "geometry/parallel.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {

std::string to_string(KernelShape k) {
  switch (k) {
    case KernelShape::Gaussian: return "gaussian";
    case KernelShape::Matern32: return "matern32";
    case KernelShape::Matern52: return "matern52";
    case KernelShape::Matern72: return "matern72";
    case KernelShape::Polyharmonic3: return "polyharmonic3";
    case KernelShape::Polyharmonic4: return "polyharmonic4";
    case KernelShape::Polyharmonic5: return "polyharmonic5";
  }
  return "?";
}

bool is_polyharmonic(KernelShape k) {
  return k == KernelShape::Polyharmonic3 || k == KernelShape::Polyharmonic4 || k == KernelShape::Polyharmonic5;
}

namespace {

// m of a polyharmonic kernel.
int polyharmonic_order(KernelShape k) {
  return k == KernelShape::Polyharmonic3 ? 3 : k == KernelShape::Polyharmonic4 ? 4 : 5;
}

int trend_degree(const KernelModel& m) { return is_polyharmonic(m.shape) ? polyharmonic_order(m.shape) - 1 : m.trend_degree; }

constexpr int trend_terms(int degree) { return (degree + 1) * (degree + 2) / 2; }

// Squared distance in a model's metric (KernelModel::aspect, angle_deg).
struct Metric {
  double c = 1, s = 0, inv_aspect = 1;
  explicit Metric(const KernelModel& m)
      : c(std::cos(m.angle_deg * std::numbers::pi / 180)), s(std::sin(m.angle_deg * std::numbers::pi / 180)),
        inv_aspect(1 / m.aspect) {}
  double dist2(const Eigen::Vector2d& d) const {
    const double along = (c * d.x() + s * d.y()) * inv_aspect, across = -s * d.x() + c * d.y();
    return along * along + across * across;
  }
};

// phi at squared distance r2 (normalised coordinates); l the normalised length.
double phi(KernelShape k, double r2, double l) {
  switch (k) {
    case KernelShape::Gaussian: return std::exp(-0.5 * r2 / (l * l));
    case KernelShape::Matern32: {
      const double a = std::sqrt(3.0 * r2) / l;
      return (1 + a) * std::exp(-a);
    }
    case KernelShape::Matern52: {
      const double a = std::sqrt(5.0 * r2) / l;
      return (1 + a + a * a / 3) * std::exp(-a);
    }
    case KernelShape::Matern72: {
      const double a = std::sqrt(7.0 * r2) / l;
      return (1 + a + a * a * (0.4 + a / 15)) * std::exp(-a);
    }
    default: {
      // r^(2m-2) log r = 0.5 r2^(m-1) log r2, 0 at r = 0.
      if (r2 <= 0) return 0;
      return 0.5 * std::pow(r2, polyharmonic_order(k) - 1) * std::log(r2);
    }
  }
}

// The monomials x^a y^b, a + b <= degree, in a fixed order.
void monomials(int degree, const Eigen::Vector2d& x, double* out) {
  int j = 0;
  for (int d = 0; d <= degree; ++d) {
    for (int b = 0; b <= d; ++b) out[j++] = std::pow(x.x(), d - b) * std::pow(x.y(), b);
  }
}

constexpr int kMaxTrendDegree = 4;  // polyharmonic 5; monomials() writes at most 15 terms

struct Solved {
  bool ok = false;
  Eigen::VectorXd coef;
  std::vector<double> loo, loo_standardised;
  double loo_rms = std::numeric_limits<double>::infinity();
};

// Solves the interpolation system of one kernel and computes the LOO residuals.
Solved solve(const std::vector<Eigen::Vector2d>& x, const std::vector<double>& z, const KernelModel& model, double scale_mm,
             double ridge) {
  Solved s;
  const KernelShape k = model.shape;
  const double l = model.length_mm / scale_mm;
  const int degree = trend_degree(model);
  const int n = static_cast<int>(x.size());
  const int q = trend_terms(degree);
  if (n < q + 1) return s;
  const int N = n + q;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(N, N);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(N);
  std::vector<double> p(static_cast<std::size_t>(q));
  const Metric metric(model);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j) {
      A(i, j) = A(j, i) = phi(k, metric.dist2(x[static_cast<std::size_t>(i)] - x[static_cast<std::size_t>(j)]), l);
    }
    monomials(degree, x[static_cast<std::size_t>(i)], p.data());
    for (int j = 0; j < q; ++j) A(i, n + j) = A(n + j, i) = p[static_cast<std::size_t>(j)];
    b(i) = z[static_cast<std::size_t>(i)];
    // The ridge, relative to phi(0) = 1, for the positive definite kernels; none for the
    // polyharmonic ones, whose saddle-point system is regular for distinct points not all on one
    // polynomial curve of degree < m, and whose entries near the nodes are tiny.
    if (!is_polyharmonic(k)) A(i, i) += ridge;
  }
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  const Eigen::MatrixXd inv = lu.inverse();
  Eigen::VectorXd c = inv * b;
  if (!inv.allFinite() || !c.allFinite()) return s;
  s.loo.resize(static_cast<std::size_t>(n));
  s.loo_standardised.resize(static_cast<std::size_t>(n));
  double sum2 = 0;
  for (int i = 0; i < n; ++i) {
    // (A^-1)_kk is positive for a positive definite kernel; for a polyharmonic one its sign is
    // (-1)^m, the kernel's (conditionally positive definite of order m up to that sign; Wendland
    // 2005, 8.3).
    const double d = inv(i, i);
    if (!(std::abs(d) > 0)) return s;
    const double e = c(i) / d;
    s.loo[static_cast<std::size_t>(i)] = e;
    // The prediction's variance is proportional to 1 / |(A^-1)_kk| (kriging variance; Dubrule
    // 1983, "Cross validation of kriging in a unique neighborhood", Math. Geol. 15): a point on
    // the hull's edge, extrapolated from one side, is predicted less surely than one inside.
    s.loo_standardised[static_cast<std::size_t>(i)] = e * std::sqrt(std::abs(d));
    sum2 += e * e;
  }
  s.loo_rms = std::sqrt(sum2 / n);
  if (!std::isfinite(s.loo_rms)) return s;
  s.coef = std::move(c);
  s.ok = true;
  return s;
}

struct Prepared {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double scale = 1;
  std::vector<Eigen::Vector2d> nodes;
  double spacing_mm = 0;  // mean point spacing: sqrt(bounding box area / n)
};

Prepared prepare(const std::vector<Eigen::Vector2d>& xy, const std::vector<double>& z) {
  if (xy.size() != z.size()) throw std::invalid_argument("fit_kernel: xy and z differ in length");
  if (xy.size() < 4) {
    throw GeometryError("the kernel interpolation needs at least 4 points, got " + std::to_string(xy.size()));
  }
  Prepared p;
  Eigen::Vector2d lo = xy.front(), hi = xy.front();
  for (const auto& x : xy) {
    p.centre += x;
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  p.centre /= static_cast<double>(xy.size());
  const Eigen::Vector2d extent = hi - lo;
  p.scale = 0.5 * extent.maxCoeff();
  if (!(p.scale > 0)) throw GeometryError("the kernel interpolation's points all coincide");
  // A bounding box of zero width (points on a line) leaves the spacing to the length alone.
  p.spacing_mm = std::sqrt(std::max(extent.x() * extent.y(), extent.maxCoeff() * extent.maxCoeff() * 1e-6) /
                           static_cast<double>(xy.size()));
  p.nodes.reserve(xy.size());
  for (const auto& x : xy) p.nodes.push_back((x - p.centre) / p.scale);
  return p;
}

}  // namespace

std::string to_string(const KernelModel& m) {
  std::string s = to_string(m.shape);
  if (!is_polyharmonic(m.shape)) {
    char buf[64];
    std::snprintf(buf, sizeof buf, ", length %.3g mm, %s trend", m.length_mm, m.trend_degree == 1 ? "linear" : m.trend_degree == 2 ? "quadratic" : "polynomial");
    s += buf;
  }
  if (m.aspect != 1) {
    char buf[64];
    std::snprintf(buf, sizeof buf, ", %.3gx along %.3g deg", m.aspect, m.angle_deg);
    s += buf;
  }
  return s;
}

double KernelInterpolant::operator()(const Eigen::Vector2d& xy_mm) const {
  const Eigen::Vector2d x = (xy_mm - centre_mm_) / scale_mm_;
  const double l = model_.length_mm / scale_mm_;
  const std::size_t n = nodes_.size();
  const Metric metric(model_);
  double z = 0;
  for (std::size_t i = 0; i < n; ++i) z += coef_(static_cast<Eigen::Index>(i)) * phi(model_.shape, metric.dist2(x - nodes_[i]), l);
  const int degree = trend_degree(model_);
  double p[trend_terms(kMaxTrendDegree)];
  monomials(degree, x, p);
  for (int j = 0; j < trend_terms(degree); ++j) z += coef_(static_cast<Eigen::Index>(n) + j) * p[j];
  return z;
}

KernelInterpolant fit_kernel_model(const std::vector<Eigen::Vector2d>& xy_mm, const std::vector<double>& z_mm,
                                   const KernelModel& model, const KernelOptions& options) {
  const Prepared p = prepare(xy_mm, z_mm);
  KernelModel m = model;
  if (is_polyharmonic(m.shape)) {
    m.length_mm = 0;
    m.trend_degree = polyharmonic_order(m.shape) - 1;
  } else if (!(m.length_mm > 0) || m.trend_degree < 0 || m.trend_degree > kMaxTrendDegree) {
    throw std::invalid_argument("fit_kernel_model: the length must be positive and the trend degree 0-4");
  }
  if (!(m.aspect >= 1) || !std::isfinite(m.aspect) || !std::isfinite(m.angle_deg)) {
    throw std::invalid_argument("fit_kernel_model: the aspect must be finite and >= 1");
  }
  Solved s = solve(p.nodes, z_mm, m, p.scale, options.ridge);
  if (!s.ok) {
    throw GeometryError("the " + to_string(m.shape) + " kernel interpolation of " + std::to_string(xy_mm.size()) +
                        " points is singular (coincident points, or too few for its polynomial part)");
  }
  KernelInterpolant k;
  k.model_ = m;
  k.loo_rms_mm_ = s.loo_rms;
  k.loo_ = std::move(s.loo);
  k.loo_standardised_ = std::move(s.loo_standardised);
  k.candidates_ = {{m, k.loo_rms_mm_}};
  k.centre_mm_ = p.centre;
  k.scale_mm_ = p.scale;
  k.nodes_ = p.nodes;
  k.coef_ = std::move(s.coef);
  return k;
}

KernelInterpolant fit_kernel(const std::vector<Eigen::Vector2d>& xy_mm, const std::vector<double>& z_mm,
                             const KernelOptions& options) {
  if (!(options.min_length_spacings > 0) || !(options.max_length_spacings >= options.min_length_spacings) ||
      !(options.coarse_ratio > 1) || !(options.fine_ratio > 1) || !(options.ridge >= 0)) {
    throw std::invalid_argument("KernelOptions: lengths must be positive and increasing, the ratios > 1, the ridge >= 0");
  }
  if (!(options.max_aspect >= 1) || !(options.aspect_step > 1) || options.directions < 1 ||
      options.anisotropic_families < 0 || !(options.anisotropic_length_span >= 1) || !(options.anisotropy_gain >= 1)) {
    throw std::invalid_argument("KernelOptions: the aspects must be >= 1 with a step > 1, directions >= 1, the span and gain >= 1");
  }
  const Prepared p = prepare(xy_mm, z_mm);
  std::vector<KernelCandidate> cand;
  auto evaluate = [&](std::size_t from) {
    geometry::parallel_blocks(cand.size() - from, options.threads, 1,
                 [&](std::size_t begin, std::size_t end, int) {
                   for (std::size_t i = from + begin; i < from + end; ++i) {
                     cand[i].loo_rms_mm = solve(p.nodes, z_mm, cand[i].model, p.scale, options.ridge).loo_rms;
                   }
                 });
  };
  auto best_of = [&](std::size_t from, std::size_t to, auto&& pred) {
    const KernelCandidate* best = nullptr;
    for (std::size_t i = from; i < to; ++i) {
      if (pred(cand[i].model) && std::isfinite(cand[i].loo_rms_mm) && (!best || cand[i].loo_rms_mm < best->loo_rms_mm)) {
        best = &cand[i];
      }
    }
    return best ? std::optional<KernelCandidate>(*best) : std::nullopt;
  };
  // Around a coarse best length (coarse_ratio apart), fine_ratio steps.
  auto refine = [&](const KernelModel& centre_model) {
    const double centre = centre_model.length_mm;
    for (double l = centre / options.coarse_ratio * options.fine_ratio; l < centre * options.coarse_ratio; l *= options.fine_ratio) {
      if (std::abs(l / centre - 1) > 1e-9) {
        KernelModel m = centre_model;
        m.length_mm = l;
        cand.push_back({m, 0.0});
      }
    }
  };
  auto same_family = [](const KernelModel& a, const KernelModel& b) {
    return a.shape == b.shape && a.trend_degree == b.trend_degree;
  };

  // Isotropic: every kernel and trend, the lengths coarse, then fine around each family's best.
  for (KernelShape k : {KernelShape::Polyharmonic3, KernelShape::Polyharmonic4, KernelShape::Polyharmonic5}) {
    cand.push_back({{k, polyharmonic_order(k) - 1, 0.0}, 0.0});
  }
  const KernelShape definite[] = {KernelShape::Gaussian, KernelShape::Matern32, KernelShape::Matern52, KernelShape::Matern72};
  const double lo = options.min_length_spacings * p.spacing_mm, hi = options.max_length_spacings * p.spacing_mm;
  for (KernelShape k : definite) {
    for (int degree : {1, 2}) {
      for (double l = lo; l <= hi * (1 + 1e-12); l *= options.coarse_ratio) cand.push_back({{k, degree, l}, 0.0});
    }
  }
  evaluate(0);
  const std::size_t coarse = cand.size();
  std::vector<KernelCandidate> family_best;  // each family's best coarse candidate
  for (const KernelCandidate& c : cand) {
    if (std::none_of(family_best.begin(), family_best.end(), [&](const KernelCandidate& f) { return same_family(f.model, c.model); })) {
      if (auto b = best_of(0, coarse, [&](const KernelModel& m) { return same_family(m, c.model); })) family_best.push_back(*b);
    }
  }
  for (const KernelCandidate& f : family_best) {
    if (!is_polyharmonic(f.model.shape)) refine(f.model);
  }
  evaluate(coarse);
  const std::size_t isotropic = cand.size();
  const auto iso_best = best_of(0, isotropic, [](const KernelModel&) { return true; });
  if (!iso_best) {
    throw GeometryError("no kernel interpolates these " + std::to_string(xy_mm.size()) +
                        " points: every system is singular (coincident points?)");
  }
  KernelModel chosen = iso_best->model;

  // Anisotropic: the best families (by their best length, fine included) with aspects and
  // directions, lengths across around their isotropic best.
  std::vector<KernelCandidate> families;
  for (const KernelCandidate& f : family_best) {
    if (auto b = best_of(0, isotropic, [&](const KernelModel& m) { return same_family(m, f.model); })) families.push_back(*b);
  }
  std::sort(families.begin(), families.end(),
            [](const KernelCandidate& a, const KernelCandidate& b) { return a.loo_rms_mm < b.loo_rms_mm; });
  families.resize(std::min(families.size(), static_cast<std::size_t>(options.anisotropic_families)));
  std::vector<double> aspects;
  for (double a = options.aspect_step; a <= options.max_aspect * (1 + 1e-12); a *= options.aspect_step) aspects.push_back(a);
  if (!aspects.empty() && !families.empty()) {
    for (const KernelCandidate& f : families) {
      for (double a : aspects) {
        for (int d = 0; d < options.directions; ++d) {
          KernelModel m = f.model;
          m.aspect = a;
          m.angle_deg = 180.0 * d / options.directions;
          if (is_polyharmonic(m.shape)) {
            cand.push_back({m, 0.0});
            continue;
          }
          const double centre = f.model.length_mm;
          for (double l = centre / options.anisotropic_length_span; l <= centre * std::sqrt(options.anisotropic_length_span) * (1 + 1e-12);
               l *= options.coarse_ratio) {
            m.length_mm = l;
            cand.push_back({m, 0.0});
          }
        }
      }
    }
    evaluate(isotropic);
    const std::size_t anisotropic = cand.size();
    if (auto b = best_of(isotropic, anisotropic, [](const KernelModel&) { return true; })) {
      if (!is_polyharmonic(b->model.shape)) refine(b->model);
      evaluate(anisotropic);
      const auto aniso_best = best_of(isotropic, cand.size(), [](const KernelModel&) { return true; });
      if (aniso_best && aniso_best->loo_rms_mm * options.anisotropy_gain < iso_best->loo_rms_mm) chosen = aniso_best->model;
    }
  }
  KernelInterpolant k = fit_kernel_model(xy_mm, z_mm, chosen, options);
  k.candidates_ = std::move(cand);
  return k;
}

}  // namespace photomill::fitsurf
