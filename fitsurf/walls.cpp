// Walls under a part's top and the floor at their foot (see walls.hpp).
#include "fitsurf/walls.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <unordered_map>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "formats/log.hpp"

namespace photomill::fitsurf {
namespace {

using Array3l = Eigen::Array<long, 3, 1>;

// Points bucketed by cubes of side `cell` (a hash map: clouds span metres at mm cells).
class Buckets {
public:
  Buckets(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& kept, double cell)
      : points_(points), cell_(cell) {
    for (std::size_t k : kept) {
      const Array3l c = ijk(points[k]);
      map_[key(c)].push_back(k);
      columns_[key(Array3l(c.x(), c.y(), 0))].push_back(k);
    }
  }
  // Calls f(index) for every point within `cell` of x (the 27 cubes around it).
  template <typename F>
  void within(const Eigen::Vector3d& x, F&& f) const {
    const Array3l c = ijk(x);
    for (long di = -1; di <= 1; ++di) {
      for (long dj = -1; dj <= 1; ++dj) {
        for (long dk = -1; dk <= 1; ++dk) {
          const auto it = map_.find(key(c + Array3l(di, dj, dk)));
          if (it == map_.end()) continue;
          for (std::size_t m : it->second) {
            if ((points_[m] - x).squaredNorm() <= cell_ * cell_) f(m);
          }
        }
      }
    }
  }

  // Calls f(index) for every point within `cell` of x in x and y, at any height.
  template <typename F>
  void column(const Eigen::Vector3d& x, F&& f) const {
    const Array3l c = ijk(x);
    for (long di = -1; di <= 1; ++di) {
      for (long dj = -1; dj <= 1; ++dj) {
        const auto it = columns_.find(key(Array3l(c.x() + di, c.y() + dj, 0)));
        if (it == columns_.end()) continue;
        for (std::size_t m : it->second) {
          if ((points_[m] - x).head<2>().squaredNorm() <= cell_ * cell_) f(m);
        }
      }
    }
  }

private:
  Array3l ijk(const Eigen::Vector3d& x) const { return (x.array() / cell_).floor().cast<long>(); }
  static std::uint64_t key(const Array3l& c) {
    // 21 bits a coordinate: +-1 million cells, kilometres at mm cells.
    auto b = [](long v) { return static_cast<std::uint64_t>(v + (1L << 20)) & 0x1fffffu; };
    return b(c.x()) | (b(c.y()) << 21) | (b(c.z()) << 42);
  }
  const std::vector<Eigen::Vector3d>& points_;
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> map_, columns_;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto at = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(at), v.end());
  return v[at];
}

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

// Step 1 of walls.hpp: the points whose own normal, or else their neighbours' best-fit plane (PCA),
// is more than slope_deg from z; marks them in `wall`.
std::vector<std::size_t> wall_points(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& kept,
                                     const Buckets& near, const WallOptions& o, const std::vector<Eigen::Vector3d>& normals,
                                     std::vector<char>& wall) {
  const double cos_wall = std::cos(o.slope_deg * std::numbers::pi / 180);
  std::vector<std::size_t> walls;
  for (std::size_t k : kept) {
    if (k < normals.size() && normals[k].allFinite() && normals[k].norm() > 0) {
      if (std::abs(normals[k].normalized().z()) < cos_wall) {
        wall[k] = 1;
        walls.push_back(k);
      }
      continue;
    }
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
    std::size_t n = 0;
    near.within(points[k], [&](std::size_t m) {
      const Eigen::Vector3d d = points[m] - points[k];
      mean += d;
      second += d * d.transpose();
      ++n;
    });
    if (n < o.min_neighbours + 1) continue;
    mean /= static_cast<double>(n);
    const Eigen::Matrix3d cov = second / static_cast<double>(n) - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    if (std::abs(eig.eigenvectors().col(0).z()) < cos_wall) {
      wall[k] = 1;
      walls.push_back(k);
    }
  }
  return walls;
}

// Step 2: the regions of the points not on a wall (flood fill over links within r no steeper
// than slope_deg); region[k] receives each point's region, members each region's points.
std::vector<std::vector<std::size_t>> regions(const std::vector<Eigen::Vector3d>& points,
                                              const std::vector<std::size_t>& kept, const Buckets& near,
                                              const std::vector<char>& wall, const WallOptions& o,
                                              std::vector<std::size_t>& region) {
  const double tan_wall = std::tan(o.slope_deg * std::numbers::pi / 180);
  auto gentle = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::abs(a.z() - b.z()) <= tan_wall * std::hypot(a.x() - b.x(), a.y() - b.y());
  };
  std::vector<std::vector<std::size_t>> members;
  std::vector<std::size_t> stack;
  for (std::size_t k : kept) {
    if (wall[k] || region[k] != kNone) continue;
    const std::size_t id = members.size();
    members.emplace_back();
    region[k] = id;
    stack.assign(1, k);
    while (!stack.empty()) {
      const std::size_t at = stack.back();
      stack.pop_back();
      members[id].push_back(at);
      near.within(points[at], [&](std::size_t m) {
        if (wall[m] || region[m] != kNone || !gentle(points[at], points[m])) return;
        region[m] = id;
        stack.push_back(m);
      });
    }
  }
  return members;
}

// Step 4: near a dropped point (within r in x, y), a kept point lower than the plane of its kept
// neighbours within r predicts, by rim_step_mm plus three robust standard deviations of their
// residuals (1.4826 MAD), is on a wall's face just under the rim (or a feature straddling the
// edge); it would pull the top's edge down. The plane z = a + b (x - px) + c (y - py) by least
// squares, once more without the neighbours that are themselves that low (other points of the
// face).
template <typename Dropped>
std::vector<char> rim_points(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& kept,
                             const Buckets& near, const Dropped& dropped, double r, const WallOptions& o) {
  std::vector<char> rim_drop(points.size(), 0);
  std::vector<Eigen::Vector3d> around;
  std::vector<double> residual;
  for (std::size_t k : kept) {
    if (dropped(k)) continue;
    const Eigen::Vector3d& p = points[k];
    bool near_wall = false;
    around.clear();
    near.column(p, [&](std::size_t m) {
      if (dropped(m)) {
        near_wall = true;
      } else if (m != k && std::abs(points[m].z() - p.z()) <= 2 * r) {
        around.push_back(points[m] - p);
      }
    });
    if (!near_wall || around.size() < o.min_neighbours) continue;
    std::vector<char> use(around.size(), 1);
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
      Eigen::Vector3d atb = Eigen::Vector3d::Zero();
      std::size_t n = 0;
      for (std::size_t i = 0; i < around.size(); ++i) {
        if (!use[i]) continue;
        const Eigen::Vector3d row(1, around[i].x(), around[i].y());
        ata += row * row.transpose();
        atb += row * around[i].z();
        ++n;
      }
      const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
      if (n < o.min_neighbours || ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-9)) break;
      const Eigen::Vector3d plane = ldlt.solve(atb);
      residual.clear();
      for (std::size_t i = 0; i < around.size(); ++i) {
        if (use[i]) residual.push_back(around[i].z() - plane.dot(Eigen::Vector3d(1, around[i].x(), around[i].y())));
      }
      for (double& e : residual) e = std::abs(e);
      const double cutoff = o.rim_step_mm + 3 * 1.4826 * quantile(residual, 0.5);
      if (pass == 1) {
        rim_drop[k] = plane[0] > cutoff;  // p is at the origin: the plane is a above it
        break;
      }
      for (std::size_t i = 0; i < around.size(); ++i) {
        use[i] = around[i].z() - plane.dot(Eigen::Vector3d(1, around[i].x(), around[i].y())) >= -cutoff;
      }
    }
  }
  return rim_drop;
}

}  // namespace

std::optional<WallSummary> split_walls(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& kept,
                                       const WallOptions& o, const std::vector<Eigen::Vector3d>& normals) {
  if (!o.enabled || kept.size() < 2 * o.min_region_points) return std::nullopt;
  // r: at least radius_spacings mean spacings of the points over their xy box.
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t k : kept) {
    lo = lo.cwiseMin(points[k].head<2>());
    hi = hi.cwiseMax(points[k].head<2>());
  }
  const double area = std::max((hi - lo).prod(), 1e-12);
  const double spacing = std::sqrt(area / static_cast<double>(kept.size()));
  const double r = std::max(o.radius_mm, o.radius_spacings * spacing);
  const Buckets near(points, kept, r);

  // 1. Wall points: the normal of the neighbourhood's best-fit plane more than slope_deg from z.
  std::vector<char> wall(points.size(), 0);
  const std::vector<std::size_t> walls = wall_points(points, kept, near, o, normals, wall);
  log::debug("walls: " + std::to_string(walls.size()) + " of " + std::to_string(kept.size()) +
             " points on faces steeper than " + std::to_string(o.slope_deg) + " degrees (radius " + std::to_string(r) + " mm)");

  // 2. Regions of the other points: two points within r of each other, joined by a segment no
  //    steeper than slope_deg, are in the same region.
  std::vector<std::size_t> region(points.size(), kNone);
  const std::vector<std::vector<std::size_t>> members = regions(points, kept, near, wall, o, region);

  // 3. Floor: a region of at least min_region_points with min_step_points of its points under
  //    another such region, higher by min_height_mm and by tan(step_slope_deg) times their
  //    horizontal distance, and lower (median) than it.
  const double tan_step = std::tan(o.step_slope_deg * std::numbers::pi / 180);
  std::vector<double> median_z(members.size(), 0);
  for (std::size_t id = 0; id < members.size(); ++id) {
    if (members[id].size() < o.min_region_points) continue;
    std::vector<double> z;
    for (std::size_t k : members[id]) z.push_back(points[k].z());
    median_z[id] = quantile(z, 0.5);
  }
  std::vector<std::size_t> under(members.size(), 0);
  std::vector<char> floor(members.size(), 0);
  std::vector<double> step_top;
  std::vector<char> below_step(points.size(), 0);
  std::vector<std::size_t> overhangs(members.size(), 0);  // points right under a higher region
  for (std::size_t k : kept) {
    const std::size_t id = region[k];
    if (id == kNone) continue;
    const bool large = members[id].size() >= o.min_region_points;
    const Eigen::Vector3d& p = points[k];
    double top = -std::numeric_limits<double>::infinity();
    bool overhung = false;
    near.column(p, [&](std::size_t m) {
      const std::size_t other = region[m];
      if (other == kNone || other == id || members[other].size() < o.min_region_points) return;
      const Eigen::Vector3d& q = points[m];
      const double dz = q.z() - p.z();
      const double dxy = std::hypot(q.x() - p.x(), q.y() - p.y());
      if (dz < o.min_height_mm || dz < tan_step * dxy) return;
      if (large ? median_z[other] <= median_z[id] : median_z[other] <= p.z()) return;
      top = std::max(top, q.z());
      overhung = overhung || dxy <= spacing;
    });
    if (large && overhung) ++overhangs[id];
    if (top > -std::numeric_limits<double>::infinity()) {
      below_step[k] = 1;
      if (large) {
        ++under[id];
        step_top.push_back(top);
      }
    }
  }
  std::size_t floor_points = 0;
  std::vector<double> floor_z;
  for (std::size_t id = 0; id < members.size(); ++id) {
    // A floor lies beside the top, not under it: a region mostly covered by a higher one is the
    // underside of an overhang (left to the fold check).
    if (under[id] < o.min_step_points || 2 * overhangs[id] >= members[id].size()) continue;
    floor[id] = 1;
    for (std::size_t k : members[id]) floor_z.push_back(points[k].z());
    floor_points += members[id].size();
  }
  // With a floor found, the regions at its height (within min_height_mm of its median: the plate
  // around the walls where the cloud is too sparse for them to join it) are floor too, and the
  // points of small regions under a step (bits of the walls' faces and of their foot) go with it.
  if (!floor_z.empty()) {
    const double floor_level = quantile(floor_z, 0.5);
    std::vector<double> z;
    for (std::size_t id = 0; id < members.size(); ++id) {
      if (floor[id]) continue;
      z.clear();
      for (std::size_t k : members[id]) z.push_back(points[k].z());
      if (std::abs(quantile(z, 0.5) - floor_level) > o.min_height_mm) continue;
      floor[id] = 1;
      floor_z.insert(floor_z.end(), z.begin(), z.end());
      floor_points += members[id].size();
    }
  }
  auto dropped = [&](std::size_t k) {
    if (wall[k]) return true;
    const std::size_t id = region[k];
    return floor[id] || (members[id].size() < o.min_region_points && below_step[k]);
  };
  log::debug("walls: " + std::to_string(members.size()) + " regions; " + std::to_string(floor_points) +
             " points in regions under a step");
  if (floor_z.empty()) return std::nullopt;

  WallSummary s;
  s.wall_points = walls.size();
  s.dropped_floor = floor_points;
  s.radius_mm = r;
  s.floor_z_mm = quantile(floor_z, 0.5);
  s.wall_top_z_mm = quantile(step_top, 0.95);
  // 4. The top's rim: a point under its neighbours' plane near what was dropped.
  const std::vector<char> rim_drop = rim_points(points, kept, near, dropped, r, o);
  std::vector<std::size_t> out;
  out.reserve(kept.size());
  for (std::size_t k : kept) {
    if (rim_drop[k]) {
      ++s.wall_points;
      continue;
    }
    if (!dropped(k)) {
      out.push_back(k);
    } else if (!wall[k] && !floor[region[k]]) {
      ++s.wall_points;  // a small region's point under a step: a bit of a wall's face or foot
    }
  }
  kept = std::move(out);
  s.top_points = kept.size();
  s.box_min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  s.box_max = -s.box_min;
  for (std::size_t k : kept) {
    s.box_min = s.box_min.cwiseMin(points[k].head<2>());
    s.box_max = s.box_max.cwiseMax(points[k].head<2>());
  }
  return s;
}

}  // namespace photomill::fitsurf
