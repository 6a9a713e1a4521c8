#include "toolpath/roughing.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <functional>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "geometry/parallel.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

std::string mm(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

// The grid: nodes lo + (i, j) cell, row by row.
struct Grid {
  Eigen::Vector2d lo = Eigen::Vector2d::Zero();
  double cell = 0;
  int nx = 0, ny = 0;
  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  Eigen::Vector2d xy(double i, double j) const { return lo + cell * Eigen::Vector2d(i, j); }
  std::size_t at(int i, int j) const { return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i); }
};

// The end mill's profile above its tip at distance rho from its axis (rho <= R).
double profile(double rho, double R, double rc) { return cutter_lift(Cutter{R, rc}, rho); }

// Step 1: the part's height at the nodes, the largest of each node and its 8 neighbours plus a
// curvature margin; off the surface the stock's bottom. A peak between nodes lies within
// d <= cell / sqrt(2) of a node and rises above it by at most |z''| d^2 / 2 <= |z''| cell^2 / 4
// (Taylor), |z''| taken as the largest second difference in x and y around the node.
std::vector<double> part_heights(const BSplineSurface& surface, const Grid& g, double bottom, int threads) {
  HeightGrid hg;
  hg.lo = g.lo, hg.cell_mm = g.cell, hg.nx = g.nx, hg.ny = g.ny;
  sample_surface_heights(surface, hg, threads);
  const auto z = [&](int i, int j) { return i < 0 || j < 0 || i >= g.nx || j >= g.ny ? -kInf : hg.z[g.at(i, j)]; };
  std::vector<double> d2(g.size(), 0.0);
  geometry::parallel_for(static_cast<std::size_t>(g.ny), threads, [&](std::size_t jj) {
    const int j = static_cast<int>(jj);
    for (int i = 0; i < g.nx; ++i) {
      const double c = z(i, j);
      if (!std::isfinite(c)) continue;
      double k = 0;
      for (const auto& [a, b] : {std::pair{z(i - 1, j), z(i + 1, j)}, std::pair{z(i, j - 1), z(i, j + 1)}}) {
        if (std::isfinite(a) && std::isfinite(b)) k = std::max(k, std::abs(a - 2 * c + b));
      }
      d2[g.at(i, j)] = k;  // |z''| cell^2
    }
  });
  std::vector<double> h(g.size(), bottom);
  geometry::parallel_for(static_cast<std::size_t>(g.ny), threads, [&](std::size_t jj) {
    const int j = static_cast<int>(jj);
    for (int i = 0; i < g.nx; ++i) {
      double best = -kInf, curv = 0;
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const double zn = z(i + di, j + dj);
          if (!std::isfinite(zn)) continue;
          best = std::max(best, zn);
          curv = std::max(curv, d2[g.at(i + di, j + dj)]);
        }
      }
      h[g.at(i, j)] = std::isfinite(best) ? std::max(bottom, best + 0.25 * curv) : bottom;
    }
  });
  return h;
}

// Step 2: the lowest tip height at every node, T(p) = max_q H(q) + allowance - f(|q - p|).
std::vector<double> tip_limits(const std::vector<double>& h, const Grid& g, double R, double rc, double allowance, int threads) {
  const int r = static_cast<int>(std::floor(R / g.cell));
  struct Offset {
    int di, dj;
    double lift;
  };
  std::vector<Offset> disk;
  for (int dj = -r; dj <= r; ++dj) {
    for (int di = -r; di <= r; ++di) {
      const double rho = g.cell * std::hypot(di, dj);
      if (rho <= R) disk.push_back({di, dj, profile(rho, R, rc)});
    }
  }
  std::vector<double> t(g.size(), -kInf);
  geometry::parallel_for(static_cast<std::size_t>(g.ny), threads, [&](std::size_t jj) {
    const int j = static_cast<int>(jj);
    for (int i = 0; i < g.nx; ++i) {
      double best = -kInf;
      for (const Offset& o : disk) {
        const int a = i + o.di, b = j + o.dj;
        if (a < 0 || b < 0 || a >= g.nx || b >= g.ny) continue;
        best = std::max(best, h[g.at(a, b)] - o.lift);
      }
      t[g.at(i, j)] = best + allowance;
    }
  });
  return t;
}

// The material's top at the nodes: the stock top inside the stock box, -inf outside; lowered by
// every cut.
class Material {
public:
  Material(const Grid& g, const StockBox& s, double R, double rc) : g_(g), R_(R), rc_(rc), top_(g.size(), -kInf) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const Eigen::Vector2d p = g.xy(i, j);
        if (p.x() >= s.min_mm.x() && p.x() <= s.max_mm.x() && p.y() >= s.min_mm.y() && p.y() <= s.max_mm.y()) top_[g.at(i, j)] = s.max_mm.z();
      }
    }
  }

  // The top lowered by an earlier program (zmap.hpp cut_material with its cutter).
  void cut_by(const ClData& cl, const Cutter& cutter, int threads) {
    HeightGrid grid;
    grid.lo = g_.lo;
    grid.cell_mm = g_.cell;
    grid.nx = g_.nx;
    grid.ny = g_.ny;
    grid.z = top_;
    cut_material(grid, cl, cutter, threads);
    top_ = std::move(grid.z);
  }
  const std::vector<double>& top() const { return top_; }

  // Highest material within R (and one cell) of the segment a-b (xy).
  double highest_near(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
    double best = -kInf;
    visit(a, b, R_ + g_.cell, [&](std::size_t k, double) { best = std::max(best, top_[k]); });
    return best;
  }

  // Lowers the material where the tool, its tip moving from a to b (the higher end counts),
  // passes.
  void cut(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double z = std::max(a.z(), b.z());
    visit(a.head<2>(), b.head<2>(), R_, [&](std::size_t k, double dist) {
      const double zc = z + profile(dist, R_, rc_);
      if (zc < top_[k]) top_[k] = zc;
    });
  }

private:
  // Calls fn(node, distance) for the nodes within `reach` of the segment a-b: row by row over
  // the x interval of the capsule (zmap.hpp capsule_row).
  template <class Fn>
  void visit(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double reach, Fn&& fn) const {
    const double ylo = std::min(a.y(), b.y()) - reach, yhi = std::max(a.y(), b.y()) + reach;
    const int j0 = std::max(0, static_cast<int>(std::ceil((ylo - g_.lo.y()) / g_.cell)));
    const int j1 = std::min(g_.ny - 1, static_cast<int>(std::floor((yhi - g_.lo.y()) / g_.cell)));
    const Eigen::Vector2d d = b - a;
    const double l2 = d.squaredNorm();
    for (int j = j0; j <= j1; ++j) {
      const double y = g_.lo.y() + j * g_.cell;
      double x0, x1;
      if (!capsule_row(a, b, reach, y, x0, x1)) continue;
      const int i0 = std::max(0, static_cast<int>(std::ceil((x0 - g_.lo.x()) / g_.cell)));
      const int i1 = std::min(g_.nx - 1, static_cast<int>(std::floor((x1 - g_.lo.x()) / g_.cell)));
      for (int i = i0; i <= i1; ++i) {
        const Eigen::Vector2d p = g_.xy(i, j);
        const double t = l2 > 0 ? std::clamp((p - a).dot(d) / l2, 0.0, 1.0) : 0.0;
        const double dist = (a + t * d - p).norm();
        if (dist <= reach) fn(g_.at(i, j), dist);
      }
    }
  }

  const Grid& g_;
  double R_, rc_;
  std::vector<double> top_;
};

struct Loop {
  std::vector<Eigen::Vector2d> pts;  // closed: the last point joins the first
  int component = 0;
  int offset_index = 0;  // j of d0 + j step-over
};

// The point of the closed loop nearest p: the segment (from pts[seg]) it lies on, and the point.
Eigen::Vector2d nearest_on_loop(const std::vector<Eigen::Vector2d>& pts, const Eigen::Vector2d& p, std::size_t& seg) {
  const std::size_t n = pts.size();
  double best = kInf;
  Eigen::Vector2d at = pts.front();
  seg = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d& a = pts[k];
    const Eigen::Vector2d d = pts[(k + 1) % n] - a;
    const double l2 = d.squaredNorm();
    const double t = l2 > 0 ? std::clamp((p - a).dot(d) / l2, 0.0, 1.0) : 0.0;
    const Eigen::Vector2d q = a + t * d;
    const double e = (q - p).squaredNorm();
    if (e < best) best = e, at = q, seg = k;
  }
  return at;
}

double loop_length(const Loop& l) {
  double s = 0;
  for (std::size_t k = 0; k < l.pts.size(); ++k) s += (l.pts[(k + 1) % l.pts.size()] - l.pts[k]).norm();
  return s;
}

// Step 4: the offset contours of one level, grouped by free component.
// `work` (rest machining; empty: everywhere): where the tool centre has material to cut.
std::vector<Loop> level_loops(const std::vector<double>& t, const Grid& g, double z, double d0, double step_over, double simplify,
                              MillingDirection dir, const cv::Mat& work, cv::Mat& dist_mm) {
  cv::Mat free(g.ny, g.nx, CV_8U);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const bool border = i == 0 || j == 0 || i == g.nx - 1 || j == g.ny - 1;
      const bool wanted = work.empty() || work.at<unsigned char>(j, i) != 0;
      free.at<unsigned char>(j, i) = !border && wanted && t[g.at(i, j)] <= z + 1e-9 ? 255 : 0;
    }
  }
  cv::Mat dist;
  cv::distanceTransform(free, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  dist_mm = dist * g.cell;
  cv::Mat labels;
  cv::connectedComponents(free, labels, 8, CV_32S);
  std::vector<Loop> loops;
  for (int k = 0;; ++k) {
    const double d = d0 + k * step_over;
    cv::Mat mask = dist_mm >= d;
    if (cv::countNonZero(mask) == 0) break;
    std::vector<std::vector<cv::Point>> contours;
    std::vector<cv::Vec4i> hierarchy;
    cv::findContours(mask, contours, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_NONE);
    for (std::size_t c = 0; c < contours.size(); ++c) {
      std::vector<cv::Point> simple;
      cv::approxPolyDP(contours[c], simple, simplify / g.cell, true);
      if (simple.empty()) continue;
      Loop l;
      l.offset_index = k;
      l.component = labels.at<int>(contours[c][0]);
      for (const cv::Point& p : simple) l.pts.push_back(g.xy(p.x, p.y));
      // Signed area (y up): > 0 counter-clockwise. Climb: free side on the left, so outer
      // boundaries counter-clockwise and holes clockwise.
      double area = 0;
      for (std::size_t q = 0; q < l.pts.size(); ++q) {
        const auto& p0 = l.pts[q];
        const auto& p1 = l.pts[(q + 1) % l.pts.size()];
        area += p0.x() * p1.y() - p1.x() * p0.y();
      }
      const bool hole = hierarchy[c][3] >= 0;
      bool want_ccw = !hole;
      if (dir == MillingDirection::Conventional) want_ccw = !want_ccw;
      if ((area > 0) != want_ccw && l.pts.size() > 2) std::reverse(l.pts.begin(), l.pts.end());
      loops.push_back(std::move(l));
    }
  }
  return loops;
}

// Writes the CL moves and keeps the figures.
class Writer {
public:
  Writer(RoughingResult& r, const RoughingOptions& o, double safe) : r_(r), o_(o), safe_(safe) {}

  const Eigen::Vector3d& pos() const { return pos_; }

  void rapid(const Eigen::Vector3d& p) {
    if (started_) r_.stats.rapid_length_mm += (p - pos_).norm();
    push({ClMove::Kind::Rapid, p, std::nullopt, 0});
  }
  void feed(const Eigen::Vector3d& p, double f) {
    if (!started_) throw GeometryError("roughing: a feed move before the first rapid");
    const double len = (p - pos_).norm();
    if (len < 1e-9) return;
    r_.stats.feed_length_mm += len;
    r_.stats.cycle_time_min += len / f;
    push({ClMove::Kind::Feed, p, std::nullopt, f});
  }
  void retract() {
    if (started_ && pos_.z() < safe_) rapid({pos_.x(), pos_.y(), safe_});
  }

private:
  void push(const ClMove& m) {
    if (r_.cl.moves.size() >= o_.max_moves) {
      throw GeometryError("roughing: more than " + std::to_string(o_.max_moves) +
                          " CL moves (the work limit, --max-moves): use a larger --cell-mm or step-over");
    }
    r_.cl.moves.push_back(m);
    pos_ = m.tip_mm;
    started_ = true;
  }
  RoughingResult& r_;
  const RoughingOptions& o_;
  double safe_;
  Eigen::Vector3d pos_ = Eigen::Vector3d::Zero();
  bool started_ = false;
};

// Step 5 and 6 for one level.
class LevelCutter {
public:
  LevelCutter(const Grid& g, const RoughingOptions& o, double R, double step_over, Material& material,
              Writer& w, RoughingStats& st)
      : g_(g), o_(o), R_(R), step_over_(step_over), material_(material), w_(w), st_(st) {}

  // Cuts the loops of one level. A loop waits for the loops one offset further in (larger D) that
  // lie within a step-over of it: those clear the material on its inner side. Among the loops
  // free to go, the one nearest the tool is next.
  void cut_level(const std::vector<Loop>& loops, const cv::Mat& dist_mm, double z) {
    dist_ = &dist_mm;
    const std::vector<std::vector<std::size_t>> outer = outer_neighbours(loops);
    std::vector<int> waits(loops.size(), 0);
    for (const auto& list : outer) {
      for (std::size_t a : list) ++waits[a];
    }
    std::vector<bool> done(loops.size(), false);
    bool at_level = false;
    for (std::size_t left = loops.size(); left > 0; --left) {
      std::size_t best = loops.size();
      double best_d = kInf;
      for (std::size_t k = 0; k < loops.size(); ++k) {
        if (done[k] || waits[k] > 0) continue;
        std::size_t seg = 0;
        const double d = (nearest_on_loop(loops[k].pts, w_.pos().head<2>(), seg) - w_.pos().head<2>()).squaredNorm();
        if (d < best_d) best_d = d, best = k;
      }
      if (best == loops.size()) throw GeometryError("roughing: the loops of a level wait on each other (a bug)");
      done[best] = true;
      at_level = cut_loop(loops[best], z, at_level);
      for (std::size_t a : outer[best]) --waits[a];
    }
  }

private:
  // For each loop, the loops one offset further out (offset index - 1) within a step-over and
  // three cells of it: found on a label grid of each offset's loops (drawn every half cell),
  // queried every quarter step-over along the loop.
  std::vector<std::vector<std::size_t>> outer_neighbours(const std::vector<Loop>& loops) const {
    std::vector<std::vector<std::size_t>> outer(loops.size());
    int top = -1;
    for (const Loop& l : loops) top = std::max(top, l.offset_index);
    cv::Mat labels(g_.ny, g_.nx, CV_32S, cv::Scalar(-1));
    double spacing = 0.5 * g_.cell;  // rasterising (below), then sparser for the queries
    const auto samples = [&](const Loop& l, auto&& fn) {
      const std::size_t n = l.pts.size();
      for (std::size_t q = 0; q < n; ++q) {
        const Eigen::Vector2d& a = l.pts[q];
        const Eigen::Vector2d& b = l.pts[(q + 1) % n];
        const int m = std::max(1, static_cast<int>(std::ceil((b - a).norm() / spacing)));
        for (int t = 0; t < m; ++t) {
          const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(t) / m);
          fn(static_cast<int>(std::lround((p.x() - g_.lo.x()) / g_.cell)), static_cast<int>(std::lround((p.y() - g_.lo.y()) / g_.cell)));
        }
      }
    };
    const double reach = step_over_ + 3 * g_.cell;
    const int w = static_cast<int>(std::ceil(reach / g_.cell));
    for (int k = 0; k < top; ++k) {
      labels.setTo(cv::Scalar(-1));
      spacing = 0.5 * g_.cell;
      for (std::size_t a = 0; a < loops.size(); ++a) {
        if (loops[a].offset_index != k) continue;
        samples(loops[a], [&](int i, int j) {
          if (i >= 0 && j >= 0 && i < g_.nx && j < g_.ny) labels.at<int>(j, i) = static_cast<int>(a);
        });
      }
      spacing = 0.25 * step_over_;
      for (std::size_t b = 0; b < loops.size(); ++b) {
        if (loops[b].offset_index != k + 1) continue;
        std::vector<std::size_t>& list = outer[b];
        samples(loops[b], [&](int i, int j) {
          for (int dj = -w; dj <= w; ++dj) {
            for (int di = -w; di <= w; ++di) {
              const int x = i + di, y = j + dj;
              if (x < 0 || y < 0 || x >= g_.nx || y >= g_.ny || di * di + dj * dj > w * w) continue;
              const int a = labels.at<int>(y, x);
              if (a >= 0 && std::find(list.begin(), list.end(), static_cast<std::size_t>(a)) == list.end()) list.push_back(static_cast<std::size_t>(a));
            }
          }
        });
      }
    }
    return outer;
  }

  double dist_at(const Eigen::Vector2d& p) const {
    const int i = static_cast<int>(std::lround((p.x() - g_.lo.x()) / g_.cell));
    const int j = static_cast<int>(std::lround((p.y() - g_.lo.y()) / g_.cell));
    if (i < 0 || j < 0 || i >= g_.nx || j >= g_.ny) return 0;
    return dist_->at<float>(j, i);
  }

  // The straight move a-b stays in the free region (sampled every half cell).
  bool free_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double margin) const {
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / (0.5 * g_.cell))));
    for (int k = 0; k <= n; ++k) {
      if (dist_at(a + (b - a) * (static_cast<double>(k) / n)) < margin) return false;
    }
    return true;
  }

  void feed(const Eigen::Vector3d& p, double f) {
    const Eigen::Vector3d a = w_.pos();
    w_.feed(p, f);
    material_.cut(a, p);
  }

  // Cuts one loop; returns whether the tool is left at the level (not retracted).
  bool cut_loop(const Loop& loop, double z, bool at_level) {
    // Start at the point of the loop nearest the tool: the loop re-ordered to begin there.
    Loop l;
    {
      std::size_t seg = 0;
      const Eigen::Vector2d q = nearest_on_loop(loop.pts, w_.pos().head<2>(), seg);
      const std::size_t m = loop.pts.size();
      l.pts.push_back(q);
      for (std::size_t k = 1; k <= m; ++k) {
        const Eigen::Vector2d& p = loop.pts[(seg + k) % m];
        if ((p - l.pts.back()).norm() > 1e-9 && (k < m || (p - q).norm() > 1e-9)) l.pts.push_back(p);
      }
    }
    const auto& pts = l.pts;
    const std::size_t n = pts.size();
    const double len = loop_length(l);
    // Highest material the tool reaches anywhere along the loop.
    double top = -kInf;
    for (std::size_t k = 0; k < n; ++k) top = std::max(top, material_.highest_near(pts[k], pts[(k + 1) % n]));
    if (top <= z + 1e-6) return at_level;  // nothing left along it (cut by a neighbour, or air)
    const std::size_t s = 0;
    const Eigen::Vector2d start = pts[s];
    const double f = o_.feed_mm_per_min, fp = o_.plunge_feed_mm_per_min;
    const double margin = 0.5 * g_.cell;  // a move's nearest node must be free
    Eigen::Vector2d entry = start;  // where the cut at z starts (and ends)
    std::size_t seg = s;            // the loop segment entry lies on (from pts[seg % n])
    if (at_level && (start - w_.pos().head<2>()).norm() <= 2 * step_over_ + 3 * g_.cell &&
        free_segment(w_.pos().head<2>(), start, margin)) {
      feed({start.x(), start.y(), z}, f);  // over to the next offset, at most a step-over into material
      ++st_.links;
    } else {
      const double here = material_.highest_near(start, start);
      const double from = std::max(top, z) + o_.clearance_mm;
      const double drop = from - z;
      const double need = drop / std::tan(o_.ramp_angle_deg * kPi / 180);  // ramp length
      if (here <= z + 1e-6) {
        approach(start, z + o_.clearance_mm);
        feed({start.x(), start.y(), z}, fp);  // straight down through air or cleared material
        ++st_.straight_entries;
      } else if (n > 2 && len >= R_) {
        // Ramp down along the loop from above its highest material, wrapping round as often as
        // needed; the ramp's vertices are the loop's, so it never leaves the loop.
        approach(start, from);
        double run = 0;
        for (std::size_t k = s;; ++k) {
          const Eigen::Vector2d& a = pts[k % n];
          const Eigen::Vector2d& b = pts[(k + 1) % n];
          const double l = (b - a).norm();
          if (run + l >= need) {
            const double t = l > 0 ? (need - run) / l : 0.0;
            entry = a + t * (b - a);
            seg = k % n;
            feed({entry.x(), entry.y(), z}, fp);
            break;
          }
          run += l;
          feed({b.x(), b.y(), from - drop * run / need}, fp);
        }
        ++st_.ramps;
      } else {
        // Too short to ramp along: a helix round the loop's centre, in the free region.
        Eigen::Vector2d c = Eigen::Vector2d::Zero();
        for (const auto& p : pts) c += p;
        c /= static_cast<double>(n);
        const double rh = std::min(o_.helix_radius_mm > 0 ? o_.helix_radius_mm : 0.5 * R_, dist_at(c) - margin);
        const double sign = o_.direction == MillingDirection::Climb ? 1.0 : -1.0;
        constexpr int kPerTurn = 24;
        // Each step is a chord of the circle, shorter than its arc: the descent per step is held
        // to the chord's length times the ramp slope.
        const double chord = 2 * std::max(rh, 1e-9) * std::sin(kPi / kPerTurn);
        const int steps = std::max(kPerTurn, static_cast<int>(std::ceil(drop / (chord * std::tan(o_.ramp_angle_deg * kPi / 180)))));
        const auto on_circle = [&](int k) { const double a = sign * 2 * kPi * k / kPerTurn; return Eigen::Vector2d(c + rh * Eigen::Vector2d(std::cos(a), std::sin(a))); };
        if (!(rh >= 0.1 * R_) || !free_segment(on_circle(steps + kPerTurn), start, margin)) {
          ++st_.skipped_loops;
          return at_level;
        }
        approach(on_circle(0), from);
        for (int k = 1; k <= steps; ++k) {
          const Eigen::Vector2d p = on_circle(k);
          feed({p.x(), p.y(), from - drop * k / steps}, fp);
        }
        for (int k = 1; k <= kPerTurn; ++k) {  // one full turn at the level
          const Eigen::Vector2d p = on_circle(steps + k);
          feed({p.x(), p.y(), z}, f);
        }
        feed({start.x(), start.y(), z}, f);
        ++st_.helices;
      }
    }
    // Round the whole loop at z, from the entry back to it.
    for (std::size_t k = 1; k <= n; ++k) {
      const Eigen::Vector2d& p = pts[(seg + k) % n];
      feed({p.x(), p.y(), z}, f);
    }
    feed({entry.x(), entry.y(), z}, f);
    ++st_.loops;
    return true;
  }

  // Up to the safe plane, across, and rapid down to `above` (never below the tool's height).
  void approach(const Eigen::Vector2d& xy, double above) {
    w_.retract();
    w_.rapid({xy.x(), xy.y(), w_.pos().z()});
    if (above < w_.pos().z()) w_.rapid({xy.x(), xy.y(), above});
  }

  const Grid& g_;
  const RoughingOptions& o_;
  double R_, step_over_;
  Material& material_;
  Writer& w_;
  RoughingStats& st_;
  const cv::Mat* dist_ = nullptr;
};

}  // namespace

StockBox default_stock_box(const BSplineSurface& surface, double margin_mm, double cell_mm, int threads) {
  const auto [lo, hi] = surface_xy_extent(surface);
  HeightGrid hg;
  hg.cell_mm = std::max(cell_mm, 0.5);
  hg.lo = lo;
  hg.nx = static_cast<long>(std::floor((hi.x() - lo.x()) / hg.cell_mm)) + 1;
  hg.ny = static_cast<long>(std::floor((hi.y() - lo.y()) / hg.cell_mm)) + 1;
  sample_surface_heights(surface, hg, threads);
  double zlo = kInf, zhi = -kInf;
  for (double z : hg.z) {
    if (std::isfinite(z)) zlo = std::min(zlo, z), zhi = std::max(zhi, z);
  }
  if (!std::isfinite(zlo)) throw GeometryError("roughing: the surface has no point over its own extent");
  StockBox s;
  const double m = margin_mm;
  s.min_mm = {lo.x() - m, lo.y() - m, zlo};
  s.max_mm = {hi.x() + m, hi.y() + m, zhi + m};
  return s;
}

StockBox parse_stock_box(const std::string& text) {
  std::vector<double> v;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    const std::string field = text.substr(at, comma - at);
    double x = 0;
    const auto r = std::from_chars(field.data(), field.data() + field.size(), x);
    if (field.empty() || r.ec != std::errc() || r.ptr != field.data() + field.size() || !std::isfinite(x)) {
      throw UsageError("--stock-box-mm: '" + field + "' is not a number (expected XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX)");
    }
    if (std::abs(x) > 1e6) throw UsageError("--stock-box-mm: '" + field + "' is beyond ±1e6 mm, not a stock");
    v.push_back(x);
    at = comma + 1;
  }
  if (v.size() != 6) throw UsageError("--stock-box-mm: " + std::to_string(v.size()) + " numbers, expected XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX");
  return StockBox{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
}

void validate(const RoughingOptions& o) {
  const auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw UsageError(std::string(name) + " must be a positive number");
  };
  positive(o.tool_diameter_mm, "--tool-diameter-mm");
  positive(o.step_down_mm, "--step-down-mm");
  positive(o.feed_mm_per_min, "--feed-mm-per-min");
  positive(o.plunge_feed_mm_per_min, "--plunge-feed-mm-per-min");
  positive(o.cell_mm, "--cell-mm");
  if (!(o.corner_radius_mm >= 0 && o.corner_radius_mm <= o.tool_diameter_mm / 2)) {
    throw UsageError("--corner-radius-mm must be 0 (flat) up to half the diameter (ball)");
  }
  if (!(o.step_over_mm >= 0 && o.step_over_mm <= o.tool_diameter_mm / 2)) {
    throw UsageError("--step-over-mm must be at most the tool radius (0: 40 % of the diameter)");
  }
  if (!(o.allowance_mm >= 0) || !std::isfinite(o.allowance_mm)) throw UsageError("--allowance-mm must be >= 0");
  if (!(o.rest_min_mm > 0) || !std::isfinite(o.rest_min_mm)) throw UsageError("--rest-min-mm must be a positive number");
  for (const PriorCut& prior : o.rest_after) {
    if (!(prior.cutter.radius_mm > 0) || !(prior.cutter.corner_radius_mm >= 0) || prior.cutter.corner_radius_mm > prior.cutter.radius_mm) {
      throw UsageError("--rest-after: the earlier program's cutter must have a diameter > 0 and a corner radius within its radius");
    }
  }
  if (!(o.stock_margin_mm >= 0) || !std::isfinite(o.stock_margin_mm)) throw UsageError("--stock-margin-mm must be >= 0");
  if (!(o.ramp_angle_deg > 0 && o.ramp_angle_deg <= 30)) throw UsageError("--ramp-angle-deg must be in (0, 30]");
  if (!(o.helix_radius_mm >= 0) || !std::isfinite(o.helix_radius_mm)) throw UsageError("--helix-radius-mm must be >= 0");
  if (!(o.retract_mm > 0) || !std::isfinite(o.retract_mm)) throw UsageError("--retract-mm must be > 0");
  if (!(o.clearance_mm >= 0 && o.clearance_mm < o.retract_mm)) throw UsageError("--clearance-mm must be in [0, --retract-mm)");
  if (!(o.simplify_mm >= 0 && o.simplify_mm <= o.cell_mm * 4)) throw UsageError("--simplify-mm must be in [0, 4 cells]");
  if (!(o.flat_tol_mm >= 0 && o.flat_tol_mm < o.step_down_mm)) throw UsageError("--flat-tol-mm must be in [0, --step-down-mm)");
  if (o.max_moves == 0) throw UsageError("--max-moves must be positive");
  if (o.stock) {
    const StockBox& s = *o.stock;
    if (!s.min_mm.allFinite() || !s.max_mm.allFinite() || !(s.max_mm.array() > s.min_mm.array()).all()) {
      throw UsageError("--stock-box-mm: each maximum must be above its minimum");
    }
  }
}

StockCheck check_stock(const BSplineSurface& surface, const StockBox& stock, const std::vector<CutProgram>& programs,
                       double allowance_mm, double cell_mm, int threads) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!(cell_mm > 0) || !std::isfinite(cell_mm)) throw UsageError("stock check: the cell must be > 0");
  HeightGrid material;
  material.lo = stock.min_mm.head<2>();
  material.cell_mm = cell_mm;
  const double nx = std::floor((stock.max_mm.x() - stock.min_mm.x()) / cell_mm) + 1;
  const double ny = std::floor((stock.max_mm.y() - stock.min_mm.y()) / cell_mm) + 1;
  if (nx * ny > 1e8) throw GeometryError("stock check: over 100 million nodes; use a larger cell");
  material.nx = static_cast<long>(nx), material.ny = static_cast<long>(ny);
  HeightGrid part = material;
  material.z.assign(static_cast<std::size_t>(material.nx * material.ny), stock.max_mm.z());
  sample_surface_heights(surface, part, threads);
  for (const CutProgram& p : programs) cut_material(material, *p.cl, p.cutter, geometry::thread_count(threads));
  StockCheck c;
  c.cell_mm = cell_mm;
  c.allowance_mm = allowance_mm;
  std::vector<double> left;
  for (long j = 0; j < material.ny; ++j) {
    for (long i = 0; i < material.nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j * material.nx + i);
      const double h = part.z[k];
      if (!std::isfinite(h) || h > stock.max_mm.z()) continue;
      ++c.nodes;
      const double e = material.z[k] - (h + allowance_mm);
      left.push_back(std::max(0.0, e));
      const Eigen::Vector2d xy = material.node_xy(i, j);
      if (-e > c.max_into_allowance_mm) c.max_into_allowance_mm = -e, c.into_allowance_at = {xy.x(), xy.y(), h};
      if (h - material.z[k] > c.max_gouge_mm) c.max_gouge_mm = h - material.z[k], c.gouge_at = {xy.x(), xy.y(), h};
    }
  }
  if (!left.empty()) {
    const auto q = left.begin() + static_cast<long>(0.95 * static_cast<double>(left.size() - 1));
    std::nth_element(left.begin(), q, left.end());
    c.p95_left_mm = *q;
    c.max_left_mm = *std::max_element(left.begin(), left.end());
  }
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return c;
}

RoughingResult generate_roughing(const BSplineSurface& surface, const RoughingOptions& opt) {
  validate(opt);
  const auto t0 = std::chrono::steady_clock::now();
  RoughingOptions o = opt;
  const int threads = geometry::thread_count(o.threads);
  const double R = o.tool_diameter_mm / 2, rc = o.corner_radius_mm;
  if (o.simplify_mm == 0) o.simplify_mm = 0.5 * o.cell_mm;
  const double step_over = o.step_over_mm > 0 ? o.step_over_mm : 0.4 * o.tool_diameter_mm;
  const StockBox stock = o.stock ? *o.stock : default_stock_box(surface, o.stock_margin_mm, o.cell_mm, threads);

  Grid g;
  g.cell = o.cell_mm;
  const double reach = R + 2 * o.cell_mm + o.simplify_mm + o.cell_mm;
  g.lo = stock.min_mm.head<2>() - Eigen::Vector2d::Constant(reach);
  const Eigen::Vector2d hi = stock.max_mm.head<2>() + Eigen::Vector2d::Constant(reach);
  const double nx = std::floor((hi.x() - g.lo.x()) / g.cell) + 1, ny = std::floor((hi.y() - g.lo.y()) / g.cell) + 1;
  if (nx * ny > 1e8) throw GeometryError("roughing: the grid would have " + mm(nx * ny) + " nodes; use a larger --cell-mm");
  g.nx = static_cast<int>(nx), g.ny = static_cast<int>(ny);

  const std::vector<double> h = part_heights(surface, g, stock.min_mm.z(), threads);
  {
    bool any = false;
    for (int j = 0; j < g.ny && !any; ++j) {
      for (int i = 0; i < g.nx && !any; ++i) {
        const Eigen::Vector2d p = g.xy(i, j);
        any = h[g.at(i, j)] > stock.min_mm.z() && p.x() >= stock.min_mm.x() && p.x() <= stock.max_mm.x() &&
              p.y() >= stock.min_mm.y() && p.y() <= stock.max_mm.y();
      }
    }
    if (!any) throw GeometryError("roughing: the stock box does not overlap the surface above its bottom");
  }
  const std::vector<double> t = tip_limits(h, g, R, rc, o.allowance_mm, threads);
  // Levels: from the stock top down by step-down to the lowest tip height inside the stock, and
  // the tops of the flats.
  // Flat nodes: T within a 1-degree slope of its four neighbours'.
  const double flat_step = std::tan(kPi / 180) * g.cell;
  std::vector<double> inside, flat;
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const Eigen::Vector2d p = g.xy(i, j);
      if (p.x() >= stock.min_mm.x() && p.x() <= stock.max_mm.x() && p.y() >= stock.min_mm.y() && p.y() <= stock.max_mm.y()) {
        const double ti = t[g.at(i, j)];
        inside.push_back(ti);
        const bool level = i > 0 && j > 0 && i + 1 < g.nx && j + 1 < g.ny && std::abs(t[g.at(i - 1, j)] - ti) <= flat_step &&
                           std::abs(t[g.at(i + 1, j)] - ti) <= flat_step && std::abs(t[g.at(i, j - 1)] - ti) <= flat_step &&
                           std::abs(t[g.at(i, j + 1)] - ti) <= flat_step;
        if (level) flat.push_back(ti);
      }
    }
  }
  std::sort(inside.begin(), inside.end());
  const double tmin = inside.front();
  std::vector<double> levels;
  for (int k = 1;; ++k) {
    const double z = stock.max_mm.z() - k * o.step_down_mm;
    if (z <= tmin + 1e-6) break;
    levels.push_back(z);
  }
  // The last level: the lowest tip height, or up to --flat-tol-mm above it, so that the nodes
  // within that tolerance of the lowest (a floor that is not quite level) are cut there too.
  const double bottom_level = std::min(tmin + o.flat_tol_mm, levels.empty() ? kInf : levels.back() - 0.01);
  if (bottom_level < stock.max_mm.z() - 1e-6) levels.push_back(std::max(tmin, bottom_level));
  std::vector<double> flats;
  if (o.flat_tol_mm > 0) {
    constexpr double kFlatAreaFraction = 0.02;
    const auto need = static_cast<std::ptrdiff_t>(std::ceil(kFlatAreaFraction * static_cast<double>(inside.size())));
    std::sort(flat.begin(), flat.end());
    for (auto it = flat.begin(); it != flat.end();) {
      const auto end = std::upper_bound(it, flat.end(), *it + o.flat_tol_mm);
      if (end - it >= need) {
        const double z = *(end - 1);
        if (z < stock.max_mm.z() - 1e-6) flats.push_back(z);
        it = end;
      } else {
        ++it;
      }
    }
  }
  for (double z : flats) {
    if (std::none_of(levels.begin(), levels.end(), [&](double l) { return std::abs(l - z) < 0.01; })) levels.push_back(z);
  }
  std::sort(levels.begin(), levels.end(), std::greater<>());

  RoughingResult r;
  r.cl.part_name = o.part_name;
  r.cl.tool_diameter_mm = o.tool_diameter_mm;
  r.cl.tool_corner_radius_mm = rc;
  r.cl.spindle_rpm = o.spindle_rpm;
  r.cl.coolant = o.coolant;
  RoughingStats& st = r.stats;
  st.stock = stock;
  st.step_over_mm = step_over;
  st.safe_z_mm = stock.max_mm.z() + o.retract_mm;
  st.levels = levels.size();
  st.flat_levels = flats.size();
  if (!levels.empty()) st.top_level_mm = levels.front(), st.bottom_level_mm = levels.back();

  Writer w(r, o, st.safe_z_mm);
  Material material(g, stock, R, rc);
  for (const PriorCut& prior : o.rest_after) material.cut_by(prior.cl, prior.cutter, threads);
  const double d0 = g.cell + o.simplify_mm;
  LevelCutter cutter(g, o, R, step_over, material, w, st);
  w.rapid({stock.min_mm.x() - R - 1, stock.min_mm.y() - R - 1, st.safe_z_mm});
  for (double z : levels) {
    cv::Mat work;
    if (!o.rest_after.empty()) {
      // Material this tool can take at this level: standing more than rest_min above it, within
      // R - the simplification of where its centre can go (the free region deeper than d0, where the loops
      // run). The loops are kept to the centres within R + step-over of that material.
      cv::Mat centres(g.ny, g.nx, CV_8U);
      for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
          const bool border = i == 0 || j == 0 || i == g.nx - 1 || j == g.ny - 1;
          centres.at<unsigned char>(j, i) = !border && t[g.at(i, j)] <= z + 1e-9 ? 255 : 0;
        }
      }
      cv::Mat depth;
      cv::distanceTransform(centres, depth, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
      cv::Mat not_centre = depth * g.cell < d0;  // 255 where no loop centre can be
      cv::Mat to_centre;
      cv::distanceTransform(not_centre, to_centre, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
      cv::Mat none(g.ny, g.nx, CV_8U);
      bool any = false;
      for (int j = 0; j < g.ny; ++j) {
        for (int i = 0; i < g.nx; ++i) {
          const bool left = material.top()[g.at(i, j)] > z + o.rest_min_mm && to_centre.at<float>(j, i) * g.cell < R - o.simplify_mm;
          none.at<unsigned char>(j, i) = left ? 0 : 255;
          any = any || left;
        }
      }
      if (!any) continue;
      cv::Mat dist;
      cv::distanceTransform(none, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
      work = dist * g.cell < R + step_over;
    }
    cv::Mat dist_mm;
    const std::vector<Loop> loops = level_loops(t, g, z, d0, step_over, o.simplify_mm, o.direction, work, dist_mm);
    if (!o.rest_after.empty() && !loops.empty()) ++st.rest_levels;
    cutter.cut_level(loops, dist_mm, z);
    w.retract();
  }
  w.retract();
  if (st.loops == 0 && !o.rest_after.empty()) {
    throw GeometryError("roughing: nothing left to cut: the earlier programs left no material more than " + mm(o.rest_min_mm) +
                        " mm above any level that this tool can reach");
  }
  if (st.loops == 0) {
    throw GeometryError(levels.empty() ? "roughing: nothing to cut: the stock's top (" + mm(stock.max_mm.z()) +
                                             " mm) is not above the surface + allowance anywhere inside it (lowest " + mm(tmin) + " mm)"
                                       : "roughing: no loop could be entered (" + std::to_string(st.skipped_loops) +
                                             " too narrow for a ramp or a helix): no program");
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace photomill::toolpath
