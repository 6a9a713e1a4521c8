// triangulate_bench: accuracy and speed of triangulate on synthetic ground truth (test_scene.hpp),
// printed as figures for scripts/bench-triangulate.sh. Not a test: it asserts nothing.
//   triangulate_bench --datum control --noise-px 0.05          accuracy on a 12-view scene
//   triangulate_bench --views 200 --random-points 100000 ...   speed on a large one
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

#include <CLI/CLI.hpp>

#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "triangulate/colmap.hpp"
#include "triangulate/reconstruct.hpp"
#include "triangulate/test_scene.hpp"

namespace {

using namespace photomill;
using namespace photomill::triangulate;

double rms_px(const Scene& scene, const std::vector<char>& in_result) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t t = 0; t < scene.tracks.size(); ++t) {
    if (!in_result[t]) continue;
    for (std::size_t o : scene.active_observations(t)) {
      const double e = reprojection_error_px(scene, o);
      sum += e * e;
      ++n;
    }
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : 0;
}

// The start: true poses rotated by ~0.1 deg and shifted by ~0.5 mm, points triangulated from them.
void compare_bundle_adjustment(const test::SceneTruth& truth, const ReconstructOptions& ro, const std::string& dir,
                               std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> rot(0, 0.1 * std::numbers::pi / 180), shift(0, 0.5);
  Reconstruction r;
  r.scene = build_scene(truth.tracks, to_camera_model(truth.camera, "synthetic"), {});
  r.camera = truth.camera;
  std::map<std::string, Pose> by_name;
  for (const Pose& p : truth.poses) by_name[p.image] = p;
  for (SceneImage& im : r.scene.images) {
    const Pose& p = by_name.at(im.name);
    const Eigen::Matrix3d dR = (Eigen::AngleAxisd(rot(rng), Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(rot(rng), Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(rot(rng), Eigen::Vector3d::UnitZ())).toRotationMatrix();
    im.cam_from_world = make_pose(dR * p.rotation(), p.cam_from_world_translation_mm + Eigen::Vector3d(shift(rng), shift(rng), shift(rng)));
    im.registered = true;
  }
  triangulate_tracks(r.scene, ro.triangulation, ro.threads);
  r.in_result.assign(r.scene.tracks.size(), 0);
  std::size_t obs = 0;
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    const auto act = r.scene.active_observations(t);
    r.in_result[t] = in_adjustment(r.scene, t, act.size());
    if (r.in_result[t]) obs += act.size();
  }
  r.sigma_mm.assign(r.scene.tracks.size(), 0);
  const double initial = rms_px(r.scene, r.in_result);
  {
    ColmapModelFiles files(dir + "/initial");
    files.write(r);
    files.commit();
  }
  // COLMAP's bundle_adjuster: first pose fixed, x of the second translation fixed, trivial loss.
  BundleSetup setup;
  setup.observation_sigma_px.fill(1);
  setup.fixed_image = 0;
  setup.fixed_translation = std::make_pair(std::size_t{1}, 0);
  BundleOptions bo = ro.bundle;
  bo.loss = LossKind::Trivial;
  const auto start = std::chrono::steady_clock::now();
  const BundleSummary s = bundle_adjust(r.scene, setup, bo);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double final_rms = rms_px(r.scene, r.in_result);
  std::printf("  %s\n", s.timing.c_str());
  std::size_t points = 0;
  for (char c : r.in_result) points += c ? 1 : 0;
  std::printf("photomill BA: %zu images, %zu points, %zu observations; %s; %d iterations; solver %.3f s, wall %.3f s; "
              "rms %.6f -> %.6f px (COLMAP's cost figure: %.7f -> %.7f)\n",
              r.scene.images.size(), points, obs, s.solver.c_str(), s.iterations, s.seconds, wall, initial, final_rms,
              initial / 2, final_rms / 2);
  ColmapModelFiles files(dir + "/photomill");
  files.write(r);
  files.commit();
}

}  // namespace

int main(int argc, char** argv) {
  test::SceneOptions so;
  ReconstructOptions ro;
  std::string datum = "control";
  int repeat = 1;
  std::string write_dir;
  std::string ba_dir;
  return tool::run(
      argc, argv, {"triangulate_bench", "accuracy and speed of triangulate on synthetic truth", "triangulate_bench --datum control"},
      [&](CLI::App& app) {
        app.add_option("--datum", datum, "control, control-sigma, scale-bars, marker-side or none")
            ->check(CLI::IsMember({"control", "control-sigma", "scale-bars", "marker-side", "none"}))->capture_default_str();
        app.add_option("--views", so.views, "Views")->capture_default_str();
        app.add_option("--noise-px", so.noise_px, "Noise per coordinate")->capture_default_str();
        app.add_option("--outlier-fraction", so.outlier_fraction, "Fraction of outliers")->capture_default_str();
        app.add_option("--random-points", so.random_part_points, "Random part points (0: grid)")->capture_default_str();
        app.add_option("--max-track-length", so.max_track_length, "Longest track (0: all views)")->capture_default_str();
        app.add_option("--seed", so.seed, "Seed")->capture_default_str();
        app.add_option("--threads", ro.threads, "Threads")->capture_default_str();
        app.add_option("--repeat", repeat, "Runs (different seeds)")->capture_default_str();
        app.add_option("--write", write_dir,
                       "Only write the scene's files here (tracks.csv, camera.yaml, control_points.csv, "
                       "scale_bars.csv, part_points.csv, poses_true.csv) and stop");
        app.add_option("--ba-compare", ba_dir,
                       "Bundle adjustment only, from perturbed poses: write the start as a COLMAP model to DIR/initial "
                       "(for colmap bundle_adjuster), adjust it with COLMAP's gauge and loss, print figures, write "
                       "DIR/photomill");
      },
      [&] {
        ro.bundle.threads = ro.threads;
        for (int k = 0; k < repeat; ++k) {
          test::SceneOptions o = so;
          o.seed = so.seed + static_cast<std::uint64_t>(k);
          if (datum == "marker-side") o.plate_marker_side_mm = 24;
          const test::SceneTruth truth = test::make_scene(o);
          if (!ba_dir.empty()) {
            compare_bundle_adjustment(truth, ro, ba_dir, o.seed);
            return;
          }
          if (!write_dir.empty()) {
            std::filesystem::create_directories(write_dir);
            const std::filesystem::path d(write_dir);
            std::ofstream(d / "tracks.csv") << [&] { std::ostringstream s; write_tracks(s, truth.tracks); return s.str(); }();
            std::ofstream(d / "camera.yaml") << [&] { std::ostringstream s; write_camera_yaml(s, truth.camera); return s.str(); }();
            std::ofstream(d / "control_points.csv") << [&] { std::ostringstream s; write_control_points(s, truth.plate_points); return s.str(); }();
            std::ofstream(d / "part_points.csv") << [&] { std::ostringstream s; write_control_points(s, truth.part_points); return s.str(); }();
            std::ofstream(d / "poses_true.csv") << [&] { std::ostringstream s; write_poses(s, truth.poses); return s.str(); }();
            std::vector<ScaleBar> bars;
            const auto& p = truth.plate_points;
            for (std::size_t i = 0; i + 1 < p.size(); i += 3) {
              bars.push_back({p[i].point_id, p[p.size() - 1 - i].point_id, (p[i].xyz_mm - p[p.size() - 1 - i].xyz_mm).norm(), 0.001});
            }
            std::ofstream(d / "scale_bars.csv") << [&] { std::ostringstream s; write_scale_bars(s, bars); return s.str(); }();
            return;
          }
          ReconstructInput in;
          in.tracks = truth.tracks;
          in.camera = truth.camera;
          ReconstructOptions opt = ro;
          if (datum == "control" || datum == "control-sigma") {
            in.control_points = truth.plate_points;
            if (datum == "control-sigma") {
              for (auto& c : in.control_points) c.sigma_mm = 0.005;
            }
          } else if (datum == "scale-bars") {
            const auto& p = truth.plate_points;
            for (std::size_t i = 0; i + 1 < p.size(); i += 3) {
              in.scale_bars.push_back({p[i].point_id, p[p.size() - 1 - i].point_id, (p[i].xyz_mm - p[p.size() - 1 - i].xyz_mm).norm(), 0.001});
            }
          } else if (datum == "marker-side") {
            opt.scale.marker_side_mm = 24;
            opt.scale.marker_side_sigma_mm = 0.002;
          } else {
            opt.scale.allow_arbitrary_scale = true;
          }
          const auto start = std::chrono::steady_clock::now();
          const Reconstruction r = reconstruct(in, opt);
          const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          const test::Accuracy direct = test::evaluate(r, truth, false);
          const test::Accuracy aligned = test::evaluate(r, truth, true);
          std::printf("seed %llu datum %s (%s): %zu images, %zu tracks, %zu obs; %zu/%zu registered, %zu points; "
                      "rms %.4f px sigma %.4f / %.4f px (coded / natural); %.3f s (BA %.3f s, %d runs)\n",
                      static_cast<unsigned long long>(o.seed), r.report.datum.c_str(), r.report.pose_initialisation.c_str(),
                      r.report.images, r.report.tracks, truth.tracks.size(), r.report.registered_images, r.report.images,
                      r.report.points, r.report.final_rms_px, r.setup.observation_sigma_px[0], r.setup.observation_sigma_px[1], seconds,
                      r.report.adjustment_seconds, r.report.adjustments);
          std::printf("  direct:  part points %zu rms %.5f mm max %.5f mm; centres rms %.5f mm max %.5f mm\n",
                      direct.part_points, direct.part_rms_mm, direct.part_max_mm, direct.centre_rms_mm, direct.centre_max_mm);
          std::printf("  aligned: part points rms %.5f mm max %.5f mm; centres rms %.5f mm max %.5f mm; scale %.7f\n",
                      aligned.part_rms_mm, aligned.part_max_mm, aligned.centre_rms_mm, aligned.centre_max_mm, aligned.scale);
          double mean_sigma = 0;
          std::size_t n = 0;
          for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
            if (r.in_result[t] && !r.scene.tracks[t].at_control) {
              mean_sigma += r.sigma_mm[t] * r.sigma_mm[t];
              ++n;
            }
          }
          std::printf("  predicted sigma (RMS over unknown points) %.5f mm per axis (%s), removed %zu of %zu outliers\n",
                      n ? std::sqrt(mean_sigma / static_cast<double>(n)) : 0.0, r.report.sigma_method.c_str(),
                      r.report.removed.size(), truth.outliers.size());
        }
      });
}
