// triangulate's command line: every option of ReconstructOptions as a long CLI11 option, the
// input files, and the outputs. Kept out of main.cpp so main stays a short sequence.
#pragma once

#include <optional>
#include <string>

#include "formats/cli_fwd.hpp"
#include "triangulate/preview.hpp"
#include "triangulate/reconstruct.hpp"

namespace photomill::triangulate {

struct Cli {
  std::string tracks = "-";
  std::string camera;
  std::vector<std::string> camera_for;  // PREFIX=FILE, one per camera
  std::string rig;                      // rig.yaml
  std::string control_points;
  std::string scale_bars;
  std::string known_poses;        // photomill's poses CSV or COLMAP's images.txt
  std::string output = "-";
  std::string ply_encoding = "binary";
  std::string poses;
  std::string report;
  std::string colmap;
  std::string refined_camera;
  std::vector<std::string> refined_camera_for;  // PREFIX=FILE, several cameras
  std::string preview;            // PNG of the cloud and the cameras
  PreviewOptions preview_options;
  std::string loss = "huber";
  std::string solver = "auto";
  std::string refine_intrinsics = "none";
  std::string marker_ids = "0-1023";
  std::optional<double> marker_side_mm;
  std::optional<double> observation_sigma_px;
  ReconstructOptions options;
  std::string preset;             // --preset (formats/tool.hpp)
};

void add_options(CLI::App& app, Cli& cli);
// Converts the parsed strings (enums, id ranges) into the options; throws UsageError.
ReconstructOptions to_options(const Cli& cli);
// Reads the input files named on the command line; throws InputError naming file and line.
ReconstructInput read_input(const Cli& cli);
// --refined-camera-for's files, each with the index of its camera in `input.cameras`; UsageError
// for a prefix that is none of the cameras'.
std::vector<std::pair<std::string, std::size_t>> refined_camera_files(const Cli& cli, const ReconstructInput& input);
// Known poses from photomill's poses CSV (header image,qw,...) or COLMAP's images.txt, told apart
// by the first line that is not blank or a comment; lines receives each pose's line.
std::vector<Pose> read_known_poses(std::istream& in, const std::string& source, std::vector<std::size_t>* lines);

}  // namespace photomill::triangulate
