// detect's marker and natural-feature modes: their command-line options and the run that reads
// images, writes the observations CSV (markers), one .feat file per image (features) and the
// markers' scale bars. Kept apart from main.cpp, which only reads the command line (the board
// modes run in board_cli.hpp).
#pragma once

#include <string>
#include <vector>

#include "detect/draw.hpp"
#include "detect/photos.hpp"
#include "formats/cli_fwd.hpp"

namespace photomill::detect {

struct PhotoCli {
  std::string aruco;             // predefined dictionary name
  std::string aruco_dict_file;   // or a dictionary file
  std::string refinement = "edges";
  std::string features_dir;      // write <dir>/<image file name>.feat
  std::string scale_bars;        // write the markers' sides as scale bars here
  std::string marker_ids;        // ... for these marker ids ("0-13,20")
  double marker_mm = 0;          // side of the markers (shared with the ChArUco option)
  PhotoOptions options;
  SiftOptions sift;
  DrawOptions draw;              // --draw DIR: pictures of what was found (every mode)
  std::string preset;            // --preset (formats/tool.hpp)
};

// Adds the options (groups "Markers", "Features" and "Drawings"; the drawing options serve the
// board modes too). `marker_mm` is registered by the caller.
void add_photo_options(CLI::App& app, PhotoCli& cli);

// True if the command line asks for markers or features.
bool photo_mode(const PhotoCli& cli);

// Runs detection on `images` and writes the outputs; `output` takes the observations CSV
// ("-": stdout; not written without markers). On failure no output file is left behind.
void run_photos(PhotoCli cli, const std::vector<std::string>& images, const std::string& output);

// "0-13,20,30-35" -> the ids; throws UsageError naming `option`.
std::vector<int> parse_id_ranges(const std::string& text, const std::string& option);

}  // namespace photomill::detect
