// detect_marker_bench: photomill's marker detection (OpenCV's candidates and decoding, then the
// edge-model corner fit) against OpenCV's own detectMarkers with CORNER_REFINE_SUBPIX, on the
// same grey photos in one run, one thread each (cv::setNumThreads(1)); the photos are decoded
// once, before the clocks start. Prints, per method, the thread CPU time of the fastest of
// --runs passes over all photos and the corners' RMS and largest error against a synth folder's
// true projections (issue #30: photomill at most 1.5 times OpenCV's time, at 0.03 px RMS or
// better). OpenCV runs with its default detector parameters (cornerSubPix: half-window 5 px, 30
// iterations, 0.1 px), and, as `detect --corner-refine subpix` does, with 100 iterations to
// 0.001 px. A fourth line runs photomill's detection with --corner-refine none: the same
// candidates and decoding without the edge fit, so the difference is the edge fit's own cost. A
// fifth line times the edge fit alone: refine_marker_corners on the markers that fourth method
// found (found once, before the clocks start), with the same options as detect, and a sixth
// without the quick start on big markers (--edge-quick-min-cell-px 1000).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>

#include <CLI/CLI.hpp>
#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "detect/markers.hpp"
#include "formats/error.hpp"
#include "formats/tables.hpp"
#include "formats/tool.hpp"

namespace {

using namespace photomill;
using namespace photomill::detect;

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

using Key = std::pair<std::string, PointId>;  // (file name, point id = 4 marker id + corner)
using Corners = std::map<Key, Eigen::Vector2d>;

struct Figures {
  double best_cpu_s = std::numeric_limits<double>::infinity();
  std::size_t corners = 0, wrong = 0;
  double rms_px = 0, max_px = 0;
};

void judge(const Corners& found, const Corners& truth, Figures& f) {
  double sum_sq = 0;
  f.corners = f.wrong = 0;
  f.max_px = 0;
  for (const auto& [key, p] : found) {
    const auto it = truth.find(key);
    if (it == truth.end()) {
      ++f.wrong;
      continue;
    }
    const double e = (p - it->second).norm();
    sum_sq += e * e;
    f.max_px = std::max(f.max_px, e);
    ++f.corners;
  }
  f.rms_px = f.corners ? std::sqrt(sum_sq / static_cast<double>(f.corners)) : 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace photomill;
  using namespace photomill::detect;
  std::vector<std::string> photos;
  std::string set, dictionary_name = "DICT_4X4_100";
  int runs = 3;
  return tool::run(
      argc, argv,
      {"detect_marker_bench", "photomill's marker corners against OpenCV's detectMarkers + CORNER_REFINE_SUBPIX",
       "detect_marker_bench data/demo/part_*.jpg --set data/demo"},
      [&](CLI::App& app) {
        app.add_option("photos", photos, "Photos")->required();
        app.add_option("--set", set, "synth folder whose observations.csv holds the true corners")->required();
        app.add_option("--dictionary", dictionary_name, "ArUco dictionary")->capture_default_str();
        app.add_option("--runs", runs, "Passes over the photos per method (the fastest counts)")
            ->capture_default_str()->check(CLI::Range(1, 100));
      },
      [&] {
        cv::setNumThreads(1);
        Corners truth;
        const std::string truth_path = set + "/observations.csv";
        for (const auto& o : read_observations(*tool::open_input(truth_path), truth_path)) {
          truth[{std::filesystem::path(o.image).filename().string(), o.point_id}] = {o.u_px, o.v_px};
        }
        std::vector<cv::Mat> greys;
        for (const auto& p : photos) {
          greys.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
          if (greys.back().empty()) throw InputError(p, 0, "cannot read this image");
        }
        const auto dictionary = MarkerDictionary::predefined(dictionary_name);
        auto name = [&](std::size_t k) { return std::filesystem::path(photos[k]).filename().string(); };

        auto opencv = [&](bool tight) {
          return [&, tight](Corners& out) {
            auto params = cv::aruco::DetectorParameters::create();
            params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
            if (tight) {
              params->cornerRefinementMinAccuracy = 0.001;
              params->cornerRefinementMaxIterations = 100;
            }
            for (std::size_t k = 0; k < greys.size(); ++k) {
              std::vector<std::vector<cv::Point2f>> corners;
              std::vector<int> ids;
              cv::aruco::detectMarkers(greys[k], cv::Ptr<cv::aruco::Dictionary>(dictionary.opencv()), corners, ids,
                                       params);
              for (std::size_t m = 0; m < ids.size(); ++m) {
                for (int c = 0; c < 4; ++c) {
                  out[{name(k), static_cast<PointId>(4 * ids[m] + c)}] = {corners[m][static_cast<std::size_t>(c)].x,
                                                                          corners[m][static_cast<std::size_t>(c)].y};
                }
              }
            }
          };
        };
        auto photomill = [&](CornerRefinement refinement) {
          return [&, refinement](Corners& out) {
            MarkerDetectOptions options;
            options.refinement = refinement;
            for (std::size_t k = 0; k < greys.size(); ++k) {
              const MarkerDetection d = detect_markers(greys[k], photos[k], dictionary, options);
              for (const auto& o : d.observations()) out[{name(k), o.point_id}] = {o.u_px, o.v_px};
            }
          };
        };
        // The edge fit alone, on the markers found without it.
        std::vector<MarkerDetection> unrefined;
        {
          MarkerDetectOptions options;
          options.refinement = CornerRefinement::None;
          for (std::size_t k = 0; k < greys.size(); ++k) {
            unrefined.push_back(detect_markers(greys[k], photos[k], dictionary, options));
          }
        }
        auto edge_fit_alone = [&](bool quick) {
          return [&, quick](Corners& out) {
            MarkerDetectOptions options;
            if (!quick) options.edges.quick_start_min_cell_px = 1000;
            const int cells = dictionary.bits_per_side() + 2;
            for (std::size_t k = 0; k < greys.size(); ++k) {
              for (std::size_t m = 0; m < unrefined[k].marker_ids.size(); ++m) {
                const int id = unrefined[k].marker_ids[m];
                const EdgeFit fit = refine_marker_corners(greys[k], unrefined[k].corners[m], cells, options.edges,
                                                          dictionary.code(id));
                if (!fit.ok) continue;
                for (int c = 0; c < 4; ++c) {
                  out[{name(k), static_cast<PointId>(4 * id + c)}] = fit.corners[static_cast<std::size_t>(c)];
                }
              }
            }
          };
        };
        struct Method {
          std::string label;
          std::function<void(Corners&)> run;
          Figures figures;
        };
        std::vector<Method> methods{{"OpenCV detectMarkers + CORNER_REFINE_SUBPIX (defaults)", opencv(false), {}},
                                    {"OpenCV detectMarkers + CORNER_REFINE_SUBPIX (0.001 px, 100 it)", opencv(true), {}},
                                    {"photomill detect_markers (edge fit)", photomill(CornerRefinement::Edges), {}},
                                    // The same candidates and decoding without the edge fit: the
                                    // difference is what the edge fit itself costs.
                                    {"photomill detect_markers, --corner-refine none",
                                     photomill(CornerRefinement::None), {}},
                                    {"photomill edge fit alone (on those markers)", edge_fit_alone(true), {}},
                                    {"photomill edge fit alone, no quick start", edge_fit_alone(false), {}}};
        // The methods take turns in every pass, so a change of machine load falls on all of them.
        for (int r = 0; r < runs; ++r) {
          for (auto& m : methods) {
            Corners found;
            const double start = thread_cpu_s();
            m.run(found);
            m.figures.best_cpu_s = std::min(m.figures.best_cpu_s, thread_cpu_s() - start);
            judge(found, truth, m.figures);
          }
        }
        std::cout << greys.size() << " photos, one thread, fastest of " << runs << " passes\n";
        std::cout << std::fixed;
        for (const auto& m : methods) {
          std::cout << std::left << std::setw(64) << m.label << std::right << std::setprecision(3) << " CPU "
                    << m.figures.best_cpu_s << " s, " << m.figures.corners << " corners, RMS " << std::setprecision(4)
                    << m.figures.rms_px << " px, max " << m.figures.max_px << " px, wrong ids " << m.figures.wrong
                    << "\n";
        }
        std::cout << std::setprecision(3) << "photomill / OpenCV (defaults): "
                  << methods[2].figures.best_cpu_s / methods[0].figures.best_cpu_s
                  << "; photomill / OpenCV (0.001 px, 100 it): "
                  << methods[2].figures.best_cpu_s / methods[1].figures.best_cpu_s << "\n";
      });
}
