// triangulate's options (see cli.hpp).
#include "triangulate/cli.hpp"

#include <algorithm>
#include <iterator>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include <CLI/CLI.hpp>

#include "formats/camera.hpp"
#include "formats/camera_bounds.hpp"
#include "formats/camera_for.hpp"
#include "formats/error.hpp"
#include "formats/option_checks.hpp"
#include "formats/text.hpp"
#include "formats/tool.hpp"
#include "triangulate/colmap.hpp"

namespace photomill::triangulate {
namespace {

const std::map<std::string, LossKind> kLoss{
    {"huber", LossKind::Huber}, {"cauchy", LossKind::Cauchy}, {"soft-l1", LossKind::SoftL1}, {"none", LossKind::Trivial}};
const std::map<std::string, SolverKind> kSolver{{"auto", SolverKind::Auto},
                                                {"dense-schur", SolverKind::DenseSchur},
                                                {"sparse-schur", SolverKind::SparseSchur},
                                                {"iterative-schur", SolverKind::IterativeSchur}};
const std::map<std::string, IntrinsicsRefinement> kRefine{{"none", IntrinsicsRefinement::None},
                                                          {"focal", IntrinsicsRefinement::Focal},
                                                          {"focal-pp", IntrinsicsRefinement::FocalPrincipalPoint},
                                                          {"all", IntrinsicsRefinement::All}};

template <typename Map>
std::vector<std::string> keys(const Map& m) {
  std::vector<std::string> k;
  for (const auto& [key, value] : m) k.push_back(key);
  return k;
}

// "0-27,40,50-55" -> {{0, 27}, {40, 40}, {50, 55}}.
std::vector<std::pair<std::int64_t, std::int64_t>> parse_ranges(const std::string& text) {
  std::vector<std::pair<std::int64_t, std::int64_t>> ranges;
  for (std::string_view part : split_fields(text, ',')) {
    const auto dash = part.find('-', 1);
    const auto lo = parse_int(part.substr(0, dash));
    const auto hi = dash == std::string_view::npos ? lo : parse_int(part.substr(dash + 1));
    if (!lo || !hi || *lo < 0 || *hi < *lo) {
      throw UsageError("--marker-ids: '" + std::string(part) + "' is not an id or a range like 0-27");
    }
    ranges.push_back({*lo, *hi});
  }
  return ranges;
}

}  // namespace

void add_options(CLI::App& app, Cli& c) {
  ReconstructOptions& o = c.options;
  app.add_option("tracks", c.tracks, "Tracks CSV (track_id,image,u_px,v_px); '-' for stdin")->capture_default_str();
  // Required, but checked in to_options() so that an unknown option is named first.
  auto* cam = app.add_option("-c,--camera", c.camera, "Camera intrinsics (camera.yaml) of every photo; or --camera-for, or --rig");
  auto* cam_for = app.add_option("--camera-for", c.camera_for,
                                 "PREFIX=FILE: the camera.yaml of the photos whose names (or file names, for a PREFIX "
                                 "without '/') start with PREFIX; repeatable, one per camera")
                      ->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  auto* rig = app.add_option("--rig", c.rig,
                             "rig.yaml (calib --rig): each photo's camera by its prefix; the photos of one frame (names "
                             "alike but for the prefix) are placed by the rig's relative poses, the rig's frame as the world");
  cam->excludes(cam_for)->excludes(rig);
  cam_for->excludes(rig);
  app.add_option("--control-points", c.control_points,
                 "Control points CSV (point_id,x_mm,y_mm,z_mm[,sigma_mm]): the datum; held fixed, or weighted by sigma_mm");
  app.add_option("-o,--output", c.output, "Point cloud PLY ('-': stdout)")->capture_default_str();
  app.add_option("--ply-encoding", c.ply_encoding, "PLY encoding")
      ->check(CLI::IsMember({"binary", "ascii"}))->capture_default_str();
  app.add_option("--poses", c.poses, "Write the camera poses CSV (cam_from_world) here");
  app.add_option("--report", c.report, "Write the report as JSON here (it also goes to stderr as text)");
  app.add_option("--colmap", c.colmap, "Write a COLMAP text model (cameras.txt, images.txt, points3D.txt) into this folder");
  app.add_option("--refined-camera", c.refined_camera, "Write the camera.yaml after --refine-intrinsics here");
  app.add_option("--refined-camera-for", c.refined_camera_for,
                 "PREFIX=FILE: with several cameras (--camera-for, --rig), write the camera.yaml of the camera of "
                 "PREFIX after --refine-intrinsics to FILE; repeatable")
      ->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--preview", c.preview,
                 "Write a PNG of the points (coloured by quality) and the cameras, oblique and from above, here");
  app.add_option("--preview-colour", c.preview_options.colour_by,
                 "Preview colour: rms = reprojection RMS per point (px), sigma = its uncertainty (mm)")
      ->check(CLI::IsMember({"rms", "sigma"}))->capture_default_str();
  app.add_option("--preview-width-px", c.preview_options.width_px, "Preview width (the height is half of it)")
      ->check(CLI::Range(400, 8000))->capture_default_str();

  const std::string scale = "Scale without control points";
  app.add_option("--scale-bars", c.scale_bars, "Scale bars CSV (point_a,point_b,distance_mm[,sigma_mm])")->group(scale);
  app.add_option("--scale-bar-sigma-mm", o.scale.default_bar_sigma_mm, "Sigma of scale bars that give none")
      ->check(tool::positive_up_to(1000))->capture_default_str()->group(scale);
  app.add_option("--marker-side-mm", c.marker_side_mm, "Side of the square markers: each side becomes a scale bar")
      ->check(tool::positive_up_to(1e4))->group(scale);
  app.add_option("--marker-side-sigma-mm", o.scale.marker_side_sigma_mm, "Sigma of a marker side")
      ->check(tool::positive_up_to(1000))->capture_default_str()->group(scale);
  app.add_option("--marker-ids", c.marker_ids, "Marker ids the side applies to (ranges: 0-27,40)")
      ->capture_default_str()->group(scale);
  app.add_option("--marker-side-tolerance", o.scale.marker_side_tolerance,
                 "Leave out marker sides further than this fraction from the median side")
      ->check(tool::positive_up_to(10))->capture_default_str()->group(scale);
  app.add_flag("--arbitrary-scale", o.scale.allow_arbitrary_scale,
               "Without any datum, go on in the arbitrary scale of the first image pair")->group(scale);

  const std::string known = "Known poses";
  app.add_option("--known-poses", c.known_poses,
                 "Camera poses known beforehand (a poses CSV as --poses writes it, or COLMAP's images.txt; "
                 "cam_from_world, mm): held fixed, or priors with --pose-sigma-mm/--pose-sigma-deg; "
                 "they are the datum")->group(known);
  app.add_option("--pose-sigma-mm", o.pose_sigma_mm, "Sigma of a known camera centre per axis (with --pose-sigma-deg)")
      ->check(tool::positive_up_to(1e6))->group(known);
  app.add_option("--pose-sigma-deg", o.pose_sigma_deg, "Sigma of a known camera rotation per axis (with --pose-sigma-mm)")
      ->check(tool::positive_up_to(180))->group(known);

  const std::string ba = "Bundle adjustment";
  app.add_option("--refine-intrinsics", c.refine_intrinsics, "Self-calibration: which intrinsics to adjust")
      ->check(CLI::IsMember(keys(kRefine)))->capture_default_str()->group(ba);
  app.add_option("--loss", c.loss, "Robust loss on reprojection errors")
      ->check(CLI::IsMember(keys(kLoss)))->capture_default_str()->group(ba);
  app.add_option("--loss-scale-px", o.bundle.loss_scale_px, "Scale of the robust loss, pixels")
      ->check(tool::positive_up_to(1e4))->capture_default_str()->group(ba);
  app.add_option("--observation-sigma-px", c.observation_sigma_px,
                 "Sigma of an image measurement [default: estimated from the residuals, per class]")
      ->check(tool::positive_up_to(1000))->group(ba);
  app.add_option("--coded-id-limit", o.coded_id_limit,
                 "Track ids below this are coded targets (marker corners), the rest natural features; "
                 "each class gets its own sigma")
      ->check(tool::non_negative_up_to(4e9))->capture_default_str()->group(ba);
  app.add_flag("!--ignore-feature-size", o.weight_by_feature_size,
               "Weigh every observation of a class alike, even when the tracks give each feature's size_px "
               "[default: sigma grows with the feature's size]")
      ->group(ba);
  app.add_option("--outlier-sigmas", o.outliers.sigmas, "Remove observations beyond this many sigmas ...")
      ->check(tool::positive_up_to(1e4))->capture_default_str()->group(ba);
  app.add_option("--outlier-min-px", o.outliers.min_px, "... but never below this threshold ...")
      ->check(tool::non_negative_up_to(1e4))->capture_default_str()->group(ba);
  app.add_option("--outlier-max-px", o.outliers.max_px, "... and always beyond this one")
      ->check(tool::positive_up_to(1e6))->capture_default_str()->group(ba);
  app.add_option("--outlier-rounds", o.outliers.rounds, "Outlier removal and re-solve rounds")
      ->check(CLI::Range(0, 100))->capture_default_str()->group(ba);
  app.add_option("--solver", c.solver, "Ceres linear solver")
      ->check(CLI::IsMember(keys(kSolver)))->capture_default_str()->group(ba);
  app.add_option("--max-iterations", o.bundle.max_iterations, "Ceres iterations per adjustment")
      ->check(CLI::Range(1, 100000))->capture_default_str()->group(ba);
  app.add_option("--max-total-iterations", o.max_total_iterations,
                 "Work limit: Ceres iterations summed over all adjustments of the run; more is an error")
      ->check(tool::finite_in(1, 1e9))->capture_default_str()->group(ba);
  app.add_option("--function-tolerance", o.bundle.function_tolerance, "Stop when the cost decreases by less (relative)")
      ->check(tool::positive_up_to(1))->capture_default_str()->group(ba);
  app.add_option("--intermediate-function-tolerance", o.intermediate_function_tolerance,
                 "The same for the adjustments between registrations and of the outlier rounds (the last one uses --function-tolerance)")
      ->check(tool::positive_up_to(1))->capture_default_str()->group(ba);
  app.add_option("--covariance-max-parameters", o.covariance.max_reduced_parameters,
                 "Largest reduced camera system inverted for the full point covariance")
      ->capture_default_str()->check(tool::non_negative_up_to(1e6))->group(ba);
  app.add_option("--threads", o.threads, "Threads (0: all cores); the bundle adjustment takes one when it refines the intrinsics (faster: docs/triangulate.md)")->check(CLI::Range(0, 1024))->capture_default_str()->group(ba);

  const std::string geo = "Poses and triangulation";
  app.add_option("--min-angle-deg", o.triangulation.min_angle_deg, "Smallest intersection angle of a track's rays")
      ->check(tool::non_negative_up_to(180))->capture_default_str()->group(geo);
  app.add_option("--max-reproj-px", o.triangulation.max_reproj_px, "Largest reprojection error when triangulating")
      ->check(tool::positive_up_to(1e4))->capture_default_str()->group(geo);
  const std::string two = "Two-view points (checked against their neighbours seen in three views)";
  app.add_flag("!--no-two-view-check", o.two_view.enabled,
               "Keep every two-view point [default: a point seen in two photos only is kept where it agrees with its "
               "neighbours seen in three or more]")
      ->group(two);
  app.add_option("--two-view-neighbours", o.two_view.neighbours, "Points seen in three views whose local surface (plane, and quadric from 10 on) judges a two-view point")
      ->check(CLI::Range(3, 1000))->capture_default_str()->group(two);
  app.add_option("--two-view-reach", o.two_view.reach,
                 "A two-view point is removed when those neighbours are farther than this many times their typical "
                 "spacing (the median distance of a point seen in three views to its neighbours')")
      ->check(tool::positive_up_to(1e6))->capture_default_str()->group(two);
  app.add_option("--two-view-sigmas", o.two_view.sigmas,
                 "... or when it lies off their surface by more than this many standard deviations (their spread and "
                 "its own sigma along the surface's normal) ...")
      ->check(tool::positive_up_to(1e6))->capture_default_str()->group(two);
  app.add_option("--two-view-tolerance-mm", o.two_view.tolerance_mm, "... and by more than this")
      ->check(tool::non_negative_up_to(1e6))->capture_default_str()->group(two);
  app.add_option("--ransac-threshold-px", o.ransac.threshold_px, "RANSAC inlier threshold (PnP, essential matrix)")
      ->check(tool::positive_up_to(1e4))->capture_default_str()->group(geo);
  app.add_option("--ransac-confidence", o.ransac.confidence, "RANSAC confidence")
      ->check(tool::finite_in(0.5, 1))->capture_default_str()->group(geo);
  app.add_option("--ransac-iterations", o.ransac.max_iterations, "RANSAC iterations at most")
      ->check(CLI::Range(1, 10000000))->capture_default_str()->group(geo);
  app.add_option("--control-min-points", o.control_min_points, "Control points an image needs for PnP from them")
      ->check(CLI::Range(4, 1000000))->capture_default_str()->group(geo);
  app.add_option("--pnp-min-inliers", o.pnp_min_inliers, "Inliers PnP against triangulated points needs")
      ->check(CLI::Range(4, 1000000))->capture_default_str()->group(geo);
  app.add_option("--relative-min-scale-points", o.relative_min_scale_points,
                 "An image PnP cannot place is registered from its relative pose to a registered one when this many "
                 "points fix the baseline's length (0: never)")
      ->check(CLI::Range(0, 1000000))->capture_default_str()->group(geo);
  app.add_option("--min-shared-tracks", o.min_shared_tracks, "Tracks an initial image pair must share")
      ->check(CLI::Range(5, 1000000))->capture_default_str()->group(geo);
  app.add_option("--initial-min-angle-deg", o.initial_min_angle_deg, "Median intersection angle of the initial pair")
      ->check(tool::non_negative_up_to(180))->capture_default_str()->group(geo);
  tool::add_presets(app, c.preset,
                    {{"features",
                      {{"--refine-intrinsics", [&c] { c.refine_intrinsics = "all"; }},
                       {"--outlier-rounds", [&o] { o.outliers.rounds = 2; }},
                       {"--function-tolerance", [&o] { o.bundle.function_tolerance = 1e-6; }}}}},
                    "features: the settings the markers + natural features chain was measured with (docs/measurements/makefile.md); options given as well win");
}

ReconstructOptions to_options(const Cli& c) {
  if (c.camera.empty() && c.camera_for.empty() && c.rig.empty()) {
    throw UsageError("--camera is required: the camera.yaml of the photos (or --camera-for PREFIX=FILE per camera, or "
                     "--rig rig.yaml)");
  }
  if (!c.rig.empty() && !c.known_poses.empty()) {
    throw UsageError("--rig places the photos by the rig's relative poses; --known-poses would replace them: give one");
  }
  ReconstructOptions o = c.options;
  o.bundle.loss = kLoss.at(c.loss);
  o.bundle.solver = kSolver.at(c.solver);
  o.bundle.refine_intrinsics = kRefine.at(c.refine_intrinsics);
  o.bundle.threads = o.threads;
  o.covariance.threads = o.threads;
  o.scale.marker_side_mm = c.marker_side_mm;
  o.scale.marker_ids = parse_ranges(c.marker_ids);
  o.observation_sigma_px = c.observation_sigma_px;
  if (o.pose_sigma_mm.has_value() != o.pose_sigma_deg.has_value()) {
    throw UsageError("--pose-sigma-mm and --pose-sigma-deg go together (a pose prior needs both)");
  }
  if (o.pose_sigma_mm && c.known_poses.empty()) throw UsageError("--pose-sigma-mm needs --known-poses");
  if (o.outliers.min_px > o.outliers.max_px) throw UsageError("--outlier-min-px is larger than --outlier-max-px");
  if (!c.refined_camera.empty() && o.bundle.refine_intrinsics == IntrinsicsRefinement::None) {
    throw UsageError("--refined-camera needs --refine-intrinsics");
  }
  if (!c.refined_camera_for.empty() && o.bundle.refine_intrinsics == IntrinsicsRefinement::None) {
    throw UsageError("--refined-camera-for needs --refine-intrinsics");
  }
  const bool several_cameras = !c.camera_for.empty() || !c.rig.empty();
  if (!c.refined_camera.empty() && several_cameras) {
    throw UsageError("--refined-camera writes one camera; with several (--camera-for, --rig) write each with "
                     "--refined-camera-for PREFIX=FILE");
  }
  if (!c.refined_camera_for.empty() && !several_cameras) {
    throw UsageError("--refined-camera-for names one of several cameras (--camera-for, --rig); with --camera write it "
                     "with --refined-camera FILE");
  }
  const auto refined_for = parse_camera_for(c.refined_camera_for, "--refined-camera-for");
  if (c.preview == "-") throw UsageError("--preview writes a PNG file, never to stdout");
  if (!c.preview.empty()) validate(c.preview_options);
  int to_stdout = 0;
  for (const std::string* p : {&c.output, &c.poses, &c.report, &c.refined_camera}) to_stdout += *p == "-" ? 1 : 0;
  for (const auto& pf : refined_for) to_stdout += pf.second == "-" ? 1 : 0;
  if (c.output.empty()) ++to_stdout;
  if (to_stdout > 1) throw UsageError("only one output can go to stdout ('-')");
  int from_stdin = 0;
  for (const std::string* p : {&c.tracks, &c.camera, &c.rig, &c.control_points, &c.scale_bars, &c.known_poses}) {
    from_stdin += *p == "-" ? 1 : 0;
  }
  if (from_stdin > 1) {
    throw UsageError("only one input can come from stdin ('-')");
  }
  return o;
}

std::vector<std::pair<std::string, std::size_t>> refined_camera_files(const Cli& c, const ReconstructInput& in) {
  std::vector<std::pair<std::string, std::size_t>> out;
  for (const auto& [prefix, file] : parse_camera_for(c.refined_camera_for, "--refined-camera-for")) {
    std::string list;
    std::size_t k = 0;
    for (; k < in.cameras.size() && in.cameras[k].prefix != prefix; ++k) {}
    if (k == in.cameras.size()) {
      for (const auto& pc : in.cameras) list += (list.empty() ? "'" : ", '") + pc.prefix + "'";
      throw UsageError("--refined-camera-for: '" + prefix + "' is none of the cameras' prefixes (" + list + ")");
    }
    out.emplace_back(file, k);
  }
  return out;
}

ReconstructInput read_input(const Cli& c) {
  ReconstructInput in;
  in.tracks_source = tool::source_name(c.tracks);
  std::optional<Rig> rig;
  if (!c.camera.empty()) {
    in.camera_source = tool::source_name(c.camera);
    in.camera = read_camera_yaml(*tool::open_input(c.camera), in.camera_source);
  } else if (!c.rig.empty()) {
    rig = read_rig_yaml(*tool::open_input(c.rig), tool::source_name(c.rig));
    for (std::size_t k = 0; k < rig->cameras.size(); ++k) {
      in.cameras.push_back({rig->cameras[k].prefix, rig->cameras[k].camera,
                            tool::source_name(c.rig) + " (camera_" + std::to_string(k) + ")"});
    }
  } else {
    for (const auto& [prefix, file] : parse_camera_for(c.camera_for)) {
      in.cameras.push_back({prefix, read_camera_yaml(*tool::open_input(file), tool::source_name(file)),
                            tool::source_name(file)});
    }
  }
  in.tracks = read_tracks(*tool::open_input(c.tracks), in.tracks_source);
  if (in.cameras.empty()) {
    check_inside_camera_image(in.tracks, in.tracks_source, in.camera, in.camera_source);
  } else {
    std::vector<std::string> prefixes;
    for (const auto& pc : in.cameras) prefixes.push_back(pc.prefix);
    std::vector<std::vector<TrackObservation>> by_camera(in.cameras.size());
    for (const auto& t : in.tracks) by_camera[require_rig_prefix(prefixes, t.image, in.tracks_source).camera].push_back(t);
    for (std::size_t k = 0; k < in.cameras.size(); ++k) {
      check_inside_camera_image(by_camera[k], in.tracks_source, in.cameras[k].camera, in.cameras[k].source);
    }
    if (rig) {
      // The photos of each frame share the rig's pose. The reference frame, the first (in name
      // order) with photos from two or more of the rig's cameras, is placed by the rig: the rig's
      // frame there is the world, and the rig's baseline the scale.
      std::map<std::string, std::set<std::size_t>> frames;
      std::map<std::string, std::size_t> image_camera;
      for (const auto& t : in.tracks) {
        const RigMatch m = require_rig_prefix(prefixes, t.image, in.tracks_source);
        frames[m.frame].insert(m.camera);
        image_camera[t.image] = m.camera;
      }
      const auto reference = std::find_if(frames.begin(), frames.end(), [](const auto& f) { return f.second.size() >= 2; });
      if (reference == frames.end()) {
        throw InputError(in.tracks_source, 0,
                         "no frame of the rig has photos from two of its cameras (" + std::to_string(frames.size()) +
                             " frames, e.g. '" + frames.begin()->first + "'): the rig places a frame's photos by "
                             "their cameras' relative poses; check the names against the rig's prefixes");
      }
      in.rig = *rig;
      in.rig_reference_frame = reference->first;
      in.known_poses_source = tool::source_name(c.rig);
      for (const auto& [image, k] : image_camera) {
        if (require_rig_prefix(prefixes, image, in.tracks_source).frame != in.rig_reference_frame) continue;
        Pose p;
        p.image = image;
        p.cam_from_world_rotation = Eigen::Quaterniond(rig->cameras[k].cam_from_rig_rotation).normalized();
        p.cam_from_world_translation_mm = rig->cameras[k].cam_from_rig_translation_mm;
        in.known_poses.push_back(p);
        in.known_pose_lines.push_back(0);
      }
    }
  }
  if (!c.control_points.empty()) {
    in.control_points = read_control_points(*tool::open_input(c.control_points), tool::source_name(c.control_points));
    // A control file none of whose points was measured is the wrong file (docs/errors.md).
    std::set<TrackId> ids;
    for (const auto& t : in.tracks) ids.insert(t.track_id);
    if (!in.tracks.empty() && !in.control_points.empty() && std::none_of(in.control_points.begin(), in.control_points.end(),
                                                   [&](const ControlPoint& p) { return ids.count(p.point_id) > 0; })) {
      throw InputError(tool::source_name(c.control_points), 0,
                       "none of its " + std::to_string(in.control_points.size()) + " control points is a track of " +
                           in.tracks_source + ": check the point ids");
    }
  }
  if (!c.scale_bars.empty()) {
    in.scale_bars = read_scale_bars(*tool::open_input(c.scale_bars), tool::source_name(c.scale_bars));
  }
  if (!c.known_poses.empty()) {
    in.known_poses_source = tool::source_name(c.known_poses);
    in.known_poses = read_known_poses(*tool::open_input(c.known_poses), in.known_poses_source, &in.known_pose_lines);
    if (in.known_poses.empty()) throw InputError(in.known_poses_source, 0, "holds no pose");
  }
  return in;
}

std::vector<Pose> read_known_poses(std::istream& in, const std::string& source, std::vector<std::size_t>* lines) {
  std::ostringstream all;
  all << in.rdbuf();
  std::string text = std::move(all).str();
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);
  std::istringstream first(text);
  std::string line;
  bool csv = false;
  while (std::getline(first, line)) {
    const std::string_view t = trim(line);
    if (t.empty() || t.front() == '#') continue;
    // A CSV header (poses or any other table, whose reader then names what is wrong) has commas;
    // COLMAP's lines have none.
    csv = t.find(',') != std::string_view::npos;
    break;
  }
  std::istringstream body(text);
  return csv ? read_poses_numbered(body, source, lines) : read_colmap_images(body, source, lines);
}

}  // namespace photomill::triangulate
