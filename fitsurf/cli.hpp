// fitsurf's command line: every option as a long CLI11 option (grouped for --help), their
// conversion into fitsurf::Options, and the writing of all requested outputs, each under a
// temporary name committed only when every output has been written.
#pragma once

#include <string>
#include <vector>

#include "fitsurf/fitsurf.hpp"
#include "fitsurf/report.hpp"
#include "fitsurf/uncertainty.hpp"
#include "formats/cli_fwd.hpp"
#include "formats/point_cloud.hpp"

namespace photomill::fitsurf {

struct Cli {
  Options options;               // filled directly by most options
  std::string input = "-";
  std::string output = "-";      // surface text
  std::string step, iges, mesh, report, residuals, preview;  // empty: not written
  std::string uncertainty;       // --uncertainty: the height's sigma grid (empty: not written)
  UncertaintyOptions uncertainty_options;
  int preview_width_px = 1200;
  double mesh_step_mm = 1.0;
  std::string net = "30x30";
  std::string knots = "uniform", plane = "auto", solver = "ldlt", robust = "reject", outline = "auto";
  std::string prefit = "auto";
  bool no_correction = false;
  std::vector<double> keep_box, keep_above;
  std::string walls = "auto";  // --walls auto|off
  double tolerance_mm = 0;       // used only when --tolerance is given
  bool tolerance_given = false;  // --tolerance on the command line: tolerance mode, else a fixed net
  std::string tolerance_stat = "rms";
  int cv_folds = 4;
  int max_poles = 200;
  std::string preset;            // --preset (formats/tool.hpp)
};

void add_options(CLI::App& app, Cli& cli);

// Throws UsageError for values that are individually valid but unusable (a bad --net, a plane
// without a normal, conflicting outputs).
Options to_options(const Cli& cli);

// "30x30" or "30" (square) -> poles along u and v.
std::pair<int, int> parse_net(const std::string& text);

// On a cloud not in mm (Result::units): the length options that acted in this run, given or by
// default (each only where it acts: --plane-threshold-mm with --drop-plane, --mesh-step-mm with
// --mesh, ...), in the order of --help. Empty for a cloud in mm. None is rescaled: fitsurf has no
// length of its own to put in their place that would be right for every part.
std::vector<LengthOption> length_options_acting(const Cli& cli, const Options& options, const Result& result);

// Writes the surface (stdout or -o), STEP, IGES, mesh, report and residual cloud.
void write_outputs(const Cli& cli, const Options& options, const PointCloud& cloud, const Result& result);

}  // namespace photomill::fitsurf
