// Exact evaluation of the synthetic part's height field and closed-form bounds on its derivatives.
#include "tools/synth/height_field.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace photomill::synth {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Maxima of the smootherstep S(t) = 6t^5 - 15t^4 + 10t^3 derivatives on [0, 1]:
// S'(t) = 30 t^2 (1-t)^2, largest at t = 1/2; S''(t) = 60 t (1-t)(1-2t), largest at
// t = 1/2 - 1/(2 sqrt 3).
constexpr double kSmoothMaxSlope = 1.875;
constexpr double kSmoothMaxCurvature = 5.7735026918962584;  // 10 / sqrt(3)
// max |tanh''| = 4 / (3 sqrt 3), at tanh = 1/sqrt 3.
constexpr double kTanhMaxCurvature = 0.76980035891950105;

// S, S', S'' at t (clamped to [0, 1]).
void smootherstep(double t, double& s, double& ds, double& dds) {
  if (t <= 0) {
    s = ds = dds = 0;
    return;
  }
  if (t >= 1) {
    s = 1;
    ds = dds = 0;
    return;
  }
  const double t2 = t * t;
  s = t2 * t * (t * (6 * t - 15) + 10);
  ds = 30 * t2 * (1 - t) * (1 - t);
  dds = 60 * t * (1 - t) * (1 - 2 * t);
}

// Window factor along one axis: S(d / b) with d the distance to the nearer edge, and its
// derivative with respect to the coordinate.
void window_1d(double x, double lo, double hi, double b, double& w, double& dw) {
  double s, ds, dds;
  const double d_lo = x - lo;
  const double d_hi = hi - x;
  if (d_lo <= d_hi) {
    smootherstep(d_lo / b, s, ds, dds);
    w = s;
    dw = ds / b;
  } else {
    smootherstep(d_hi / b, s, ds, dds);
    w = s;
    dw = -ds / b;
  }
}

// f and grad f of one term.
double term_value(const ShapeTerm& t, double x, double y, Eigen::Vector2d& grad) {
  switch (t.kind) {
    case ShapeTerm::Kind::Gauss: {
      const double u = (x - t.x0_mm) / t.s1_mm;
      const double v = (y - t.y0_mm) / t.s2_mm;
      const double e = t.amplitude_mm * std::exp(-0.5 * (u * u + v * v));
      grad = {-e * u / t.s1_mm, -e * v / t.s2_mm};
      return e;
    }
    case ShapeTerm::Kind::Wave: {
      const double kx = t.s1_mm > 0 ? kTwoPi / t.s1_mm : 0.0;
      const double ky = t.s2_mm > 0 ? kTwoPi / t.s2_mm : 0.0;
      const double ax = kx * (x - t.x0_mm);
      const double ay = ky * (y - t.y0_mm);
      const double cx = std::cos(ax), sx = std::sin(ax);
      const double cy = std::cos(ay), sy = std::sin(ay);
      grad = {-t.amplitude_mm * kx * sx * cy, -t.amplitude_mm * ky * cx * sy};
      return t.amplitude_mm * cx * cy;
    }
    case ShapeTerm::Kind::Saddle: {
      const double tu = std::tanh((x - t.x0_mm) / t.s1_mm);
      const double tv = std::tanh((y - t.y0_mm) / t.s2_mm);
      grad = {t.amplitude_mm * (1 - tu * tu) * tv / t.s1_mm,
              t.amplitude_mm * tu * (1 - tv * tv) / t.s2_mm};
      return t.amplitude_mm * tu * tv;
    }
  }
  throw std::logic_error("unknown shape term kind");
}

}  // namespace

std::string to_string(ShapeTerm::Kind kind) {
  switch (kind) {
    case ShapeTerm::Kind::Gauss: return "gauss";
    case ShapeTerm::Kind::Wave: return "wave";
    case ShapeTerm::Kind::Saddle: return "saddle";
  }
  return "?";
}

ShapeTerm::Kind shape_term_kind(const std::string& name) {
  if (name == "gauss") return ShapeTerm::Kind::Gauss;
  if (name == "wave") return ShapeTerm::Kind::Wave;
  if (name == "saddle") return ShapeTerm::Kind::Saddle;
  throw std::invalid_argument("unknown shape term '" + name + "' (expected gauss, wave or saddle)");
}

namespace {

// f and grad f of the field (without the window).
double shape_value(const HeightField& h, double x, double y, Eigen::Vector2d& df) {
  double f = h.base_mm;
  df.setZero();
  for (const ShapeTerm& t : h.terms) {
    Eigen::Vector2d g;
    f += term_value(t, x, y, g);
    df += g;
  }
  return f;
}

}  // namespace

double HeightField::evaluate(double x, double y, Eigen::Vector2d& grad) const {
  if (walled()) {
    // The closed rectangle: a point on the edge is on the top (the wall's upper rim).
    if (x < x_min_mm || x > x_max_mm || y < y_min_mm || y > y_max_mm) {
      grad.setZero();
      return 0;
    }
    return shape_value(*this, x, y, grad);
  }
  if (!contains(x, y)) {
    grad.setZero();
    return 0;
  }
  double wx, dwx, wy, dwy;
  window_1d(x, x_min_mm, x_max_mm, edge_blend_mm, wx, dwx);
  window_1d(y, y_min_mm, y_max_mm, edge_blend_mm, wy, dwy);
  Eigen::Vector2d df;
  const double f = shape_value(*this, x, y, df);
  const double w = wx * wy;
  grad = {dwx * wy * f + w * df.x(), wx * dwy * f + w * df.y()};
  return w * f;
}

double HeightField::wall_top_mm(double x, double y) const {
  Eigen::Vector2d df;
  return shape_value(*this, std::clamp(x, x_min_mm, x_max_mm), std::clamp(y, y_min_mm, y_max_mm), df);
}

double HeightField::height_mm(double x, double y) const {
  Eigen::Vector2d g;
  return evaluate(x, y, g);
}

Eigen::Vector2d HeightField::gradient(double x, double y) const {
  Eigen::Vector2d g;
  evaluate(x, y, g);
  return g;
}

Eigen::Vector3d HeightField::normal(double x, double y) const {
  const Eigen::Vector2d g = gradient(x, y);
  return Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
}

double HeightField::height_bound() const {
  double f = std::abs(base_mm);
  for (const ShapeTerm& t : terms) f += std::abs(t.amplitude_mm);
  return f;
}

// |grad(w f)| <= |grad w| max|f| + max|grad f|, with
//   |grad w| <= sqrt(2) * 1.875 / b (0 for a walled part: w = 1 on its top),
//   Gauss:  |grad| <= |a| e^(-1/2) / min(s1, s2),
//   Wave:   |grad| <= |a| sqrt(kx^2 + ky^2),
//   Saddle: |grad| <= |a| sqrt(1/s1^2 + 1/s2^2).
double HeightField::slope_bound() const {
  double df = 0;
  for (const ShapeTerm& t : terms) {
    const double a = std::abs(t.amplitude_mm);
    switch (t.kind) {
      case ShapeTerm::Kind::Gauss: df += a * std::exp(-0.5) / std::min(t.s1_mm, t.s2_mm); break;
      case ShapeTerm::Kind::Wave: {
        const double kx = t.s1_mm > 0 ? kTwoPi / t.s1_mm : 0.0;
        const double ky = t.s2_mm > 0 ? kTwoPi / t.s2_mm : 0.0;
        df += a * std::hypot(kx, ky);
        break;
      }
      case ShapeTerm::Kind::Saddle: df += a * std::hypot(1 / t.s1_mm, 1 / t.s2_mm); break;
    }
  }
  if (walled()) return df;
  return std::sqrt(2.0) * kSmoothMaxSlope / edge_blend_mm * height_bound() + df;
}

// ||H(w f)|| <= max|f| ||H w|| + 2 |grad w| |grad f| + ||H f||, each factor bounded in closed
// form (Frobenius norms bound the spectral norm):
//   ||H w||  <= sqrt(2 (S''max / b^2)^2 + 2 (S'max / b)^4)   (0 for a walled part),
//   Gauss:  ||H|| <= |a| / min(s1, s2)^2   (eigenvalues of (uu^T - I) e^(-|u|^2/2) are <= 1),
//   Wave:   ||H|| <= |a| (kx^2 + ky^2),
//   Saddle: ||H|| <= |a| sqrt(c^2/s1^4 + 2/(s1 s2)^2 + c^2/s2^4), c = max|tanh''|.
double HeightField::curvature_bound() const {
  const double b = edge_blend_mm;
  const double hw = walled() ? 0.0
                             : std::sqrt(2 * std::pow(kSmoothMaxCurvature / (b * b), 2) +
                                         2 * std::pow(kSmoothMaxSlope / b, 4));
  const double gw = walled() ? 0.0 : std::sqrt(2.0) * kSmoothMaxSlope / b;
  double gf = 0, hf = 0;
  for (const ShapeTerm& t : terms) {
    const double a = std::abs(t.amplitude_mm);
    switch (t.kind) {
      case ShapeTerm::Kind::Gauss: {
        const double s = std::min(t.s1_mm, t.s2_mm);
        gf += a * std::exp(-0.5) / s;
        hf += a / (s * s);
        break;
      }
      case ShapeTerm::Kind::Wave: {
        const double kx = t.s1_mm > 0 ? kTwoPi / t.s1_mm : 0.0;
        const double ky = t.s2_mm > 0 ? kTwoPi / t.s2_mm : 0.0;
        gf += a * std::hypot(kx, ky);
        hf += a * (kx * kx + ky * ky);
        break;
      }
      case ShapeTerm::Kind::Saddle: {
        const double s1 = t.s1_mm, s2 = t.s2_mm;
        const double c = kTanhMaxCurvature;
        gf += a * std::hypot(1 / s1, 1 / s2);
        hf += a * std::sqrt(c * c / std::pow(s1, 4) + 2 / std::pow(s1 * s2, 2) +
                            c * c / std::pow(s2, 4));
        break;
      }
    }
  }
  return height_bound() * hw + 2 * gw * gf + hf;
}

void validate(const HeightField& f) {
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(f.x_min_mm) || !finite(f.x_max_mm) || !finite(f.y_min_mm) || !finite(f.y_max_mm) ||
      !finite(f.edge_blend_mm) || !finite(f.base_mm)) {
    throw std::invalid_argument("height field: non-finite number");
  }
  if (!(f.x_max_mm > f.x_min_mm) || !(f.y_max_mm > f.y_min_mm)) {
    throw std::invalid_argument("height field: empty part rectangle");
  }
  const double half = 0.5 * std::min(f.x_max_mm - f.x_min_mm, f.y_max_mm - f.y_min_mm);
  if (!(f.edge_blend_mm >= 0) || f.edge_blend_mm > half) {
    throw std::invalid_argument("height field: edge blend must be 0 (walls) or in (0, " +
                                std::to_string(half) + "] mm");
  }
  for (const ShapeTerm& t : f.terms) {
    if (!finite(t.amplitude_mm) || !finite(t.x0_mm) || !finite(t.y0_mm) || !finite(t.s1_mm) ||
        !finite(t.s2_mm)) {
      throw std::invalid_argument("height field: non-finite term parameter");
    }
    const bool wave = t.kind == ShapeTerm::Kind::Wave;
    if (wave ? (t.s1_mm < 0 || t.s2_mm < 0) : (t.s1_mm <= 0 || t.s2_mm <= 0)) {
      throw std::invalid_argument("height field: " + to_string(t.kind) +
                                  " term needs positive scales");
    }
  }
}

std::vector<std::string> shape_names() { return {"bumps", "saddle", "wave", "dome"}; }

HeightField make_shape(const std::string& name, double lx, double ly, double height_mm,
                       double edge_blend_mm) {
  HeightField f;
  f.x_min_mm = -lx / 2;
  f.x_max_mm = lx / 2;
  f.y_min_mm = -ly / 2;
  f.y_max_mm = ly / 2;
  f.edge_blend_mm = edge_blend_mm;
  using K = ShapeTerm::Kind;
  // Shapes are written for a unit-ish size (fractions of lx, ly) and scaled below.
  if (name == "bumps") {
    f.base_mm = 0.45;
    f.terms = {{K::Gauss, 0.55, -0.18 * lx, 0.10 * ly, 0.14 * lx, 0.20 * ly},
               {K::Gauss, 0.35, 0.22 * lx, -0.12 * ly, 0.10 * lx, 0.15 * ly},
               {K::Gauss, 0.25, 0.05 * lx, -0.28 * ly, 0.08 * lx, 0.10 * ly},
               {K::Gauss, -0.15, 0.20 * lx, 0.22 * ly, 0.07 * lx, 0.09 * ly}};
  } else if (name == "saddle") {
    f.base_mm = 0.6;
    f.terms = {{K::Saddle, 0.35, 0.03 * lx, -0.02 * ly, 0.22 * lx, 0.25 * ly},
               {K::Gauss, 0.15, -0.15 * lx, -0.15 * ly, 0.12 * lx, 0.15 * ly}};
  } else if (name == "wave") {
    f.base_mm = 0.6;
    f.terms = {{K::Wave, 0.25, 0.1 * lx, 0.0, 0.55 * lx, 0.0},
               {K::Wave, 0.15, 0.0, 0.05 * ly, 0.8 * lx, 0.7 * ly}};
  } else if (name == "dome") {
    f.base_mm = 0.2;
    f.terms = {{K::Gauss, 0.8, 0.05 * lx, -0.05 * ly, 0.30 * lx, 0.32 * ly},
               {K::Wave, 0.06, 0.0, 0.0, 0.3 * lx, 0.0}};
  } else {
    throw std::invalid_argument("unknown shape '" + name + "'");
  }
  validate(f);
  // Scale f so that the sampled maximum of h is height_mm (h is linear in f).
  double top = 0;
  const int n = 400;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const double x = f.x_min_mm + lx * i / n;
      const double y = f.y_min_mm + ly * j / n;
      top = std::max(top, f.height_mm(x, y));
    }
  }
  if (!(top > 0)) throw std::invalid_argument("shape '" + name + "' has no positive height");
  const double k = height_mm / top;
  f.base_mm *= k;
  for (ShapeTerm& t : f.terms) t.amplitude_mm *= k;
  if (f.walled()) {
    // A walled part's top must stand above the plate everywhere (its walls' height > 0).
    double low = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j <= n; ++j) low = std::min(low, f.height_mm(f.x_min_mm + lx * i / n, f.y_min_mm + ly * j / n));
    }
    if (!(low > 0)) {
      throw std::invalid_argument("shape '" + name + "' with walls dips to " + std::to_string(low) +
                                  " mm, not above the plate");
    }
  }
  return f;
}

}  // namespace photomill::synth
