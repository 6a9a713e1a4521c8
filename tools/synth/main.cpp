// synth: renders photos of a known freeform part (and of a ChArUco board) with their ground truth:
// camera.yaml, poses, marker corners, their true projections, the surface. Writes a folder; stdout
// stays empty. See docs/synth.md.
#include <stdexcept>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "tools/synth/cli.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  synth::SynthCli cli;
  std::string command_line = "synth";
  for (int i = 1; i < argc; ++i) command_line += std::string(" ") + argv[i];
  return tool::run(
      argc, argv,
      {"synth", "render ground-truth photos of a known part, a calibration board and their truth",
       "synth -o demo --views 12 --calib-views 10 && ls demo"},
      [&](CLI::App& app) { synth::add_options(app, cli); },
      [&] {
        const synth::SynthOptions options = synth::to_options(cli, command_line);
        synth::DatasetSummary summary;
        try {
          summary = synth::write_dataset(options, cli.output_dir);
        } catch (const std::invalid_argument& e) {
          throw UsageError(e.what());  // options that are valid one by one but not together
        }
        log::info(cli.output_dir + ": " + std::to_string(summary.part_images) + " part views, " +
                  std::to_string(summary.board_images) + " board views, " +
                  std::to_string(summary.observations) + " marker-corner observations, " +
                  std::to_string(summary.files.size()) + " files, " +
                  std::to_string(summary.bytes / 1024) + " KiB; rendering took " +
                  std::to_string(summary.render_seconds) + " s");
      });
}
