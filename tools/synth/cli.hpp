// synth's command line: every option of SynthOptions as a long CLI11 option, and the conversion
// of the parsed values into SynthOptions (derived defaults such as the principal point).
#pragma once

#include <optional>
#include <string>

#include "formats/cli_fwd.hpp"
#include "tools/synth/dataset.hpp"

namespace photomill::synth {

struct SynthCli {
  SynthOptions options;        // filled directly by most options
  std::string output_dir;
  int width_px = 2000;
  int height_px = 1500;
  double fx = 2400;
  std::optional<double> fy;    // default fx
  std::optional<double> cx;    // default (width - 1) / 2
  std::optional<double> cy;    // default (height - 1) / 2
  double k1 = -0.08, k2 = 0.06, p1 = 0.0004, p2 = -0.0003, k3 = 0;
};

void add_options(CLI::App& app, SynthCli& cli);
// Throws photomill::UsageError for values that are individually valid but unusable together.
SynthOptions to_options(const SynthCli& cli, const std::string& command_line);

}  // namespace photomill::synth
