#include "toolpath/cutsim.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/run.hpp"
#include "formats/error.hpp"
#include "formats/json.hpp"
#include "geometry/parallel.hpp"
#include "formats/plot.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

std::string f3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

// The material's top at the node nearest xy (-inf outside the grid).
double material_at(const HeightGrid& m, const Eigen::Vector2d& xy) {
  const long i = std::lround((xy.x() - m.lo.x()) / m.cell_mm), j = std::lround((xy.y() - m.lo.y()) / m.cell_mm);
  if (i < 0 || j < 0 || i >= m.nx || j >= m.ny) return -kInf;
  return m.z[static_cast<std::size_t>(j * m.nx + i)];
}

// The surface closed by the cutter (cutsim.hpp): E(x) = min_p max_q H(q) - f(|q-p|) + f(|x-p|).
std::vector<double> closing(const HeightGrid& part, const Cutter& c, int threads) {
  const long r = static_cast<long>(std::floor(c.radius_mm / part.cell_mm));
  struct Offset {
    long di, dj;
    double f;
  };
  std::vector<Offset> disk;
  for (long dj = -r; dj <= r; ++dj) {
    for (long di = -r; di <= r; ++di) {
      const double rho = part.cell_mm * std::hypot(static_cast<double>(di), static_cast<double>(dj));
      if (rho <= c.radius_mm) disk.push_back({di, dj, cutter_lift(c, rho)});
    }
  }
  const long nx = part.nx, ny = part.ny;
  const auto at = [&](long i, long j) { return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i); };
  // Off the surface H is unknown: the tip there is free (-inf), so it never holds E up.
  std::vector<double> tip(part.z.size(), -kInf), e(part.z.size(), kInf);
  geometry::parallel_for(static_cast<std::size_t>(ny), threads, [&](std::size_t jj) {
    const long j = static_cast<long>(jj);
    for (long i = 0; i < nx; ++i) {
      double t = -kInf;
      for (const Offset& o : disk) {
        const long a = i + o.di, b = j + o.dj;
        if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
        const double h = part.z[at(a, b)];
        if (std::isfinite(h)) t = std::max(t, h - o.f);
      }
      tip[at(i, j)] = t;
    }
  });
  geometry::parallel_for(static_cast<std::size_t>(ny), threads, [&](std::size_t jj) {
    const long j = static_cast<long>(jj);
    for (long i = 0; i < nx; ++i) {
      double best = kInf;
      for (const Offset& o : disk) {
        const long a = i + o.di, b = j + o.dj;
        if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
        const double t = tip[at(a, b)];
        if (t > -kInf) best = std::min(best, t + o.f);
      }
      e[at(i, j)] = best;
    }
  });
  return e;
}

// n_z of the surface's unit normal from central differences of H (one-sided at its edges).
double normal_z(const HeightGrid& h, long i, long j) {
  const auto z = [&](long a, long b) {
    return a < 0 || b < 0 || a >= h.nx || b >= h.ny ? kInf : h.z[static_cast<std::size_t>(b * h.nx + a)];
  };
  const auto slope = [&](double zm, double z0, double zp) {
    if (std::isfinite(zm) && std::isfinite(zp)) return (zp - zm) / (2 * h.cell_mm);
    if (std::isfinite(zp)) return (zp - z0) / h.cell_mm;
    if (std::isfinite(zm)) return (z0 - zm) / h.cell_mm;
    return 0.0;
  };
  const double z0 = z(i, j);
  const double zx = slope(z(i - 1, j), z0, z(i + 1, j)), zy = slope(z(i, j - 1), z0, z(i, j + 1));
  return 1.0 / std::sqrt(1 + zx * zx + zy * zy);
}

double p95(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto q = v.begin() + static_cast<long>(0.95 * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), q, v.end());
  return *q;
}

}  // namespace

CutsimResult simulate_cutting(const BSplineSurface& surface, const std::vector<CutsimProgram>& programs, const CutsimOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(o.cell_mm > 0) || !std::isfinite(o.cell_mm)) throw UsageError("--cell-mm must be > 0");
  if (!(o.allowance_mm >= 0) || !std::isfinite(o.allowance_mm)) throw UsageError("--allowance-mm must be >= 0");
  if (!(o.plunge_angle_deg > 0 && o.plunge_angle_deg <= 90)) throw UsageError("--plunge-angle-deg must be in (0, 90]");
  if (!(o.stock_margin_mm >= 0) || !std::isfinite(o.stock_margin_mm)) throw UsageError("--stock-margin-mm must be >= 0");
  if (programs.empty()) throw UsageError("no CL program to simulate");
  for (const CutsimProgram& p : programs) {
    if (!(p.cutter.radius_mm > 0) || !(p.cutter.corner_radius_mm >= 0 && p.cutter.corner_radius_mm <= p.cutter.radius_mm)) {
      throw UsageError(p.name + ": no cutter (no CUTTER or TLDATA record): give --tool-diameter-mm and --corner-radius-mm");
    }
  }
  const int threads = geometry::thread_count(o.threads);
  CutsimResult r;
  r.stock = o.stock ? *o.stock : default_stock_box(surface, o.stock_margin_mm, o.cell_mm, threads);
  const StockBox& s = r.stock;
  if (!s.min_mm.allFinite() || !s.max_mm.allFinite() || !(s.max_mm.array() > s.min_mm.array()).all()) {
    throw UsageError("--stock-box-mm: each maximum must be above its minimum");
  }
  r.cell_mm = o.cell_mm;
  HeightGrid& m = r.material;
  m.lo = s.min_mm.head<2>();
  m.cell_mm = o.cell_mm;
  const double nx = std::floor((s.max_mm.x() - s.min_mm.x()) / o.cell_mm) + 1, ny = std::floor((s.max_mm.y() - s.min_mm.y()) / o.cell_mm) + 1;
  if (nx * ny > 1e8) throw GeometryError("the z-map would have over 100 million nodes; use a larger --cell-mm");
  m.nx = static_cast<long>(nx), m.ny = static_cast<long>(ny);
  r.part = m;
  m.z.assign(static_cast<std::size_t>(m.nx * m.ny), s.max_mm.z());
  sample_surface_heights(surface, r.part, threads);

  // The programs in turn, move by move (faults are judged against the material of that moment).
  const double cot = 1 / std::tan(o.plunge_angle_deg * kPi / 180);
  for (const CutsimProgram& p : programs) {
    CutsimProgramFigures f;
    f.name = p.name;
    f.moves = p.cl.moves.size();
    for (std::size_t k = 1; k < p.cl.moves.size(); ++k) {
      const ClMove& mv = p.cl.moves[k];
      const Eigen::Vector3d& a = p.cl.moves[k - 1].tip_mm;
      const Eigen::Vector3d& b = mv.tip_mm;
      const double len = (b - a).norm();
      const bool rapid = mv.kind == ClMove::Kind::Rapid;
      if (rapid) {
        f.rapid_length_mm += len;
      } else {
        f.feed_length_mm += len;
        if (mv.feed_mm_per_min > 0) f.feed_time_min += len / mv.feed_mm_per_min;
      }
      // A plunge goes down steeply into material under the cutter's own axis (end cutting): the
      // material at the node nearest its end was above the end's tip before the move.
      const bool steep = !rapid && a.z() > b.z() && (b.head<2>() - a.head<2>()).norm() <= (a.z() - b.z()) * cot + 1e-9;
      const double under = steep ? material_at(m, b.head<2>()) : -kInf;
      Eigen::Vector2d at = Eigen::Vector2d::Zero();
      const double cut = cut_move_rows(m, a, b, p.cutter, 0, m.ny - 1, &at);
      if (cut <= o.tolerance_mm) continue;
      const bool plunge = steep && under > b.z() + o.tolerance_mm;
      if (!rapid && !plunge) continue;
      (rapid ? f.rapids_into_material : f.plunges) += 1;
      if (f.first_fault.empty()) {
        f.first_fault = std::string(rapid ? "rapid" : "plunge") + " move " + std::to_string(k + 1) + " to (" + f3(b.x()) + ", " +
                        f3(b.y()) + ", " + f3(b.z()) + ") cuts " + f3(cut) + " mm of material at (" + f3(at.x()) + ", " +
                        f3(at.y()) + ")";
      }
    }
    r.programs.push_back(f);
  }

  // What is left, against the surface and against the last cutter's reach.
  const std::vector<double> reach = closing(r.part, programs.back().cutter, threads);
  std::vector<double> left, left_reach;
  for (long j = 0; j < m.ny; ++j) {
    for (long i = 0; i < m.nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j * m.nx + i);
      const double h = r.part.z[k];
      if (!std::isfinite(h) || h > s.max_mm.z()) continue;
      ++r.nodes;
      const double nz = normal_z(r.part, i, j);
      const Eigen::Vector3d p(m.lo.x() + i * m.cell_mm, m.lo.y() + j * m.cell_mm, h);
      const double e = (m.z[k] - h) * nz - o.allowance_mm;
      left.push_back(std::max(0.0, e));
      if (e > r.max_left_mm) r.max_left_mm = e, r.max_left_at = p;
      const double g = (h - m.z[k]) * nz;
      if (g > r.max_gouge_mm) r.max_gouge_mm = g, r.max_gouge_at = p;
      const double floor_z = std::max(h, std::isfinite(reach[k]) ? reach[k] : h);
      if (floor_z > h + 1e-3) ++r.unreachable_nodes;
      const double er = (m.z[k] - floor_z) * nz - o.allowance_mm;
      left_reach.push_back(std::max(0.0, er));
      if (er > r.max_left_reachable_mm) r.max_left_reachable_mm = er, r.max_left_reachable_at = p;
    }
  }
  if (r.nodes == 0) throw GeometryError("the stock box does not overlap the surface");
  r.p95_left_mm = p95(left);
  r.p95_left_reachable_mm = p95(left_reach);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

std::vector<std::string> cutsim_summary(const CutsimResult& r) {
  std::vector<std::string> lines;
  for (const CutsimProgramFigures& f : r.programs) {
    lines.push_back(f.name + ": " + std::to_string(f.moves) + " moves, feed " + f3(f.feed_length_mm) + " mm (" + f3(f.feed_time_min) +
                    " min at feed), rapid " + f3(f.rapid_length_mm) + " mm, " + std::to_string(f.rapids_into_material) +
                    " rapids and " + std::to_string(f.plunges) + " plunges into material");
  }
  const auto at = [](const Eigen::Vector3d& p) {
    std::string s(1, '(');  // built by appending: GCC 12's -Wrestrict misfires on "(" + std::string&&
    s += f3(p.x());
    s += ", ";
    s += f3(p.y());
    s += ')';
    return s;
  };
  lines.push_back(f3(r.cell_mm) + " mm z-map, " + std::to_string(r.nodes) + " nodes over the surface: material left p95 " +
                  f3(r.p95_left_mm) + ", max " + f3(r.max_left_mm) + " mm at " + at(r.max_left_at) + "; deepest gouge " +
                  f3(r.max_gouge_mm) + " mm at " + at(r.max_gouge_at));
  lines.push_back("where the last cutter reaches (" + std::to_string(r.nodes - r.unreachable_nodes) + " nodes): left p95 " +
                  f3(r.p95_left_reachable_mm) + ", max " + f3(r.max_left_reachable_mm) + " mm at " + at(r.max_left_reachable_at) +
                  "; " + std::to_string(r.unreachable_nodes) + " nodes it cannot reach");
  return lines;
}

void write_cutsim_report(std::ostream& out, const CutsimResult& r, const CutsimOptions& o) {
  const auto xyz = [](JsonWriter& j, std::string_view key, const Eigen::Vector3d& p) {
    j.key(key).begin_array().value(p.x()).value(p.y()).value(p.z()).end_array();
  };
  JsonWriter j(out);
  j.begin_object();
  j.field("tool", "cutsim");
  j.field("run_id", run_id());
  j.field("version", PHOTOMILL_VERSION);
  j.key("options").begin_object();
  j.field("cell_mm", o.cell_mm);
  j.field("allowance_mm", o.allowance_mm);
  j.field("plunge_angle_deg", o.plunge_angle_deg);
  j.end_object();
  j.key("stock").begin_object();
  xyz(j, "min_mm", r.stock.min_mm);
  xyz(j, "max_mm", r.stock.max_mm);
  j.end_object();
  j.key("programs").begin_array();
  for (const CutsimProgramFigures& f : r.programs) {
    j.begin_object();
    j.field("name", f.name);
    j.field("moves", f.moves);
    j.field("feed_length_mm", f.feed_length_mm);
    j.field("rapid_length_mm", f.rapid_length_mm);
    j.field("feed_time_min", f.feed_time_min);
    j.field("rapids_into_material", f.rapids_into_material);
    j.field("plunges", f.plunges);
    j.field("first_fault", f.first_fault);
    j.end_object();
  }
  j.end_array();
  j.field("nodes", r.nodes);
  j.key("left").begin_object();
  j.field("p95_mm", r.p95_left_mm);
  j.field("max_mm", r.max_left_mm);
  xyz(j, "max_at", r.max_left_at);
  j.field("reachable_p95_mm", r.p95_left_reachable_mm);
  j.field("reachable_max_mm", r.max_left_reachable_mm);
  xyz(j, "reachable_max_at", r.max_left_reachable_at);
  j.field("unreachable_nodes", r.unreachable_nodes);
  j.end_object();
  j.key("gouge").begin_object();
  j.field("max_mm", r.max_gouge_mm);
  xyz(j, "at", r.max_gouge_at);
  j.end_object();
  j.field("seconds", r.seconds);
  j.end_object();
  out << '\n';
}

std::vector<unsigned char> render_cutsim_png(const CutsimResult& r, double allowance_mm) {
  const HeightGrid& m = r.material;
  const HeightGrid& h = r.part;
  const double w_mm = (m.nx - 1) * m.cell_mm, h_mm = (m.ny - 1) * m.cell_mm;
  const int plot_w = 800, plot_h = std::max(200, static_cast<int>(std::lround(plot_w * h_mm / std::max(w_mm, 1e-9))));
  cv::Mat img(plot_h + plot::kAxisBottomPx + plot::kAxisTopPx + 30, plot_w + plot::kAxisLeftPx + plot::kColourBarAreaPx + 20, CV_8UC3,
              cv::Scalar(255, 255, 255));
  plot::Axes ax;
  ax.plot = cv::Rect(plot::kAxisLeftPx, plot::kAxisTopPx + 30, plot_w, plot_h);
  ax.x0 = m.lo.x(), ax.x1 = m.lo.x() + w_mm, ax.y0 = m.lo.y(), ax.y1 = m.lo.y() + h_mm;
  ax.x_label = "x mm", ax.y_label = "y mm";
  const double top = std::max(r.p95_left_mm * 2, 0.02);
  for (int py = 0; py < plot_h; ++py) {
    for (int px = 0; px < plot_w; ++px) {
      const long i = std::clamp(static_cast<long>(std::lround(static_cast<double>(px) / (plot_w - 1) * (m.nx - 1))), 0L, m.nx - 1);
      const long j = std::clamp(static_cast<long>(std::lround(static_cast<double>(plot_h - 1 - py) / (plot_h - 1) * (m.ny - 1))), 0L, m.ny - 1);
      const std::size_t k = static_cast<std::size_t>(j * m.nx + i);
      cv::Scalar c(235, 235, 235);  // off the surface
      if (std::isfinite(h.z[k])) {
        const double e = m.z[k] - h.z[k] - allowance_mm;
        c = m.z[k] < h.z[k] - 1e-3 ? cv::Scalar(255, 0, 255) : plot::viridis(e / top);
      }
      img.at<cv::Vec3b>(ax.plot.y + py, ax.plot.x + px) = cv::Vec3b(static_cast<unsigned char>(c[0]), static_cast<unsigned char>(c[1]),
                                                                      static_cast<unsigned char>(c[2]));
    }
  }
  plot::draw_axes(img, ax);
  plot::text(img, "material left above the surface" + std::string(allowance_mm > 0 ? " + allowance" : "") +
                      " (vertical); magenta: gouge; grey: off the surface", {plot::kAxisLeftPx, 18});
  const plot::ColourBar bar{cv::Rect(ax.plot.x + plot_w + 20, ax.plot.y, 18, plot_h), 0, top, "left", "mm", {}, r.max_left_mm > top, false};
  plot::draw_colour_bar(img, bar);
  std::vector<unsigned char> png;
  cv::imencode(".png", img, png);
  return png;
}

}  // namespace photomill::toolpath
