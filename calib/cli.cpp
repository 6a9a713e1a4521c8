// calib's options (see cli.hpp).
#include "calib/cli.hpp"

#include <map>
#include <set>
#include <sstream>

#include <Eigen/Core>

#include <CLI/CLI.hpp>

#include "calib/rig.hpp"
#include "geometry/board.hpp"
#include "formats/error.hpp"
#include "formats/text.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"

namespace photomill::calib {

void add_options(CLI::App& app, CalibCli& c) {
  auto& o = c.options;
  app.add_option("observations", c.observations, "Observations CSV (image,point_id,u_px,v_px); '-' = stdin")
      ->capture_default_str();
  app.add_option("-o,--output", c.output, "camera.yaml to write (default: stdout)");
  const std::string g_in = "Control points (one of)";
  auto* ctl = app.add_option("--control", c.control, "Control points CSV (point_id,x_mm,y_mm,z_mm); repeatable")
                  ->group(g_in)->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  auto* cb = app.add_option("--chessboard", c.chessboard, "A chessboard with COLSxROWS inner corners (as detect)")
                 ->group(g_in);
  auto* ch = app.add_option("--charuco", c.charuco, "A ChArUco board with COLSxROWS squares (as detect)")->group(g_in);
  ctl->excludes(cb)->excludes(ch);
  cb->excludes(ch);
  app.add_option("--square-mm", c.square_mm, "Board square side, mm (sets the unit of the poses only)")
      ->group(g_in)->capture_default_str()->check(tool::positive_up_to(10000.0));
  app.add_option("--image-size", c.image_size, "WxH in px (default: read from the images the observations name)");

  const std::string g_m = "Method";
  app.add_option("--method", c.method, "Initial estimate: planar (Zhang), dlt (normalised DLT), auto (by the points)")
      ->group(g_m)->capture_default_str()->check(CLI::IsMember({"auto", "planar", "dlt"}));
  app.add_option("--optimizer", c.optimizer,
                 "Refinement: opencv (calibrateCamera), lm (Ceres LM), simplex (Nelder-Mead); auto: opencv "
                 "for boards, lm otherwise")
      ->group(g_m)->capture_default_str()->check(CLI::IsMember({"auto", "opencv", "lm", "simplex"}));
  app.add_flag("--fix-aspect-ratio", o.model.fix_aspect_ratio, "fx = fy")->group(g_m);
  app.add_flag("--fix-principal-point", o.model.fix_principal_point, "cx, cy at the image centre")->group(g_m);
  app.add_flag("--zero-tangent", o.model.zero_tangent, "p1 = p2 = 0")->group(g_m);
  app.add_flag("--fix-k3", o.model.fix_k3, "k3 = 0")->group(g_m);
  app.add_flag("--rational-model", o.model.rational, "Estimate k4, k5, k6 too (8 coefficients)")->group(g_m);
  app.add_option("--max-iterations", o.lm.max_iterations, "LM iterations (lm, opencv)")
      ->group(g_m)->capture_default_str()->check(CLI::Range(1, 1'000'000));
  app.add_option("--simplex-scaling", c.simplex_scaling,
                 "Simplex coordinates: jacobian (whitened by J^T J at each restart) or diagonal (fixed steps)")
      ->group(g_m)->capture_default_str()->check(CLI::IsMember({"jacobian", "diagonal"}));
  app.add_option("--simplex-max-evaluations", o.simplex.simplex.max_evaluations, "Simplex: cost evaluations at most")
      ->group(g_m)->capture_default_str()->check(CLI::Range(1, 100'000'000));
  app.add_option("--simplex-ftol", o.simplex.simplex.ftol, "Simplex: relative spread of the vertex costs that ends a run")
      ->group(g_m)->capture_default_str()->check(tool::positive_up_to(1.0));

  const std::string g_q = "Quality";
  app.add_option("--reject-factor", o.reject_factor,
                 "Reject the worst view while its RMS > FACTOR x median view RMS (0: never)")
      ->group(g_q)->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  app.add_option("--reject-min-px", o.reject_min_px, "... and > this RMS, px")
      ->group(g_q)->capture_default_str()->check(CLI::Range(0.0, 10000.0));
  app.add_option("--min-views", o.min_views, "Warn below this many views; rejection keeps at least this many")
      ->group(g_q)->capture_default_str()->check(CLI::Range(1, 100'000));
  app.add_option("--min-points", o.min_points_per_view, "Skip views with fewer control-point observations")
      ->group(g_q)->capture_default_str()->check(CLI::Range(4, 1000000));
  app.add_option("--report", c.report, "Write a JSON report to FILE")->group(g_q);
  auto* plot = app.add_option("--plot", c.plot, "Write the residual vectors over the image frame to FILE.png")->group(g_q);

  const std::string g_r = "Rig (several cameras at once, e.g. a stereo pair)";
  app.add_option("--rig", c.rig,
                 "Image name prefix of one rig camera (e.g. left, or cam1/); give it once per camera, the "
                 "reference camera first. Photos named alike but for the prefix were taken at once. Writes rig.yaml")
      ->group(g_r)->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)->excludes(plot);
  app.add_flag("--rig-fix-intrinsics", c.rig_fix_intrinsics,
               "Hold each camera's intrinsics at its own calibration's (OpenCV's CALIB_FIX_INTRINSIC); by default "
               "the rig adjustment refines them too")
      ->group(g_r);
}

CalibOptions to_options(const CalibCli& c) {
  CalibOptions o = c.options;
  o.method = c.method == "planar" ? Method::Planar : c.method == "dlt" ? Method::Dlt : Method::Auto;
  o.optimizer = c.optimizer == "opencv"    ? Optimizer::OpenCv
                : c.optimizer == "lm"      ? Optimizer::Lm
                : c.optimizer == "simplex" ? Optimizer::Simplex
                                           : Optimizer::Auto;
  o.simplex.scaling = c.simplex_scaling == "diagonal" ? SimplexScaling::Diagonal : SimplexScaling::Jacobian;
  return o;
}

std::vector<ControlPoint> load_control(const CalibCli& c) {
  if (!c.control.empty()) {
    std::vector<ControlPoint> all;
    std::map<PointId, std::string> defined_in;
    for (const auto& path : c.control) {
      auto in = tool::open_input(path);
      for (auto& p : read_control_points(*in, tool::source_name(path))) {
        const auto [it, fresh] = defined_in.emplace(p.point_id, path);
        if (!fresh) {
          throw InputError(tool::source_name(path), 0,
                           "point " + std::to_string(p.point_id) + " is also defined in " + it->second);
        }
        all.push_back(std::move(p));
      }
    }
    return all;
  }
  geometry::BoardSpec spec;
  spec.square_mm = c.square_mm;
  if (!c.chessboard.empty()) {
    spec.kind = geometry::BoardKind::Chessboard;
    std::tie(spec.cols, spec.rows) = geometry::parse_grid(c.chessboard, "--chessboard");
  } else if (!c.charuco.empty()) {
    spec.kind = geometry::BoardKind::Charuco;
    std::tie(spec.cols, spec.rows) = geometry::parse_grid(c.charuco, "--charuco");
  } else {
    throw UsageError("give the control points: --control FILE, --chessboard COLSxROWS or --charuco COLSxROWS");
  }
  return geometry::board_control_points(spec);
}

std::string observation_sources(const CalibCli& c) {
  std::string sources;
  for (const auto& p : c.observations) sources += (sources.empty() ? "" : ", ") + tool::source_name(p);
  return sources;
}

namespace {

// Two views whose corners agree within kRepeatedViewPx on every point are one photo given twice
// (or copied under another name): two exposures differ by their noise, 0.01 px and more. A copy
// adds no geometry, yet it counts as an independent view: the uncertainties shrink by the square
// root of the copies while the answer stays as weak as one view's (issue #25: ten copies of
// one view gave fx 2583 +- 9 px, truth 2400, with exit 0).
constexpr double kRepeatedViewPx = 1e-3;

void check_no_repeated_view(const std::vector<Observation>& observations, const std::string& sources) {
  std::map<std::string, std::map<PointId, Eigen::Vector2d>> views;
  std::vector<std::string> order;
  for (const auto& o : observations) {
    auto [it, fresh] = views.try_emplace(o.image);
    if (fresh) order.push_back(o.image);
    it->second[o.point_id] = {o.u_px, o.v_px};
  }
  for (std::size_t i = 0; i < order.size(); ++i) {
    const auto& a = views.at(order[i]);
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      const auto& b = views.at(order[j]);
      if (a.size() != b.size() || a.size() < 4) continue;
      bool same = true;
      for (auto ia = a.begin(), ib = b.begin(); same && ia != a.end(); ++ia, ++ib) {
        same = ia->first == ib->first && (ia->second - ib->second).norm() <= kRepeatedViewPx;
      }
      if (same) {
        throw InputError(sources, 0, "views '" + order[i] + "' and '" + order[j] + "' hold the same " +
                                         std::to_string(a.size()) + " corners (within " + format_double(kRepeatedViewPx) +
                                         " px): one photo given twice adds no geometry and makes the uncertainties "
                                         "too small; leave the copy out");
      }
    }
  }
}

}  // namespace

void check_observations(const CalibCli& c, const std::vector<Observation>& observations,
                        const std::vector<ControlPoint>& control) {
  const std::string sources = observation_sources(c);
  if (observations.empty()) throw InputError(sources, 0, "no observations: the input holds only a header");
  check_no_repeated_view(observations, sources);
  std::set<PointId> ids;
  for (const auto& p : control) ids.insert(p.point_id);
  for (const auto& o : observations) {
    if (ids.count(o.point_id)) return;
  }
  std::string of;
  for (const auto& p : c.control) of += (of.empty() ? " in " : ", ") + tool::source_name(p);
  if (of.empty()) of = !c.chessboard.empty() ? " of the --chessboard board" : " of the --charuco board";
  throw InputError(sources, 0,
                   "no observation refers to a control point (" + std::to_string(observations.size()) + " observations, " +
                       std::to_string(control.size()) + " control points" + of + "): check the point ids");
}

namespace {

// The first observation that lies off a w x h image, if any. OpenCV's pixel centres are the
// integers, so the image covers [-0.5, w - 0.5] x [-0.5, h - 0.5].
const Observation* off_the_image(const std::vector<Observation>& observations, cv::Size size) {
  for (const Observation& o : observations) {
    if (!(o.u_px >= -0.5 && o.u_px <= size.width - 0.5 && o.v_px >= -0.5 && o.v_px <= size.height - 0.5)) return &o;
  }
  return nullptr;
}

std::string describe(const Observation& o, cv::Size size) {
  std::ostringstream s;
  s << "point " << o.point_id << " of " << o.image << " at (" << o.u_px << ", " << o.v_px << ") px lies off a "
    << size.width << " x " << size.height << " px image";
  return s.str();
}

}  // namespace

cv::Size resolve_image_size(const CalibCli& c, const std::vector<Observation>& observations) {
  if (!c.image_size.empty()) {
    const auto [w, h] = geometry::parse_grid(c.image_size, "--image-size");
    if (w <= 0 || h <= 0) throw UsageError("--image-size: width and height must be positive");
    const cv::Size size(w, h);
    if (const Observation* o = off_the_image(observations, size)) {
      throw UsageError("--image-size " + c.image_size + " is too small for the observations: " + describe(*o, size));
    }
    return size;
  }
  const auto size = image_size_from_files(observations);
  if (!size) {
    throw UsageError("the image size is unknown: give --image-size WxH (the images the observations name "
                     "cannot be read from here)");
  }
  if (const Observation* o = off_the_image(observations, *size)) {
    throw InputError(observation_sources(c), 0,
                     describe(*o, *size) + " (its size read from the image file): the observations do not belong "
                                           "to that image");
  }
  return *size;
}

std::vector<cv::Size> resolve_rig_image_sizes(const CalibCli& c, const std::vector<Observation>& observations) {
  if (c.rig.size() < 2) throw UsageError("--rig: give two image name prefixes or more (one per camera)");
  std::vector<cv::Size> sizes;
  for (const auto& part : split_by_camera(observations, c.rig, observation_sources(c))) {
    sizes.push_back(resolve_image_size(c, part));
  }
  return sizes;
}

}  // namespace photomill::calib
