// match: correspondences between images: observations to tracks.
// Not built yet (issue #5): only --help and --version work; running it says so and exits 1.
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  return photomill::tool::run(
      argc, argv,
      {"match", "correspondences between images: observations to tracks (not built yet, issue #5)", "match --help"},
      [&](CLI::App& app) { app.add_option("inputs", inputs, "Input files ('-' for stdin)"); },
      [] { throw std::runtime_error("this stage is not built yet (issue #5); no output written"); });
}
