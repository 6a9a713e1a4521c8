// calib: camera calibration from boards and 3D control points.
// Not built yet (issue #4): only --help and --version work; running it says so and exits 1.
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  return photomill::tool::run(
      argc, argv,
      {"calib", "camera calibration from boards and 3D control points (not built yet, issue #4)", "calib --help"},
      [&](CLI::App& app) { app.add_option("inputs", inputs, "Input files ('-' for stdin)"); },
      [] { throw std::runtime_error("this stage is not built yet (issue #4); no output written"); });
}
