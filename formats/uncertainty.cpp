#include "formats/uncertainty.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "formats/csv.hpp"
#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"

namespace photomill {
namespace {

// The index of node coordinate v on the axis x0 + i step, or -1 when v is not on it.
long node_index(double v, double x0, double step, std::size_t n) {
  if (n == 1) return v == x0 ? 0 : -1;
  const double f = (v - x0) / step;
  const double i = std::round(f);
  if (!(std::abs(f - i) <= 1e-6) || i < 0 || i >= static_cast<double>(n)) return -1;
  return static_cast<long>(i);
}

}  // namespace

double UncertaintyGrid::sample(double x_mm, double y_mm) const {
  if (nx == 0 || ny == 0) return 0;
  const auto coord = [&](double v, double v0, std::size_t n, std::size_t& i, double& t) {
    double f = (v - v0) / step_mm;
    if (!(f > 0)) f = 0;  // NaN too
    const double last = static_cast<double>(n - 1);
    if (f >= last) f = last;
    i = std::min(static_cast<std::size_t>(f), n > 1 ? n - 2 : 0);
    t = n > 1 ? f - static_cast<double>(i) : 0;
  };
  std::size_t i = 0, j = 0;
  double tx = 0, ty = 0;
  coord(x_mm, x0_mm, nx, i, tx);
  coord(y_mm, y0_mm, ny, j, ty);
  const std::size_t i1 = std::min(i + 1, nx - 1), j1 = std::min(j + 1, ny - 1);
  return (1 - ty) * ((1 - tx) * at(i, j) + tx * at(i1, j)) + ty * ((1 - tx) * at(i, j1) + tx * at(i1, j1));
}

double UncertaintyGrid::max_within(double x_mm, double y_mm, double radius_mm) const {
  if (nx == 0 || ny == 0) return 0;
  const auto range = [&](double v, double v0, std::size_t n, std::size_t& lo, std::size_t& hi) {
    const double last = static_cast<double>(n - 1);
    const double a = std::clamp(std::floor((v - radius_mm - v0) / step_mm), 0.0, last);
    const double b = std::clamp(std::ceil((v + radius_mm - v0) / step_mm), 0.0, last);
    lo = static_cast<std::size_t>(a);
    hi = static_cast<std::size_t>(b);
  };
  std::size_t i0 = 0, i1 = 0, j0 = 0, j1 = 0;
  range(x_mm, x0_mm, nx, i0, i1);
  range(y_mm, y0_mm, ny, j0, j1);
  // The nodes of every cell the disk's bounding square touches: the bilinear field inside those
  // cells is at most their largest node, so this bounds the field over the disk from above.
  double m = sample(x_mm, y_mm);
  for (std::size_t j = j0; j <= j1; ++j) {
    for (std::size_t i = i0; i <= i1; ++i) m = std::max(m, at(i, j));
  }
  return m;
}

UncertaintyGrid read_uncertainty_grid(std::istream& in, const std::string& source) {
  CsvReader csv(in, source, {"x_mm", "y_mm", "sigma_mm"});
  struct Row {
    double x, y, s;
    std::size_t line;
  };
  std::vector<Row> rows;
  while (csv.next()) {
    const Row r{csv.number(0), csv.number(1), csv.number(2), csv.line_number()};
    if (!std::isfinite(r.x) || !std::isfinite(r.y) || std::abs(r.x) > 1e9 || std::abs(r.y) > 1e9) {
      csv.fail("x_mm and y_mm must be finite, within 1e9 mm");
    }
    if (!std::isfinite(r.s) || r.s < 0) csv.fail("sigma_mm must be finite and not negative");
    if (rows.size() >= kMaxUncertaintyNodes) csv.fail("more than " + std::to_string(kMaxUncertaintyNodes) + " nodes");
    rows.push_back(r);
  }
  if (rows.empty()) throw InputError(source, 0, "an uncertainty grid needs at least one node");
  std::vector<double> xs, ys;
  for (const Row& r : rows) xs.push_back(r.x), ys.push_back(r.y);
  for (auto* v : {&xs, &ys}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  UncertaintyGrid g;
  g.nx = xs.size();
  g.ny = ys.size();
  g.x0_mm = xs.front();
  g.y0_mm = ys.front();
  if (g.nx * g.ny != rows.size()) {  // nx, ny <= rows.size() <= 16e6: no overflow
    throw InputError(source, 0, std::to_string(rows.size()) + " nodes on " + std::to_string(g.nx) + " x values and " +
                                    std::to_string(g.ny) + " y values: the grid needs every node once (" +
                                    std::to_string(g.nx * g.ny) + ")");
  }
  const double sx = g.nx > 1 ? (xs.back() - xs.front()) / static_cast<double>(g.nx - 1) : 0;
  const double sy = g.ny > 1 ? (ys.back() - ys.front()) / static_cast<double>(g.ny - 1) : 0;
  g.step_mm = sx > 0 ? sx : sy > 0 ? sy : 1;
  if (sx > 0 && sy > 0 && std::abs(sx - sy) > 1e-6 * std::max(sx, sy)) {
    throw InputError(source, 0, "the node spacing along x (" + format_double(sx) + " mm) and along y (" +
                                    format_double(sy) + " mm) differ");
  }
  if (!(g.step_mm > 0) || !std::isfinite(g.step_mm)) throw InputError(source, 0, "the node spacing is not a positive length");
  g.sigma_mm.assign(rows.size(), -1);
  for (const Row& r : rows) {
    const long i = node_index(r.x, g.x0_mm, g.step_mm, g.nx), j = node_index(r.y, g.y0_mm, g.step_mm, g.ny);
    if (i < 0 || j < 0) {
      throw InputError(source, r.line, "node (" + format_double(r.x) + ", " + format_double(r.y) +
                                           ") is not on a regular grid of spacing " + format_double(g.step_mm) + " mm");
    }
    double& s = g.sigma_mm[static_cast<std::size_t>(j) * g.nx + static_cast<std::size_t>(i)];
    if (s >= 0) throw InputError(source, r.line, "node (" + format_double(r.x) + ", " + format_double(r.y) + ") given twice");
    s = r.s;
  }
  return g;
}

void write_uncertainty_grid(std::ostream& out, const UncertaintyGrid& g) {
  if (g.nx == 0 || g.ny == 0 || g.sigma_mm.size() != g.nx * g.ny) throw std::invalid_argument("uncertainty grid: sizes do not match");
  if (!(g.step_mm > 0) || !std::isfinite(g.step_mm) || !std::isfinite(g.x0_mm) || !std::isfinite(g.y0_mm)) {
    throw std::invalid_argument("uncertainty grid: origin and spacing must be finite, spacing positive");
  }
  out << stamp_line(g.sigma_mm.size());
  write_csv_row(out, {"x_mm", "y_mm", "sigma_mm"});
  for (std::size_t j = 0; j < g.ny; ++j) {
    const std::string y = format_double(g.y0_mm + static_cast<double>(j) * g.step_mm);
    for (std::size_t i = 0; i < g.nx; ++i) {
      const double s = g.at(i, j);
      if (!std::isfinite(s) || s < 0) throw std::invalid_argument("uncertainty grid: sigma must be finite and not negative");
      write_csv_row(out, {format_double(g.x0_mm + static_cast<double>(i) * g.step_mm), y, format_double(s)});
    }
  }
}

}  // namespace photomill
