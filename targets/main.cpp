// targets: print-ready PDF (and SVG) of a ChArUco calibration board or of a plate of ArUco
// markers at exact scale, with the target's control points CSV from the same run.
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "formats/log.hpp"
#include "formats/tables.hpp"
#include "formats/tool.hpp"
#include "targets/cli.hpp"
#include "targets/render.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  targets::TargetsCli cli;
  std::string command = "targets";
  for (int i = 1; i < argc; ++i) command += std::string(" ") + argv[i];
  return tool::run(
      argc, argv,
      {"targets", "print-ready targets at exact scale: a ChArUco board or a marker plate -> PDF, SVG, control points CSV",
       "targets plate --paper A3 --control-points control_points.csv -o plate.pdf"},
      [&](CLI::App& app) { targets::add_options(app, cli); },
      [&] {
        const targets::TargetSheet sheet = targets::make_sheet(cli, command);
        tool::OutputFile pdf(cli.output);
        targets::write_pdf(pdf.stream(), sheet.sheet);
        std::optional<tool::OutputFile> svg, points, bars;
        if (!cli.svg.empty()) {
          svg.emplace(cli.svg);
          targets::write_svg(svg->stream(), sheet.sheet);
        }
        if (!cli.control_points.empty()) {
          points.emplace(cli.control_points);
          write_control_points(points->stream(), sheet.control_points);
        } else if (cli.plate_command->parsed()) {
          log::warn("no --control-points FILE: the plate's control points were not written (triangulate needs them)");
        }
        if (!cli.scale_bars.empty()) {
          bars.emplace(cli.scale_bars);
          write_scale_bars(bars->stream(), sheet.scale_bars);
        }
        log::info(targets::describe(cli, sheet));
        if (bars) bars->commit();
        if (points) points->commit();
        if (svg) svg->commit();
        pdf.commit();
      });
}
