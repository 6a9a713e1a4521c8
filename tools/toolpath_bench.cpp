// toolpath_bench: times generate_toolpath on the test surfaces (150 x 100 mm) and prints the
// figures the issue asks for: wall time (best and median of N runs) and the process CPU time of
// the best run (all threads), passes, CL points, feed path length. With --write-surfaces DIR it also writes the surfaces as photomill surface text,
// so scripts/bench-toolpath.sh can time the whole CLI. Figures go to stdout (this is a bench,
// not a pipeline stage).
#include <algorithm>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "formats/surface.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/toolpath.hpp"

using namespace photomill;
using namespace photomill::toolpath;

int main(int argc, char** argv) {
  int runs = 5, threads = 0;
  std::string write_dir;
  std::vector<std::string> names;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--runs" && k + 1 < argc) runs = std::max(1, std::atoi(argv[++k]));
    else if (a == "--threads" && k + 1 < argc) threads = std::atoi(argv[++k]);
    else if (a == "--write-surfaces" && k + 1 < argc) write_dir = argv[++k];
    else if (a == "--help") {
      std::printf("usage: toolpath_bench [--runs N] [--threads N] [--write-surfaces DIR] [bumps|wave|groove ...]\n");
      return 0;
    } else names.push_back(a);
  }
  if (names.empty()) names = {"bumps", "wave", "groove"};
  ToolpathOptions o;  // R = 3, h = 0.01, e = 0.005: the figures
  o.threads = threads;
  std::printf("# R = %g mm, h = %g mm, e = %g mm, gouge tol = %g mm, threads = %d (0 = all)\n", o.tool_radius_mm,
              o.scallop_mm, o.chord_tol_mm, o.gouge_tol_mm, threads);
  std::printf("%-8s %8s %8s %8s %8s %10s %12s %10s %10s %10s\n", "surface", "best_s", "median_s", "cpu_s", "passes",
              "cl_points", "feed_mm", "gouge_pts", "retracts", "rejected");
  for (const std::string& name : names) {
    const BSplineSurface s = test::named_surface(name);
    if (!write_dir.empty()) {
      std::ofstream out(write_dir + "/" + name + ".surf");
      write_surface(out, s);
    }
    std::vector<double> times;
    double best_cpu = 1e300;
    ToolpathResult r;
    for (int k = 0; k < runs; ++k) {
      const std::clock_t c0 = std::clock();
      r = generate_toolpath(s, o);
      const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
      if (times.empty() || r.stats.seconds < *std::min_element(times.begin(), times.end())) best_cpu = cpu;
      times.push_back(r.stats.seconds);
    }
    std::sort(times.begin(), times.end());
    std::printf("%-8s %8.3f %8.3f %8.3f %8zu %10zu %12.1f %10zu %10zu %10zu\n", name.c_str(), times.front(),
                times[times.size() / 2], best_cpu, r.stats.passes, r.stats.cl_points, r.stats.feed_length_mm,
                r.stats.gouge_points, r.stats.retracts, r.stats.rejected_steps);
  }
  return 0;
}
