// calib's command line: the options (registered on a CLI11 app) and their translation into the
// library's CalibOptions, the control points and the image size.
#pragma once

#include <string>
#include <vector>

#include "calib/calibrate.hpp"
#include "formats/cli_fwd.hpp"

namespace photomill::calib {

struct CalibCli {
  std::vector<std::string> observations{"-"};
  std::string output = "-";
  std::vector<std::string> control;  // control points CSVs (merged; an id defined twice is an error)
  std::string chessboard;   // or a board: "9x6" inner corners
  std::string charuco;      // or "5x7" squares
  double square_mm = 1;
  std::string image_size;   // "WxH"
  std::string method = "auto";
  std::string optimizer = "auto";
  std::string simplex_scaling = "jacobian";
  std::string report;       // JSON
  std::string plot;         // PNG
  std::vector<std::string> rig;  // image name prefixes, one per rig camera (camera 0 first)
  bool rig_fix_intrinsics = false;
  CalibOptions options;
};

void add_options(CLI::App& app, CalibCli& cli);

// Parses the enumerations into cli.options; throws UsageError.
CalibOptions to_options(const CalibCli& cli);

// The control points: the CSVs of --control, or the board of --chessboard/--charuco.
std::vector<ControlPoint> load_control(const CalibCli& cli);

// Throws InputError naming the observation source(s) if they hold no observation, or none that
// refers to a control point (docs/errors.md).
// The observation files' names, for errors about their content.
std::string observation_sources(const CalibCli& cli);

void check_observations(const CalibCli& cli, const std::vector<Observation>& observations,
                        const std::vector<ControlPoint>& control);

// --image-size, else the size of the images named in the observations; throws UsageError if
// neither is available.
cv::Size resolve_image_size(const CalibCli& cli, const std::vector<Observation>& observations);

// With --rig: the image size of each rig camera (from --image-size, or each camera's images).
std::vector<cv::Size> resolve_rig_image_sizes(const CalibCli& cli, const std::vector<Observation>& observations);

}  // namespace photomill::calib
