// match's command line: options, reading the inputs (observations CSVs and .feat files, told
// apart by content; a folder of .feat files; camera and poses), and the summary on stderr.
#pragma once

#include <string>
#include <vector>

#include "formats/cli_fwd.hpp"
#include "match/match.hpp"

namespace photomill::match {

struct Cli {
  std::vector<std::string> inputs;  // observations CSVs and/or .feat files; "-" = stdin
  std::string features_dir;         // every *.feat in it
  std::string camera;
  std::vector<std::string> camera_for;  // PREFIX=FILE, one per camera
  std::string rig;                      // rig.yaml: its cameras by prefix
  std::string poses;
  std::string output = "-";
  bool no_mutual = false;
  std::string refine = "lsm";       // lsm | none
  LsmOptions lsm;
  std::string image_dir;            // where the images named in .feat files are (default: as named)
  MatchOptions options;
  std::string preset;               // --preset (formats/tool.hpp)
};

void add_options(CLI::App& app, Cli& cli);

// Reads everything the command line names. Throws InputError naming the file.
MatchInputs read_inputs(Cli& cli);

// The summary on stderr (pairs, inliers per pair, dropped observations, track lengths); with -v
// one line per pair and every dropped observation.
void report(const MatchResult& result, const Cli& cli);
// Throws InputError naming the inputs and the cause when the result holds no track: a tracks
// file with only its header is no answer (issue #25), and triangulate would blame it instead.
void require_tracks(const MatchResult& result, const Cli& cli);

}  // namespace photomill::match
