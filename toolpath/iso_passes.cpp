#include "toolpath/iso_passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "formats/error.hpp"
#include "geometry/parallel.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Squared length below which a derivative counts as zero (mm^2 per parameter unit^2).
constexpr double kTinySquared = 1e-24;

std::string where(const Eigen::Vector2d& uv) {
  std::ostringstream s;
  s.precision(9);
  s << "(u, v) = (" << uv.x() << ", " << uv.y() << ")";
  return s.str();
}

}  // namespace

Eigen::Vector3d IsoCurve::point(double t) const {
  const Eigen::Vector2d p = uv(t);
  return surface_point(*surface_, p.x(), p.y());
}

PassFrame IsoCurve::frame(double t) const {
  const Eigen::Vector2d p = uv(t);
  return pass_frame(*surface_, direction_, p.x(), p.y());
}

PassFrame pass_frame(const BSplineSurface& surface, PassDirection direction, double u, double v) {
  const auto [u0, u1] = domain_u(surface);
  const auto [v0, v1] = domain_v(surface);
  u = std::clamp(u, u0, u1);
  v = std::clamp(v, v0, v1);
  const SurfaceDerivatives d = surface_derivatives(surface, u, v);
  // su x sv vanishing against |su|^2 + |sv|^2 (rounding noise on a collapsed edge is not a
  // direction) means a collapsed edge or a pole: the normal is taken a little way towards the
  // domain's centre, where its limit usually exists.
  const auto normal_of = [](const SurfaceDerivatives& e) {
    const Eigen::Vector3d c = e.su.cross(e.sv);
    const double scale = e.su.squaredNorm() + e.sv.squaredNorm();
    return c.norm() > 1e-10 * scale ? Eigen::Vector3d(c.normalized()) : Eigen::Vector3d::Zero();
  };
  Eigen::Vector3d n = normal_of(d);
  if (n.squaredNorm() == 0.0) {
    const double du = 1e-7 * (u1 - u0), dv = 1e-7 * (v1 - v0);
    const double un = u + (u < 0.5 * (u0 + u1) ? du : -du);
    const double vn = v + (v < 0.5 * (v0 + v1) ? dv : -dv);
    n = normal_of(surface_derivatives(surface, un, vn));
    if (n.squaredNorm() == 0.0) {
      throw GeometryError("the surface has no normal at " + where({u, v}) +
                          " (its derivatives are parallel or zero there), so the tool position is undefined");
    }
  }
  PassFrame f;
  f.uv = {u, v};
  f.p = d.p;
  f.normal = n;
  if (direction == PassDirection::U) {
    f.st = d.su, f.sw = d.sv, f.stt = d.suu, f.stw = d.suv, f.sww = d.svv;
  } else {
    f.st = d.sv, f.sw = d.su, f.stt = d.svv, f.stw = d.suv, f.sww = d.suu;
  }
  return f;
}

// Even-odd point-in-polygon test (a ray towards +u).
bool inside_uv_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y())) {
      inside = !inside;
    }
  }
  return inside;
}

SurfaceFacing surface_facing(const BSplineSurface& surface) {
  // With dA = |S_u x S_v| du dv and n_z the z component of S_u x S_v / |S_u x S_v|:
  //   area = sum dA,  up = sum max(n_z, 0) dA,  down = sum max(-n_z, 0) dA
  // (up - down is the z component of the vector area, the signed projection onto the xy plane).
  // Midpoint rule on a kGrid x kGrid grid of the domain, cells inside the boundary polygon only.
  constexpr int kGrid = 48;
  const auto [u0, u1] = domain_u(surface);
  const auto [v0, v1] = domain_v(surface);
  const double du = (u1 - u0) / kGrid, dv = (v1 - v0) / kGrid;
  SurfaceFacing out;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      const Eigen::Vector2d uv(u0 + (i + 0.5) * du, v0 + (j + 0.5) * dv);
      if (!surface.boundary_uv.empty() && !inside_uv_polygon(surface.boundary_uv, uv)) continue;
      const SurfaceDerivatives d = surface_derivatives(surface, uv.x(), uv.y());
      const Eigen::Vector3d c = d.su.cross(d.sv) * (du * dv);
      out.area_mm2 += c.norm();
      (c.z() >= 0 ? out.up_mm2 : out.down_mm2) += std::abs(c.z());
    }
  }
  return out;
}

BSplineSurface mirrored_u(const BSplineSurface& s) {
  // u' = u0 + u1 - u: knots reflected and reversed, pole rows reversed; the boundary polygon
  // reflected and reversed so that it stays counter-clockwise. S'(u', v) = S(u, v), and
  // S'_u' x S'_v = -(S_u x S_v).
  BSplineSurface m = s;
  const auto [u0, u1] = domain_u(s);
  const std::size_t nk = s.knots_u.size();
  for (std::size_t k = 0; k < nk; ++k) m.knots_u[k] = u0 + u1 - s.knots_u[nk - 1 - k];
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      const std::size_t to = static_cast<std::size_t>(i) * s.num_poles_v + j;
      const std::size_t from = static_cast<std::size_t>(s.num_poles_u - 1 - i) * s.num_poles_v + j;
      m.poles_mm[to] = s.poles_mm[from];
      if (s.rational()) m.weights[to] = s.weights[from];
    }
  }
  m.boundary_uv.clear();
  for (auto it = s.boundary_uv.rbegin(); it != s.boundary_uv.rend(); ++it) m.boundary_uv.push_back({u0 + u1 - it->x(), it->y()});
  return m;
}

BSplineSurface upward_oriented(const BSplineSurface& surface) {
  const SurfaceFacing f = surface_facing(surface);
  return f.up_mm2 < f.down_mm2 ? mirrored_u(surface) : surface;
}

std::pair<double, double> along_domain(const BSplineSurface& surface, PassDirection direction) {
  return direction == PassDirection::U ? domain_u(surface) : domain_v(surface);
}

std::pair<double, double> across_domain(const BSplineSurface& surface, PassDirection direction) {
  return direction == PassDirection::U ? domain_v(surface) : domain_u(surface);
}

double normal_curvature(const PassFrame& f, double a, double b) {
  const double E = f.st.dot(f.st), F = f.st.dot(f.sw), G = f.sw.dot(f.sw);
  const double L = f.stt.dot(f.normal), M = f.stw.dot(f.normal), N = f.sww.dot(f.normal);
  const double first = a * a * E + 2 * a * b * F + b * b * G;
  if (first <= kTinySquared) return 0.0;
  return (a * a * L + 2 * a * b * M + b * b * N) / first;
}

double along_curvature(const PassFrame& f) { return normal_curvature(f, 1.0, 0.0); }

double across_curvature(const PassFrame& f) {
  const double E = f.st.dot(f.st), F = f.st.dot(f.sw);
  if (E <= kTinySquared) return normal_curvature(f, 0.0, 1.0);
  return normal_curvature(f, -F, E);
}

double max_concave_curvature(const PassFrame& f) {
  const double E = f.st.dot(f.st), F = f.st.dot(f.sw), G = f.sw.dot(f.sw);
  const double L = f.stt.dot(f.normal), M = f.stw.dot(f.normal), N = f.sww.dot(f.normal);
  const double a = E * G - F * F;
  if (a <= kTinySquared) return 0.0;
  const double b = E * N + G * L - 2 * F * M;
  const double c = L * N - M * M;
  const double disc = std::max(0.0, b * b - 4 * a * c);
  return (b + std::sqrt(disc)) / (2 * a);
}

double side_step_mm(double R, double h, double a, double kappa) {
  // Formula and sources in the header (law of cosines over two ball centres and the cusp tip).
  const double num = h * (2 * R - h);  // R^2 - (R - h)^2
  if (std::abs(kappa) * (R + a) < 1e-12) return 2 * std::sqrt(num);
  double rho, A, B;
  if (kappa < 0) {
    rho = 1.0 / -kappa;
    A = rho + a + R;
    B = rho + a + h;
  } else {
    rho = std::max(1.0 / kappa, 2 * (R + a));
    A = rho - a - R;
    B = rho - a - h;
  }
  const double s2 = std::min(1.0, num / (4 * A * B));
  return rho * 4 * std::asin(std::sqrt(s2));
}

double across_param_step(const PassFrame& f, double g) {
  const double E = f.st.dot(f.st), F = f.st.dot(f.sw), G = f.sw.dot(f.sw);
  const double perp2 = E > kTinySquared ? G - F * F / E : G;
  if (perp2 <= kTinySquared) return kInf;
  return g / std::sqrt(perp2);
}

std::vector<Interval> clip_to_boundary(const BSplineSurface& surface, PassDirection direction, double w) {
  const auto [t0, t1] = along_domain(surface, direction);
  if (surface.boundary_uv.empty()) return {{t0, t1}};
  // Polygon vertices as (t, w).
  const auto tw = [&](const Eigen::Vector2d& uv) {
    return direction == PassDirection::U ? uv : Eigen::Vector2d(uv.y(), uv.x());
  };
  std::vector<double> xs;
  const auto& poly = surface.boundary_uv;
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Eigen::Vector2d a = tw(poly[k]);
    const Eigen::Vector2d b = tw(poly[(k + 1) % poly.size()]);
    // Half-open rule: an edge counts if it crosses w with one end <= w and the other > w, so a
    // vertex on the line is counted once.
    if ((a.y() <= w) != (b.y() <= w)) xs.push_back(a.x() + (w - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
  }
  std::sort(xs.begin(), xs.end());
  std::vector<Interval> out;
  // Slivers where a line grazes a polygon vertex (shorter than a millionth of the domain) are
  // dropped: the neighbouring passes' balls cover them.
  const double min_len = 1e-6 * (t1 - t0);
  for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
    const double a = std::max(xs[k], t0), b = std::min(xs[k + 1], t1);
    if (b - a > min_len) out.push_back({a, b});
  }
  return out;
}

double cusp_budget_mm(const PassFrame& f, const PassPlanOptions& o) {
  const double kappa = along_curvature(f);
  double delta = 0.0;
  if (kappa > 0) {
    const double rho = 1.0 / kappa, r = o.tool_radius_mm + o.stock_mm;
    const double sagitta = std::min(o.chord_tol_mm, o.max_step_mm * o.max_step_mm * kappa / 8);
    delta = rho > r ? sagitta * (rho - r) / rho : sagitta;
  }
  return o.scallop_mm - delta;
}

namespace {


// Parameters at which a line is sampled: uniform in t within each interval, at most `spacing` mm
// apart (lengths estimated on a 16-piece polyline) and at least 2 per knot span crossed (the
// curvature of a B-spline varies within a span, smoothly).
std::vector<double> line_samples(const BSplineSurface& s, PassDirection dir, double w,
                                 const std::vector<Interval>& intervals, double spacing) {
  const IsoCurve curve(s, dir, w);
  const std::vector<double>& knots = dir == PassDirection::U ? s.knots_u : s.knots_v;
  std::vector<double> ts;
  for (const Interval& iv : intervals) {
    double length = 0;
    Eigen::Vector3d prev = curve.point(iv.t0);
    constexpr int kPieces = 16;
    for (int k = 1; k <= kPieces; ++k) {
      const Eigen::Vector3d p = curve.point(iv.t0 + (iv.t1 - iv.t0) * k / kPieces);
      length += (p - prev).norm();
      prev = p;
    }
    const auto spans = std::count_if(knots.begin(), knots.end(), [&](double k) { return k > iv.t0 && k < iv.t1; }) + 1;
    const long n = std::max<long>({2, static_cast<long>(std::ceil(length / spacing)) + 1, 2 * static_cast<long>(spans) + 1});
    for (long k = 0; k < n; ++k) ts.push_back(iv.t0 + (iv.t1 - iv.t0) * static_cast<double>(k) / static_cast<double>(n - 1));
  }
  return ts;
}

struct LineStep {
  double across_step = kInf;  // smallest dw over the samples
  double g_min_mm = kInf;     // smallest side step g
};

LineStep step_on_line(const BSplineSurface& s, const PassPlanOptions& o, double w, const std::vector<Interval>& fallback) {
  std::vector<Interval> intervals = clip_to_boundary(s, o.direction, w);
  if (intervals.empty()) intervals = fallback;
  const IsoCurve curve(s, o.direction, w);
  const std::vector<double> ts = line_samples(s, o.direction, w, intervals, o.sample_mm);
  // Samples are independent: evaluate them in chunks on the worker threads.
  constexpr std::size_t kChunk = 64;
  const std::size_t chunks = (ts.size() + kChunk - 1) / kChunk;
  std::vector<LineStep> partial(chunks);
  geometry::parallel_for(chunks, geometry::thread_count(o.threads), [&](std::size_t c) {
    LineStep& out = partial[c];
    for (std::size_t k = c * kChunk; k < std::min(ts.size(), (c + 1) * kChunk); ++k) {
      const PassFrame f = curve.frame(ts[k]);
      const double cusp = cusp_budget_mm(f, o);
      const double g = side_step_mm(o.tool_radius_mm, cusp, o.stock_mm, across_curvature(f));
      out.g_min_mm = std::min(out.g_min_mm, g);
      out.across_step = std::min(out.across_step, across_param_step(f, g));
    }
  });
  LineStep out;
  for (const LineStep& p : partial) {
    out.g_min_mm = std::min(out.g_min_mm, p.g_min_mm);
    out.across_step = std::min(out.across_step, p.across_step);
  }
  return out;
}

}  // namespace

namespace {

// conservative_across_step with a cache: the evaluation of the next line, reused as the first
// evaluation of the following call when the step was not reduced (the next line is then exactly
// where it was evaluated).
struct StepCache {
  double w = std::numeric_limits<double>::quiet_NaN();
  LineStep step;
};

double across_step_cached(const BSplineSurface& surface, const PassPlanOptions& o, double w, double* g_min_mm,
                          StepCache* cache) {
  const auto [w0, w1] = across_domain(surface, o.direction);
  std::vector<Interval> here = clip_to_boundary(surface, o.direction, w);
  if (here.empty()) here = {Interval{along_domain(surface, o.direction).first, along_domain(surface, o.direction).second}};
  const LineStep first = cache && cache->w == w ? cache->step : step_on_line(surface, o, w, here);
  const double dw0 = first.across_step;
  if (!std::isfinite(dw0)) {
    if (g_min_mm) *g_min_mm = first.g_min_mm;
    return dw0;
  }
  // The cusps between this line and the next lie in [w, w + dw0]: the step is also evaluated
  // halfway and on the next line, and the smallest of the three is taken (the final step is no
  // longer than dw0, so its whole strip was sampled).
  const double w_next = std::min(w + dw0, w1);
  const LineStep mid = step_on_line(surface, o, std::min(w + 0.5 * dw0, w1), here);
  const LineStep next = step_on_line(surface, o, w_next, here);
  const double dw = std::min({dw0, mid.across_step, next.across_step});
  if (g_min_mm) *g_min_mm = std::min({first.g_min_mm, mid.g_min_mm, next.g_min_mm});
  if (!(dw > 0)) {
    throw GeometryError("cannot compute a side step at w = " + std::to_string(w) +
                        ": the scallop height leaves no room for cusps");
  }
  if (cache) {
    cache->w = dw == dw0 ? w_next : std::numeric_limits<double>::quiet_NaN();
    cache->step = next;
  }
  return dw;
}

}  // namespace

double conservative_across_step(const BSplineSurface& surface, const PassPlanOptions& o, double w, double* g_min_mm) {
  return across_step_cached(surface, o, w, g_min_mm, nullptr);
}

std::vector<PassLine> plan_passes(const BSplineSurface& surface, const PassPlanOptions& o) {
  auto [w_start, w_end] = across_domain(surface, o.direction);
  const double range = w_end - w_start;
  if (!surface.boundary_uv.empty()) {
    // Only the polygon's extent across the passes needs passes.
    double lo = kInf, hi = -kInf;
    for (const auto& uv : surface.boundary_uv) {
      const double wc = o.direction == PassDirection::U ? uv.y() : uv.x();
      lo = std::min(lo, wc), hi = std::max(hi, wc);
    }
    w_start = std::max(w_start, lo);
    w_end = std::min(w_end, hi);
    if (!(w_end > w_start)) throw GeometryError("the boundary polygon lies outside the surface's parameter domain");
  }
  // A line exactly through the polygon's lowest or highest vertex meets it in a point; the end
  // lines are taken this far inside instead.
  const double nudge = 1e-9 * range;
  constexpr std::size_t kMaxPasses = 200000;
  std::vector<PassLine> lines;
  StepCache cache;
  double w = w_start;
  for (;;) {
    PassLine line;
    line.w = w;
    double wc = w;
    if (!surface.boundary_uv.empty()) wc = std::clamp(w, w_start + nudge, w_end - nudge);
    line.intervals = clip_to_boundary(surface, o.direction, wc);
    if (w >= w_end) {
      lines.push_back(std::move(line));
      break;
    }
    line.across_step = across_step_cached(surface, o, wc, &line.side_step_mm, &cache);
    if (lines.size() >= kMaxPasses) {
      throw GeometryError("more than " + std::to_string(kMaxPasses) + " passes would be needed (side step " +
                          std::to_string(line.side_step_mm) + " mm): the surface is degenerate or the scallop height tiny");
    }
    // The last pass lies on the boundary (never further than one step from the one before).
    const double next = w + line.across_step;
    lines.push_back(std::move(line));
    w = std::min(next, w_end);
  }
  if (!surface.boundary_uv.empty()) {
    // Each pass machines the strip halfway to its neighbours: where a polygon edge crosses the
    // passes at a slant, the strip reaches further along the pass than the line itself, so the
    // pass runs to the farthest end of the polygon over its strip (else the corner between two
    // pass ends would keep a scallop up to four times h).
    std::vector<std::vector<Interval>> widened(lines.size());
    for (std::size_t k = 0; k < lines.size(); ++k) {
      std::vector<Interval> all = lines[k].intervals;
      for (const int side : {-1, 1}) {
        const std::size_t j = side < 0 ? (k == 0 ? k : k - 1) : (k + 1 == lines.size() ? k : k + 1);
        if (j == k) continue;
        const double wm = std::clamp(0.5 * (lines[k].w + lines[j].w), w_start + nudge, w_end - nudge);
        for (const Interval& iv : clip_to_boundary(surface, o.direction, wm)) all.push_back(iv);
      }
      std::sort(all.begin(), all.end(), [](const Interval& a, const Interval& b) { return a.t0 < b.t0; });
      for (const Interval& iv : all) {
        auto& out = widened[k];
        if (!out.empty() && iv.t0 <= out.back().t1) out.back().t1 = std::max(out.back().t1, iv.t1);
        else out.push_back(iv);
      }
    }
    for (std::size_t k = 0; k < lines.size(); ++k) lines[k].intervals = std::move(widened[k]);
  }
  return lines;
}

}  // namespace photomill::toolpath
