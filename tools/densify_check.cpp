// densify_check: a dense point cloud against a synth folder's true surface (benchmark support).
// Prints one "name value" line per figure on stdout: the points, those over the part's rectangle
// (the on-part points), their distance to the true surface (RMS, median, p95, max, how many over
// 1 mm) and signed vertical offset (mean), and the coverage of the part's rectangle, on a grid of
// --cell-mm cells and on a 5 mm grid, by on-part points within 0.5 mm of the truth, the cells
// under a part marker or its quiet zone left out. --distances writes each on-part point's figures;
// -v adds the mean signed offset by the true surface's curvature (stderr). The top_ figures are
// the same over the part's top alone: on a walled part, the rectangle less synth::kWallMarginMm along its
// walls (issue 24's "more than 2 mm in x, y from a wall's edge"); on a blended part, the whole
// rectangle.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/point_cloud.hpp"
#include "formats/text.hpp"
#include "formats/tool.hpp"
#include "geometry/parallel.hpp"
#include "tools/synth/scene.hpp"
#include "tools/synth/surface_distance.hpp"

using namespace photomill;

namespace {

// Below this vertical offset the distance to the truth is taken as the vertical offset (an upper
// bound, as synth_accuracy's --cloud-distances does); above it the surface is searched around.
constexpr double kVerticalWithinMm = 0.01;
// A point farther than this from the truth does not cover its cell; `over_1mm` counts those
// farther than kFarMm.
constexpr double kCoverMm = 0.5, kFarMm = 1;
// The coarse coverage grid's cell.
constexpr double kCoarseCellMm = 5;
// Grids with more cells than this are refused (a mistyped --cell-mm).
constexpr double kMaxCells = 1e8;

// An on-part point: where it is, its distance to the true surface and z minus the true height.
struct Judged {
  Eigen::Vector3d p;
  double distance_mm = 0, signed_mm = 0;
};

// The value as a figure: shortest round-trip text, "nan" when there is none (no on-part point).
std::string figure(double v) { return std::isfinite(v) ? format_double(v) : std::string("nan"); }

// Quantile q (0..1) of `values` by linear interpolation between the order statistics at
// (n - 1) q; NaN when empty. Reorders `values`.
double quantile(std::vector<double>& values, double q) {
  if (values.empty()) return NAN;
  const double at = q * static_cast<double>(values.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(at));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(lo), values.end());
  const double a = values[lo];
  if (lo + 1 >= values.size()) return a;
  const double b = *std::min_element(values.begin() + static_cast<std::ptrdiff_t>(lo) + 1, values.end());
  return a + (at - static_cast<double>(lo)) * (b - a);
}

// A rectangle of the plate plane (closed).
struct Box {
  double x0, x1, y0, y1;
  bool contains(double x, double y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

// The squares the part markers and their quiet zones cover: each marker square grown by
// quiet_zone_cells cells of size_mm / (bits + 2) on each side (how synth prints them).
std::vector<Box> part_marker_zones(const synth::PartScene& scene) {
  const int bits = synth::dictionary_bits(scene.dictionary);
  std::vector<Box> zones;
  for (const synth::Marker& m : scene.markers) {
    if (!m.on_part) continue;
    const double q = scene.quiet_zone_cells * m.size_mm / (bits + 2);
    zones.push_back({m.top_left_mm.x() - q, m.top_left_mm.x() + m.size_mm + q, m.top_left_mm.y() - m.size_mm - q,
                     m.top_left_mm.y() + q});
  }
  return zones;
}

struct Coverage {
  std::size_t considered = 0, covered = 0;
  double percent() const {
    return considered ? 100.0 * static_cast<double>(covered) / static_cast<double>(considered) : NAN;
  }
};

// (x, y) over the part's rectangle less `margin_mm` on every side (closed).
bool inside_rectangle(const synth::HeightField& h, double x, double y, double margin_mm) {
  return x >= h.x_min_mm + margin_mm && x <= h.x_max_mm - margin_mm && y >= h.y_min_mm + margin_mm && y <= h.y_max_mm - margin_mm;
}

// Coverage of the part's rectangle by the on-part points within kCoverMm of the truth: the
// rectangle cut into cells of `cell_mm` from its (x_min, y_min) corner (the last column and row
// narrower when the sides are not multiples of it), a point in the cell its (x, y) falls in (one
// on the far edges in the last); the cells whose centre (of the part inside the rectangle) lies in
// one of `excluded`, or within `margin_mm` of the rectangle's edge, are left out.
Coverage coverage(const synth::HeightField& h, const std::vector<Judged>& points, double cell_mm,
                  const std::vector<Box>& excluded, double margin_mm = 0) {
  const auto cells = [&](double length) {
    return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(length / cell_mm - 1e-9)));
  };
  const std::size_t nx = cells(h.x_max_mm - h.x_min_mm), ny = cells(h.y_max_mm - h.y_min_mm);
  const auto index = [&](double v, double v0, std::size_t n) {
    const double i = std::floor((v - v0) / cell_mm);
    return i <= 0 ? std::size_t{0} : std::min(n - 1, static_cast<std::size_t>(i));
  };
  std::vector<char> covered(nx * ny, 0);
  for (const Judged& j : points) {
    if (j.distance_mm <= kCoverMm) covered[index(j.p.y(), h.y_min_mm, ny) * nx + index(j.p.x(), h.x_min_mm, nx)] = 1;
  }
  Coverage c;
  for (std::size_t iy = 0; iy < ny; ++iy) {
    const double y0 = h.y_min_mm + static_cast<double>(iy) * cell_mm;
    const double cy = (y0 + std::min(h.y_max_mm, y0 + cell_mm)) / 2;
    for (std::size_t ix = 0; ix < nx; ++ix) {
      const double x0 = h.x_min_mm + static_cast<double>(ix) * cell_mm;
      const double cx = (x0 + std::min(h.x_max_mm, x0 + cell_mm)) / 2;
      if (std::any_of(excluded.begin(), excluded.end(), [&](const Box& b) { return b.contains(cx, cy); })) continue;
      if (!inside_rectangle(h, cx, cy, margin_mm)) continue;
      ++c.considered;
      c.covered += covered[iy * nx + ix] ? 1 : 0;
    }
  }
  return c;
}

// The mean signed offset of the on-part points by the true surface's Laplacian h_xx + h_yy
// (central second differences over kLaplacianStepMm) in bins of kLaplacianBinPerMm, printed with
// -v: a bias of the matching that follows the surface's curvature shows as a trend, e.g. points
// below the caps (Laplacian < 0) and above the bowls (docs/measurements/densify.md, session 66).
constexpr double kLaplacianStepMm = 0.05, kLaplacianBinPerMm = 0.05;
void log_offset_by_laplacian(const synth::HeightField& h, const std::vector<Judged>& on_part) {
  struct Bin {
    std::size_t n = 0;
    double sum = 0, sum_sq = 0;
  };
  std::map<long, Bin> bins;
  const double e = kLaplacianStepMm;
  for (const Judged& j : on_part) {
    const double x = j.p.x(), y = j.p.y();
    // Points within a step of the rectangle's edge straddle the wall or the blend's foot.
    if (x - e < h.x_min_mm || x + e > h.x_max_mm || y - e < h.y_min_mm || y + e > h.y_max_mm) continue;
    const double lap =
        (h.height_mm(x + e, y) + h.height_mm(x - e, y) + h.height_mm(x, y + e) + h.height_mm(x, y - e) - 4 * h.height_mm(x, y)) /
        (e * e);
    Bin& b = bins[std::lround(std::floor(lap / kLaplacianBinPerMm))];
    ++b.n;
    b.sum += j.signed_mm;
    b.sum_sq += j.signed_mm * j.signed_mm;
  }
  for (const auto& [k, b] : bins) {
    const double n = static_cast<double>(b.n);
    // (bin edges k / (1 / bin), exact in decimal for bins of 1/20; figures to 0.1 micrometre)
    const double per = std::round(1 / kLaplacianBinPerMm);
    auto um = [](double v) { return format_double(std::round(v * 1e4) / 1e4); };
    log::debug("Laplacian " + format_double(static_cast<double>(k) / per) + " to " + format_double(static_cast<double>(k + 1) / per) +
               " /mm: " + std::to_string(b.n) + " points, signed offset mean " + um(b.sum / n) + " mm, RMS " +
               um(std::sqrt(b.sum_sq / n)) + " mm");
  }
}

// The on-part points of `cloud` (x, y over the part's closed rectangle) with their distance to
// the true surface (synth::distance_to_surface: exact up to its reach, an upper bound beyond and
// below kVerticalWithinMm vertically) and z minus the true height, in the cloud's order.
std::vector<Judged> judge(const synth::HeightField& h, const PointCloud& cloud, int threads) {
  std::vector<Judged> on_part;
  for (const Eigen::Vector3d& p : cloud.points_mm) {
    if (p.x() >= h.x_min_mm && p.x() <= h.x_max_mm && p.y() >= h.y_min_mm && p.y() <= h.y_max_mm) {
      on_part.push_back({p, 0, 0});
    }
  }
  geometry::parallel_for(on_part.size(), threads, [&](std::size_t k) {
    Judged& j = on_part[k];
    j.distance_mm = synth::distance_to_surface(h, j.p, kVerticalWithinMm);
    j.signed_mm = j.p.z() - h.height_mm(j.p.x(), j.p.y());
  });
  return on_part;
}

// --distances FILE: "x_mm,y_mm,z_mm,distance_mm,signed_mm", one line per on-part point.
void write_distances(const std::string& path, const std::vector<Judged>& points) {
  tool::OutputFile out(path);
  std::ostream& s = out.stream();
  s << "x_mm,y_mm,z_mm,distance_mm,signed_mm\n";
  for (const Judged& j : points) {
    s << figure(j.p.x()) << "," << figure(j.p.y()) << "," << figure(j.p.z()) << "," << figure(j.distance_mm) << ","
      << figure(j.signed_mm) << "\n";
  }
  out.commit();
}

}  // namespace

int main(int argc, char** argv) {
  std::string truth_dir, cloud_path, distances_path;
  double cell_mm = 1;
  int threads = 0;
  return tool::run(
      argc, argv,
      {"densify_check", "judge a dense point cloud against a synth folder's true surface",
       "densify_check --truth data/demo dense.ply --cell-mm 1 --distances distances.csv"},
      [&](CLI::App& app) {
        app.add_option("cloud", cloud_path, "Point cloud PLY (mm, synth's world frame)")->required();
        app.add_option("--truth", truth_dir, "synth folder (scene.txt)")->required();
        app.add_option("--cell-mm", cell_mm, "Cell of the coverage grid over the part's rectangle")
            ->check(tool::positive_up_to(1000))
            ->capture_default_str();
        app.add_option("--distances", distances_path,
                       "Write x_mm,y_mm,z_mm,distance_mm,signed_mm of every on-part point (CSV)");
        app.add_option("--threads", threads, "Threads (0: all cores)")
            ->check(tool::non_negative_up_to(1024))
            ->capture_default_str();
      },
      [&] {
        if (distances_path == "-") throw UsageError("--distances: give a file; stdout carries the figures");
        const std::string scene_path = truth_dir + "/scene.txt";
        const synth::PartScene scene = synth::read_scene(*tool::open_input(scene_path), scene_path);
        const synth::HeightField& h = scene.surface;
        for (const double cell : {cell_mm, kCoarseCellMm}) {
          const double n = std::ceil((h.x_max_mm - h.x_min_mm) / cell) * std::ceil((h.y_max_mm - h.y_min_mm) / cell);
          if (n > kMaxCells) {
            throw UsageError("--cell-mm " + format_double(cell) + " makes " + format_double(n) +
                             " cells over the part; at most " + format_double(kMaxCells));
          }
        }
        const PointCloud cloud = read_ply(*tool::open_input(cloud_path), tool::source_name(cloud_path));

        const auto start = std::chrono::steady_clock::now();
        std::vector<Judged> on_part;
        {
          log::Step step("distances of the on-part points to the true surface");
          on_part = judge(h, cloud, threads);
        }
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        log::info(std::to_string(cloud.points_mm.size()) + " points, " + std::to_string(on_part.size()) +
                  " over the part's rectangle; their distances to the true surface in " +
                  format_double(std::round(seconds * 1000) / 1000) + " s");

        std::vector<double> distances;
        distances.reserve(on_part.size());
        double sum_sq = 0, sum_signed = 0, max = on_part.empty() ? NAN : 0;
        std::size_t far = 0;
        for (const Judged& j : on_part) {
          distances.push_back(j.distance_mm);
          sum_sq += j.distance_mm * j.distance_mm;
          sum_signed += j.signed_mm;
          max = std::max(max, j.distance_mm);
          far += j.distance_mm > kFarMm ? 1 : 0;
        }
        const double n = static_cast<double>(on_part.size());
        const double rms = on_part.empty() ? NAN : std::sqrt(sum_sq / n);
        const double mean_signed = on_part.empty() ? NAN : sum_signed / n;
        const double median = quantile(distances, 0.5), p95 = quantile(distances, 0.95);

        // The part's top alone.
        const double top_margin_mm = h.walled() ? synth::kWallMarginMm : 0;
        std::vector<double> top_distances;
        double top_sum_sq = 0;
        for (const Judged& j : on_part) {
          if (!inside_rectangle(h, j.p.x(), j.p.y(), top_margin_mm)) continue;
          top_distances.push_back(j.distance_mm);
          top_sum_sq += j.distance_mm * j.distance_mm;
        }
        const double top_rms = top_distances.empty() ? NAN : std::sqrt(top_sum_sq / static_cast<double>(top_distances.size()));
        const double top_median = quantile(top_distances, 0.5);

        const std::vector<Box> zones = part_marker_zones(scene);
        const Coverage fine = coverage(h, on_part, cell_mm, zones);
        const Coverage coarse = coverage(h, on_part, kCoarseCellMm, zones);
        const Coverage top = coverage(h, on_part, cell_mm, zones, top_margin_mm);
        log::info("coverage: " + std::to_string(fine.covered) + " of " + std::to_string(fine.considered) +
                  " cells of " + format_double(cell_mm) + " mm hold a point within " + format_double(kCoverMm) +
                  " mm of the truth (" + std::to_string(zones.size()) + " part markers' quiet zones left out); " +
                  std::to_string(coarse.covered) + " of " + std::to_string(coarse.considered) + " cells of " +
                  format_double(kCoarseCellMm) + " mm");

        log_offset_by_laplacian(h, on_part);
        if (!distances_path.empty()) write_distances(distances_path, on_part);
        std::cout << "points_total " << cloud.points_mm.size() << "\n"
                  << "points_on_part " << on_part.size() << "\n"
                  << "rms_mm " << figure(rms) << "\n"
                  << "median_mm " << figure(median) << "\n"
                  << "p95_mm " << figure(p95) << "\n"
                  << "max_mm " << figure(max) << "\n"
                  << "mean_signed_mm " << figure(mean_signed) << "\n"
                  << "over_1mm " << far << "\n"
                  << "cells_considered " << fine.considered << "\n"
                  << "cells_covered " << fine.covered << "\n"
                  << "coverage_percent " << figure(fine.percent()) << "\n"
                  << "cells5_considered " << coarse.considered << "\n"
                  << "cells5_covered " << coarse.covered << "\n"
                  << "coverage5_percent " << figure(coarse.percent()) << "\n"
                  << "top_points " << top_distances.size() << "\n"
                  << "top_rms_mm " << figure(top_rms) << "\n"
                  << "top_median_mm " << figure(top_median) << "\n"
                  << "top_cells_considered " << top.considered << "\n"
                  << "top_cells_covered " << top.covered << "\n"
                  << "top_coverage_percent " << figure(top.percent()) << "\n";
      });
}
