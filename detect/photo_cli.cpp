// detect's marker and feature modes (see photo_cli.hpp).
#include "detect/photo_cli.hpp"

#include <algorithm>
#include <filesystem>
#include <map>
#include <memory>

#include <CLI/CLI.hpp>

#include "detect/boards.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tables.hpp"
#include "formats/text.hpp"
#include "formats/tool.hpp"

namespace photomill::detect {

namespace fs = std::filesystem;

std::vector<int> parse_id_ranges(const std::string& text, const std::string& option) {
  std::vector<int> ids;
  for (std::string_view part : split_fields(text, ',')) {
    const auto dash = part.find('-', 1);
    const auto lo = parse_int(part.substr(0, dash));
    const auto hi = dash == std::string_view::npos ? lo : parse_int(part.substr(dash + 1));
    if (!lo || !hi || *lo < 0 || *hi < *lo || *hi > 1'000'000) {
      throw UsageError(option + ": '" + std::string(part) + "' is not an id or a range like 0-13");
    }
    for (auto id = *lo; id <= *hi; ++id) ids.push_back(static_cast<int>(id));
  }
  return ids;
}

void add_photo_options(CLI::App& app, PhotoCli& c) {
  const std::string markers = "Markers", features = "Features";
  auto* aruco = app.add_option("--aruco", c.aruco, "Find ArUco markers of this predefined dictionary")
                    ->group(markers)->check(CLI::IsMember(aruco_dictionary_names()));
  auto* file = app.add_option("--aruco-dict-file", c.aruco_dict_file,
                              "Find ArUco markers of a custom dictionary (OpenCV's YAML: nmarkers, markersize, "
                              "marker_0..; maxCorrectionBits, default 0)")
                   ->group(markers);
  aruco->excludes(file);
  app.add_option("--corner-refine", c.refinement,
                 "Marker corners: edges = fit the four edges and intersect them; subpix, contour, none = OpenCV's")
      ->group(markers)->capture_default_str()->check(CLI::IsMember(corner_refinement_names()));
  auto& e = c.options.markers.edges;
  app.add_option("--edge-degree", e.degree, "Edge fit: highest polynomial degree of an edge (1 = straight)")
      ->group(markers)->capture_default_str()->check(CLI::Range(1, 3));
  app.add_option("--edge-span", e.span, "Edge fit: fraction of each edge fitted for each corner (1 = whole edge)")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.2, 1.0));
  app.add_option("--edge-max-window-px", e.max_window_px, "Edge fit: widest band on each side of an edge, px")
      ->group(markers)->capture_default_str()->check(CLI::Range(1.0, 50.0));
  app.add_option("--edge-min-contrast", e.min_contrast, "Edge fit: reject a marker whose edges have less contrast, grey levels")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.0, 255.0));
  app.add_option("--edge-max-blur-px", e.max_blur_px, "Edge fit: reject a marker whose edges are blurrier (sigma), px")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.1, 50.0));
  app.add_option("--edge-gamma", e.gamma,
                 "Edge fit: grey v is fitted as 255 (v/255)^gamma; 1 = linear images (synth), ~2.2 = sRGB JPEGs")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.2, 5.0));
  app.add_option("--edge-quick-min-cell-px", e.quick_start_min_cell_px,
                 "Edge fit: markers whose cells are at least this wide (px) start the fine pass from the coarse one "
                 "(one round instead of two); 1000 = never")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  app.add_flag("--edge-ignore-code", [&e](std::int64_t) { e.model_code = false; },
               "Edge fit: take the inside of the border as black instead of modelling the decoded code cells there")
      ->group(markers);
  app.add_option("--aruco-error-correction", c.options.markers.error_correction_rate,
                 "OpenCV's errorCorrectionRate: share of the dictionary's correctable bits used")
      ->group(markers)->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--threshold-window-min-px", c.options.markers.threshold_window_min_px,
                 "Smallest adaptive-threshold window of the marker candidate search, px (then every 10 px up to 23): "
                 "13 makes the search ~3x faster but may miss small, foreshortened markers")
      ->group(markers)->capture_default_str()->check(CLI::Range(3, 23));
  app.add_option("--scale-bars-out", c.scale_bars,
                 "Write each found marker's four sides (--marker-mm long) as a scale bars CSV for triangulate")
      ->group(markers);
  app.add_option("--marker-ids", c.marker_ids, "Markers whose side is --marker-mm (ranges: 0-13,20; default: all)")
      ->group(markers);
  app.add_option("--features", c.features_dir, "Write SIFT features, one <image file name>.feat per image, here")
      ->group(features);
  app.add_option("--max-features", c.sift.max_features, "SIFT features kept per image, in --cap-order (0: all)")
      ->group(features)->capture_default_str()->check(CLI::Range(0, 10'000'000));
  app.add_option("--cap-order", c.sift.cap_order,
                 "Which features --max-features keeps: response (the strongest) or scale (the largest first, "
                 "as COLMAP does: they match across wider baselines)")
      ->group(features)
      ->transform(CLI::CheckedTransformer(std::map<std::string, CapOrder>{{"response", CapOrder::Response},
                                                                          {"scale", CapOrder::Scale}}))
      ->default_str("response");
  app.add_option("--cap-cell-px", c.sift.cap_cell_px,
                 "Spread the --max-features cap over square cells of this side: each cell's strongest first, so "
                 "shadowed parts keep features (0: the image's strongest)")
      ->group(features)->capture_default_str()->check(CLI::Range(0, 100'000));
  app.add_option("--sift-contrast-threshold", c.sift.contrast_threshold,
                 "SIFT contrast threshold (OpenCV's; divided by the octave layers)")
      ->group(features)->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--sift-edge-threshold", c.sift.edge_threshold, "SIFT edge threshold (Lowe's r)")
      ->group(features)->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  app.add_option("--sift-octave-layers", c.sift.octave_layers, "SIFT scales per octave (Lowe's s)")
      ->group(features)->capture_default_str()->check(CLI::Range(1, 10));
  app.add_flag("--mask-markers", c.options.mask_markers, "No features on the markers and their quiet zones")
      ->group(features);
  app.add_option("--mask-margin-cells", c.options.mask_margin_cells, "Masked margin around each marker, marker cells")
      ->group(features)->capture_default_str()->check(CLI::Range(0.0, 100.0));
  app.add_option("--mask-clearance-per-size", c.sift.mask_clearance_per_size,
                 "With --mask-markers, also drop features nearer to the mask than this many times their size (0: "
                 "only their position is tested)")
      ->group(features)->capture_default_str()->check(CLI::Range(0.0, 100.0));
  const std::string drawings = "Drawings";
  app.add_option("--draw", c.draw.dir,
                 "Draw what was found over each photo into <image file name>.jpg (or .png) in this folder")
      ->group(drawings);
  app.add_option("--draw-format", c.draw.format, "Drawings as jpg (small) or png")
      ->group(drawings)->capture_default_str()->check(CLI::IsMember({"jpg", "png"}));
  app.add_option("--draw-max-width-px", c.draw.max_width_px, "Drawings of wider photos are scaled down to this width (0: full size, else at least 100)")
      ->group(drawings)->capture_default_str()->check(CLI::Range(0, 100'000));
  tool::add_presets(app, c.preset,
                    {{"features",
                      {{"--mask-markers", [&c] { c.options.mask_markers = true; }},
                       {"--mask-clearance-per-size", [&c] { c.sift.mask_clearance_per_size = 1; }},
                       {"--max-features", [&c] { c.sift.max_features = 20000; }},
                       {"--cap-cell-px", [&c] { c.sift.cap_cell_px = 64; }}}}},
                    "features: the settings the markers + natural features chain was measured with (docs/measurements/makefile.md); options given as well win");
}

bool photo_mode(const PhotoCli& c) { return !c.aruco.empty() || !c.aruco_dict_file.empty() || !c.features_dir.empty(); }

namespace {

std::string marker_report(const MarkerDetection& m) {
  std::string line = std::to_string(m.marker_ids.size()) + " markers";
  if (!m.rejected.empty()) {
    line += ", " + std::to_string(m.rejected.size()) + " rejected (";
    for (std::size_t k = 0; k < m.rejected.size(); ++k) {
      line += (k ? "; id " : "id ") + std::to_string(m.rejected[k].marker_id) + ": " + m.rejected[k].reason;
    }
    line += ")";
  }
  return line;
}

// Feature file of an image: <dir>/<file name>.feat. Two images with one file name would collide.
std::map<std::string, fs::path> feature_paths(const std::vector<std::string>& images, const fs::path& dir) {
  std::map<std::string, fs::path> paths;
  std::map<std::string, std::string> by_name;
  for (const auto& image : images) {
    const std::string name = fs::path(image).filename().string() + ".feat";
    const auto [it, fresh] = by_name.emplace(name, image);
    if (!fresh && it->second != image) {
      throw UsageError("--features: images '" + it->second + "' and '" + image + "' would both write " + name);
    }
    paths[image] = dir / name;
  }
  return paths;
}

}  // namespace

void run_photos(PhotoCli c, const std::vector<std::string>& images, const std::string& output) {
  if (images.empty()) throw UsageError("no images given");
  PhotoOptions& o = c.options;
  o.markers.refinement = corner_refinement_from_name(c.refinement);
  if (!c.aruco.empty()) o.dictionary = MarkerDictionary::predefined(c.aruco);
  if (!c.aruco_dict_file.empty()) o.dictionary = MarkerDictionary::from_file(c.aruco_dict_file);
  if (!c.features_dir.empty()) o.sift = c.sift;
  if (!c.scale_bars.empty() && !(c.marker_mm > 0)) throw UsageError("--scale-bars-out needs --marker-mm (the markers' side)");
  if (!c.scale_bars.empty() && !o.dictionary) throw UsageError("--scale-bars-out needs markers (--aruco or --aruco-dict-file)");
  if (!c.marker_ids.empty() && c.scale_bars.empty()) throw UsageError("--marker-ids needs --scale-bars-out");
  // Features alone make no observations: an output named for them would silently stay unwritten.
  if (!o.dictionary && output != "-") {
    throw UsageError("-o " + output + ": without markers (--aruco or --aruco-dict-file) there are no observations to "
                     "write; the features go to --features DIR");
  }
  validate(o);
  std::map<std::string, fs::path> feat_paths;
  if (o.sift) {
    feat_paths = feature_paths(images, c.features_dir);
    std::error_code ec;
    fs::create_directories(c.features_dir, ec);
    if (!fs::is_directory(c.features_dir)) throw InputError(c.features_dir, 0, "cannot create the features folder");
  }
  std::optional<DrawingFiles> drawings;
  PhotoImageHook draw;
  if (!c.draw.dir.empty()) {
    drawings.emplace(c.draw, images);
    draw = [&](const cv::Mat& grey, const PhotoResult& r) {
      drawings->write(images[r.index], draw_photo(grey, r.markers ? &*r.markers : nullptr,
                                                  r.features ? &*r.features : nullptr, c.draw));
    };
  }
  std::unique_ptr<tool::OutputFile> out, bars;
  if (o.dictionary) out = std::make_unique<tool::OutputFile>(output);
  if (!c.scale_bars.empty()) bars = std::make_unique<tool::OutputFile>(c.scale_bars);

  std::vector<std::optional<MarkerDetection>> found(images.size());
  std::size_t done = 0, features = 0, markers = 0, rejected = 0;
  // The feature files, drawings and observations are renamed into place together when the run
  // succeeded (tool::run): a failed run leaves the previous run's files as they were.
  {
    detect_photos(images, o, [&](PhotoResult&& r) {
      const std::string& image = images[r.index];
      std::string line = image + ":";
      if (r.markers) {
        line += " " + marker_report(*r.markers);
        markers += r.markers->marker_ids.size();
        rejected += r.markers->rejected.size();
      }
      if (r.features) {
        tool::OutputFile feat(feat_paths.at(image).string());
        write_features(feat.stream(), *r.features);
        feat.commit();
        features += r.features->keypoints.size();
        line += std::string(r.markers ? "," : "") + " " + std::to_string(r.features->keypoints.size()) + " features";
      }
      log::info(line);
      log::debug("[" + std::to_string(++done) + "/" + std::to_string(images.size()) + "] " + image + " done");
      found[r.index] = std::move(r.markers);
    }, draw);
    if (o.dictionary) {
      std::vector<Observation> observations;
      std::vector<int> ids;
      for (const auto& m : found) {
        const auto obs = m->observations();
        observations.insert(observations.end(), obs.begin(), obs.end());
        ids.insert(ids.end(), m->marker_ids.begin(), m->marker_ids.end());
      }
      if (bars) {
        if (!c.marker_ids.empty()) {
          const auto wanted = parse_id_ranges(c.marker_ids, "--marker-ids");
          std::erase_if(ids, [&](int id) { return std::find(wanted.begin(), wanted.end(), id) == wanted.end(); });
        }
        write_scale_bars(bars->stream(), marker_scale_bars(ids, c.marker_mm));
      }
      write_observations(out->stream(), observations);
      if (bars) bars->commit();
      out->commit();
    }
  }
  std::string summary = std::to_string(images.size()) + " images";
  if (o.dictionary) summary += ", " + std::to_string(markers) + " markers, " + std::to_string(rejected) + " rejected";
  if (o.sift) summary += ", " + std::to_string(features) + " features in " + c.features_dir;
  if (drawings) summary += ", " + std::to_string(images.size()) + " drawings in " + c.draw.dir;
  log::info(summary);
}

}  // namespace photomill::detect
