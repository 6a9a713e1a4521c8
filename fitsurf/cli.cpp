// fitsurf's options and outputs (cli.hpp).
#include "fitsurf/cli.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>

#include <CLI/CLI.hpp>

#include "fitsurf/mesh.hpp"
#include "fitsurf/numbers.hpp"
#include "fitsurf/preview.hpp"
#include "fitsurf/report.hpp"
#include "formats/cad.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/surface.hpp"
#include "formats/tool.hpp"

namespace photomill::fitsurf {

void add_options(CLI::App& app, Cli& c) {
  Options& o = c.options;
  FitOptions& f = o.fit;
  SelectOptions& s = o.select;
  app.add_option("input", c.input, "Point cloud: PLY, or x y z text ('-' = stdin)")->capture_default_str();

  const std::string out = "Outputs";
  app.add_option("-o,--output", c.output, "Surface in photomill's text format ('-' = stdout)")
      ->capture_default_str()->group(out);
  app.add_option("--step", c.step, "Also write the surface as STEP (AP214), trimmed by the outline")->group(out);
  app.add_option("--iges", c.iges, "Also write the surface as IGES 5.3, trimmed by the outline")->group(out);
  app.add_option("--mesh", c.mesh, "Also write a triangle mesh of the surface: FILE.stl (binary) or FILE.obj")->group(out);
  app.add_option("--mesh-step-mm", c.mesh_step_mm, "Sample spacing of --mesh, mm")->capture_default_str()->group(out)->check(tool::positive_up_to(1000));
  app.add_option("--report", c.report, "Write a JSON report (residual statistics, net, smoothing, rounds)")->group(out);
  app.add_option("--residuals", c.residuals,
                 "Write the fitted points as PLY with scalar fields residual_mm (signed distance) and weight")
      ->group(out);
  app.add_option("--preview", c.preview,
                 "Write a PNG view of the fit along the plane normal: the shaded surface and the points coloured "
                 "by residual, with a colour bar in mm")
      ->group(out);
  app.add_option("--uncertainty", c.uncertainty,
                 "Also write how well each part of the surface is measured: the standard deviation of its height on "
                 "a grid over the data's x, y (CSV x_mm,y_mm,sigma_mm; for toolpath --stock-uncertainty): the points' "
                 "sigma and residuals near a node, grown with its distance to the nearest point (docs/fitsurf.md)")
      ->group(out);
  app.add_option("--uncertainty-cell-mm", c.uncertainty_options.cell_mm, "Node spacing of --uncertainty, mm")
      ->capture_default_str()->group(out)->check(tool::positive_up_to(1000));
  app.add_option("--preview-width-px", c.preview_width_px, "Width of --preview; the height follows the part")
      ->capture_default_str()->check(CLI::Range(400, 8000))->group(out);

  const std::string sel = "Selecting the part";
  app.add_option("--keep-box", c.keep_box, "Keep only points inside XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (mm)")
      ->expected(6)->delimiter(',')->group(sel)->check(tool::finite_in(-1e9, 1e9));
  app.add_option("--keep-above", c.keep_above, "Keep only points with A x + B y + C z + D > 0: A,B,C,D (mm)")
      ->expected(4)->delimiter(',')->group(sel)->check(tool::finite_in(-1e9, 1e9));
  app.add_flag("--drop-plane", s.drop_plane,
               "Drop the dominant plane (RANSAC: the plate) and everything beyond it")->group(sel);
  app.add_option("--plane-threshold-mm", s.plane_threshold_mm, "Distance within which a point belongs to the plane")
      ->capture_default_str()->group(sel)->check(tool::positive_up_to(1e4));
  app.add_option("--seed", s.seed, "Seed of RANSAC's sampling")->capture_default_str()->group(sel);
  app.add_option("--walls", c.walls, "Where the part stands on walls (steps steeper than --wall-slope-deg): "
                 "auto fits its top alone, dropping the walls and the floor at their foot; off fits them all")
      ->check(CLI::IsMember({"auto", "off"}))->capture_default_str()->group(sel);
  app.add_option("--wall-slope-deg", s.walls.slope_deg, "A face steeper than this is a wall (degrees, 45-89.9)")
      ->capture_default_str()->check(tool::finite_in(45, 89.9))->group(sel);
  app.add_option("--wall-radius-mm", s.walls.radius_mm,
                 "Neighbourhood of a point's normal and of the regions (mm; at least 3 mean point spacings)")
      ->capture_default_str()->check(tool::finite_in(0.01, 1000))->group(sel);

  const std::string srf = "Surface";
  app.add_option("--degree-u", f.degree_u, "Degree p along u")->capture_default_str()->check(CLI::Range(1, 25))->group(srf);
  app.add_option("--degree-v", f.degree_v, "Degree q along v")->capture_default_str()->check(CLI::Range(1, 25))->group(srf);
  app.add_option("--net", c.net, "Control net NUxNV (poles along u and v), or N for NxN")->capture_default_str()->group(srf);
  app.add_option("--knots", c.knots,
                 "Knot placement: clamped uniform, averaged over the data (NURBS Book 9.69), or adaptive: placed by "
                 "the shape of a first uniform fit, denser where it bends sharply (de Boor's NEWNOT; twice the time)")
      ->capture_default_str()->check(CLI::IsMember({"uniform", "averaged", "adaptive"}))->group(srf);
  app.add_option("--plane", c.plane,
                 "Parameter plane: best-fit plane of the points (pca), world xy, or auto: pca unless xy holds the "
                 "data better as a height field (their steepest slopes over it lower by more than 1 degree)")
      ->capture_default_str()->check(CLI::IsMember({"auto", "pca", "xy"}))->group(srf);
  app.add_option("--smoothing", f.smoothing_mm4,
                 "Smoothing weight lambda, mm^4 (order 2; mm^6 with --smoothing-order 3): its 4th (6th) root is the "
                 "length below which detail is smoothed away; 0 = none")
      ->capture_default_str()->group(srf)->check(tool::non_negative_up_to(1e15));
  app.add_option("--smoothing-order", f.smoothing_order,
                 "Derivatives the smoothing penalises: 2 thin plate (bends; a plane costs nothing), 3 (changes of "
                 "bend; any quadric costs nothing, so gaps on curved parts are bridged along the curvature instead "
                 "of flattened)")
      ->capture_default_str()->check(CLI::Range(2, 3))->group(srf);
  app.add_option("--noise-mm", f.noise_mm,
                 "Noise of the points (standard deviation, mm): choose the smoothing so the residuals match it "
                 "(Reinsch), instead of --smoothing; for sparse noisy points such as markers")
      ->group(srf)->check(tool::non_negative_up_to(100));
  app.add_option("--prefit", c.prefit,
                 "Sparse points: first interpolate them by the radial kernel (Gaussian, Matern 3/2, 5/2, 7/2 with "
                 "their length and trend, or polyharmonic 3-5) that predicts each point best from the others "
                 "(leave-one-out), then fit the net to it; auto: when there are at most 400 points, fewer than "
                 "the net's poles, and no --tolerance, --noise-mm or --weight-by-sigma")
      ->capture_default_str()->check(CLI::IsMember({"auto", "kernel", "none"}))->group(srf);
  app.add_option("--outline", c.outline,
                 "Data outline written with the surface: concave (grid), convex (hull), auto (concave from 2000 "
                 "points), none")
      ->capture_default_str()->check(CLI::IsMember({"auto", "concave", "convex", "none"}))->group(srf);
  app.add_option("--max-slope-deg", f.fold.max_slope_deg,
                 "Steepest slope of the fitted surface over its plane inside the outline where the data are not as "
                 "steep (there it may follow them: their slope + 3 degrees, at most 89); steeper, or folding, fails")
      ->capture_default_str()->check(tool::finite_in(1, 90))->group(srf);
  app.add_option("--outline-cell-mm", o.outline.cell_mm, "Grid cell of the concave outline (0 = 3 mean point spacings)")
      ->capture_default_str()->group(srf)->check(tool::non_negative_up_to(1e4));

  const std::string slv = "Solving";
  app.add_option("--solver", c.solver, "Linear solver: sparse Cholesky (ldlt) or conjugate gradients (cg)")
      ->capture_default_str()->check(CLI::IsMember({"ldlt", "cg"}))->group(slv);
  app.add_option("--cg-tolerance", f.cg_tolerance, "CG: relative residual to reach")->capture_default_str()->group(slv)->check(tool::positive_up_to(0.1));
  app.add_flag("--no-correction", c.no_correction,
               "No parameter correction: keep the projection onto the plane as parameters")->group(slv);
  app.add_option("--max-rounds", f.max_rounds, "Fits at most (each followed by parameter correction and reweighting)")
      ->capture_default_str()->group(slv)->check(tool::finite_in(1, 1000));
  app.add_option("--max-smoothing-factor", c.options.max_smoothing_factor,
                 "When parameter correction stops before a round that would curl the surface, fit again with the "
                 "smoothing raised by steps of sqrt(10) up to this factor while it still stops, and keep the fit "
                 "closest to the data; 1 = keep the smoothing given")
      ->capture_default_str()->group(slv)->check(tool::finite_in(1, 1e6));
  app.add_option("--min-gain", f.min_rms_gain, "Stop when a round lowers the RMS by less than this fraction")
      ->capture_default_str()->group(slv)->check(tool::finite_in(0, 0.999));
  app.add_option("--robust", c.robust,
                 "Outliers, judged against their neighbours: reject (weight 0 beyond the cutoff), huber, tukey "
                 "(IRLS weights), or none (for noise-free data)")
      ->capture_default_str()->check(CLI::IsMember({"none", "reject", "huber", "tukey"}))->group(slv);
  app.add_option("--robust-threshold", f.robust_threshold,
                 "Cutoff in robust standard deviations (0 = 5 for reject, 1.345 for huber, 4.685 for tukey)")
      ->capture_default_str()->group(slv)->check(tool::non_negative_up_to(100));
  app.add_option("--robust-floor-mm", f.robust_min_scale_mm,
                 "Smallest robust standard deviation: residuals below threshold x this are never outliers")
      ->capture_default_str()->group(slv)->check(tool::positive_up_to(100));
  app.add_flag("--weight-by-sigma", c.options.weight_by_sigma,
               "Weight each point by 1/sigma^2 from the cloud's sigma_mm property (triangulate's standard deviation "
               "of the point): a point seen in two photos counts less than one seen in eight")
      ->group(slv);
  app.add_option("--sigma-floor-mm", c.options.sigma_floor_mm,
                 "Smallest sigma_mm --weight-by-sigma uses (marker corners and control points are near 0)")
      ->capture_default_str()->group(slv)->check(tool::positive_up_to(100));
  app.add_option("--max-net-poles", f.max_net_poles,
                 "Work limit: a net of more poles (--net, or tried by --tolerance) is refused before any work")
      ->capture_default_str()->group(slv)->check(tool::finite_in(1, 1e8));
  app.add_option("--threads", f.threads, "Worker threads (0 = all cores)")->capture_default_str()->group(slv)->check(tool::non_negative_up_to(1024));

  const std::string tol = "Tolerance mode";
  app.add_option("--tolerance", c.tolerance_mm,
                 "Grow the net until the cross-validated deviation is at most this (mm); fails if it cannot be met")
      ->each([&c](const std::string&) { c.tolerance_given = true; })
      ->group(tol)->check(tool::positive_up_to(1e4));
  app.add_option("--tolerance-stat", c.tolerance_stat, "Deviation compared with --tolerance")
      ->capture_default_str()->check(CLI::IsMember({"rms", "p90", "p95", "p99", "max"}))->group(tol);
  app.add_option("--cv-folds", c.cv_folds, "Cross-validation folds")
      ->capture_default_str()->check(CLI::Range(2, 1000))->group(tol);
  app.add_option("--max-poles", c.max_poles, "Largest net tried, poles per direction")->capture_default_str()->group(tol)->check(tool::finite_in(2, 2000));
  tool::add_presets(app, c.preset,
                    {{"features",
                      {{"--weight-by-sigma", [&c] { c.options.weight_by_sigma = true; }},
                       {"--smoothing-order", [&f] { f.smoothing_order = 3; }}}}},
                    "features: the settings the markers + natural features chain was measured with (docs/measurements/makefile.md); options given as well win");
}

std::pair<int, int> parse_net(const std::string& text) {
  auto number = [&](std::string_view t) {
    int v = 0;
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || ptr != t.data() + t.size() || v < 2) {
      throw UsageError("--net: expected NUxNV or N with whole numbers >= 2, got '" + text + "'");
    }
    return v;
  };
  const auto x = text.find_first_of("xX");
  if (x == std::string::npos) {
    const int n = number(text);
    return {n, n};
  }
  return {number(std::string_view(text).substr(0, x)), number(std::string_view(text).substr(x + 1))};
}

Options to_options(const Cli& c) {
  Options o = c.options;
  std::tie(o.fit.poles_u, o.fit.poles_v) = parse_net(c.net);
  o.fit.knots = c.knots == "averaged"   ? KnotPlacement::Averaged
                : c.knots == "adaptive" ? KnotPlacement::Adaptive
                                        : KnotPlacement::Uniform;
  o.fit.plane = c.plane == "xy" ? PlaneChoice::Xy : c.plane == "pca" ? PlaneChoice::Pca : PlaneChoice::Auto;
  o.fit.solver = c.solver == "cg" ? LinearSolver::Cg : LinearSolver::Ldlt;
  o.fit.robust = c.robust == "none"    ? RobustLoss::None
                 : c.robust == "huber" ? RobustLoss::Huber
                 : c.robust == "tukey" ? RobustLoss::Tukey
                                       : RobustLoss::Reject;
  o.fit.parameter_correction = !c.no_correction;
  o.prefit.mode = c.prefit == "kernel" ? Prefit::Kernel : c.prefit == "none" ? Prefit::None : Prefit::Auto;
  o.outline.method = c.outline == "concave" ? OutlineMethod::Concave
                     : c.outline == "convex" ? OutlineMethod::Convex
                     : c.outline == "none"   ? OutlineMethod::None
                                             : OutlineMethod::Auto;
  if (!c.keep_box.empty()) {
    const auto& b = c.keep_box;
    if (!(b[0] < b[3] && b[1] < b[4] && b[2] < b[5])) throw UsageError("--keep-box: each minimum must be below its maximum");
    o.select.keep_box_mm = std::array<double, 6>{b[0], b[1], b[2], b[3], b[4], b[5]};
  }
  o.select.walls.enabled = c.walls == "auto";
  if (!c.keep_above.empty()) {
    const Eigen::Vector3d n(c.keep_above[0], c.keep_above[1], c.keep_above[2]);
    if (!(n.norm() > 0) || !std::isfinite(c.keep_above[3])) throw UsageError("--keep-above: A,B,C must not all be 0");
    o.select.keep_above = Plane{n / n.norm(), c.keep_above[3] / n.norm()};
  }
  if (!(o.select.plane_threshold_mm > 0)) throw UsageError("--plane-threshold-mm must be positive");
  if (!(c.mesh_step_mm > 0)) throw UsageError("--mesh-step-mm must be positive");
  if (!c.mesh.empty()) mesh_format_for(c.mesh);
  if (c.tolerance_given) {
    ToleranceOptions t;
    t.tolerance_mm = c.tolerance_mm;
    t.stat = c.tolerance_stat == "p90"   ? ToleranceStat::P90
             : c.tolerance_stat == "p95" ? ToleranceStat::P95
             : c.tolerance_stat == "p99" ? ToleranceStat::P99
             : c.tolerance_stat == "max" ? ToleranceStat::Max
                                         : ToleranceStat::Rms;
    t.folds = c.cv_folds;
    t.max_poles = c.max_poles;
    if (!(t.tolerance_mm > 0)) throw UsageError("--tolerance must be a positive length in mm");
    o.tolerance = t;
  }
  validate(o.fit);
  // Every file output distinct, and only -o on stdout.
  std::set<std::string> paths;
  for (const std::string* p : {&c.step, &c.iges, &c.mesh, &c.report, &c.residuals, &c.preview, &c.uncertainty, &c.output}) {
    if (p->empty() || (p == &c.output && *p == "-")) continue;
    if (*p == "-") throw UsageError("only -o may write to stdout ('-'); give the other outputs file names");
    if (!paths.insert(*p).second) throw UsageError("'" + *p + "' is named for two outputs");
  }
  return o;
}

std::vector<LengthOption> length_options_acting(const Cli& c, const Options& o, const Result& r) {
  std::vector<LengthOption> out;
  if (r.units == kSurfaceUnitMm) return out;
  const Cli d;  // the defaults
  const auto add = [&](const char* option, double value, double default_value, bool acts) {
    if (acts) out.push_back({option, {value}, value == default_value, value, ""});
  };
  const auto sides = [](const std::array<double, 6>& b) { return std::max({b[3] - b[0], b[4] - b[1], b[5] - b[2]}); };
  add("--mesh-step-mm", c.mesh_step_mm, d.mesh_step_mm, !c.mesh.empty());
  add("--uncertainty-cell-mm", c.uncertainty_options.cell_mm, d.uncertainty_options.cell_mm, !c.uncertainty.empty());
  if (const auto& b = o.select.keep_box_mm) {
    out.push_back({"--keep-box", std::vector<double>(b->begin(), b->end()), false, sides(*b), "a box " + sig(sides(*b), 3) + " across"});
  }
  // A plane through the origin is the same plane in any unit.
  if (o.select.keep_above && o.select.keep_above->offset_mm != 0) {
    const double dist = std::abs(o.select.keep_above->offset_mm);
    out.push_back({"--keep-above", c.keep_above, false, dist, "a plane " + sig(dist, 3) + " from the origin"});
  }
  add("--plane-threshold-mm", o.select.plane_threshold_mm, d.options.select.plane_threshold_mm, o.select.drop_plane);
  // The walls' neighbourhood is at least 2.5 point spacings: where walls were found, whether the
  // option or the spacing set it is known.
  const auto& walls = r.selection.walls;
  add("--wall-radius-mm", o.select.walls.radius_mm, d.options.select.walls.radius_mm,
      o.select.walls.enabled && (!walls || walls->radius_mm == o.select.walls.radius_mm));
  // lambda is a length to the power 2m: its 2m-th root is the length below which detail goes.
  if (o.fit.noise_mm == 0 && o.fit.smoothing_mm4 > 0) {
    const int root = 2 * o.fit.smoothing_order;
    const double length = std::pow(o.fit.smoothing_mm4, 1.0 / root);
    out.push_back({"--smoothing", {o.fit.smoothing_mm4}, o.fit.smoothing_mm4 == d.options.fit.smoothing_mm4, length,
                   "its " + std::to_string(root) + "th root " + sig(length, 3)});
  }
  add("--noise-mm", o.fit.noise_mm, d.options.fit.noise_mm, o.fit.noise_mm > 0);
  // The concave outline's cell, when given (0: from the point spacing) and the outline is concave.
  std::size_t outlined = 0;
  for (std::size_t k = 0; k < r.fit.uv.size(); ++k) outlined += k >= r.fit.weight.size() || r.fit.weight[k] > 0;
  const bool concave = o.outline.method == OutlineMethod::Concave ||
                       (o.outline.method == OutlineMethod::Auto && outlined >= o.outline.concave_min_points);
  add("--outline-cell-mm", o.outline.cell_mm, d.options.outline.cell_mm, o.outline.cell_mm > 0 && concave);
  add("--robust-floor-mm", o.fit.robust_min_scale_mm, d.options.fit.robust_min_scale_mm, o.fit.robust != RobustLoss::None);
  add("--sigma-floor-mm", o.sigma_floor_mm, d.options.sigma_floor_mm, o.weight_by_sigma);
  if (o.tolerance) out.push_back({"--tolerance", {o.tolerance->tolerance_mm}, false, o.tolerance->tolerance_mm, ""});
  return out;
}

void write_outputs(const Cli& c, const Options& options, const PointCloud& cloud, const Result& result) {
  const BSplineSurface& surface = result.fit.surface;
  std::vector<std::unique_ptr<tool::OutputFile>> files;
  auto file = [&](const std::string& path) -> tool::OutputFile& {
    files.push_back(std::make_unique<tool::OutputFile>(path));
    return *files.back();
  };
  // The headers name the file the user asked for, not the temporary it is written to.
  const auto header = [&](const std::string& name) {
    CadHeader h{name == "-" ? "" : std::filesystem::path(name).filename().string()};
    if (!surface.in_mm()) {
      // STEP and IGES have no arbitrary unit: the file says millimetres. The warning says it is
      // not, and so do the writers in the file's header (formats/cad.cpp).
      log::warn(name + ": the CAD file says millimetres, but the surface's scale is arbitrary (fitted from a cloud "
                "oriented without a datum): scale it before any use in mm");
    }
    return h;
  };
  if (!c.step.empty()) write_step(surface, file(c.step).temp_path(), header(c.step));
  if (!c.iges.empty()) write_iges(surface, file(c.iges).temp_path(), header(c.iges));
  if (!c.mesh.empty()) {
    MeshOptions m;
    m.step_mm = c.mesh_step_mm;
    write_mesh(file(c.mesh).stream(), surface, mesh_format_for(c.mesh), m);
  }
  if (!c.report.empty()) {
    write_report(file(c.report).stream(), result, options, tool::source_name(c.input), length_options_acting(c, options, result));
  }
  if (!c.residuals.empty()) {
    write_ply(file(c.residuals).stream(), residual_cloud(cloud, result), PlyEncoding::BinaryLittleEndian,
              "fitsurf residuals: residual_mm = signed distance to the surface, weight = robust weight");
  }
  if (!c.uncertainty.empty()) {
    std::vector<Eigen::Vector3d> fitted;
    std::vector<double> sigma, window;
    const PointProperty* ps = cloud.find("sigma_mm");
    const PointProperty* pw = cloud.find("window_mm");  // densify's matching windows
    fitted.reserve(result.selection.kept.size());
    for (std::size_t k : result.selection.kept) {
      fitted.push_back(cloud.points_mm[k]);
      if (ps != nullptr) sigma.push_back(ps->values[k]);
      if (pw != nullptr) window.push_back(pw->values[k]);
    }
    UncertaintyOptions uo = c.uncertainty_options;
    // rho: the net's knot span, the length over which the spline averages the points.
    const FitResult& fr = result.fit;
    uo.resolution_mm = std::max(fr.box.length_u_mm() / std::max(1, fr.surface.num_poles_u - fr.surface.degree_u),
                                fr.box.length_v_mm() / std::max(1, fr.surface.num_poles_v - fr.surface.degree_v));
    if (result.prefit) uo.residual_floor_mm = std::max(uo.residual_floor_mm, result.prefit->loo_rms_mm);
    UncertaintySummary sum;
    const UncertaintyGrid grid = surface_uncertainty(fitted, result.fit.residual_mm, result.fit.weight, sigma, window, uo, &sum);
    const auto mm = [](double v) {
      char t[32];
      std::snprintf(t, sizeof t, "%.4f", v);
      return std::string(t);
    };
    log::info("uncertainty: height sigma " + mm(sum.min_mm) + " .. " + mm(sum.max_mm) + " mm (median " + mm(sum.median_mm) +
              ", p95 " + mm(sum.p95_mm) + ") on " + std::to_string(grid.nx) + " x " + std::to_string(grid.ny) +
              " nodes; point spacing " + mm(sum.spacing_mm) + " mm, surface resolution " + mm(sum.resolution_mm) + " mm" +
              (ps == nullptr ? "; the cloud has no sigma_mm: residuals only" : ""));
    write_uncertainty_grid(file(c.uncertainty).stream(), grid);
  }
  if (!c.preview.empty()) {
    std::vector<Eigen::Vector3d> fitted;
    fitted.reserve(result.selection.kept.size());
    for (std::size_t k : result.selection.kept) fitted.push_back(cloud.points_mm[k]);
    PreviewOptions po;
    po.width_px = c.preview_width_px;
    const std::vector<std::uint8_t> png = render_preview_png(result, fitted, po);
    file(c.preview).stream().write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  }
  tool::OutputFile surface_out(c.output);
  if (!surface_out.is_stdout()) write_surface(surface_out.stream(), surface);
  // All files are complete: rename them into place, and only then put the surface on stdout.
  for (auto& f : files) f->commit();
  if (surface_out.is_stdout()) write_surface(surface_out.stream(), surface);
  surface_out.commit();
}

}  // namespace photomill::fitsurf
