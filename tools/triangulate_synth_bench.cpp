// triangulate_synth_bench: the accuracy targets on synth's default scene (12 views,
// 2000 x 1500 px, plate and part markers), with noise added to synth's true corner projections.
// Prints figures for scripts/bench-triangulate.sh; asserts nothing.
#include <chrono>
#include <algorithm>
#include <cstdio>

#include <CLI/CLI.hpp>

#include "formats/tool.hpp"
#include "tools/synth_truth.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  using namespace photomill::triangulate;
  double noise_px = 0.05;
  int repeat = 5;
  std::string datum = "control";
  test::NaturalFeatures natural;
  return tool::run(
      argc, argv, {"triangulate_synth_bench", "triangulate's accuracy on synth's default scene", "triangulate_synth_bench --noise-px 0.1"},
      [&](CLI::App& app) {
        app.add_option("--noise-px", noise_px, "Noise per coordinate of the corner positions")->capture_default_str();
        app.add_option("--repeat", repeat, "Noise draws")->capture_default_str();
        app.add_option("--datum", datum, "control, marker-side or scale-bars")
            ->check(CLI::IsMember({"control", "marker-side", "scale-bars"}))->capture_default_str();
        app.add_option("--natural-features", natural.count, "Simulated natural-feature points on the part")->capture_default_str();
        app.add_option("--natural-noise-px", natural.noise_px, "Their noise per coordinate")->capture_default_str();
      },
      [&] {
        const synth::SynthOptions so = test::synth_default_options();
        double worst_points = 0, worst_centres = 0, sum_points = 0, sum_centres = 0, seconds = 0;
        for (int k = 0; k < repeat; ++k) {
          const test::SceneTruth truth = test::synth_truth(so, noise_px, 100 + static_cast<std::uint64_t>(k), natural);
          ReconstructInput in;
          in.tracks = truth.tracks;
          in.camera = truth.camera;
          ReconstructOptions o;
          if (datum == "control") {
            in.control_points = truth.plate_points;
          } else if (datum == "marker-side") {
            o.scale.marker_side_mm = so.layout.plate_marker_mm;
            o.scale.marker_side_sigma_mm = 0.002;
          } else {
            // Scale bars across the plate between plate-marker corners.
            const auto& p = truth.plate_points;
            for (std::size_t i = 0; i + 1 < p.size() / 2; i += 4) {
              const auto& a = p[i];
              const auto& b = p[p.size() / 2 + i];
              in.scale_bars.push_back({a.point_id, b.point_id, (a.xyz_mm - b.xyz_mm).norm(), 0.002});
            }
          }
          const auto start = std::chrono::steady_clock::now();
          const Reconstruction r = reconstruct(in, o);
          const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          seconds += s;
          const bool align = datum != "control";
          test::SceneTruth markers = truth;  // accuracy of the part-marker corners only
          markers.part_points.erase(std::remove_if(markers.part_points.begin(), markers.part_points.end(),
                                                   [](const ControlPoint& p) { return p.point_id >= test::kNaturalIdOffset; }),
                                    markers.part_points.end());
          const test::Accuracy a = test::evaluate(r, markers, align);
          if (natural.count > 0) {
            test::SceneTruth features = truth;
            features.part_points.erase(std::remove_if(features.part_points.begin(), features.part_points.end(),
                                                      [](const ControlPoint& p) { return p.point_id < test::kNaturalIdOffset; }),
                                       features.part_points.end());
            const test::Accuracy f = test::evaluate(r, features, align);
            std::printf("  natural features: %zu reconstructed, rms %.5f mm max %.5f mm\n", f.part_points, f.part_rms_mm, f.part_max_mm);
          }
          std::printf("draw %d: %zu images %zu points (%zu part corners) rms %.4f px; part corners rms %.5f mm max %.5f; "
                      "centres rms %.5f mm max %.5f%s; %.3f s\n",
                      k, r.report.registered_images, r.report.points, a.part_points, r.report.final_rms_px, a.part_rms_mm,
                      a.part_max_mm, a.centre_rms_mm, a.centre_max_mm, align ? " (after similarity)" : "", s);
          worst_points = std::max(worst_points, a.part_rms_mm);
          worst_centres = std::max(worst_centres, a.centre_rms_mm);
          sum_points += a.part_rms_mm * a.part_rms_mm;
          sum_centres += a.centre_rms_mm * a.centre_rms_mm;
        }
        std::printf("datum %s, noise %.3f px, %d draws: part corners rms %.5f mm (worst draw %.5f); centres rms %.5f mm "
                    "(worst draw %.5f); mean time %.3f s\n",
                    datum.c_str(), noise_px, repeat, std::sqrt(sum_points / repeat), worst_points,
                    std::sqrt(sum_centres / repeat), worst_centres, seconds / repeat);
      });
}
