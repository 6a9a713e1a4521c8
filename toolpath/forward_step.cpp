#include "toolpath/forward_step.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>

#include "formats/error.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxSamples = 32;
// Golden-section search stops when the bracket is this fraction of the segment's parameter span
// (the value found is then within ~1e-6 relative of the bump's top).
constexpr double kBracketFraction = 1e-3;

// Golden-section search for the maximum of f on [a, b], f(m) known at an interior point m.
// The bracket shrinks by 1/phi a step until it is `stop` wide, but never below what double
// precision can tell apart at a and b (8 ulp): a sub-curve only a few ulp long in t (knot spans
// of 1e-15 at t = 0.5) had a stop of 1e-18, which no bracket reaches, and the search ran forever.
SubcurveMax golden_max(const std::function<double(double)>& f, double a, double b, double stop) {
  constexpr double kInvPhi = 0.6180339887498949;
  stop = std::max(stop, 8 * std::numeric_limits<double>::epsilon() * std::max(std::abs(a), std::abs(b)));
  double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
  double f1 = f(x1), f2 = f(x2);
  // 1/phi^100 < 1e-20: more steps than any stop above rounding needs.
  for (int step = 0; step < 100 && std::abs(b - a) > stop; ++step) {
    if (f1 > f2) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - kInvPhi * (b - a);
      f1 = f(x1);
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + kInvPhi * (b - a);
      f2 = f(x2);
    }
  }
  return f1 > f2 ? SubcurveMax{f1, x1} : SubcurveMax{f2, x2};
}

// Dense samples of f on (t0, t1), then golden search around the best sample when it comes within
// `refine_above` of mattering.
SubcurveMax sampled_max(const std::array<double, kMaxSamples + 2>& ts, const std::array<double, kMaxSamples + 2>& vals,
                        int samples, const std::function<double(double)>& f, double refine_above) {
  int best = 1;
  for (int k = 2; k <= samples; ++k) {
    if (vals[static_cast<std::size_t>(k)] > vals[static_cast<std::size_t>(best)]) best = k;
  }
  SubcurveMax m{vals[static_cast<std::size_t>(best)], ts[static_cast<std::size_t>(best)]};
  if (m.value < refine_above) return m;
  const double a = ts[static_cast<std::size_t>(best - 1)], b = ts[static_cast<std::size_t>(best + 1)];
  const SubcurveMax g = golden_max(f, std::min(a, b), std::max(a, b),
                                   kBracketFraction * std::abs(ts[static_cast<std::size_t>(samples + 1)] - ts[0]));
  return g.value > m.value ? g : m;
}

struct SegmentCheck {
  SubcurveMax deviation;
  SubcurveMax penetration;
};

// One evaluation pass for both criteria: the sub-curve points are shared.
SegmentCheck check_segment(const IsoCurve& curve, double t0, double t1, const Eigen::Vector3d& p0,
                           const Eigen::Vector3d& p1, const Eigen::Vector3d& c0, const Eigen::Vector3d& c1,
                           double r, double dev_refine_above, double pen_refine_above, bool check_penetration) {
  constexpr int kSamples = 8;
  std::array<double, kMaxSamples + 2> ts{}, dev{}, pen{};
  ts[0] = t0;
  ts[kSamples + 1] = t1;
  for (int k = 1; k <= kSamples; ++k) {
    const double t = t0 + (t1 - t0) * k / (kSamples + 1);
    const Eigen::Vector3d q = curve.point(t);
    ts[static_cast<std::size_t>(k)] = t;
    dev[static_cast<std::size_t>(k)] = distance_to_segment(q, p0, p1);
    pen[static_cast<std::size_t>(k)] = check_penetration ? r - distance_to_segment(q, c0, c1) : -kInf;
  }
  SegmentCheck out;
  out.deviation = sampled_max(ts, dev, kSamples,
                              [&](double t) { return distance_to_segment(curve.point(t), p0, p1); }, dev_refine_above);
  if (check_penetration) {
    out.penetration = sampled_max(ts, pen, kSamples,
                                  [&](double t) { return r - distance_to_segment(curve.point(t), c0, c1); },
                                  pen_refine_above);
  } else {
    out.penetration = {-kInf, t0};
  }
  return out;
}

// The work limit (ForwardStepOptions::max_points): every CL point computed, kept or not, counts,
// so that neither a path of endless points nor a step shortened for ever outlives it.
void count_work(const ForwardStepOptions& o, std::atomic<std::size_t>& taken, const IsoCurve& curve, double t) {
  if (++taken <= o.max_points) return;
  const Eigen::Vector2d uv = curve.uv(t);
  std::ostringstream msg;
  msg.precision(9);
  msg << "more than " << o.max_points << " CL points computed (the work limit, --max-cl-points), the last at (u, v) = ("
      << uv.x() << ", " << uv.y() << "): raise --max-cl-points for a job this large, or coarsen --scallop-mm and "
      << "--chord-tol-mm";
  throw GeometryError(msg.str());
}

}  // namespace

double chord_length_for_tolerance(double radius_mm, double tol_mm) {
  if (!std::isfinite(radius_mm)) return kInf;
  if (tol_mm >= radius_mm) return 2 * radius_mm;  // any chord of the circle; the diameter is longest
  return 2 * std::sqrt(tol_mm * (2 * radius_mm - tol_mm));
}

double forward_param_step(double length_mm, const Eigen::Vector3d& tangent) {
  const double speed = tangent.norm();
  return speed > 0 ? length_mm / speed : kInf;
}

double distance_to_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

SubcurveMax max_over_subcurve(const std::function<double(double)>& f, double t0, double t1, int samples) {
  samples = std::clamp(samples, 1, kMaxSamples);
  std::array<double, kMaxSamples + 2> ts{}, vals{};
  ts[0] = t0;
  ts[static_cast<std::size_t>(samples + 1)] = t1;
  for (int k = 1; k <= samples; ++k) {
    ts[static_cast<std::size_t>(k)] = t0 + (t1 - t0) * k / (samples + 1);
    vals[static_cast<std::size_t>(k)] = f(ts[static_cast<std::size_t>(k)]);
  }
  return sampled_max(ts, vals, samples, f, -kInf);
}

SubcurveMax chord_deviation(const IsoCurve& curve, double t0, double t1, int samples) {
  const Eigen::Vector3d a = curve.point(t0), b = curve.point(t1);
  return max_over_subcurve([&](double t) { return distance_to_segment(curve.point(t), a, b); }, t0, t1, samples);
}

SubcurveMax ball_penetration(const IsoCurve& curve, double t0, double t1, const Eigen::Vector3d& c0,
                             const Eigen::Vector3d& c1, double r, int samples) {
  return max_over_subcurve([&](double t) { return r - distance_to_segment(curve.point(t), c0, c1); }, t0, t1, samples);
}

MarchResult march_interval(const IsoCurve& curve, double t0, double t1, const ForwardStepOptions& o, double r,
                           const std::function<CutterLocation(const PassFrame&)>& locate) {
  MarchResult out;
  const double dir = t1 >= t0 ? 1.0 : -1.0;
  double t = t0;
  PassFrame f = curve.frame(t);
  CutterLocation cl = locate(f);
  out.points.push_back(cl);
  out.ts.push_back(t);
  const double lifted_step = chord_length_for_tolerance(r, o.aim * o.gouge_tol_mm);
  std::atomic<std::size_t> own_count{0};  // without a shared count, this interval's alone
  double last_dt = kInf, growth = 1.5, last_dev = 0, last_pen = 0, last_centre_step = 0;
  while (t != t1) {
    // Step 2: chord length from the curvature of the pass (3D curvature |C' x C''| / |C'|^3 for
    // the CC chord; the normal curvature along the pass for the ball centres, whose curve has
    // radius rho + r where the surface is convex, so their chord sags L_c^2 / (8 (rho + r)) with
    // L_c = L (rho + r) / rho).
    const double speed = f.st.norm();
    double length = o.max_step_mm;
    if (speed > 0) {
      const double kappa3 = f.st.cross(f.stt).norm() / (speed * speed * speed);
      if (kappa3 > 0) length = std::min(length, chord_length_for_tolerance(1.0 / kappa3, o.aim * o.chord_tol_mm));
      const double kn = along_curvature(f);
      if (kn < 0) {
        const double rho = 1.0 / -kn;
        length = std::min(length, chord_length_for_tolerance(rho + r, o.aim * o.gouge_tol_mm) * rho / (rho + r));
      }
    }
    if (cl.lifted) length = std::min(length, lifted_step);
    // Step 3: to the parameter domain. The curvature at t does not see what lies ahead, nor the
    // turning of the normal that moves the ball centres: the last step's measured deviations,
    // which grow as the square of the step, predict the next one too. After a step that had to be
    // shortened, the next may grow by at most a quarter (else a half).
    double dt = std::min(forward_param_step(length, f.st), growth * last_dt);
    if (last_dev > 0.1 * o.chord_tol_mm) dt = std::min(dt, last_dt * std::sqrt(o.aim * o.chord_tol_mm / last_dev));
    if (last_pen > 0.1 * o.gouge_tol_mm) dt = std::min(dt, last_dt * std::sqrt(o.aim * o.gouge_tol_mm / last_pen));
    if (cl.lifted && last_centre_step > 0) dt = std::min(dt, last_dt * 0.95 * lifted_step / last_centre_step);
    bool shortened = false;
    for (;;) {
      double tn = t + dir * dt;
      if (!std::isfinite(tn) || dir * (tn - t1) >= 0) tn = t1;
      count_work(o, o.points_taken ? *o.points_taken : own_count, curve, tn);
      const PassFrame fn = curve.frame(tn);
      const CutterLocation cln = locate(fn);
      const bool penetration_matters = o.enforce_gouge || (!cl.gouge && !cln.gouge);
      const SegmentCheck c = check_segment(curve, t, tn, cl.cc, cln.cc, cl.centre, cln.centre, r,
                                           0.5 * o.chord_tol_mm, 0.5 * o.gouge_tol_mm, penetration_matters);
      // Where the ball was lifted it rests on the surface away from the CC curve, so the dip of
      // the straight move is bounded by geometry instead: the drop cutter's centre surface is the
      // surface dilated by the ball, whose convex parts have radius >= r, so a move of length l
      // between two of its points dips at most l^2 / (8 r) below it (creases are concave and lie
      // below the chord). Such moves are kept within that chord length for the gouge tolerance.
      const double centre_step = (cln.centre - cl.centre).norm();
      const bool lifted_too_long = penetration_matters && (cl.lifted || cln.lifted) && centre_step > lifted_step;
      if (c.deviation.value <= o.chord_tol_mm && c.penetration.value <= o.gouge_tol_mm && !lifted_too_long) {
        out.max_chord_error_mm = std::max(out.max_chord_error_mm, c.deviation.value);
        out.max_penetration_mm = std::max(out.max_penetration_mm, c.penetration.value);
        last_dt = std::abs(tn - t);
        last_dev = c.deviation.value;
        last_pen = c.penetration.value;
        last_centre_step = centre_step;
        growth = shortened ? 1.25 : 1.5;
        t = tn, f = fn, cl = cln;
        out.points.push_back(cl);
        out.ts.push_back(t);
        break;
      }
      // Shorten in proportion to the square root of the excess (deviation ~ L^2).
      double ratio = 0.9;
      if (c.deviation.value > o.chord_tol_mm) ratio = std::min(ratio, std::sqrt(o.aim * o.chord_tol_mm / c.deviation.value));
      if (c.penetration.value > o.gouge_tol_mm) ratio = std::min(ratio, std::sqrt(o.aim * o.gouge_tol_mm / c.penetration.value));
      if (lifted_too_long) ratio = std::min(ratio, lifted_step / centre_step);
      dt = std::abs(tn - t) * std::max(ratio, 0.1);
      shortened = true;
      ++out.rejected_steps;
      // Degenerate only if neither the contact nor the ball would move by the minimum step (at a
      // pole the contact stays put while the ball rolls around it).
      const double moved = std::max((cln.cc - cl.cc).norm(), centre_step) * std::max(ratio, 0.1);
      // A step too small to change t in double precision (the ball jumps while the contact
      // cannot move: a normal that turns over within rounding) is the same failure, and so is a
      // shorter step that rounds to the same tn: within a few ulp of t, t + dt rounds up to
      // where it was, and at a crease (a knot of multiplicity p, u = 0.5) the march proposed
      // that one tn for ever.
      const double next = t + dir * dt;
      if (moved < o.min_step_mm || next == t || next == tn) {
        std::ostringstream msg;
        msg.precision(9);
        const Eigen::Vector2d uv = curve.uv(t);
        msg << "the forward step at (u, v) = (" << uv.x() << ", " << uv.y() << "), (x, y, z) = (" << cl.cc.x() << ", "
            << cl.cc.y() << ", " << cl.cc.z() << ") mm falls below " << o.min_step_mm
            << " mm: the surface has a kink or a fold there (chord error " << c.deviation.value << " mm, ball dips "
            << c.penetration.value << " mm)";
        throw GeometryError(msg.str());
      }
    }
  }
  return out;
}

}  // namespace photomill::toolpath
