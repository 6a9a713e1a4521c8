// detect_marker_stability: how much the edge fit's marker corners depend on where it starts. For
// every marker OpenCV's detectMarkers finds in a photo, the corners are refined from OpenCV's
// polygon (the reference) and then again from that polygon with each corner moved by a Gaussian
// jitter of --jitter-px per coordinate (--trials times). A fit that finds the edges' own minimum
// lands on the same corners wherever it starts within its reach (OpenCV's corners are up to ~1 px
// off); the spread is how far a corner is determined by the photo rather than by the start. Prints,
// per photo, the markers, their mean px per cell, the edge fit's mean blur and band half-width,
// the corners' RMS and largest movement and the refits that failed, by reason (numbers shown as #);
// --per-marker one line per marker; --no-code-model fits without the code cells (markers.hpp).
// Needs no truth, so it runs on any photo (real sets included).
// Data on stdout. A photo with no refined marker, or whose refits all failed, says so instead of
// figures; a run in which no photo had a corner to compare fails.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <map>
#include <random>

#include <CLI/CLI.hpp>
#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "detect/markers.hpp"
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  using namespace photomill::detect;
  std::vector<std::string> photos;
  std::string dictionary_name = "DICT_4X4_100";
  double jitter_px = 0.3, gamma = 1;
  int trials = 10, degree = EdgeFitOptions{}.degree;
  unsigned seed = 1;
  bool per_marker = false, no_code_model = false;
  return tool::run(
      argc, argv,
      {"detect_marker_stability", "How far the edge fit's marker corners move when its start moves",
       "detect_marker_stability ../shared/data/opencv-aruco/img_0*.jpg --dictionary DICT_6X6_250 --gamma 2.2"},
      [&](CLI::App& app) {
        app.add_option("photos", photos, "Photos")->required();
        app.add_option("--dictionary", dictionary_name, "ArUco dictionary")->capture_default_str();
        app.add_option("--gamma", gamma, "Edge fit: --edge-gamma (1 linear renders, ~2.2 sRGB JPEGs)")
            ->capture_default_str()->check(CLI::Range(0.2, 5.0));
        app.add_option("--jitter-px", jitter_px, "Standard deviation of each start coordinate's jitter, px")
            ->capture_default_str()->check(CLI::Range(0.0, 5.0));
        app.add_option("--edge-degree", degree, "Edge fit: --edge-degree")->capture_default_str()->check(CLI::Range(1, 3));
        app.add_option("--trials", trials, "Jittered refits per marker")->capture_default_str()->check(CLI::Range(1, 1000));
        app.add_option("--seed", seed, "Random seed of the jitter")->capture_default_str();
        app.add_flag("--per-marker", per_marker, "Also one line per marker");
        app.add_flag("--no-code-model", no_code_model, "Edge fit without the code cells inside the border (the inside taken as black)");
      },
      [&] {
        const auto dictionary = MarkerDictionary::predefined(dictionary_name);
        const int cells = dictionary.bits_per_side() + 2;
        EdgeFitOptions options;
        options.gamma = gamma;
        options.degree = degree;
        std::mt19937 rng(seed);
        std::normal_distribution<double> jitter(0, jitter_px);
        std::cout << std::fixed << std::setprecision(4);
        int measured_photos = 0;
        for (const auto& photo : photos) {
          const cv::Mat grey = cv::imread(photo, cv::IMREAD_GRAYSCALE);
          if (grey.empty()) throw InputError(photo, 0, "cannot read this image");
          std::vector<std::vector<cv::Point2f>> polygons;
          std::vector<int> ids;
          cv::aruco::detectMarkers(grey, cv::Ptr<cv::aruco::Dictionary>(dictionary.opencv()), polygons, ids,
                                   cv::aruco::DetectorParameters::create());
          double sum_sq = 0, largest = 0, px_per_cell = 0, blur = 0, band = 0;
          std::map<std::string, int> reasons;  // refusals by reason, numbers left out
          int moved = 0, failed = 0, markers = 0;
          for (std::size_t m = 0; m < ids.size(); ++m) {
            std::array<Eigen::Vector2d, 4> start;
            for (int c = 0; c < 4; ++c) start[c] = {polygons[m][c].x, polygons[m][c].y};
            const cv::Mat code = no_code_model ? cv::Mat() : dictionary.code(ids[m]);
            const EdgeFit reference = refine_marker_corners(grey, start, cells, options, code);
            if (!reference.ok) continue;
            double side = 0;
            for (int c = 0; c < 4; ++c) side += 0.25 * (start[(c + 1) % 4] - start[c]).norm();
            const double cell = side / cells;
            const double w = reference.band_px;
            double marker_sq = 0, marker_max = 0;
            int marker_n = 0, marker_failed = 0;
            for (int t = 0; t < trials; ++t) {
              std::array<Eigen::Vector2d, 4> from = start;
              for (auto& p : from) p += Eigen::Vector2d(jitter(rng), jitter(rng));
              const EdgeFit fit = refine_marker_corners(grey, from, cells, options, code);
              if (!fit.ok) {
                ++marker_failed;
                std::string reason;
                for (char ch : fit.failure) {
                  if ((ch >= '0' && ch <= '9') || ch == '.') {
                    if (reason.empty() || reason.back() != '#') reason += '#';
                  } else {
                    reason += ch;
                  }
                }
                ++reasons[reason];
                continue;
              }
              for (int c = 0; c < 4; ++c) {
                const double d = (fit.corners[c] - reference.corners[c]).norm();
                marker_sq += d * d;
                marker_max = std::max(marker_max, d);
                ++marker_n;
              }
            }
            ++markers;
            px_per_cell += cell;
            blur += reference.blur_px;
            band += w;
            sum_sq += marker_sq;
            largest = std::max(largest, marker_max);
            moved += marker_n;
            failed += marker_failed;
            if (per_marker) {
              std::cout << photo << " marker " << ids[m] << ": " << std::setprecision(2) << cell << " px/cell, blur "
                        << reference.blur_px << " px, band +-" << w << " px; ";
              if (marker_n > 0) {
                std::cout << "corners moved RMS " << std::setprecision(4) << std::sqrt(marker_sq / marker_n) << " px, max "
                          << marker_max << " px, ";
              } else {
                std::cout << "no corners to compare, ";
              }
              std::cout << marker_failed << " of " << trials << " refits failed\n";
            }
          }
          if (moved == 0) {
            std::cout << photo << ": " << markers << " markers refined, " << failed << " of " << markers * trials
                      << " refits failed: no corners to compare\n";
            for (const auto& [reason, count] : reasons) std::cout << "  " << count << " x " << reason << "\n";
            continue;
          }
          ++measured_photos;
          const double n = markers;
          std::cout << photo << ": " << markers << " markers, " << std::setprecision(2) << px_per_cell / n
                    << " px/cell, blur " << blur / n << " px, band +-" << band / n << " px; corners moved RMS "
                    << std::setprecision(4) << std::sqrt(sum_sq / moved) << " px, max " << largest
                    << " px under a start jitter of " << std::setprecision(2) << jitter_px << " px; " << failed << " of "
                    << markers * trials << " refits failed\n";
          for (const auto& [reason, count] : reasons) std::cout << "  " << count << " x " << reason << "\n";
        }
        if (measured_photos == 0) {
          throw GeometryError("no photo had a marker whose corners could be refitted: nothing measured");
        }
      });
}
