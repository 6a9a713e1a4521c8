// Data outline in parameter space: convex hull or occupancy-grid concave outline (outline.hpp).
#include "fitsurf/outline.hpp"

#include <algorithm>
#include <limits>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <unordered_map>

namespace photomill::fitsurf {
namespace {

double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Removes vertices closer than tol to the segment joining their neighbours (a convex polygon
// stays convex and only shrinks).
std::vector<Eigen::Vector2d> drop_flat_vertices(std::vector<Eigen::Vector2d> poly, double tol) {
  bool changed = true;
  while (changed && poly.size() > 3) {
    changed = false;
    for (std::size_t k = 0; k < poly.size() && poly.size() > 3; ++k) {
      const auto& prev = poly[(k + poly.size() - 1) % poly.size()];
      const auto& next = poly[(k + 1) % poly.size()];
      if (segment_distance(poly[k], prev, next) <= tol) {
        poly.erase(poly.begin() + static_cast<std::ptrdiff_t>(k));
        changed = true;
      }
    }
  }
  return poly;
}

// Douglas-Peucker on the open chain poly[first..last] (indices modulo n), marking kept vertices.
void douglas_peucker(const std::vector<Eigen::Vector2d>& poly, std::size_t first, std::size_t last, double tol,
                     std::vector<bool>& keep) {
  const std::size_t n = poly.size();
  double worst = -1;
  std::size_t worst_k = first;
  for (std::size_t k = (first + 1) % n; k != last; k = (k + 1) % n) {
    const double d = segment_distance(poly[k], poly[first], poly[last]);
    if (d > worst) {
      worst = d;
      worst_k = k;
    }
  }
  if (worst > tol) {
    keep[worst_k] = true;
    douglas_peucker(poly, first, worst_k, tol, keep);
    douglas_peucker(poly, worst_k, last, tol, keep);
  }
}

std::vector<Eigen::Vector2d> simplify_closed(const std::vector<Eigen::Vector2d>& poly, double tol) {
  const std::size_t n = poly.size();
  if (n <= 4 || tol <= 0) return poly;
  // Split the ring at vertex 0 and the vertex farthest from it.
  std::size_t far = 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((poly[k] - poly[0]).squaredNorm() > (poly[far] - poly[0]).squaredNorm()) far = k;
  }
  std::vector<bool> keep(n, false);
  keep[0] = keep[far] = true;
  douglas_peucker(poly, 0, far, tol, keep);
  douglas_peucker(poly, far, 0, tol, keep);
  std::vector<Eigen::Vector2d> out;
  for (std::size_t k = 0; k < n; ++k) {
    if (keep[k]) out.push_back(poly[k]);
  }
  return out;
}

// Removes repeated and collinear consecutive vertices.
std::vector<Eigen::Vector2d> clean(const std::vector<Eigen::Vector2d>& poly) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& x : poly) {
    if (out.empty() || (x - out.back()).norm() > 1e-12) out.push_back(x);
  }
  while (out.size() > 1 && (out.front() - out.back()).norm() <= 1e-12) out.pop_back();
  bool changed = true;
  while (changed && out.size() > 3) {
    changed = false;
    for (std::size_t k = 0; k < out.size() && out.size() > 3; ++k) {
      const auto& a = out[(k + out.size() - 1) % out.size()];
      const auto& b = out[(k + 1) % out.size()];
      if (std::abs(cross(a, out[k], b)) <= 1e-12 * std::max(1.0, (b - a).squaredNorm())) {
        out.erase(out.begin() + static_cast<std::ptrdiff_t>(k));
        changed = true;
      }
    }
  }
  return out;
}

// The border of the filled cells of a binary grid (w x h, row-major, no filled cell on the grid's
// edge), as a counter-clockwise polygon on the corner lattice. Requires one 4-connected region
// without holes or diagonal-only contacts, so every border corner has one outgoing edge.
std::vector<Eigen::Vector2d> trace_border(const std::vector<std::uint8_t>& grid, int w, int h) {
  auto filled = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < w && y < h && grid[static_cast<std::size_t>(y) * w + x] != 0;
  };
  auto key = [&](int cx, int cy) { return static_cast<std::int64_t>(cy) * (w + 1) + cx; };
  std::unordered_map<std::int64_t, std::int64_t> next;
  std::int64_t start = -1;
  auto edge = [&](int x0, int y0, int x1, int y1) {
    next[key(x0, y0)] = key(x1, y1);
    if (start < 0) start = key(x0, y0);
  };
  // Interior on the left of each directed edge.
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!filled(x, y)) continue;
      if (!filled(x, y - 1)) edge(x, y, x + 1, y);
      if (!filled(x + 1, y)) edge(x + 1, y, x + 1, y + 1);
      if (!filled(x, y + 1)) edge(x + 1, y + 1, x, y + 1);
      if (!filled(x - 1, y)) edge(x, y + 1, x, y);
    }
  }
  std::vector<Eigen::Vector2d> poly;
  if (start < 0) return poly;
  std::int64_t k = start;
  do {
    poly.emplace_back(static_cast<double>(k % (w + 1)), static_cast<double>(k / (w + 1)));
    const auto it = next.find(k);
    if (it == next.end()) throw std::logic_error("trace_border: open border");
    k = it->second;
  } while (k != start && poly.size() <= next.size());
  return poly;
}

// Fills the empty cells not reachable from the grid's edge through empty cells (4-connected).
void fill_holes(std::vector<std::uint8_t>& g, int w, int h) {
  std::vector<std::uint8_t> outside(g.size(), 0);
  std::vector<int> stack;
  auto push = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    const std::size_t i = static_cast<std::size_t>(y) * w + x;
    if (g[i] || outside[i]) return;
    outside[i] = 1;
    stack.push_back(static_cast<int>(i));
  };
  for (int x = 0; x < w; ++x) {
    push(x, 0);
    push(x, h - 1);
  }
  for (int y = 0; y < h; ++y) {
    push(0, y);
    push(w - 1, y);
  }
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    const int x = i % w, y = i / w;
    push(x + 1, y);
    push(x - 1, y);
    push(x, y + 1);
    push(x, y - 1);
  }
  for (std::size_t i = 0; i < g.size(); ++i) g[i] = outside[i] ? 0 : 1;
}

// Keeps the largest 4-connected filled region.
void keep_largest_region(std::vector<std::uint8_t>& g, int w, int h) {
  std::vector<int> label(g.size(), -1);
  int best = -1;
  std::size_t best_size = 0;
  int next_label = 0;
  std::vector<int> stack;
  for (std::size_t s = 0; s < g.size(); ++s) {
    if (!g[s] || label[s] >= 0) continue;
    std::size_t size = 0;
    stack.push_back(static_cast<int>(s));
    label[s] = next_label;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      ++size;
      const int x = i % w, y = i / w;
      const int nb[4][2] = {{x + 1, y}, {x - 1, y}, {x, y + 1}, {x, y - 1}};
      for (const auto& c : nb) {
        if (c[0] < 0 || c[1] < 0 || c[0] >= w || c[1] >= h) continue;
        const std::size_t j = static_cast<std::size_t>(c[1]) * w + c[0];
        if (g[j] && label[j] < 0) {
          label[j] = next_label;
          stack.push_back(static_cast<int>(j));
        }
      }
    }
    if (size > best_size) {
      best_size = size;
      best = next_label;
    }
    ++next_label;
  }
  for (std::size_t i = 0; i < g.size(); ++i) g[i] = label[i] == best ? 1 : 0;
}

// Fills the empty cells of every 2x2 block whose filled cells touch only diagonally; true if
// anything changed.
bool fill_diagonal_contacts(std::vector<std::uint8_t>& g, int w, int h) {
  bool changed = false;
  for (int y = 0; y + 1 < h; ++y) {
    for (int x = 0; x + 1 < w; ++x) {
      auto at = [&](int dx, int dy) -> std::uint8_t& { return g[static_cast<std::size_t>(y + dy) * w + x + dx]; };
      const bool a = at(0, 0), b = at(1, 0), c = at(0, 1), d = at(1, 1);
      if ((a && d && !b && !c) || (b && c && !a && !d)) {
        at(0, 0) = at(1, 0) = at(0, 1) = at(1, 1) = 1;
        changed = true;
      }
    }
  }
  return changed;
}

// Dilation (grow = true) or erosion by a (2r+1) x (2r+1) square; outside the grid counts as empty.
std::vector<std::uint8_t> morph(const std::vector<std::uint8_t>& g, int w, int h, int r, bool grow) {
  std::vector<std::uint8_t> out(g.size(), 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      bool any = false, all = true;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const int xx = x + dx, yy = y + dy;
          const bool f = xx >= 0 && yy >= 0 && xx < w && yy < h && g[static_cast<std::size_t>(yy) * w + xx];
          any = any || f;
          all = all && f;
        }
      }
      out[static_cast<std::size_t>(y) * w + x] = grow ? any : all;
    }
  }
  return out;
}

std::vector<Eigen::Vector2d> concave_outline(const std::vector<Eigen::Vector2d>& xy, double lu, double lv,
                                             double spacing, const OutlineOptions& o) {
  double cell = o.cell_mm > 0 ? o.cell_mm : o.cell_spacings * spacing;
  cell = std::max({cell, lu / o.max_cells, lv / o.max_cells});
  const int nx = std::max(1, static_cast<int>(std::ceil(lu / cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil(lv / cell)));
  const int margin = o.closing_cells + 1;
  const int w = nx + 2 * margin, h = ny + 2 * margin;
  std::vector<std::uint8_t> g(static_cast<std::size_t>(w) * h, 0);
  for (const auto& p : xy) {
    const int ix = std::clamp(static_cast<int>(std::floor(p.x() / cell)), 0, nx - 1) + margin;
    const int iy = std::clamp(static_cast<int>(std::floor(p.y() / cell)), 0, ny - 1) + margin;
    g[static_cast<std::size_t>(iy) * w + ix] = 1;
  }
  if (o.closing_cells > 0) g = morph(morph(g, w, h, o.closing_cells, true), w, h, o.closing_cells, false);
  fill_holes(g, w, h);
  keep_largest_region(g, w, h);
  while (fill_diagonal_contacts(g, w, h)) fill_holes(g, w, h);
  std::vector<Eigen::Vector2d> poly = trace_border(g, w, h);
  for (auto& c : poly) {
    c.x() = std::clamp((c.x() - margin) * cell, 0.0, lu);
    c.y() = std::clamp((c.y() - margin) * cell, 0.0, lv);
  }
  poly = clean(poly);
  // Douglas-Peucker may, rarely, make the polygon cross itself: then simplify less.
  for (double tol = o.simplify_mm > 0 ? o.simplify_mm : cell; tol > 1e-3 * cell; tol *= 0.5) {
    auto simple = clean(simplify_closed(poly, tol));
    if (simple.size() >= 3 && is_simple_polygon(simple) && signed_area(simple) > 0) return simple;
  }
  return poly;
}

}  // namespace

std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> pts) {
  std::sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  if (pts.size() < 3) return pts;
  std::vector<Eigen::Vector2d> hull(2 * pts.size());
  std::size_t k = 0;
  for (const auto& p : pts) {  // lower hull
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, lower = k + 1; i-- > 0;) {  // upper hull
    while (k >= lower && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);
  return hull;
}

double signed_area(const std::vector<Eigen::Vector2d>& poly) {
  double a = 0;
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const auto& p = poly[k];
    const auto& q = poly[(k + 1) % poly.size()];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * a;
}

bool point_in_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& x) {
  // Crossing number (even-odd rule).
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto& a = poly[i];
    const auto& b = poly[j];
    if ((a.y() > x.y()) != (b.y() > x.y()) && x.x() < (b.x() - a.x()) * (x.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

bool is_simple_polygon(const std::vector<Eigen::Vector2d>& poly) {
  const std::size_t n = poly.size();
  if (n < 3) return false;
  auto orient = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    const double v = cross(a, b, c);
    return v > 0 ? 1 : v < 0 ? -1 : 0;
  };
  auto on_segment = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    return std::min(a.x(), b.x()) <= c.x() && c.x() <= std::max(a.x(), b.x()) && std::min(a.y(), b.y()) <= c.y() &&
           c.y() <= std::max(a.y(), b.y());
  };
  for (std::size_t i = 0; i < n; ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % n];
    for (std::size_t j = i + 1; j < n; ++j) {
      if (j == i + 1 || (i == 0 && j == n - 1)) continue;  // neighbouring edges share a vertex
      const auto& c = poly[j];
      const auto& d = poly[(j + 1) % n];
      const int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
      if (o1 != o2 && o3 != o4) return false;
      if ((o1 == 0 && on_segment(a, b, c)) || (o2 == 0 && on_segment(a, b, d)) || (o3 == 0 && on_segment(c, d, a)) ||
          (o4 == 0 && on_segment(c, d, b))) {
        return false;
      }
    }
  }
  return true;
}

std::vector<Eigen::Vector2d> data_outline(const std::vector<Eigen::Vector2d>& uv, const std::vector<double>& weights,
                                          double lu, double lv, const OutlineOptions& o) {
  if (o.method == OutlineMethod::None) return {};
  std::vector<Eigen::Vector2d> xy;
  xy.reserve(uv.size());
  for (std::size_t k = 0; k < uv.size(); ++k) {
    if (weights.empty() || weights[k] > 0) xy.emplace_back(uv[k].x() * lu, uv[k].y() * lv);
  }
  std::vector<Eigen::Vector2d> hull = convex_hull(xy);
  if (hull.size() < 3) return {};
  const double spacing = std::sqrt(signed_area(hull) / static_cast<double>(xy.size()));
  const bool concave = o.method == OutlineMethod::Concave ||
                       (o.method == OutlineMethod::Auto && xy.size() >= o.concave_min_points);
  std::vector<Eigen::Vector2d> poly =
      concave ? concave_outline(xy, lu, lv, spacing, o)
              : drop_flat_vertices(hull, o.simplify_mm > 0 ? o.simplify_mm : 0.5 * spacing);
  for (auto& p : poly) p = Eigen::Vector2d(std::clamp(p.x() / lu, 0.0, 1.0), std::clamp(p.y() / lv, 0.0, 1.0));
  return poly;
}

double segment_distance(const Eigen::Vector2d& x, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((x - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - x).norm();
}

double boundary_distance(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& x) {
  double d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < polygon.size(); ++i) d = std::min(d, segment_distance(x, polygon[i], polygon[(i + 1) % polygon.size()]));
  return d;
}

}  // namespace photomill::fitsurf
