// triangulate: camera poses, 3D points and bundle adjustment.
// Not built yet (issue #6): only --help and --version work; running it says so and exits 1.
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  return photomill::tool::run(
      argc, argv,
      {"triangulate", "camera poses, 3D points and bundle adjustment (not built yet, issue #6)", "triangulate --help"},
      [&](CLI::App& app) { app.add_option("inputs", inputs, "Input files ('-' for stdin)"); },
      [] { throw std::runtime_error("this stage is not built yet (issue #6); no output written"); });
}
