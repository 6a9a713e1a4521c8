// detect_marker_check: marker-corner observations against a synth folder's true projections
// (benchmark support). Prints, for the plate markers, the part markers and all: corners compared,
// RMS and largest error (px); and the corners whose (image, point id) the truth does not have
// (wrong ids) or that were not found.
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>

#include <CLI/CLI.hpp>

#include "formats/tables.hpp"
#include "formats/tool.hpp"
#include "tools/synth/scene.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  std::string observations_path, set;
  return tool::run(
      argc, argv,
      {"detect_marker_check", "marker corners against a synth folder's true projections",
       "detect_marker_check obs.csv --set data/demo"},
      [&](CLI::App& app) {
        app.add_option("observations", observations_path, "Observations CSV from detect --aruco")->required();
        app.add_option("--set", set, "synth folder (observations.csv = truth, scene.txt)")->required();
      },
      [&] {
        auto key = [](const Observation& o) {
          return std::make_pair(std::filesystem::path(o.image).filename().string(), o.point_id);
        };
        std::map<std::pair<std::string, PointId>, Eigen::Vector2d> truth;
        for (const auto& o : read_observations(*tool::open_input(set + "/observations.csv"), set + "/observations.csv")) {
          truth[key(o)] = {o.u_px, o.v_px};
        }
        std::map<int, bool> on_part;
        for (const auto& m : synth::read_scene(*tool::open_input(set + "/scene.txt"), set + "/scene.txt").markers) {
          on_part[m.id] = m.on_part;
        }
        struct Stats {
          double sum_sq = 0, max = 0;
          std::size_t n = 0;
        } plate, part, all;
        std::size_t wrong = 0;
        for (const auto& o : read_observations(*tool::open_input(observations_path), observations_path)) {
          const auto it = truth.find(key(o));
          if (it == truth.end()) {
            ++wrong;
            continue;
          }
          const double e = (Eigen::Vector2d(o.u_px, o.v_px) - it->second).norm();
          for (Stats* s : {on_part[static_cast<int>(o.point_id / 4)] ? &part : &plate, &all}) {
            s->sum_sq += e * e;
            s->max = std::max(s->max, e);
            ++s->n;
          }
          truth.erase(it);
        }
        for (auto [name, s] : {std::pair{"plate markers", &plate}, {"part markers", &part}, {"all markers", &all}}) {
          std::cout << name << ": " << s->n << " corners, RMS " << (s->n ? std::sqrt(s->sum_sq / s->n) : 0) << " px, max "
                    << s->max << " px\n";
        }
        std::cout << "wrong ids: " << wrong << " corners; true corners not found: " << truth.size() << "\n";
      });
}
