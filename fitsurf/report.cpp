// JSON report and stderr summary of a fit (report.hpp).
#include "fitsurf/report.hpp"

#include "fitsurf/numbers.hpp"
#include "formats/run.hpp"
#include "formats/json.hpp"

namespace photomill::fitsurf {
namespace {

std::string num(double v) { return sig(v, 4); }

}  // namespace

std::string to_string(KnotPlacement k) {
  return k == KnotPlacement::Uniform ? "uniform" : k == KnotPlacement::Averaged ? "averaged" : "adaptive";
}
std::string to_string(PlaneChoice p) {
  switch (p) {
    case PlaneChoice::Pca: return "pca";
    case PlaneChoice::Xy: return "xy";
    case PlaneChoice::Auto: return "auto";
  }
  return "pca";
}
std::string to_string(LinearSolver s) { return s == LinearSolver::Ldlt ? "ldlt" : "cg"; }
std::string to_string(RobustLoss r) {
  switch (r) {
    case RobustLoss::None: return "none";
    case RobustLoss::Reject: return "reject";
    case RobustLoss::Huber: return "huber";
    case RobustLoss::Tukey: return "tukey";
  }
  return "?";
}
std::string to_string(OutlineMethod m) {
  switch (m) {
    case OutlineMethod::Auto: return "auto";
    case OutlineMethod::Concave: return "concave";
    case OutlineMethod::Convex: return "convex";
    case OutlineMethod::None: return "none";
  }
  return "?";
}

void write_report(std::ostream& out, const Result& r, const Options& o, const std::string& source,
                  const std::vector<LengthOption>& length_options) {
  const FitResult& f = r.fit;
  const BSplineSurface& s = f.surface;
  JsonWriter j(out);
  j.begin_object();
  j.field("tool", "fitsurf");
  j.field("run_id", run_id());
  j.field("input", source);
  j.field("input_points", r.input_points);
  j.field("units", r.units);
  j.field("cloud_extent", r.extent);  // in the cloud's unit
  // The length options that acted in the cloud's unit because it is not mm (empty in mm).
  j.key("length_options_in_cloud_units").begin_array();
  for (const LengthOption& l : length_options) {
    j.begin_object();
    j.field("option", l.option);
    j.key("value");
    if (l.values.size() == 1) {
      j.value(l.values.front());
    } else {
      j.begin_array();
      for (double v : l.values) j.value(v);
      j.end_array();
    }
    j.field("default", l.is_default);
    j.field("length", l.length);
    j.field("fraction_of_extent", r.extent > 0 ? l.length / r.extent : 0.0);
    j.end_object();
  }
  j.end_array();
  j.key("selection").begin_object();
  j.field("fitted_points", r.selection.kept.size());
  j.field("dropped_box", r.selection.dropped_box);
  j.field("dropped_below", r.selection.dropped_below);
  j.field("dropped_plane", r.selection.dropped_plane);
  j.field("dropped_beyond_plane", r.selection.dropped_beyond_plane);
  j.key("plane");
  if (r.selection.plane) {
    const Plane& p = *r.selection.plane;
    j.begin_array().value(p.normal.x()).value(p.normal.y()).value(p.normal.z()).value(p.offset_mm).end_array();
  } else {
    j.null();
  }
  j.key("walls");
  if (const auto& w = r.selection.walls) {
    j.begin_object();
    j.field("wall_points", w->wall_points);
    j.field("dropped_floor", w->dropped_floor);
    j.field("top_points", w->top_points);
    j.field("radius_mm", w->radius_mm);
    j.field("floor_z_mm", w->floor_z_mm);
    j.field("wall_top_z_mm", w->wall_top_z_mm);
    j.key("top_xy_box_mm").begin_array().value(w->box_min.x()).value(w->box_min.y()).value(w->box_max.x()).value(w->box_max.y()).end_array();
    j.end_object();
  } else {
    j.null();
  }
  j.end_object();
  j.key("surface").begin_object();
  j.field("degree_u", s.degree_u);
  j.field("degree_v", s.degree_v);
  j.field("poles_u", s.num_poles_u);
  j.field("poles_v", s.num_poles_v);
  j.field("knots", to_string(o.fit.knots));
  j.field("parameter_plane", to_string(f.plane));
  j.field("parameter_plane_option", to_string(o.fit.plane));
  // The data's steepest slopes (99th percentile of the cells, slope.hpp) over both candidate
  // planes when --plane auto chose between them, and over the plane used.
  if (f.pca_slope_deg >= 0) {
    j.field("data_slope_pca_deg", f.pca_slope_deg);
    j.field("data_slope_xy_deg", f.xy_slope_deg);
  }
  j.field("data_slope_max_deg", f.data_slope.max_deg);
  j.field("stopped_before_fold", f.stopped_at_round > 0);
  j.key("plane_origin_mm").begin_array();
  for (int k = 0; k < 3; ++k) j.value(f.frame.origin_mm[k]);
  j.end_array();
  j.key("plane_normal").begin_array();
  for (int k = 0; k < 3; ++k) j.value(f.frame.axes(k, 2));
  j.end_array();
  j.field("extent_u_mm", f.box.length_u_mm());
  j.field("extent_v_mm", f.box.length_v_mm());
  j.field("outline", to_string(o.outline.method));
  j.field("boundary_vertices", s.boundary_uv.size());
  j.end_object();
  j.key("fit").begin_object();
  // lambda in mm^(2 m): the key names its unit ("smoothing_mm4" for the thin plate, m = 2).
  j.field(o.fit.smoothing_order == 3 ? "smoothing_mm6" : "smoothing_mm4", f.smoothing_mm4);
  j.field("smoothing_order", o.fit.smoothing_order);
  // The smoothing ladder (Options::max_smoothing_factor): each fit tried, the given smoothing's first.
  j.key("smoothing_ladder").begin_array();
  for (const SmoothingTrial& t : r.smoothing_ladder) {
    j.begin_object();
    j.field("smoothing", t.smoothing);
    j.field("rounds", t.rounds);
    j.field("stopped_before_fold", t.stopped);
    j.field("rms_mm", t.score_rms_mm);
    j.key("refused");
    if (t.refused.empty()) {
      j.null();
    } else {
      j.value(t.refused);
    }
    j.end_object();
  }
  j.end_array();
  j.field("weight_by_sigma", o.weight_by_sigma);
  j.key("noise_mm");
  if (o.fit.noise_mm > 0) {
    j.value(o.fit.noise_mm);
  } else {
    j.null();
  }
  j.key("prefit");
  if (r.prefit) {
    const PrefitSummary& k = *r.prefit;
    j.begin_object();
    j.field("kernel", to_string(k.model.shape));
    j.key("length_mm");
    if (k.model.length_mm > 0) {
      j.value(k.model.length_mm);
    } else {
      j.null();
    }
    j.field("trend_degree", k.model.trend_degree);
    j.field("aspect", k.model.aspect);
    j.field("long_axis_deg", k.model.angle_deg);
    j.field("loo_rms_mm", k.loo_rms_mm);
    j.field("candidates", k.candidates);
    j.field("samples", k.samples);
    j.field("outliers", k.outliers);
    j.field("outlier_cutoff_mm", k.outlier_cutoff_mm);
    j.end_object();
  } else {
    j.null();
  }
  j.field("solver", to_string(o.fit.solver));
  j.field("parameter_correction", o.fit.parameter_correction);
  j.key("round_rms_mm").begin_array();
  for (double x : f.round_rms_mm) j.value(x);
  j.end_array();
  j.field("robust", to_string(o.fit.robust));
  j.field("robust_applied", f.robust_applied);
  j.field("robust_scale_mm", f.robust_scale_mm);
  j.field("robust_cutoff_mm", f.robust_cutoff_mm);
  j.field("outliers", f.outliers);
  j.field("gross_outliers", f.gross_outliers);
  j.key("robust_net").begin_array();
  if (f.robust_applied && f.robust_poles_u > 0) {  // empty: not judged on a net (none, or the kernel prefit)
    j.value(f.robust_poles_u);
    j.value(f.robust_poles_v);
  }
  j.end_array();
  j.end_object();
  j.key("residuals").begin_object();
  j.field("count", r.stats.count);
  j.field("rms_mm", r.stats.rms_mm);
  j.field("mean_mm", r.stats.mean_mm);
  j.field("max_abs_mm", r.stats.max_abs_mm);
  j.field("p50_mm", r.stats.p50_mm);
  j.field("p90_mm", r.stats.p90_mm);
  j.field("p95_mm", r.stats.p95_mm);
  j.field("p99_mm", r.stats.p99_mm);
  j.field("inliers", r.stats.inliers);
  j.field("inlier_rms_mm", r.stats.inlier_rms_mm);
  j.end_object();
  j.key("tolerance");
  if (r.tolerance && o.tolerance) {
    j.begin_object();
    j.field("tolerance_mm", o.tolerance->tolerance_mm);
    j.field("statistic", to_string(o.tolerance->stat));
    j.field("folds", o.tolerance->folds);
    j.field("cross_validated_mm", r.tolerance->cv_mm);
    j.key("steps").begin_array();
    for (const auto& st : r.tolerance->steps) {
      j.begin_object().field("poles_u", st.poles_u).field("poles_v", st.poles_v).field("cross_validated_mm", st.cv_mm).end_object();
    }
    j.end_array();
    j.end_object();
  } else {
    j.null();
  }
  j.field("seconds", r.seconds);
  j.end_object();
  out << "\n";
}

std::string units_warning(const Result& r) {
  return "the point cloud's scale is " + r.units +
         ", not mm (oriented without control points, scale bars or known poses): the surface and its mm figures "
         "are in that unit, and the surface file says so (toolpath and rough refuse it); give triangulate a datum "
         "before machining";
}

std::string length_options_warning(const std::vector<LengthOption>& options, const Result& r) {
  std::string s = "these length options act in the cloud's unit, not in mm (the cloud's extent: " + sig(r.extent, 3) + " " +
                  (r.units == "mm" ? "mm" : "units") + "):";
  for (std::size_t k = 0; k < options.size(); ++k) {
    const LengthOption& l = options[k];
    s += k == 0 ? " " : ", ";
    s += l.option;
    for (std::size_t i = 0; i < l.values.size(); ++i) {
      s += i == 0 ? ' ' : ',';
      s += sig(l.values[i], 4);
    }
    s += l.is_default ? " (default; " : " (";
    if (!l.note.empty()) s += l.note + ", ";
    const double percent = r.extent > 0 ? 100 * l.length / r.extent : 0;
    s += !(r.extent > 0) ? std::string("?") : percent >= 10 ? fixed(percent, 0) : sig(percent, 2);
    s += " % of the extent)";
  }
  s += "; give lengths in the cloud's unit, or give triangulate a datum (control points, scale bars, --marker-side-mm "
       "or known poses)";
  return s;
}

std::vector<std::string> summary(const Result& r, const Options& o) {
  const FitResult& f = r.fit;
  const std::size_t dropped = r.input_points - r.selection.kept.size();
  std::string s = std::to_string(r.selection.kept.size()) + " points fitted";
  if (dropped) s += " (" + std::to_string(dropped) + " of " + std::to_string(r.input_points) + " dropped by selection)";
  s += "; " + std::to_string(f.surface.num_poles_u) + "x" + std::to_string(f.surface.num_poles_v) + " poles, degree " +
       std::to_string(f.surface.degree_u) + "x" + std::to_string(f.surface.degree_v) +
       (o.fit.knots == KnotPlacement::Uniform ? "" : ", " + to_string(o.fit.knots) + " knots") + ", smoothing " +
       num(f.smoothing_mm4) + (o.fit.smoothing_order == 3 ? " mm^6 (order 3)" : " mm^4") +
       (o.fit.noise_mm > 0 ? " (for noise " + num(o.fit.noise_mm) + " mm)" : "") +
       (o.weight_by_sigma ? ", points weighted by 1/sigma^2" : "") + ", " + std::to_string(f.round_rms_mm.size()) + " round" +
       (f.round_rms_mm.size() == 1 ? "" : "s") + ", " + sig(r.seconds, 3) + " s";
  std::vector<std::string> lines{s};
  if (const auto& w = r.selection.walls) {
    lines.push_back("the part stands on walls (faces steeper than " + num(o.select.walls.slope_deg) + " degrees, from z " +
                    num(w->floor_z_mm) + " up to " + num(w->wall_top_z_mm) + " mm): its top fitted alone, to the walls' edge (x " + num(w->box_min.x()) +
                    " to " + num(w->box_max.x()) + ", y " + num(w->box_min.y()) + " to " + num(w->box_max.y()) + " mm); " + std::to_string(w->wall_points) +
                    " points of the walls and " + std::to_string(w->dropped_floor) +
                    " of the floor at their foot left out (the walls are not in the surface; --walls off fits them all)");
  }
  if (r.prefit) {
    const PrefitSummary& k = *r.prefit;
    lines.push_back("kernel prefit (" + std::to_string(r.selection.kept.size()) + " points" +
                    (o.prefit.mode == Prefit::Kernel ? ", --prefit kernel" : ", fewer than the net's poles") + "): " +
                    to_string(k.model) + ", chosen of " + std::to_string(k.candidates) + " by leave-one-out RMS " + num(k.loo_rms_mm) +
                    " mm (the error to expect between points); the net fitted to " + std::to_string(k.samples) +
                    " samples of it");
  }
  s = "residuals: RMS " + num(r.stats.rms_mm) + " mm, max " + num(r.stats.max_abs_mm) + " mm, p50 " +
       num(r.stats.p50_mm) + ", p95 " + num(r.stats.p95_mm) + ", p99 " + num(r.stats.p99_mm) + " mm";
  if (f.robust_applied) {
    s += "; " + std::to_string(f.outliers) + " outlier" + (f.outliers == 1 ? "" : "s") + " beyond " +
         num(f.robust_cutoff_mm) + " mm (inlier RMS " + num(r.stats.inlier_rms_mm) + " mm)";
    if (r.prefit) {
      s += ", judged by their leave-one-out residuals in the kernel prefit";
    } else if (f.robust_poles_u != o.fit.poles_u || f.robust_poles_v != o.fit.poles_v) {
      s += ", judged on a " + std::to_string(f.robust_poles_u) + "x" + std::to_string(f.robust_poles_v) +
           " net (too few points per pole for the fit's own)";
    }
  }
  if (f.gross_outliers > 0) {
    s += "; " + std::to_string(f.gross_outliers) + " gross outlier" + (f.gross_outliers == 1 ? "" : "s") +
         " left out before the first round";
  }
  lines.push_back(s);
  if (r.tolerance && o.tolerance) {
    lines.push_back("tolerance " + num(o.tolerance->tolerance_mm) + " mm (" + to_string(o.tolerance->stat) +
         ") met: cross-validated " + num(r.tolerance->cv_mm) + " mm after " + std::to_string(r.tolerance->steps.size()) +
         " net sizes");
  }
  return lines;
}

}  // namespace photomill::fitsurf
