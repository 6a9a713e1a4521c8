// fitsurf: least-squares B-spline surface from a point cloud.
// Not built yet (issue #7): only --help and --version work; running it says so and exits 1.
#include "formats/error.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  std::vector<std::string> inputs;
  return photomill::tool::run(
      argc, argv,
      {"fitsurf", "least-squares B-spline surface from a point cloud (not built yet, issue #7)", "fitsurf --help"},
      [&](CLI::App& app) { app.add_option("inputs", inputs, "Input files ('-' for stdin)"); },
      [] { throw std::runtime_error("this stage is not built yet (issue #7); no output written"); });
}
