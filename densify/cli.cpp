// densify's command line, input reading and summary (see cli.hpp).
#include "densify/cli.hpp"

#include <algorithm>
#include <exception>
#include <filesystem>
#include <set>

#include <CLI/CLI.hpp>

#include "formats/camera.hpp"
#include "formats/error.hpp"
#include "formats/image_decode.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/text.hpp"
#include "formats/tool.hpp"
#include "geometry/parallel.hpp"

namespace photomill::densify {

namespace fs = std::filesystem;

void add_options(CLI::App& app, Cli& c) {
  DensifyOptions& o = c.options;
  PatchOptions& p = o.patch;
  app.add_option("cloud", c.cloud, "The sparse cloud (triangulate's cloud.ply): seeds and the default box; '-' reads stdin");
  app.add_option("--camera", c.camera, "camera.yaml of the photos (triangulate's --refined-camera if it wrote one)");
  app.add_option("--poses", c.poses, "The photos' poses (triangulate's poses.csv); its image names name the photos");
  app.add_option("--image-dir", c.image_dir, "Read the photos by file name from this folder (default: as poses.csv names them)");
  app.add_option("--observations", c.observations,
                 "detect's observations CSV(s): the markers (and their quiet zones) are masked out");
  app.add_option("--box", c.box, "Keep only points inside XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (the cloud's unit; default: the sparse cloud's box)")
      ->delimiter(',')->expected(6);
  app.add_option("-o,--output", c.output, "The dense cloud (binary PLY; default: stdout)");
  app.add_option("-j,--jobs", o.threads, "Threads (0 = every core)")->check(tool::non_negative_up_to(1024))->capture_default_str();
  const std::string grow = "Growth";
  app.add_option("--spacing-px", o.spacing_px, "One point per cell of this many pixels of the reference photo")
      ->group(grow)->check(tool::finite_in(1, 64))->capture_default_str();
  app.add_option("--max-views", o.max_views, "Views matched with each reference photo (besides it)")
      ->group(grow)->check(tool::finite_in(1, 64))->capture_default_str();
  app.add_option("--min-angle-deg", o.min_angle_deg, "A neighbour view's ray meets the reference's at the scene's centre at least at this angle")
      ->group(grow)->check(tool::finite_in(0, 90))->capture_default_str();
  app.add_option("--max-angle-deg", o.max_angle_deg, "... and at most this")
      ->group(grow)->check(tool::finite_in(1, 180))->capture_default_str();
  app.add_option("--max-attempts", o.max_attempts, "A cell is measured at most this many times (from different neighbours)")
      ->group(grow)->check(tool::finite_in(1, 16))->capture_default_str();
  app.add_option("--marker-margin", o.marker_margin, "The masked quiet zone around a marker, in marker sides on each side")
      ->group(grow)->check(tool::finite_in(0, 5))->capture_default_str();
  app.add_flag("!--no-marker-corners", o.marker_corners,
               "Leave out the sparse cloud's marker corners, which are otherwise written with the dense points (marker_corner 1) to hold the fitted surface across the masked markers")
      ->group(grow);
  app.add_flag("!--no-marker-squares", o.marker_squares,
               "Leave the markers' printed squares unmeasured (otherwise each is measured from the photos that see it most squarely, starting from the surface its corners and the points around it predict)")
      ->group(grow);
  app.add_option("--marker-square-views", o.marker_square_views, "A marker's square is measured from this many photos (as references)")
      ->group(grow)->check(tool::finite_in(1, 64))->capture_default_str();
  app.add_option("--marker-square-window", o.marker_square_window,
                 "... with a window of this half-width, in marker sides in the photo (at least --half-window-px)")
      ->group(grow)->check(tool::finite_in(0, 2))->capture_default_str();
  app.add_option("--marker-square-tolerance", o.marker_square_tolerance,
                 "... and keeps a point within this many marker sides of the surface predicted there")
      ->group(grow)->check(tool::finite_in(0, 1))->capture_default_str();
  app.add_option("--box-margin", o.box_margin, "Without --box: the sparse cloud's box grown by this share of its size on each side")
      ->group(grow)->check(tool::finite_in(0, 10))->capture_default_str();
  app.add_option("--free-space-min-violations", o.free_space_min_violations,
                 "Remove a point that lies this many times in front of a point a view saw behind it (0: no check)")
      ->check(tool::non_negative_up_to(1000000))->capture_default_str();
  app.add_option("--free-space-gap", o.free_space_gap_footprints,
                 "... more than this many of its cell's widths in front of it")
      ->check(tool::finite_in(0, 1000))->capture_default_str();
  app.add_option("--tile-cells", o.tile_cells, "Tiles of this many cells a side grow in parallel")
      ->group(grow)->check(tool::finite_in(4, 100000))->capture_default_str();
  const std::string lsm = "Multi-image least-squares matching";
  app.add_option("--half-window-px", p.half_window_px, "The patch window's half-width in the reference photo")
      ->group(lsm)->check(tool::finite_in(2, 50))->capture_default_str();
  app.add_option("--window-stride-px", p.window_stride_px, "The window is sampled every this many pixels")
      ->group(lsm)->check(tool::finite_in(1, 10))->capture_default_str();
  app.add_flag("!--planar", p.quadratic, "Match planes only (no curvature terms: biased on curved surfaces)")->group(lsm);
  app.add_option("--min-correlation", p.min_correlation, "A view whose aligned window correlates below this is dropped")
      ->group(lsm)->check(tool::finite_in(-1, 1))->capture_default_str();
  app.add_option("--centre-half-window-px", p.centre_half_window_px, "The window's central square checked alone (half-width)")
      ->group(lsm)->check(tool::finite_in(1, 50))->capture_default_str();
  app.add_option("--min-centre-correlation", p.min_centre_correlation,
                 "A view whose central square correlates below this is dropped (a centre seeing past a depth edge)")
      ->group(lsm)->check(tool::finite_in(-1, 1))->capture_default_str();
  app.add_option("--min-views", p.min_views, "Photos a point must be matched in, the reference included")
      ->group(lsm)->check(tool::finite_in(2, 64))->capture_default_str();
  app.add_option("--max-iterations", p.max_iterations, "Gauss-Newton iterations per patch at most")
      ->group(lsm)->check(tool::finite_in(1, 1000))->capture_default_str();
  app.add_option("--converged-px", p.converged_px, "Converged when the window centre moves less than this in every view")
      ->group(lsm)->check(tool::positive_up_to(1))->capture_default_str();
  app.add_option("--max-shift-px", p.max_shift_px, "Refused when the centre moved farther than this in a view from its start")
      ->group(lsm)->check(tool::positive_up_to(100))->capture_default_str();
  app.add_option("--max-bend-deg", p.max_bend_deg, "Refused when the fitted surface's normal turns by more than this across the window")
      ->group(lsm)->check(tool::finite_in(0, 180, true))->capture_default_str();
  app.add_option("--bend-check-half-window-px", p.bend_check_half_window_px,
                 "A bent patch's point is kept if a window of this half-width bends at most --bend-shrink-ratio as much (0: none)")
      ->group(lsm)->check(tool::non_negative_up_to(100))->capture_default_str();
  app.add_option("--bend-shrink-ratio", p.bend_shrink_ratio, "... of the bent patch's bend")
      ->group(lsm)->check(tool::finite_in(0, 1))->capture_default_str();
  app.add_option("--max-reprojection-px", p.max_reprojection_px,
                 "Refused when the views' free matches lie farther than this from the point's projection, RMS (0: no check)")
      ->group(lsm)->check(tool::non_negative_up_to(100))->capture_default_str();
  app.add_option("--max-obliquity-deg", p.max_obliquity_deg, "Refused when the reference sees the patch more obliquely than this")
      ->group(lsm)->check(tool::finite_in(1, 90))->capture_default_str();
}

DensifyInputs read_inputs(Cli& c) {
  DensifyOptions& o = c.options;
  if (c.cloud.empty()) throw UsageError("give the sparse cloud (triangulate's cloud.ply)");
  if (c.camera.empty() || c.poses.empty()) throw UsageError("give the photos' camera and poses: --camera FILE --poses FILE");
  if (o.min_angle_deg >= o.max_angle_deg) throw UsageError("--min-angle-deg must be below --max-angle-deg");
  if (o.patch.bend_check_half_window_px > 0 && o.patch.bend_check_half_window_px >= o.patch.half_window_px) {
    throw UsageError("--bend-check-half-window-px must be below --half-window-px (" + std::to_string(o.patch.half_window_px) +
                     "), or 0 for no second window");
  }
  if (!c.box.empty()) {
    if (!(c.box[0] < c.box[3] && c.box[1] < c.box[4] && c.box[2] < c.box[5])) {
      throw UsageError("--box: each minimum must be below its maximum");
    }
    o.box = std::array<double, 6>{c.box[0], c.box[1], c.box[2], c.box[3], c.box[4], c.box[5]};
  }
  if (c.cloud == "-" && c.poses == "-") throw UsageError("the cloud and --poses cannot both be stdin");
  DensifyInputs in;
  in.cloud_source = tool::source_name(c.cloud);
  in.poses_source = tool::source_name(c.poses);
  {
    auto s = tool::open_input(c.cloud);
    in.sparse = read_point_cloud(*s, tool::source_name(c.cloud));
  }
  if (in.sparse.points_mm.empty()) throw InputError(tool::source_name(c.cloud), 0, "the sparse cloud has no point to seed from");
  {
    auto s = tool::open_input(c.camera);
    const Camera camera = read_camera_yaml(*s, tool::source_name(c.camera));
    validate_camera(camera, tool::source_name(c.camera));
    in.camera = geometry::to_camera_model(camera, tool::source_name(c.camera));
  }
  {
    auto s = tool::open_input(c.poses);
    in.poses = read_poses(*s, tool::source_name(c.poses));
  }
  if (in.poses.size() < 2) throw InputError(tool::source_name(c.poses), 0, "densify needs the poses of at least 2 photos");
  // A cloud and poses of two different triangulate runs do not describe one reconstruction.
  const auto cloud_run = tool::file_run_id(c.cloud), poses_run = tool::file_run_id(c.poses);
  if (cloud_run && poses_run && *cloud_run != *poses_run) {
    throw InputError(tool::source_name(c.poses), 0,
                     "made by another run (" + *poses_run + ") than the cloud " + c.cloud + " (" + *cloud_run +
                         "): give the poses and the cloud of the same triangulate run");
  }
  for (const std::string& file : c.observations) {
    auto s = tool::open_input(file);
    const auto obs = read_observations(*s, tool::source_name(file));
    in.observations.insert(in.observations.end(), obs.begin(), obs.end());
  }
  // The photos, in the poses' order, read in parallel; each must be the camera's size.
  in.photos.resize(in.poses.size());
  std::vector<std::exception_ptr> errors(in.poses.size());
  std::vector<std::string> paths(in.poses.size());
  for (std::size_t i = 0; i < in.poses.size(); ++i) {
    paths[i] = c.image_dir.empty() ? in.poses[i].image : (fs::path(c.image_dir) / fs::path(in.poses[i].image).filename()).string();
    if (!image_file_exists(paths[i])) {
      throw InputError(tool::source_name(c.poses), 0,
                       "photo " + paths[i] + " of pose " + in.poses[i].image + " does not exist" +
                           (c.image_dir.empty() ? std::string(" (give the photos' folder with --image-dir)") : std::string()));
    }
  }
  geometry::parallel_for(in.poses.size(), geometry::thread_count(o.threads), [&](std::size_t i) {
    try {
      cv::Mat g8 = read_image(paths[i], cv::IMREAD_GRAYSCALE);
      g8.convertTo(in.photos[i], CV_32F);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  for (std::size_t i = 0; i < in.poses.size(); ++i) {
    if (in.photos[i].cols != in.camera.width_px || in.photos[i].rows != in.camera.height_px) {
      throw InputError(tool::source_name(c.camera), 0,
                       "the camera is " + std::to_string(in.camera.width_px) + " x " + std::to_string(in.camera.height_px) +
                           " px but photo " + paths[i] + " is " + std::to_string(in.photos[i].cols) + " x " +
                           std::to_string(in.photos[i].rows) + " px");
    }
  }
  if (in.sparse.units != "mm") {
    log::warn("the sparse cloud is in an arbitrary unit (no control points or scale): so are the dense cloud and its sigma_mm");
  }
  return in;
}

void report(const DensifyResult& result, const DensifyInputs& in) {
  for (std::size_t i = 0; i < result.references.size(); ++i) {
    const ReferenceStats& st = result.references[i];
    std::string nb;
    for (int j : st.neighbours) nb += (nb.empty() ? "" : " ") + fs::path(in.poses[static_cast<std::size_t>(j)].image).filename().string();
    std::string why;
    for (std::size_t k = 1; k < st.failures.size(); ++k) {
      if (st.failures[k] == 0) continue;
      why += std::string(why.empty() ? "" : ", ") + to_string(static_cast<PatchFailure>(k)) + " " + std::to_string(st.failures[k]);
    }
    if (st.outside_box) why += std::string(why.empty() ? "" : ", ") + "outside the box " + std::to_string(st.outside_box);
    if (st.free_space) why += std::string(why.empty() ? "" : ", ") + "in front of a surface seen behind " + std::to_string(st.free_space);
    log::debug(fs::path(in.poses[i].image).filename().string() + ": neighbours " + (nb.empty() ? "none" : nb) + "; " +
               std::to_string(st.seeds) + " seeds, " + std::to_string(st.measured) + " patches measured, " +
               std::to_string(st.accepted) + " accepted, " + std::to_string(st.occupied) +
               " cells held an earlier photo's point" + (why.empty() ? "" : "; refused: " + why));
  }
  const PointCloud& cloud = result.cloud;
  const PointProperty* sigma = cloud.find("sigma_mm");
  const PointProperty* views = cloud.find("views");
  const PointProperty* reprojection = cloud.find("reprojection_px");
  std::vector<double> s = sigma->values, v = views->values, e = reprojection->values;
  auto median = [](std::vector<double> x) {
    std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2), x.end());
    return x[x.size() / 2];
  };
  log::info(std::to_string(cloud.points_mm.size()) + " points; median sigma along the ray " + format_double(median(s)) + " " +
            cloud.units + ", median views " + format_double(median(v)) + ", median reprojection error " +
            format_double(median(e)) + " px; " + std::to_string(result.free_space_removed) +
            " removed by the free-space check; " + std::to_string(result.markers_projected) +
            " markers masked in photos where they were not detected (projected from the others); " +
            std::to_string(result.marker_corners) + " marker corners of the sparse cloud written with them; " +
            std::to_string(result.marker_square_points) + " points measured on " + std::to_string(result.marker_squares_measured) +
            " markers' printed squares" +
            (result.marker_squares_unpredicted ? " (" + std::to_string(result.marker_squares_unpredicted) +
                                                     " markers in the box not measured: too few points around them to predict the surface under them)"
                                               : ""));
}

}  // namespace photomill::densify
