// triangulate: camera poses, 3D points and bundle adjustment. Reads tracks (file or stdin), the
// camera and the datum (control points, scale bars or a marker side); writes the point cloud
// (PLY, -o or stdout), and on request the poses CSV, a JSON report, a COLMAP text model and a
// PNG preview.
// The report also goes to stderr. See docs/triangulate.md.
#include <deque>

#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "triangulate/cli.hpp"
#include "triangulate/colmap.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  triangulate::Cli cli;
  return tool::run(
      argc, argv,
      {"triangulate", "camera poses, 3D points and bundle adjustment from tracks and a calibrated camera",
       "match obs.csv | triangulate -c camera.yaml --control-points plate.csv --poses poses.csv -o cloud.ply"},
      [&](CLI::App& app) { triangulate::add_options(app, cli); },
      [&] {
        const triangulate::ReconstructOptions options = triangulate::to_options(cli);
        const triangulate::ReconstructInput input = triangulate::read_input(cli);
        const auto refined_for = triangulate::refined_camera_files(cli, input);
        if (!cli.colmap.empty()) {
          if (input.cameras.empty()) triangulate::check_colmap_camera(input.camera, input.camera_source);
          for (const auto& c : input.cameras) triangulate::check_colmap_camera(c.camera, c.source);
        }

        const triangulate::Reconstruction result = triangulate::reconstruct(input, options);
        triangulate::log_report(result.report);

        // Every output is written under a temporary name and committed only when all succeeded.
        tool::OutputFile cloud(cli.output);
        write_ply(cloud.stream(), triangulate::make_point_cloud(result),
                  cli.ply_encoding == "ascii" ? PlyEncoding::Ascii : PlyEncoding::BinaryLittleEndian,
                  "photomill triangulate");
        std::optional<tool::OutputFile> poses, report, camera, preview;
        if (!cli.poses.empty()) write_poses(poses.emplace(cli.poses).stream(), triangulate::registered_poses(result));
        if (!cli.report.empty()) triangulate::write_report_json(report.emplace(cli.report).stream(), result.report);
        if (!cli.refined_camera.empty()) write_camera_yaml(camera.emplace(cli.refined_camera).stream(), result.camera);
        std::deque<tool::OutputFile> cameras;  // not movable: a deque keeps them in place
        for (const auto& [file, k] : refined_for) write_camera_yaml(cameras.emplace_back(file).stream(), result.cameras[k]);
        if (!cli.preview.empty()) triangulate::write_preview(preview.emplace(cli.preview).stream(), result, cli.preview_options);
        triangulate::ColmapModelFiles colmap(cli.colmap);
        if (!cli.colmap.empty()) colmap.write(result);

        cloud.commit();
        for (auto* f : {&poses, &report, &camera, &preview}) {
          if (*f) (*f)->commit();
        }
        for (auto& f : cameras) f.commit();
        colmap.commit();
      });
}
