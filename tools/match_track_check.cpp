// match_track_check: tracks CSV against a synth folder's truth (benchmark support). Prints, for
// natural-feature tracks (ids >= --min-id) of length >= 2 and >= 3, how many there are and how
// many are outliers (see track_truth.hpp), and the same for coded tracks (ids below --min-id).
#include <algorithm>
#include <vector>
#include <fstream>
#include <iostream>

#include <CLI/CLI.hpp>

#include "formats/camera.hpp"
#include "formats/tool.hpp"
#include "tools/track_truth.hpp"
#include "tools/synth/scene.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  std::string tracks_path, set;
  double threshold_px = 2;
  TrackId min_id = 1'000'000;
  return tool::run(
      argc, argv,
      {"match_track_check", "judge tracks against a synth folder's exact geometry",
       "match_track_check tracks.csv --set data/demo"},
      [&](CLI::App& app) {
        app.add_option("tracks", tracks_path, "Tracks CSV")->required();
        app.add_option("--set", set, "synth folder (scene.txt, camera.yaml, poses.csv)")->required();
        app.add_option("--threshold-px", threshold_px, "A track is an outlier beyond this error")->capture_default_str();
        app.add_option("--min-id", min_id, "First natural-feature track id")->capture_default_str();
      },
      [&] {
        const auto tracks = read_tracks(*tool::open_input(tracks_path), tracks_path);
        const auto scene = synth::read_scene(*tool::open_input(set + "/scene.txt"), set + "/scene.txt");
        const auto camera = read_camera_yaml(*tool::open_input(set + "/camera.yaml"), set + "/camera.yaml");
        const auto poses = read_poses(*tool::open_input(set + "/poses.csv"), set + "/poses.csv");
        const auto judged = match::truth::judge_tracks(tracks, scene, camera, poses);
        for (std::size_t min_length : {2, 3}) {
          const auto f = match::truth::summarise(judged, min_length, threshold_px, min_id);
          std::cout << "feature tracks of length >= " << min_length << ": " << f.tracks << ", outliers " << f.outliers
                    << " (" << f.outlier_percent() << " %, error > " << threshold_px << " px)\n";
        }
        // The error distribution of the natural-feature tracks (their consistency with the truth).
        std::vector<double> errors;
        for (const auto& j : judged) {
          if (j.track_id >= min_id && j.length >= 2) errors.push_back(j.error_px);
        }
        std::sort(errors.begin(), errors.end());
        if (!errors.empty()) {
          auto at = [&](double q) { return errors[static_cast<std::size_t>(q * static_cast<double>(errors.size() - 1))]; };
          std::cout << "feature track error px: median " << at(0.5) << ", p90 " << at(0.9) << ", p99 " << at(0.99) << "\n";
        }
        std::size_t coded = 0, coded_outliers = 0;
        for (const auto& j : judged) {
          if (j.track_id >= min_id) continue;
          ++coded;
          coded_outliers += j.error_px <= threshold_px ? 0 : 1;
        }
        std::cout << "coded tracks: " << coded << ", outliers " << coded_outliers << "\n";
      });
}
