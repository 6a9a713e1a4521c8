// targets' command line: two subcommands, `charuco` and `plate`, sharing the page and output
// options (see docs/targets.md).
#pragma once

#include <string>
#include <vector>

#include "formats/cli_fwd.hpp"
#include "targets/sheet.hpp"

namespace photomill::targets {

struct TargetsCli {
  CharucoTarget charuco;
  PlateTarget plate;
  PageOptions page;
  std::string squares = "7x5";
  std::string layout = "ring";
  std::string orientation = "auto";
  std::string output = "-";   // PDF
  std::string svg;            // SVG too
  std::string control_points; // CSV
  std::string scale_bars;     // CSV (plate with --scale-bar-mm)
  CLI::App* charuco_command = nullptr;
  CLI::App* plate_command = nullptr;
};

void add_options(CLI::App& app, TargetsCli& cli);

// Checks the combination (UsageError) and builds the sheet the subcommand asks for; `command` is
// the command line printed on the sheet.
TargetSheet make_sheet(TargetsCli& cli, const std::string& command);

// One line for stderr: what the sheet holds and where it went.
std::string describe(const TargetsCli& cli, const TargetSheet& sheet);

}  // namespace photomill::targets
