// densify's command line: options, reading the inputs (sparse cloud, camera, poses, the photos,
// marker observations), and the summary on stderr.
#pragma once

#include <string>
#include <vector>

#include "densify/densify.hpp"
#include "formats/cli_fwd.hpp"

namespace photomill::densify {

struct Cli {
  std::string cloud;                // the sparse cloud (triangulate's cloud.ply); "-" = stdin
  std::string camera;
  std::string poses;
  std::string image_dir;            // the photos by file name in this folder (default: as poses.csv names them)
  std::vector<std::string> observations;  // marker corners (detect's observations CSV)
  std::vector<double> box;          // --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX
  std::string output = "-";
  DensifyOptions options;
};

void add_options(CLI::App& app, Cli& cli);

// Reads everything the command line names. Throws InputError naming the file and the problem.
DensifyInputs read_inputs(Cli& cli);

// The summary on stderr: per reference photo its neighbours, points and refusals (with -v every
// reason); the whole cloud's count, median sigma and views.
void report(const DensifyResult& result, const DensifyInputs& inputs);

}  // namespace photomill::densify
