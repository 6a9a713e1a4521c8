// densify: a dense point cloud from the oriented photos by multi-image least-squares matching
// (issue 28): cloud.ply (sparse) + camera + poses + photos -> dense.ply with normals, sigma_mm,
// views, the reference photo and the correlation per point.
#include "densify/cli.hpp"
#include "formats/log.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  photomill::densify::Cli cli;
  return photomill::tool::run(
      argc, argv,
      {"densify", "a dense point cloud from the oriented photos (multi-image least-squares matching)",
       "densify cloud.ply --camera camera-refined.yaml --poses poses.csv --observations observations.csv -o dense.ply"},
      [&](CLI::App& app) { photomill::densify::add_options(app, cli); },
      [&] {
        const auto inputs = photomill::densify::read_inputs(cli);
        photomill::log::Step step("densifying");
        const auto result = photomill::densify::densify(inputs, cli.options, [&step](const std::string& m) {
          photomill::log::debug(m);
          step.set("densifying: " + m);
        });
        photomill::densify::report(result, inputs);
        photomill::tool::OutputFile out(cli.output);
        photomill::write_ply(out.stream(), result.cloud, photomill::PlyEncoding::BinaryLittleEndian, "photomill densify");
        out.commit();
      });
}
