// match's command line, input reading and summary (see cli.hpp).
#include "match/cli.hpp"

#include <algorithm>
#include <exception>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include <CLI/CLI.hpp>

#include "formats/camera.hpp"
#include "formats/camera_bounds.hpp"
#include "formats/camera_for.hpp"
#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/image_decode.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "geometry/parallel.hpp"

namespace photomill::match {

namespace fs = std::filesystem;

void add_options(CLI::App& app, Cli& c) {
  MatchOptions& o = c.options;
  app.add_option("inputs", c.inputs,
                 "Observations CSVs (image,point_id,u_px,v_px) and/or .feat files, told apart by content; "
                 "'-' reads stdin (the default when nothing else is given)");
  app.add_option("--features", c.features_dir, "Folder of .feat files (detect --features): all *.feat in it");
  app.add_option("-o,--output", c.output, "Tracks CSV (default: stdout)");
  auto* cam = app.add_option("--camera", c.camera, "camera.yaml: undistort before the epipolar checks (recommended)");
  auto* cam_for = app.add_option("--camera-for", c.camera_for,
                                 "PREFIX=FILE: the camera.yaml of the photos whose names (or file names, for a PREFIX "
                                 "without '/') start with PREFIX; repeatable, one per camera")
                      ->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  auto* rig = app.add_option("--rig", c.rig, "rig.yaml (calib --rig): each photo's camera by its prefix");
  cam->excludes(cam_for)->excludes(rig);
  cam_for->excludes(rig);
  app.add_option("--poses", c.poses, "Known poses CSV (cam_from_world): verify with F from them (needs --camera)");
  const std::string verify = "Verification";
  app.add_option("--threshold-px", o.fit.threshold_px, "Epipolar inlier threshold (Sampson distance), px")
      ->group(verify)->capture_default_str()->check(CLI::Range(1e-3, 1e3));
  app.add_option("--ransac-confidence", o.fit.confidence, "USAC/MAGSAC++ confidence")
      ->group(verify)->capture_default_str()->check(CLI::Range(0.5, 1.0));
  app.add_option("--ransac-iterations", o.fit.max_iterations, "USAC/MAGSAC++ iterations at most")
      ->group(verify)->capture_default_str()->check(CLI::Range(10, 10'000'000));
  app.add_option("--min-inliers", o.fit.min_inliers, "Inliers a pair needs to count as verified")
      ->group(verify)->capture_default_str()->check(CLI::Range(8, 1'000'000));
  app.add_option("--min-inlier-ratio", o.fit.min_inlier_ratio, "... and their share of the pair's correspondences")
      ->group(verify)->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_flag("--keep-unverified", o.keep_unverified,
               "Keep coded observations no pair could verify (pairs with < 8 shared points, no --poses)")
      ->group(verify);
  const std::string feat = "Features";
  app.add_option("--ratio", o.ratio, "Lowe's ratio test: best < ratio * second best descriptor distance")
      ->group(feat)->capture_default_str()->check(CLI::Range(0.1, 1.0));
  app.add_flag("--no-mutual", c.no_mutual, "Skip the mutual-best check")->group(feat);
  app.add_flag("--root-sift", o.root_sift,
               "Compare RootSIFT descriptors (square root of the L1-normalised SIFT, as COLMAP does)")
      ->group(feat);
  app.add_flag("!--no-guided", o.guided,
               "With --poses, still search all features by kd-tree instead of along the epipolar lines")
      ->group(feat);
  app.add_option("--guided-ratio", o.guided_ratio, "Ratio test of guided matching (among the epipolar band's features)")
      ->group(feat)->capture_default_str()->check(CLI::Range(0.1, 1.0));
  app.add_option("--guided-max-axis-angle-deg", o.guided_max_axis_angle_deg,
                 "With --poses, match every pair whose optical axes are at most this far apart (and the pairs sharing coded points)")
      ->group(feat)->capture_default_str()->check(CLI::Range(0.0, 180.0));
  app.add_option("--flann-checks", o.flann_checks, "FLANN kd-tree leaves visited per query")
      ->group(feat)->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--exhaustive-max-images", o.exhaustive_max_images, "Match all pairs up to this many images ...")
      ->group(feat)->capture_default_str()->check(CLI::Range(0, 100000));
  app.add_option("--sequence-neighbours", o.sequence_neighbours, "... beyond, each image with its next N in input order")
      ->group(feat)->capture_default_str()->check(CLI::Range(0, 1000));
  app.add_option("--coded-neighbours", o.coded_neighbours, "... and with the N images sharing most coded points")
      ->group(feat)->capture_default_str()->check(CLI::Range(0, 1000));
  app.add_option("--min-track-length", o.min_track_length, "Images a track must span")
      ->group(feat)->capture_default_str()->check(CLI::Range(2, 100000));
  app.add_option("--feature-id-offset", o.feature_track_offset, "First track id of natural-feature tracks")
      ->group(feat)->capture_default_str()->check(CLI::Range(std::int64_t{0}, std::int64_t{1} << 53));
  const std::string lsm = "Least-squares matching (refines natural features to the pixel's hundredths)";
  app.add_option("--refine", c.refine,
                 "lsm: align each feature observation's grey values to its track's reference observation "
                 "(needs the images named in the .feat files); none: keep SIFT's positions and write their size_px")
      ->group(lsm)->capture_default_str()->check(CLI::IsMember({"lsm", "none"}));
  app.add_option("--image-dir", c.image_dir, "Read the images named in the .feat files from this folder (by file name)")
      ->group(lsm);
  app.add_option("--lsm-window-per-size", c.lsm.window_per_size, "Window half-width per px of the reference feature's size")
      ->group(lsm)->capture_default_str()->check(CLI::Range(0.1, 10.0));
  app.add_option("--lsm-min-half-window-px", c.lsm.min_half_window_px, "... at least this")
      ->group(lsm)->capture_default_str()->check(CLI::Range(2, 100));
  app.add_option("--lsm-max-half-window-px", c.lsm.max_half_window_px, "... at most this")
      ->group(lsm)->capture_default_str()->check(CLI::Range(2, 100));
  app.add_option("--lsm-max-shift-px", c.lsm.max_shift_px, "Refuse an alignment that moves the point farther")
      ->group(lsm)->capture_default_str()->check(CLI::Range(0.01, 100.0));
  app.add_flag("--lsm-quadratic", c.lsm.quadratic,
               "Second-order terms in the window's geometric model: unbiased on curved surfaces, 14 unknowns instead of 8")
      ->group(lsm);
  app.add_option("--lsm-min-correlation", c.lsm.min_correlation, "Refuse an alignment whose windows correlate less")
      ->group(lsm)->capture_default_str()->check(CLI::Range(-1.0, 1.0));
  app.add_option("-j,--threads,--jobs", o.jobs, "Image pairs matched in parallel (0: all cores; --jobs: the old name)")
      ->capture_default_str()->check(CLI::Range(0, 1024));
  tool::add_presets(app, c.preset,
                    {{"features",
                      {{"--flann-checks", [&o] { o.flann_checks = 16; }},
                       {"--lsm-quadratic", [&c] { c.lsm.quadratic = true; }}}}},
                    "features: the settings the markers + natural features chain was measured with (docs/measurements/makefile.md); options given as well win");
}

namespace {

bool is_feature_file(const std::string& text) {
  std::size_t at = text.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0;
  while (at < text.size() && (text[at] == ' ' || text[at] == '\t' || text[at] == '\r' || text[at] == '\n')) ++at;
  return text.compare(at, 18, "photomill-features") == 0;
}

// An image's features and its marker observations, where both carry detect's run id, must come
// from one run: detect renames its outputs one after the other, and a run killed between two
// renames leaves one of them from the run before (issue #25).
void check_same_detect_runs(const std::vector<FeatureSet>& features, const std::vector<std::string>& feature_sources,
                            const std::map<std::string, std::string>& run_of_image,
                            const std::map<std::string, std::string>& observations_source) {
  for (std::size_t k = 0; k < features.size(); ++k) {
    const auto run = run_of_image.find(features[k].image);
    if (features[k].run_id.empty() || run == run_of_image.end() || run->second == features[k].run_id) continue;
    throw InputError(feature_sources[k], 0,
                     "made by another run of detect (" + features[k].run_id + ") than the observations of '" +
                         features[k].image + "' in " + observations_source.at(features[k].image) + " (" +
                         run->second + "): a run was interrupted; run detect on this photo again");
  }
}

}  // namespace

MatchInputs read_inputs(Cli& c) {
  c.options.mutual = !c.no_mutual;
  std::vector<std::string> paths = c.inputs;
  if (!c.features_dir.empty()) {
    if (!fs::is_directory(c.features_dir)) throw InputError(c.features_dir, 0, "not a folder");
    std::vector<std::string> feats;
    for (const auto& e : fs::directory_iterator(c.features_dir)) {
      if (e.path().extension() == ".feat") feats.push_back(e.path().string());
    }
    std::sort(feats.begin(), feats.end());
    if (feats.empty()) throw InputError(c.features_dir, 0, "no .feat files in this folder");
    paths.insert(paths.end(), feats.begin(), feats.end());
  }
  if (paths.empty()) paths.push_back("-");
  MatchInputs in;
  std::map<std::string, std::string> run_of_image, observations_source;
  std::vector<std::string> feature_sources;  // the detect run of each image's observations
  std::vector<std::string> camera_sources;
  if (!c.camera.empty()) {
    in.camera = read_camera_yaml(*tool::open_input(c.camera), tool::source_name(c.camera));
  } else if (!c.rig.empty()) {
    const Rig rig = read_rig_yaml(*tool::open_input(c.rig), tool::source_name(c.rig));
    for (std::size_t k = 0; k < rig.cameras.size(); ++k) {
      in.cameras_by_prefix.emplace_back(rig.cameras[k].prefix, rig.cameras[k].camera);
      camera_sources.push_back(tool::source_name(c.rig) + " (camera_" + std::to_string(k) + ")");
    }
  } else if (!c.camera_for.empty()) {
    for (const auto& [prefix, file] : parse_camera_for(c.camera_for)) {
      in.cameras_by_prefix.emplace_back(prefix, read_camera_yaml(*tool::open_input(file), tool::source_name(file)));
      camera_sources.push_back(tool::source_name(file));
    }
  } else {
    log::warn("no --camera: epipolar checks on distorted pixels, where lens distortion can reject correct points");
  }
  // The inputs read, and the feature files parsed, on all cores (a photo's features are ~10 MB
  // of text, ~0.08 s to parse); then taken in the order given, the observations parsed there, so
  // that the first bad input in that order is the one reported.
  struct Loaded {
    std::optional<FeatureSet> features;
    std::string text;  // an observations file's
    std::exception_ptr error;
  };
  std::vector<Loaded> loaded(paths.size());
  geometry::parallel_for(paths.size(), c.options.jobs, [&](std::size_t i) {
    try {
      std::string text = tool::read_all(paths[i], std::size_t{1} << 32);
      if (is_feature_file(text)) {
        std::istringstream stream(text);
        loaded[i].features = read_features(stream, tool::source_name(paths[i]));
      } else {
        loaded[i].text = std::move(text);
      }
    } catch (...) {
      loaded[i].error = std::current_exception();
    }
  });
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const std::string& path = paths[i];
    if (loaded[i].error) std::rethrow_exception(loaded[i].error);
    if (loaded[i].features) {
      in.features.push_back(std::move(*loaded[i].features));
      loaded[i].features.reset();
      feature_sources.push_back(tool::source_name(path));
    } else {
      std::istringstream stream(std::move(loaded[i].text));
      const auto obs = read_observations_with_runs(stream, tool::source_name(path), &run_of_image);
      for (const auto& [image, run] : run_of_image) observations_source.emplace(image, tool::source_name(path));
      if (in.camera) check_inside_camera_image(obs, tool::source_name(path), *in.camera, tool::source_name(c.camera));
      if (!in.cameras_by_prefix.empty()) {
        std::vector<std::string> prefixes;
        for (const auto& pc : in.cameras_by_prefix) prefixes.push_back(pc.first);
        std::vector<std::vector<Observation>> by_camera(prefixes.size());
        for (const auto& ob : obs) by_camera[require_rig_prefix(prefixes, ob.image, tool::source_name(path)).camera].push_back(ob);
        for (std::size_t k = 0; k < prefixes.size(); ++k) {
          check_inside_camera_image(by_camera[k], tool::source_name(path), in.cameras_by_prefix[k].second,
                                    camera_sources[k]);
        }
      }
      in.observations.insert(in.observations.end(), obs.begin(), obs.end());
    }
  }
  check_same_detect_runs(in.features, feature_sources, run_of_image, observations_source);
  if (in.observations.empty() && in.features.empty()) {
    std::string sources;
    for (const auto& path : paths) sources += (sources.empty() ? "" : ", ") + tool::source_name(path);
    throw InputError(sources, 0, "no observations: nothing to match");
  }
  if (!c.poses.empty()) {
    in.poses = read_poses(*tool::open_input(c.poses), tool::source_name(c.poses));
    // Without a pose, matching would go on as if --poses had not been given (issue #25).
    if (in.poses.empty()) throw InputError(tool::source_name(c.poses), 0, "no poses: the --poses file holds only its header");
  }
  if (c.refine == "lsm" && !in.features.empty()) {
    if (c.lsm.min_half_window_px > c.lsm.max_half_window_px) {
      throw UsageError("--lsm-min-half-window-px is larger than --lsm-max-half-window-px");
    }
    c.options.refine = c.lsm;
    in.grey_images.resize(in.features.size());
    for (std::size_t k = 0; k < in.features.size(); ++k) {
      const std::string& named = in.features[k].image;
      const std::string path = c.image_dir.empty() ? named : (fs::path(c.image_dir) / fs::path(named).filename()).string();
      if (!image_file_exists(path)) {
        throw InputError(path, 0, "image named in a features file not found (--refine lsm reads the photos: run match "
                                  "where detect ran, give --image-dir, or use --refine none)");
      }
      const cv::Mat grey = read_image(path, cv::IMREAD_GRAYSCALE);
      grey.convertTo(in.grey_images[k], CV_32F);
    }
  }
  return in;
}

void report(const MatchResult& r, const Cli& c) {
  std::vector<int> inliers;
  std::size_t verified = 0;
  for (const auto& p : r.pairs) {
    const int total = p.coded_inliers + p.feature_inliers;
    if (p.verified) {
      ++verified;
      inliers.push_back(total);
    }
    log::debug(r.images[p.a] + " - " + r.images[p.b] + ": " + std::to_string(p.coded_shared) + " coded points (" +
               std::to_string(p.coded_inliers) + " consistent), " + std::to_string(p.feature_matches) +
               " feature matches (" + std::to_string(p.feature_inliers) + " inliers), " +
               (p.verified ? (p.from_poses ? "F from poses" : "F estimated") : "not verified"));
  }
  std::string line = std::to_string(r.images.size()) + " images, " + std::to_string(r.pairs.size()) + " pairs looked at, " +
                     std::to_string(verified) + " verified";
  if (!inliers.empty()) {
    std::sort(inliers.begin(), inliers.end());
    line += "; inliers per verified pair: min " + std::to_string(inliers.front()) + ", median " +
            std::to_string(inliers[inliers.size() / 2]) + ", max " + std::to_string(inliers.back());
  }
  log::info(line);
  std::size_t inconsistent = 0;
  for (const auto& d : r.dropped) {
    if (d.reason.rfind("inconsistent", 0) == 0) ++inconsistent;
    log::debug("dropped " + d.image + " point " + std::to_string(d.point_id) + ": " + d.reason);
  }
  log::info("coded points: " + std::to_string(r.coded_tracks) + " tracks; " + std::to_string(r.dropped.size()) +
            " observations left out (" + std::to_string(inconsistent) + " inconsistent with their other images)" +
            (r.dropped.empty() ? "" : "; -v lists them"));
  if (r.feature_tracks > 0 || r.feature_unions.edges > 0) {
    log::info("natural features: " + std::to_string(r.feature_tracks) + " tracks from " +
              std::to_string(r.feature_unions.edges) + " verified matches; " +
              std::to_string(r.feature_unions.conflicts) + " matches refused (two features of one image), " +
              std::to_string(r.feature_observations_voted_out) + " observations voted out; ids from " +
              std::to_string(c.options.feature_track_offset));
  }
  if (c.options.refine) {
    std::string why;
    std::size_t refused = 0;
    for (const auto& [reason, count] : r.refine_refused) {
      why += (why.empty() ? "" : ", ") + std::to_string(count) + " " + reason;
      refused += count;
    }
    log::info("least-squares matching: " + std::to_string(r.refined_observations) + " observations kept, " +
              std::to_string(refused) + " refused" + (why.empty() ? "" : " (" + why + ")") + ", " +
              std::to_string(r.refine_tracks_dropped) + " tracks left too short");
  }
  std::string hist = "track lengths:";
  for (const auto& [length, count] : r.track_lengths) hist += " " + std::to_string(length) + ": " + std::to_string(count) + ",";
  if (!r.track_lengths.empty()) hist.pop_back();
  log::info(r.track_lengths.empty() ? "no tracks" : hist);
}

void require_tracks(const MatchResult& r, const Cli& c) {
  if (!r.tracks.empty()) return;
  std::string sources;
  for (const auto& p : c.inputs) sources += (sources.empty() ? "" : ", ") + tool::source_name(p);
  if (!c.features_dir.empty()) sources += (sources.empty() ? "" : ", ") + c.features_dir;
  if (sources.empty()) sources = "<stdin>";
  std::size_t verified = 0;
  for (const auto& p : r.pairs) verified += p.verified ? 1 : 0;
  std::string why = "no tracks: no point is seen in two of the " + std::to_string(r.images.size()) + " images (" +
                    std::to_string(r.pairs.size()) + " pairs looked at, " + std::to_string(verified) + " verified";
  if (!r.dropped.empty()) why += ", " + std::to_string(r.dropped.size()) + " coded observations left out (-v lists them)";
  why += "): do the photos overlap, and were the features detected in all of them?";
  throw InputError(sources, 0, why);
}

}  // namespace photomill::match
