// toolpath: ball-end finishing tool path (CL data) on a B-spline surface.
// Not built yet (issue #8): only --help and --version work; running it says so and exits 1.
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  return photomill::tool::run(
      argc, argv,
      {"toolpath", "ball-end finishing tool path (CL data) on a B-spline surface (not built yet, issue #8)", "toolpath --help"},
      [&](CLI::App& app) { app.add_option("inputs", inputs, "Input files ('-' for stdin)"); },
      [] { throw std::runtime_error("this stage is not built yet (issue #8); no output written"); });
}
