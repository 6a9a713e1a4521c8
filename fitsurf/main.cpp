// fitsurf: least-squares B-spline surface from a point cloud (issue #7; method in docs/fitsurf.md).
// Reads a point cloud (PLY or x y z text, a file or stdin), selects the part, fits, and writes the
// surface text to stdout or -o, plus STEP, IGES, a mesh, a JSON report and residuals on request.
#include "fitsurf/cli.hpp"
#include "fitsurf/fitsurf.hpp"
#include "fitsurf/report.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  fitsurf::Cli cli;
  return tool::run(
      argc, argv,
      {"fitsurf", "least-squares B-spline surface from a point cloud (PLY or x y z text)",
       "cat scan.xyz | fitsurf --drop-plane --net 30x30 --step part.step --report fit.json > part.surf"},
      [&](CLI::App& app) { fitsurf::add_options(app, cli); },
      [&] {
        const fitsurf::Options options = fitsurf::to_options(cli);
        const PointCloud cloud = read_point_cloud(*tool::open_input(cli.input), tool::source_name(cli.input));
        if (cloud.points_mm.empty()) throw InputError(tool::source_name(cli.input), 0, "no points: nothing to fit");
        const fitsurf::Result result = fitsurf::fit_point_cloud(cloud, options, tool::source_name(cli.input));
        for (const auto& line : fitsurf::summary(result, options)) log::info(line);
        if (result.units != "mm") {
          log::warn(fitsurf::units_warning(result));
          const auto lengths = fitsurf::length_options_acting(cli, options, result);
          if (!lengths.empty()) log::warn(fitsurf::length_options_warning(lengths, result));
        }
        fitsurf::write_outputs(cli, options, cloud, result);
      });
}
