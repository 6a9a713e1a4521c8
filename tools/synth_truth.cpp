// Ground truth from synth's scene (see synth_truth.hpp).
#include <CLI/CLI.hpp>

#include "tools/synth_truth.hpp"

#include <algorithm>
#include <random>

#include "tools/synth/camera_model.hpp"
#include "tools/synth/cli.hpp"
#include "tools/synth/render.hpp"

namespace photomill::triangulate::test {

synth::SynthOptions synth_default_options() {
  CLI::App app;
  synth::SynthCli cli;
  synth::add_options(app, cli);
  cli.output_dir = "unused";
  return synth::to_options(cli, "triangulate test");
}

SceneTruth synth_truth(const synth::SynthOptions& options, double noise_px, std::uint64_t noise_seed,
                       const NaturalFeatures& natural) {
  SceneTruth t;
  const synth::PartScene scene = synth::make_part_scene(options);
  const synth::PartRayScene rays(scene);
  t.camera = options.camera;
  t.poses = synth::part_view_poses(options);
  t.plate_points = synth::marker_corners(scene, false);
  t.part_points = synth::marker_corners(scene, true);
  std::mt19937_64 rng(noise_seed);
  std::normal_distribution<double> noise(0, noise_px);
  for (const Pose& pose : t.poses) {
    for (const Observation& o : synth::marker_observations(rays, options.camera, pose)) {
      t.tracks.push_back({o.point_id, o.image, o.u_px + noise(rng), o.v_px + noise(rng)});
    }
  }
  std::normal_distribution<double> feature_noise(0, natural.noise_px);
  std::uniform_real_distribution<double> unit(0, 1);
  const synth::HeightField& h = scene.surface;
  for (std::size_t k = 0; k < natural.count; ++k) {
    const double x = h.x_min_mm + (h.x_max_mm - h.x_min_mm) * unit(rng);
    const double y = h.y_min_mm + (h.y_max_mm - h.y_min_mm) * unit(rng);
    const Eigen::Vector3d X(x, y, h.height_mm(x, y));
    const PointId id = kNaturalIdOffset + static_cast<PointId>(k);
    std::vector<std::pair<std::string, Eigen::Vector2d>> seen;
    for (const Pose& pose : t.poses) {
      if (!synth::visible(rays, options.camera, pose, X)) continue;
      seen.push_back({pose.image, *synth::project(options.camera, pose, X)});
    }
    if (seen.size() > natural.max_track_length) {
      std::shuffle(seen.begin(), seen.end(), rng);
      seen.resize(natural.max_track_length);
    }
    if (seen.size() < 2) continue;
    t.part_points.push_back({id, X, std::nullopt});
    for (const auto& [image, uv] : seen) {
      t.tracks.push_back({id, image, uv.x() + feature_noise(rng), uv.y() + feature_noise(rng)});
    }
  }
  return t;
}

}  // namespace photomill::triangulate::test
