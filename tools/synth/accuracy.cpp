// synth_accuracy: runs photomill's pipeline on a synth scene and compares every stage with the
// truth, one line per figure on stdout ("name: value unit (bound B) ok|FAIL" or
// "name: not yet available (why)"). Exit 0 when every available figure is within its bound,
// 1 when one is not or a built stage fails (any exit status but 0, 2 included), 2 for bad usage.
// Stage command lines live in stages(): keep them the same as Makefile.example's.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "fitsurf/outline.hpp"
#include "formats/bspline.hpp"
#include "formats/camera.hpp"
#include "formats/error.hpp"
#include "formats/text.hpp"
#include "formats/cl_data.hpp"
#include "formats/log.hpp"
#include "formats/point_cloud.hpp"
#include "formats/surface.hpp"
#include "formats/tables.hpp"
#include "formats/tool.hpp"
#include "geometry/parallel.hpp"
#include "tests/run_tool.hpp"
#include "tools/synth/dataset.hpp"
#include "tools/synth/surface_distance.hpp"

namespace fs = std::filesystem;
using namespace photomill;

namespace {

// One pipeline stage: the executable and its arguments; "{set}" is the synth folder, "{work}"
// the folder for the pipeline's outputs. Each stage reads earlier outputs and writes its own.
struct Stage {
  std::string tool;
  std::vector<std::string> args;
  std::vector<std::string> needs;  // earlier stages whose outputs it reads
};

const std::map<std::string, Stage>& stages() {
  static const std::map<std::string, Stage> s = {
      {"detect-board",
       {"detect",
        {"{set}/board_*.jpg", "--charuco", "7x5", "--square-mm", "30", "--marker-mm", "22", "--dict", "DICT_5X5_100", "-o",
         "{work}/board_observations.csv"},
        {}}},
      {"calib",
       {"calib", {"{work}/board_observations.csv", "--charuco", "7x5", "--square-mm", "30", "-o", "{work}/camera.yaml"},
        {"detect-board"}}},
      // Makefile.example's chain (FEATURES=1): markers and SIFT features per photo; the marker
      // tracks give the poses; with them every pair is verified, and the features triangulated
      // with self-calibration; the part and a plate margin fitted.
      {"detect",
       {"detect",
        {"{set}/part_*.jpg", "--aruco", "DICT_4X4_100", "--features", "{work}/features", "--preset", "features", "-o",
         "{work}/observations.csv"},
        {}}},
      {"match-markers",
       {"match", {"{work}/observations.csv", "--camera", "{work}/camera.yaml", "-o", "{work}/marker_tracks.csv"},
        {"detect", "calib"}}},
      {"triangulate-markers",
       {"triangulate",
        {"{work}/marker_tracks.csv", "--camera", "{work}/camera.yaml", "--control-points", "{set}/control_points.csv",
         "--poses", "{work}/marker_poses.csv", "-o", "{work}/marker_cloud.ply"},
        {"match-markers"}}},
      {"match",
       {"match",
        {"{work}/observations.csv", "--features", "{work}/features", "--camera", "{work}/camera.yaml", "--poses",
         "{work}/marker_poses.csv", "--preset", "features", "-o", "{work}/tracks.csv"},
        {"triangulate-markers"}}},
      {"triangulate",
       {"triangulate",
        {"{work}/tracks.csv", "--camera", "{work}/camera.yaml", "--control-points", "{set}/control_points.csv",
         "--preset", "features", "--poses", "{work}/poses.csv", "-o", "{work}/cloud.ply"},
        {"calib", "match"}}},
      {"fitsurf",
       {"fitsurf",
        {"{work}/cloud.ply", "--keep-box", "-85,-60,-5,85,60,100", "--robust", "reject", "--net", "60x40", "--smoothing",
         "1", "-o", "{work}/surface.txt"},
        {"triangulate"}}},
      {"toolpath", {"toolpath", {"{work}/surface.txt", "--tool-radius-mm", "3", "-o", "{work}/path.cl"}, {"fitsurf"}}},
  };
  return s;
}

// Bounds the small scene must meet once a stage is built.
struct Bounds {
  double focal_percent = 0.2, principal_point_px = 2.0;
  double marker_rms_mm = 0.1, marker_max_mm = 0.3;
  double surface_rms_mm = 0.1, surface_max_mm = 0.5;
  double gouge_mm = 0.05, excess_p95_mm = 0.1, excess_mm = 0.5;
};

std::string expand(std::string s, const fs::path& set, const fs::path& work) {
  for (auto [key, value] : {std::pair<std::string, std::string>{"{set}", set.string()}, {"{work}", work.string()}}) {
    for (auto at = s.find(key); at != std::string::npos; at = s.find(key)) s.replace(at, key.size(), value);
  }
  return s;
}

// Glob "dir/prefix*.ext" without a shell.
std::vector<std::string> expand_glob(const std::string& pattern) {
  const auto star = pattern.find('*');
  if (star == std::string::npos) return {pattern};
  const fs::path p(pattern);
  const std::string name = p.filename().string();
  const auto s = name.find('*');
  const std::string head = name.substr(0, s), tail = name.substr(s + 1);
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(p.parent_path())) {
    const std::string f = e.path().filename().string();
    if (f.size() >= head.size() + tail.size() && f.compare(0, head.size(), head) == 0 &&
        f.compare(f.size() - tail.size(), tail.size(), tail) == 0) {
      out.push_back(e.path().string());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

struct Report {
  bool failed = false;
  // Figures known to be out of bounds (an open issue): printed FAIL (expected), not failing the
  // run; one of them within its bound fails the run instead, so the list cannot go stale.
  std::set<std::string> expected_failures;
  std::set<std::string> seen;
  void line(const std::string& name, double value, const std::string& unit, double bound) {
    const bool ok = std::isfinite(value) && value <= bound;
    const bool expected = expected_failures.count(name) > 0;
    seen.insert(name);
    failed = failed || (ok == expected);
    std::cout << name << ": " << format_double(value) << " " << unit << " (bound " << format_double(bound) << ") "
              << (ok ? (expected ? "ok, but expected to FAIL: drop --expect-fail" : "ok")
                     : (expected ? "FAIL (expected)" : "FAIL"))
              << "\n";
  }
  void missing(const std::string& name, const std::string& why) {
    std::cout << name << ": not yet available (" << why << ")\n";
  }
};

template <typename T, typename Reader>
T read(const fs::path& path, Reader reader) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), 0, "missing output");
  return reader(in, path.string());
}

// --- the figures -------------------------------------------------------------------------------
void calibration_figures(Report& r, const Camera& truth, const Camera& got, const Bounds& b) {
  const double focal = 100 * std::max(std::abs(got.fx() / truth.fx() - 1), std::abs(got.fy() / truth.fy() - 1));
  r.line("calibration focal length error", focal, "%", b.focal_percent);
  r.line("calibration principal point error", std::hypot(got.cx() - truth.cx(), got.cy() - truth.cy()), "px",
         b.principal_point_px);
}

// Marker corners are the cloud's points whose track_id is a marker-corner point id.
void marker_figures(Report& r, const std::map<PointId, Eigen::Vector3d>& truth, const PointCloud& got,
                    const Bounds& b) {
  double sum = 0, max = 0;
  std::size_t n = 0;
  const PointProperty* ids = got.find("track_id");
  for (std::size_t k = 0; ids != nullptr && k < got.points_mm.size(); ++k) {
    const auto it = truth.find(static_cast<PointId>(ids->values[k]));
    if (it == truth.end()) continue;
    const double e = (got.points_mm[k] - it->second).norm();
    sum += e * e;
    max = std::max(max, e);
    ++n;
  }
  r.line("marker corner 3D error RMS", n ? std::sqrt(sum / n) : NAN, "mm", b.marker_rms_mm);
  r.line("marker corner 3D error max", n ? max : NAN, "mm", b.marker_max_mm);
}

// The part's top, where the surface and the material left are judged: inside a blended part's
// edge blend, more than synth::kWallMarginMm inside a walled part's walls.
double judged_margin(const synth::HeightField& h) { return h.walled() ? synth::kWallMarginMm : h.edge_blend_mm; }
bool on_judged_top(const synth::HeightField& h, double x, double y) {
  const double margin = judged_margin(h);
  return x >= h.x_min_mm + margin && x <= h.x_max_mm - margin && y >= h.y_min_mm + margin && y <= h.y_max_mm - margin;
}

// Vertical deviation of the fitted surface from the true one, over the part's top. The debug log
// splits it between the squares densify leaves unmeasured around the part markers (each marker
// grown by kMaskMarginSides of its side, densify's --marker-margin) and the rest of the top.
void surface_figures(Report& r, const synth::PartScene& scene, const BSplineSurface& s, const Bounds& b) {
  const synth::HeightField& h = scene.surface;
  constexpr double kMaskMarginSides = 0.34;
  const auto under_marker = [&](double x, double y) {
    for (const synth::Marker& m : scene.markers) {
      if (!m.on_part) continue;
      const double q = kMaskMarginSides * m.size_mm;
      if (x >= m.top_left_mm.x() - q && x <= m.top_left_mm.x() + m.size_mm + q && y >= m.top_left_mm.y() - m.size_mm - q &&
          y <= m.top_left_mm.y() + q)
        return true;
    }
    return false;
  };
  double split_sum[2] = {0, 0};
  std::size_t split_n[2] = {0, 0};
  const double u0 = s.knots_u[s.degree_u], u1 = s.knots_u[s.num_poles_u];
  const double v0 = s.knots_v[s.degree_v], v1 = s.knots_v[s.num_poles_v];
  double sum = 0, max = 0;
  Eigen::Vector3d at_max = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (int i = 0; i <= 100; ++i) {
    for (int j = 0; j <= 100; ++j) {
      const Eigen::Vector3d p = surface_point(s, u0 + (u1 - u0) * i / 100, v0 + (v1 - v0) * j / 100);
      if (!on_judged_top(h, p.x(), p.y())) continue;
      const double e = std::abs(p.z() - h.height_mm(p.x(), p.y()));
      sum += e * e;
      const int k = under_marker(p.x(), p.y()) ? 1 : 0;
      split_sum[k] += e * e;
      ++split_n[k];
      if (e > max) {
        max = e;
        at_max = p;
      }
      ++n;
    }
  }
  if (n) log::debug("surface deviation max at (" + format_double(at_max.x()) + ", " + format_double(at_max.y()) + ")");
  const auto rms = [&](int k) { return split_n[k] ? std::sqrt(split_sum[k] / static_cast<double>(split_n[k])) : NAN; };
  if (n)
    log::debug("surface deviation RMS under the part markers' masked squares: " + format_double(rms(1)) + " mm (" +
               std::to_string(split_n[1]) + " of " + std::to_string(n) + " samples); elsewhere: " + format_double(rms(0)) + " mm");
  if (h.walled()) {
    // Within the margin of the walls (not judged): the worst deviation there, inside the fit's outline.
    double edge_max = 0, band_max[4] = {0, 0, 0, 0};
    Eigen::Vector3d edge_at = Eigen::Vector3d::Zero();
    for (int i = 0; i <= 400; ++i) {
      for (int j = 0; j <= 400; ++j) {
        const double u = u0 + (u1 - u0) * i / 400, v = v0 + (v1 - v0) * j / 400;
        if (!s.boundary_uv.empty() && !fitsurf::point_in_polygon(s.boundary_uv, {u, v})) continue;
        const Eigen::Vector3d p = surface_point(s, u, v);
        if (!h.contains(p.x(), p.y())) continue;
        const double e = std::abs(p.z() - h.height_mm(p.x(), p.y()));
        const double inset = std::min({p.x() - h.x_min_mm, h.x_max_mm - p.x(), p.y() - h.y_min_mm, h.y_max_mm - p.y()});
        const int band = std::min(3, static_cast<int>(inset / 0.5));
        band_max[band] = std::max(band_max[band], e);
        if (e > edge_max) {
          edge_max = e;
          edge_at = p;
        }
      }
    }
    log::debug("surface deviation max inside the outline, up to the walls: " + format_double(edge_max) + " mm at (" +
               format_double(edge_at.x()) + ", " + format_double(edge_at.y()) + "); within 0-0.5, 0.5-1, 1-1.5 mm of them and beyond: " +
               format_double(band_max[0]) + ", " + format_double(band_max[1]) + ", " + format_double(band_max[2]) + ", " +
               format_double(band_max[3]) + " mm");
  }
  r.line("surface deviation RMS", n ? std::sqrt(sum / n) : NAN, "mm", b.surface_rms_mm);
  r.line("surface deviation max", n ? max : NAN, "mm", b.surface_max_mm);
}

// Distance from c to the true part, the solid z <= h(x, y) (h = 0 on the plate around the part;
// a walled part's sides included): the least over the columns (x, y) of a 0.1 mm grid over
// |x - c.x|, |y - c.y| <= reach, and over the columns on a wall's line, of
//   sqrt((x - c.x)^2 + (y - c.y)^2 + max(0, c.z - h(x, y))^2),
// the distance from c to the column's nearest point. The grid can only overestimate the distance:
// by about t^2 / (2 R), t the offset of the nearest grid point along the surface (at most 0.07 mm
// times sqrt(1 + slope^2)), a few micrometres for R = 3 mm; a wall's line is sampled exactly.
double distance_to_truth(const synth::HeightField& h, const Eigen::Vector3d& c, double reach) {
  std::vector<double> xs, ys;
  for (double dx = -reach; dx <= reach; dx += 0.1) xs.push_back(c.x() + dx);
  for (double dy = -reach; dy <= reach; dy += 0.1) ys.push_back(c.y() + dy);
  if (h.walled()) {
    for (double x : {h.x_min_mm, h.x_max_mm}) {
      if (std::abs(x - c.x()) <= reach) xs.push_back(x);
    }
    for (double y : {h.y_min_mm, h.y_max_mm}) {
      if (std::abs(y - c.y()) <= reach) ys.push_back(y);
    }
  }
  auto column = [&](double x, double y) {
    const double above = std::max(0.0, c.z() - h.height_mm(x, y));
    return (x - c.x()) * (x - c.x()) + (y - c.y()) * (y - c.y()) + above * above;
  };
  // The column nearest c first; then a column whose horizontal distance alone reaches the least
  // found so far cannot lower it and is skipped (the same least, without evaluating h there).
  auto nearest = [](const std::vector<double>& v, double t) {
    return *std::min_element(v.begin(), v.end(), [t](double a, double b) { return std::abs(a - t) < std::abs(b - t); });
  };
  double d2 = column(nearest(xs, c.x()), nearest(ys, c.y()));
  for (double x : xs) {
    const double hx2 = (x - c.x()) * (x - c.x());
    if (hx2 >= d2) continue;
    for (double y : ys) {
      if (hx2 + (y - c.y()) * (y - c.y()) >= d2) continue;
      d2 = std::min(d2, column(x, y));
    }
  }
  return std::sqrt(d2);
}

// Issue 24: "no point of the photo cloud more than 1 mm from the truth reaches the fit: each is
// removed before fitsurf or reported as an outlier by it (--residuals)". Counts the cloud's
// points (control points left out) farther than kFarPointMm from the true surface, and of
// those the ones fitsurf's residual cloud (residuals.ply: the points it fitted, scalar_weight 0
// for an outlier) holds with a positive weight. -v lists each one that reached the fit.
constexpr double kFarPointMm = 1;

// The height a point over the part's top should have: h inside the part's rectangle and, on a
// walled part, the top at the wall (f at the rectangle's nearest point) up to kFarPointMm outside
// it; NaN beyond (the plate). A point on a wall's face is on the true surface but, for a fit of
// the top as a height field, as far off as it is under the rim: counted apart.
double top_height_mm(const synth::HeightField& h, double x, double y) {
  const double out_x = std::max({h.x_min_mm - x, x - h.x_max_mm, 0.0});
  const double out_y = std::max({h.y_min_mm - y, y - h.y_max_mm, 0.0});
  if (out_x == 0 && out_y == 0) return h.walled() ? h.wall_top_mm(x, y) : h.height_mm(x, y);
  if (h.walled() && std::hypot(out_x, out_y) <= kFarPointMm) return h.wall_top_mm(x, y);
  return NAN;
}

// --cloud-distances FILE: every point of the cloud (control points left out) with its distance
// to the true surface (exact up to synth::kPointReachMm, at least that beyond; below 0.01 mm the
// vertical distance, an upper bound) and its vertical offset
// from the top (top_height_mm; empty over the plate), for studying what reaches the fit.
void write_cloud_distances(const fs::path& file, const synth::HeightField& h, const PointCloud& cloud) {
  std::ofstream out(file);
  if (!out) throw InputError(file.string(), 0, "cannot write");
  out.precision(10);
  out << "track_id,x_mm,y_mm,z_mm,views,sigma_mm,distance_mm,top_offset_mm\n";
  const PointProperty* control = cloud.find("control");
  const PointProperty* views = cloud.find("views");
  const PointProperty* sigma = cloud.find("sigma_mm");
  const PointProperty* ids = cloud.find("track_id");
  for (std::size_t k = 0; k < cloud.points_mm.size(); ++k) {
    if (control && control->values[k] != 0) continue;
    const Eigen::Vector3d& p = cloud.points_mm[k];
    const double top = top_height_mm(h, p.x(), p.y());
    out << (ids ? ids->values[k] : NAN) << "," << p.x() << "," << p.y() << "," << p.z() << ","
        << (views ? views->values[k] : NAN) << "," << (sigma ? sigma->values[k] : NAN) << ","
        << synth::distance_to_surface(h, p, 0.01) << ",";
    if (std::isfinite(top)) out << p.z() - top;
    out << "\n";
  }
  if (!out) throw InputError(file.string(), 0, "write failed");
}

void cloud_figures(Report& r, const synth::HeightField& h, const PointCloud& cloud, const PointCloud* fitted) {
  auto far = [&](const PointCloud& pc, const PointProperty* weight, std::size_t& n, std::size_t& far_n, std::size_t& two_view_far) {
    const PointProperty* control = pc.find("control");
    const PointProperty* views = pc.find("views");
    const PointProperty* sigma = pc.find("sigma_mm");
    const PointProperty* ids = pc.find("track_id");
    for (std::size_t k = 0; k < pc.points_mm.size(); ++k) {
      if (control && control->values[k] != 0) continue;
      if (weight && !(weight->values[k] > 0)) continue;
      ++n;
      const double d = synth::distance_to_surface(h, pc.points_mm[k], kFarPointMm);
      if (!(d > kFarPointMm)) continue;
      ++far_n;
      if (views && views->values[k] == 2) ++two_view_far;
      if (weight) {
        const Eigen::Vector3d& p = pc.points_mm[k];
        log::debug("in the fit, " + format_double(d) + " mm (or more) from the true surface: track " +
                   (ids ? format_double(ids->values[k]) : std::string("?")) + " at (" + format_double(p.x()) + ", " +
                   format_double(p.y()) + ", " + format_double(p.z()) + "), " +
                   (views ? format_double(views->values[k]) : std::string("?")) + " views, sigma_mm " +
                   (sigma ? format_double(sigma->values[k]) : std::string("?")) + ", weight " +
                   format_double(weight->values[k]));
      }
    }
  };
  std::size_t n = 0, far_n = 0, two_view = 0;
  far(cloud, nullptr, n, far_n, two_view);
  log::info("cloud: " + std::to_string(far_n) + " of " + std::to_string(n) + " points more than " +
            format_double(kFarPointMm) + " mm from the true surface (" + std::to_string(two_view) + " of them two-view)");
  if (!fitted) {
    r.missing("cloud points over 1 mm off the truth in the fit", "no residuals.ply: run fitsurf with --residuals");
    return;
  }
  const PointProperty* weight = fitted->find("weight");
  if (!weight) {
    r.missing("cloud points over 1 mm off the truth in the fit", "residuals.ply has no weight property");
    return;
  }
  std::size_t fn = 0, ffar = 0, ftwo = 0;
  far(*fitted, weight, fn, ffar, ftwo);
  log::info("fit: " + std::to_string(ffar) + " of the " + std::to_string(fn) + " points fitsurf weighted more than " +
            format_double(kFarPointMm) + " mm from the true surface (" + std::to_string(ftwo) + " of them two-view)");
  std::size_t off_top = 0, off_top_two_view = 0;
  const PointProperty* views = fitted->find("views");
  for (std::size_t k = 0; k < fitted->points_mm.size(); ++k) {
    if (!(weight->values[k] > 0)) continue;
    const Eigen::Vector3d& p = fitted->points_mm[k];
    const double top = top_height_mm(h, p.x(), p.y());
    if (!(std::abs(p.z() - top) > kFarPointMm)) continue;
    ++off_top;
    if (views && views->values[k] == 2) ++off_top_two_view;
    log::debug("in the fit, " + format_double(p.z() - top) + " mm off the top vertically at (" + format_double(p.x()) +
               ", " + format_double(p.y()) + ", " + format_double(p.z()) + ")" +
               (views ? ", " + format_double(views->values[k]) + " views" : std::string()));
  }
  log::info("fit: " + std::to_string(off_top) + " of its points over the part's top (a walled part's up to " +
            format_double(kFarPointMm) + " mm beyond its walls) more than " + format_double(kFarPointMm) +
            " mm above or under it (" + std::to_string(off_top_two_view) + " of them two-view)");
  r.line("cloud points over 1 mm off the truth in the fit", static_cast<double>(ffar), "points", 0);
}

// Material left on the part's top by a ball end mill of radius R: a z-map (Anderson 1978, the
// "z-buffer" of CAM verification) on a kZmapCellMm grid over the judged top holds the lowest
// point of the ball over each cell, cz - sqrt(R^2 - d^2) for every ball centre within R in x, y;
// the centres are the feed moves' sampled every kZmapStepMm along each segment. Excess at a cell =
// that height - h (infinite where no ball passed). Returns the 0.95 quantile and the maximum.
constexpr double kZmapCellMm = 0.25, kZmapStepMm = 0.1;
std::pair<double, double> material_left(const synth::HeightField& h, const ClData& cl, double R,
                                        Eigen::Vector2d& at_max) {
  const double margin = judged_margin(h);
  const double x0 = h.x_min_mm + margin, y0 = h.y_min_mm + margin;
  const int nx = static_cast<int>((h.x_max_mm - margin - x0) / kZmapCellMm) + 1;
  const int ny = static_cast<int>((h.y_max_mm - margin - y0) / kZmapCellMm) + 1;
  if (nx <= 0 || ny <= 0) return {NAN, NAN};
  std::vector<double> low(static_cast<std::size_t>(nx) * ny, INFINITY);
  auto stamp = [&](const Eigen::Vector3d& c) {
    const int i0 = std::max(0, static_cast<int>(std::ceil((c.x() - R - x0) / kZmapCellMm)));
    const int i1 = std::min(nx - 1, static_cast<int>(std::floor((c.x() + R - x0) / kZmapCellMm)));
    const int j0 = std::max(0, static_cast<int>(std::ceil((c.y() - R - y0) / kZmapCellMm)));
    const int j1 = std::min(ny - 1, static_cast<int>(std::floor((c.y() + R - y0) / kZmapCellMm)));
    for (int j = j0; j <= j1; ++j) {
      const double dy = y0 + j * kZmapCellMm - c.y();
      for (int i = i0; i <= i1; ++i) {
        const double dx = x0 + i * kZmapCellMm - c.x();
        const double d2 = dx * dx + dy * dy;
        if (d2 > R * R) continue;
        double& z = low[static_cast<std::size_t>(j) * nx + i];
        z = std::min(z, c.z() - std::sqrt(R * R - d2));
      }
    }
  };
  std::optional<Eigen::Vector3d> previous;
  for (const ClMove& m : cl.moves) {
    const Eigen::Vector3d c = m.tip_mm + R * m.axis.value_or(Eigen::Vector3d::UnitZ());
    if (m.kind == ClMove::Kind::Feed && previous) {
      const int steps = std::max(1, static_cast<int>(std::ceil((c - *previous).norm() / kZmapStepMm)));
      for (int k = 1; k <= steps; ++k) stamp(*previous + (c - *previous) * (static_cast<double>(k) / steps));
    } else if (m.kind == ClMove::Kind::Feed) {
      stamp(c);
    }
    previous = c;
  }
  std::vector<double> excess;
  double max = -INFINITY;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double x = x0 + i * kZmapCellMm, y = y0 + j * kZmapCellMm;
      if (!on_judged_top(h, x, y)) continue;
      const double e = low[static_cast<std::size_t>(j) * nx + i] - h.height_mm(x, y);
      excess.push_back(e);
      if (e > max) {
        max = e;
        at_max = {x, y};
      }
    }
  }
  if (excess.empty()) return {NAN, NAN};
  const auto at = excess.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(excess.size() - 1));
  std::nth_element(excess.begin(), at, excess.end());
  return {*at, max};
}

// For each feed move the ball centre is tip + R axis; its distance d to the true part gives
// gouge R - d > 0. Every feed move over the plate counts, not only those over the part: a path
// that cuts into the plate around the part gouges too (the fitted surface's corners extrapolated
// below z = 0 did, by 0.85 mm, in the demo's scan chain). The material left over the part's top
// comes from the z-map (material_left).
void toolpath_figures(Report& r, const synth::PartScene& scene, const ClData& cl, const Bounds& b) {
  const synth::HeightField& h = scene.surface;
  const double R = cl.tool_diameter_mm / 2;
  // Each move's distance on all cores (the truth's evaluation is most of this tool's time); the
  // largest gouge is then taken in move order, so the figure and its place do not depend on them.
  std::vector<double> depth(cl.moves.size(), 0.0);
  geometry::parallel_for(cl.moves.size(), 0, [&](std::size_t k) {
    const ClMove& m = cl.moves[k];
    if (m.kind != ClMove::Kind::Feed || !(R > 0)) return;
    const Eigen::Vector3d c = m.tip_mm + R * m.axis.value_or(Eigen::Vector3d::UnitZ());
    if (c.x() < scene.plate_x_min_mm || c.x() > scene.plate_x_max_mm || c.y() < scene.plate_y_min_mm ||
        c.y() > scene.plate_y_max_mm) {
      return;
    }
    depth[k] = R - distance_to_truth(h, c, R + 1);
  });
  double gouge = 0;
  Eigen::Vector3d at_gouge = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < cl.moves.size(); ++k) {
    if (depth[k] > gouge) {
      gouge = depth[k];
      at_gouge = cl.moves[k].tip_mm;
    }
  }
  if (gouge > 0) {
    log::debug("tool path gouge max at tip (" + format_double(at_gouge.x()) + ", " + format_double(at_gouge.y()) + ", " +
               format_double(at_gouge.z()) + ")");
  }
  Eigen::Vector2d at_excess = Eigen::Vector2d::Zero();
  const auto [p95, max] = R > 0 ? material_left(h, cl, R, at_excess) : std::pair<double, double>{NAN, NAN};
  log::debug("tool path excess material max at (" + format_double(at_excess.x()) + ", " + format_double(at_excess.y()) + ")");
  r.line("tool path gouge max", gouge, "mm", b.gouge_mm);
  r.line("tool path excess material p95", p95, "mm", b.excess_p95_mm);
  r.line("tool path excess material max", max, "mm", b.excess_mm);
}

// Every figure that the outputs in `out` allow, against the truth in `set`; a stage listed in
// `unavailable` (or whose output file is missing) prints "not yet available".
void evaluate(const fs::path& set, const fs::path& out, std::map<std::string, std::string> unavailable,
              const Bounds& bounds, Report& report, const std::string& cloud_distances = "") {
  const synth::PartScene scene = read<synth::PartScene>(set / "scene.txt", synth::read_scene);
  auto why = [&](const std::string& stage, const fs::path& file) {
    if (unavailable.count(stage)) return unavailable[stage];
    return fs::exists(file) ? std::string() : "no " + file.string();
  };
  const auto camera = [](std::istream& in, const std::string& s) { return read_camera_yaml(in, s); };
  if (const auto w = why("calib", out / "camera.yaml"); !w.empty()) {
    report.missing("calibration focal length error", w);
    report.missing("calibration principal point error", w);
  } else {
    calibration_figures(report, read<Camera>(set / "camera.yaml", camera), read<Camera>(out / "camera.yaml", camera), bounds);
  }
  if (const auto w = why("triangulate", out / "cloud.ply"); !w.empty()) {
    report.missing("marker corner 3D error RMS", w);
    report.missing("marker corner 3D error max", w);
  } else {
    std::map<PointId, Eigen::Vector3d> truth;
    for (const bool part : {false, true}) {
      for (const ControlPoint& p : synth::marker_corners(scene, part)) truth[p.point_id] = p.xyz_mm;
    }
    marker_figures(report, truth,
                   read<PointCloud>(out / "cloud.ply", [](std::istream& in, const std::string& s) { return read_ply(in, s); }),
                   bounds);
  }
  if (const auto w = why("triangulate", out / "cloud.ply"); !w.empty()) {
    report.missing("cloud points over 1 mm off the truth in the fit", w);
  } else {
    const auto ply = [](std::istream& in, const std::string& s) { return read_ply(in, s); };
    const PointCloud cloud = read<PointCloud>(out / "cloud.ply", ply);
    std::optional<PointCloud> fitted;
    if (fs::exists(out / "residuals.ply")) fitted = read<PointCloud>(out / "residuals.ply", ply);
    cloud_figures(report, scene.surface, cloud, fitted ? &*fitted : nullptr);
    if (!cloud_distances.empty()) write_cloud_distances(cloud_distances, scene.surface, cloud);
  }
  if (const auto w = why("fitsurf", out / "surface.txt"); !w.empty()) {
    report.missing("surface deviation RMS", w);
    report.missing("surface deviation max", w);
  } else {
    surface_figures(report, scene, read<BSplineSurface>(out / "surface.txt", read_surface), bounds);
  }
  if (const auto w = why("toolpath", out / "path.cl"); !w.empty()) {
    report.missing("tool path gouge max", w);
    report.missing("tool path excess material p95", w);
    report.missing("tool path excess material max", w);
  } else {
    toolpath_figures(report, scene, read<ClData>(out / "path.cl", read_cl), bounds);
  }
}

const std::vector<std::string>& stage_order() {
  static const std::vector<std::string> order = {"detect-board",        "calib", "detect",      "match-markers",
                                                 "triangulate-markers", "match", "triangulate", "fitsurf",
                                                 "toolpath"};
  return order;
}

// Runs the stages in order on the scene in `set`, writing into `out`, up to and including
// `until` (empty: all); returns the stages that did not run and why.
std::map<std::string, std::string> run_pipeline(const std::string& bin_dir, const fs::path& set, const fs::path& out,
                                                const std::string& until, Report& report) {
  std::map<std::string, std::string> unavailable;  // stage -> why
  bool past_until = false;
  for (const std::string& name : stage_order()) {
    const Stage& st = stages().at(name);
    if (past_until) unavailable[name] = "not run (--until " + until + ")";
    past_until = past_until || name == until;
    for (const auto& need : st.needs) {
      if (unavailable.count(need)) unavailable[name] = unavailable[need];
    }
    if (unavailable.count(name)) continue;
    std::vector<std::string> args;
    for (const auto& a : st.args) {
      for (const auto& e : expand_glob(expand(a, set, out))) args.push_back(e);
    }
    const fs::path exe = fs::path(bin_dir) / st.tool;
    if (!fs::exists(exe)) {
      unavailable[name] = exe.string() + " is not in this build";
      continue;
    }
    const test::ToolResult res = test::run_tool(exe.string(), args);
    if (res.exit_code == 0) continue;
    if (res.err.find("not built yet") != std::string::npos) {
      unavailable[name] = st.tool + " not built yet";
    } else {
      // Every stage is built now, so exit 2 (bad usage) means the command line here and the
      // stage disagree: a failure, not a stage still to come.
      if (res.exit_code == 2) {
        std::cerr << "synth_accuracy: " << name << ": bad usage; update its command line in stages()\n";
      }
      unavailable[name] = name + " failed (exit " + std::to_string(res.exit_code) + ")";
      std::cerr << "synth_accuracy: " << name << " failed:\n" << res.err;
      report.failed = true;
    }
  }
  return unavailable;
}

}  // namespace

int main(int argc, char** argv) {
  std::string bin_dir = PHOTOMILL_BIN_DIR, work_dir, truth_dir, outputs_dir, until, cloud_distances;
  bool small = false;
  Bounds bounds;
  synth::SynthOptions scene_options;  // the scene --work-dir renders: shape, walls, seed
  std::vector<std::string> expect_fail;
  return tool::run(
      argc, argv,
      {"synth_accuracy", "run the pipeline on a synth scene and compare every stage with the truth",
       "synth_accuracy --small --work-dir /tmp/acc   |   synth_accuracy --truth data/demo --outputs out/demo"},
      [&](CLI::App& app) {
        app.add_option("--bin-dir", bin_dir, "Folder of the photomill executables")->capture_default_str();
        auto* work = app.add_option("--work-dir", work_dir,
                                    "Render a scene into DIR/set, run the pipeline into DIR/pipeline (both replaced)");
        app.add_flag("--small", small, "A small scene (800x600, 6 + 8 views) for ctest");
        app.add_option("--shape", scene_options.shape, "The part's shape (with --work-dir)")
            ->check(CLI::IsMember(synth::shape_names()))->capture_default_str()->needs(work);
        app.add_option("--edge-blend-mm", scene_options.edge_blend_mm,
                       "The ramp from the plate up to the part; 0: vertical walls (with --work-dir)")
            ->check(CLI::NonNegativeNumber)->capture_default_str()->needs(work);
        app.add_option("--seed", scene_options.seed, "Seed of the scene's random choices (with --work-dir)")
            ->capture_default_str()->needs(work);
        app.add_option("--until", until, "Run the stages up to this one only; later figures are reported as not run")
            ->check(CLI::IsMember(stage_order()))
            ->needs(work);
        auto* truth = app.add_option("--truth", truth_dir, "Evaluate existing outputs instead: the synth set with the truth");
        auto* outputs = app.add_option("--outputs", outputs_dir,
                                       "... and the folder with camera.yaml, cloud.ply, surface.txt, path.cl");
        app.add_option("--cloud-distances", cloud_distances,
                       "Write every cloud point's distance to the true surface and vertical offset from the top (CSV)");
        truth->needs(outputs);
        outputs->needs(truth);
        work->excludes(truth);
        app.add_option("--surface-rms-bound-mm", bounds.surface_rms_mm, "Bound on the surface deviation RMS, mm")
            ->capture_default_str()->check(CLI::PositiveNumber);
        app.add_option("--expect-fail", expect_fail,
                       "A figure known to be out of bounds (its name as printed, e.g. 'tool path gouge max'): "
                       "FAIL is expected, ok fails the run")
            ->take_last();
      },
      [&] {
        if (work_dir.empty() && truth_dir.empty()) throw UsageError("give --work-dir DIR, or --truth DIR --outputs DIR");
        Report report;
        report.expected_failures.insert(expect_fail.begin(), expect_fail.end());
        if (!truth_dir.empty()) {
          evaluate(truth_dir, outputs_dir, {}, bounds, report, cloud_distances);
        } else {
          const fs::path work = fs::absolute(work_dir), set = work / "set", out = work / "pipeline";
          // Only the two subfolders this tool owns are replaced, never the folder given.
          fs::remove_all(set);
          fs::remove_all(out);
          fs::create_directories(out);
          synth::SynthOptions o = scene_options;
          o.camera.image_width_px = small ? 800 : 2000;
          o.camera.image_height_px = small ? 600 : 1500;
          const double f = small ? 960 : 2400;
          o.camera.camera_matrix << f, 0, (o.camera.image_width_px - 1) / 2.0, 0, f,
              (o.camera.image_height_px - 1) / 2.0, 0, 0, 1;
          o.camera.distortion = {-0.08, 0.06, 0.0004, -0.0003, 0};
          o.views.count = small ? 6 : 12;
          o.calibration.count = small ? 8 : 10;
          o.render.noise_sigma = 1;
          o.surface_step_mm = 5;
          o.command_line = "synth_accuracy";
          synth::write_dataset(o, set.string());
          tool::publish_committed();  // the stages below read the data set
          evaluate(set, out, run_pipeline(bin_dir, set, out, until, report), bounds, report);
        }
        for (const auto& name : report.expected_failures) {
          if (!report.seen.count(name)) throw UsageError("--expect-fail '" + name + "': no figure of that name was evaluated");
        }
        if (report.failed) throw std::runtime_error("some figures are out of bounds or a stage failed");
      });
}
