#include "toolpath/zmap.hpp"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>
#include <cmath>
#include <vector>

#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "geometry/parallel.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// (x, y) -> (u, v, z, n_z) on the surface: Newton's method on S_xy(u, v) = (x, y) with a
// finite-difference Jacobian that is reused between neighbouring grid nodes (only point
// evaluations, so a grid of millions of nodes stays cheap); start values from a coarse grid of
// samples bucketed by (x, y).
class SurfaceInverter {
public:
  explicit SurfaceInverter(const BSplineSurface& s) : s_(s) {
    const auto [u0, u1] = domain_u(s);
    const auto [v0, v1] = domain_v(s);
    u0_ = u0, u1_ = u1, v0_ = v0, v1_ = v1;
    constexpr int kCoarse = 32;
    double longest = 0;
    std::vector<Eigen::Vector3d> c((kCoarse + 1) * (kCoarse + 1));
    for (int i = 0; i <= kCoarse; ++i) {
      for (int j = 0; j <= kCoarse; ++j) {
        c[static_cast<std::size_t>(i * (kCoarse + 1) + j)] =
            surface_point(s, u0 + (u1 - u0) * i / kCoarse, v0 + (v1 - v0) * j / kCoarse);
      }
    }
    for (int i = 0; i < kCoarse; ++i) {
      for (int j = 0; j < kCoarse; ++j) {
        const auto& p = c[static_cast<std::size_t>(i * (kCoarse + 1) + j)];
        longest = std::max({longest, (c[static_cast<std::size_t>((i + 1) * (kCoarse + 1) + j)] - p).norm(),
                            (c[static_cast<std::size_t>(i * (kCoarse + 1) + j + 1)] - p).norm()});
      }
    }
    // Samples about 1 mm apart (at least the coarse grid).
    n_ = kCoarse * std::clamp(static_cast<int>(std::ceil(longest)), 1, 64) + 1;
    pts_.resize(static_cast<std::size_t>(n_) * n_);
    uvs_.resize(pts_.size());
    lo_ = Eigen::Vector2d::Constant(kInf);
    hi_ = -lo_;
    for (int i = 0; i < n_; ++i) {
      for (int j = 0; j < n_; ++j) {
        const Eigen::Vector2d uv(u0 + (u1 - u0) * i / (n_ - 1), v0 + (v1 - v0) * j / (n_ - 1));
        const std::size_t k = static_cast<std::size_t>(i) * n_ + j;
        uvs_[k] = uv;
        pts_[k] = surface_point(s, uv.x(), uv.y());
        lo_ = lo_.cwiseMin(pts_[k].head<2>());
        hi_ = hi_.cwiseMax(pts_[k].head<2>());
      }
    }
    spacing_ = std::max(longest * kCoarse / (n_ - 1), 1e-9);
    bucket_ = 2 * spacing_;
    bx_ = std::max(1, static_cast<int>(std::ceil((hi_.x() - lo_.x()) / bucket_)));
    by_ = std::max(1, static_cast<int>(std::ceil((hi_.y() - lo_.y()) / bucket_)));
    if (static_cast<double>(bx_) * by_ > 5e7) {
      bucket_ = std::max(hi_.x() - lo_.x(), hi_.y() - lo_.y()) / 4096;
      bx_ = std::max(1, static_cast<int>(std::ceil((hi_.x() - lo_.x()) / bucket_)));
      by_ = std::max(1, static_cast<int>(std::ceil((hi_.y() - lo_.y()) / bucket_)));
    }
    start_.assign(static_cast<std::size_t>(bx_) * by_ + 1, 0);
    for (const auto& p : pts_) ++start_[bucket_of(p.head<2>()) + 1];
    for (std::size_t b = 1; b < start_.size(); ++b) start_[b] += start_[b - 1];
    items_.resize(pts_.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (std::size_t k = 0; k < pts_.size(); ++k) items_[static_cast<std::size_t>(fill[bucket_of(pts_[k].head<2>())]++)] = static_cast<int>(k);
  }

  Eigen::Vector2d lo() const { return lo_; }
  Eigen::Vector2d hi() const { return hi_; }

  // (u, v) of the nearest coarse sample within two buckets, if any.
  bool nearest_uv(const Eigen::Vector2d& xy, Eigen::Vector2d& uv) const {
    const int cx = static_cast<int>(std::floor((xy.x() - lo_.x()) / bucket_));
    const int cy = static_cast<int>(std::floor((xy.y() - lo_.y()) / bucket_));
    double best = kInf;
    for (int y = std::max(0, cy - 1); y <= std::min(by_ - 1, cy + 1); ++y) {
      for (int x = std::max(0, cx - 1); x <= std::min(bx_ - 1, cx + 1); ++x) {
        const std::size_t b = static_cast<std::size_t>(y) * bx_ + x;
        for (int i = start_[b]; i < start_[b + 1]; ++i) {
          const std::size_t k = static_cast<std::size_t>(items_[static_cast<std::size_t>(i)]);
          const double d2 = (pts_[k].head<2>() - xy).squaredNorm();
          if (d2 < best) best = d2, uv = uvs_[k];
        }
      }
    }
    return std::isfinite(best);
  }

  struct Jacobian {
    Eigen::Vector3d su = Eigen::Vector3d::Zero(), sv = Eigen::Vector3d::Zero();
    bool valid = false;
  };

  // Solves S_xy(u, v) = xy from uv; on success uv and z are set, and with `nz` also n_z (|n_z| of
  // the unit normal, from a Jacobian evaluated at the solution).
  bool solve(const Eigen::Vector2d& xy, Eigen::Vector2d& uv, Jacobian& jac, double& z, double* nz = nullptr) const {
    constexpr double kResidual = 1e-9;  // mm
    Eigen::Vector3d p = surface_point(s_, uv.x(), uv.y());
    double res_norm = (xy - p.head<2>()).norm();
    bool fresh = false;
    if (!jac.valid) jac = jacobian(uv), fresh = true;
    for (int it = 0; it < 16 && res_norm > kResidual; ++it) {
      Eigen::Matrix2d J;
      J << jac.su.x(), jac.sv.x(), jac.su.y(), jac.sv.y();
      const double det = J.determinant();
      if (!(std::abs(det) > 1e-300)) {
        if (fresh) return false;
        jac = jacobian(uv), fresh = true;
        continue;
      }
      const Eigen::Vector2d delta = J.inverse() * (xy - p.head<2>());
      const Eigen::Vector2d next(std::clamp(uv.x() + delta.x(), u0_, u1_), std::clamp(uv.y() + delta.y(), v0_, v1_));
      if (next == uv) return false;  // pushed against the domain's edge: xy is off the surface
      const Eigen::Vector3d pn = surface_point(s_, next.x(), next.y());
      const double rn = (xy - pn.head<2>()).norm();
      if (rn > 0.5 * res_norm && !fresh) {
        jac = jacobian(uv), fresh = true;  // stale Jacobian: refresh and retry from uv
        continue;
      }
      uv = next, p = pn, res_norm = rn;
      fresh = false;
    }
    if (!(res_norm <= kResidual)) return false;
    z = p.z();
    if (nz) {
      jac = jacobian(uv);
      const Eigen::Vector3d n = jac.su.cross(jac.sv);
      const double len = n.norm();
      if (!(len > 0)) return false;
      *nz = std::abs(n.z()) / len;
    }
    return true;
  }

private:
  std::size_t bucket_of(const Eigen::Vector2d& xy) const {
    const int x = std::clamp(static_cast<int>((xy.x() - lo_.x()) / bucket_), 0, bx_ - 1);
    const int y = std::clamp(static_cast<int>((xy.y() - lo_.y()) / bucket_), 0, by_ - 1);
    return static_cast<std::size_t>(y) * bx_ + x;
  }

  Jacobian jacobian(const Eigen::Vector2d& uv) const {
    const double hu = 1e-7 * (u1_ - u0_), hv = 1e-7 * (v1_ - v0_);
    const double du = uv.x() + hu <= u1_ ? hu : -hu, dv = uv.y() + hv <= v1_ ? hv : -hv;
    const Eigen::Vector3d p = surface_point(s_, uv.x(), uv.y());
    Jacobian j;
    j.su = (surface_point(s_, uv.x() + du, uv.y()) - p) / du;
    j.sv = (surface_point(s_, uv.x(), uv.y() + dv) - p) / dv;
    j.valid = true;
    return j;
  }

  const BSplineSurface& s_;
  double u0_, u1_, v0_, v1_;
  int n_ = 0;
  std::vector<Eigen::Vector3d> pts_;
  std::vector<Eigen::Vector2d> uvs_;
  Eigen::Vector2d lo_, hi_;
  double spacing_ = 1, bucket_ = 2;
  int bx_ = 1, by_ = 1;
  std::vector<int> start_, items_;
};

bool inside_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto& a = poly[i];
    const auto& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) in = !in;
  }
  return in;
}

struct Segment {
  Eigen::Vector3d a, b;  // ball centres
};

// The z-map's nodes: (lo_x + i cell, lo_y + j cell) for i < nx, j < ny, stored row by row (k = j nx + i).
struct Grid {
  Eigen::Vector2d lo, hi;  // the window (mm)
  double cell = 0;
  long nx = 0, ny = 0;

  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  Eigen::Vector2d node_xy(long i, long j) const { return Eigen::Vector2d(lo.x() + i * cell, lo.y() + j * cell); }
  Eigen::Vector2d node_xy(std::size_t k) const { return node_xy(static_cast<long>(k % nx), static_cast<long>(k / nx)); }
};

// The grid over the surface's extent, cut to the options' window.
Grid make_grid(const SurfaceInverter& inv, const ZmapOptions& o) {
  Grid g;
  g.cell = o.cell_mm;
  g.lo = inv.lo(), g.hi = inv.hi();
  if (o.window_min) g.lo = g.lo.cwiseMax(*o.window_min);
  if (o.window_max) g.hi = g.hi.cwiseMin(*o.window_max);
  if (!(g.hi.x() >= g.lo.x() && g.hi.y() >= g.lo.y())) throw GeometryError("the z-map window does not overlap the surface");
  g.nx = static_cast<long>(std::floor((g.hi.x() - g.lo.x()) / o.cell_mm)) + 1;
  g.ny = static_cast<long>(std::floor((g.hi.y() - g.lo.y()) / o.cell_mm)) + 1;
  if (static_cast<double>(g.nx) * static_cast<double>(g.ny) > 1e8) {
    throw GeometryError("the z-map would have " + std::to_string(g.nx) + " x " + std::to_string(g.ny) +
                        " nodes; use a larger cell or a window");
  }
  return g;
}

// The surface under the nodes: height z (+inf off the surface or outside its boundary polygon),
// n_z of its unit normal, and the (u, v) the height was found at.
struct SurfaceSamples {
  std::vector<double> z;
  std::vector<float> nz;
  std::vector<Eigen::Vector2d> uv;
};

// Heights by Newton from the previous node of the row (from the nearest coarse sample after a miss).
void surface_heights(const SurfaceInverter& inv, const Grid& g, int threads, SurfaceSamples& s) {
  const long nx = g.nx;
  geometry::parallel_for(static_cast<std::size_t>(g.ny), threads, [&](std::size_t jj) {
    const long j = static_cast<long>(jj);
    SurfaceInverter::Jacobian jac;
    bool have_guess = false;
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
    for (long i = 0; i < nx; ++i) {
      const Eigen::Vector2d xy = g.node_xy(i, j);
      if (!have_guess) {
        if (!inv.nearest_uv(xy, uv)) continue;
        jac.valid = false;
      }
      double z = 0;
      Eigen::Vector2d trial = uv;
      if (inv.solve(xy, trial, jac, z)) {
        const std::size_t k = static_cast<std::size_t>(j) * nx + i;
        s.z[k] = z;
        s.uv[k] = trial;
        uv = trial;
        have_guess = true;
      } else {
        have_guess = false;
      }
    }
  });
}

// n_z = 1 / sqrt(1 + z_x^2 + z_y^2) from central differences of the heights (one-sided at the
// edges; error O(cell^2 z''')).
void normal_z(const Grid& g, int threads, SurfaceSamples& s) {
  const long nx = g.nx, ny = g.ny;
  const std::vector<double>& zs = s.z;
  geometry::parallel_for(static_cast<std::size_t>(ny), threads, [&](std::size_t jj) {
    const long j = static_cast<long>(jj);
    const auto z_at = [&](long i, long jn) {
      return i < 0 || jn < 0 || i >= nx || jn >= ny ? kInf : zs[static_cast<std::size_t>(jn) * nx + i];
    };
    const auto slope = [&](double zm, double z0, double zp) {
      if (std::isfinite(zm) && std::isfinite(zp)) return (zp - zm) / (2 * g.cell);
      if (std::isfinite(zp)) return (zp - z0) / g.cell;
      if (std::isfinite(zm)) return (z0 - zm) / g.cell;
      return 0.0;
    };
    for (long i = 0; i < nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * nx + i;
      const double z0 = zs[k];
      if (!std::isfinite(z0)) continue;
      const double zx = slope(z_at(i - 1, j), z0, z_at(i + 1, j)), zy = slope(z_at(i, j - 1), z0, z_at(i, j + 1));
      s.nz[k] = static_cast<float>(1.0 / std::sqrt(1 + zx * zx + zy * zy));
    }
  });
}

// The surface's height under every node and n_z there; nodes outside the boundary polygon are
// dropped after n_z is taken (the differences there still see the heights beyond it).
SurfaceSamples sample_surface(const BSplineSurface& surface, const SurfaceInverter& inv, const Grid& g, int threads) {
  const std::size_t N = g.size();
  SurfaceSamples s{std::vector<double>(N, kInf), std::vector<float>(N, 0.0f), std::vector<Eigen::Vector2d>(N)};
  surface_heights(inv, g, threads, s);
  normal_z(g, threads, s);
  if (!surface.boundary_uv.empty()) {
    for (std::size_t k = 0; k < N; ++k) {
      if (std::isfinite(s.z[k]) && !inside_polygon(surface.boundary_uv, s.uv[k])) s.z[k] = kInf;
    }
  }
  return s;
}

// The ball centres of every move (centres = tips + R z).
std::vector<Segment> ball_segments(const ClData& cl, double R) {
  std::vector<Segment> segs;
  for (std::size_t k = 1; k < cl.moves.size(); ++k) {
    const Eigen::Vector3d up(0, 0, R);
    segs.push_back({cl.moves[k - 1].tip_mm + up, cl.moves[k].tip_mm + up});
  }
  return segs;
}

// Lowers the cut heights of rows jb0..jb1 to where the ball swept along `sg` reaches:
// swept_ball_bottom with the segment's invariants hoisted and sigma0, perp stepped along the
// row; a node whose cut is already below the lowest this move can reach there is skipped.
void sweep_rows(const Segment& sg, const Grid& g, double R, long jb0, long jb1, std::vector<double>& zc) {
  const double R2 = R * R;
  const Eigen::Vector2d d = sg.b.head<2>() - sg.a.head<2>();
  const double l = d.norm();
  const bool point_like = l < 1e-12;
  const Eigen::Vector2d e = point_like ? Eigen::Vector2d(1, 0) : Eigen::Vector2d(d / l);
  const double m = point_like ? 0.0 : (sg.b.z() - sg.a.z()) / l;
  const double k = std::sqrt(1 + m * m);
  const double zmin = std::min(sg.a.z(), sg.b.z());
  for (long j = jb0; j <= jb1; ++j) {
    const double y = g.lo.y() + j * g.cell;
    double x0, x1;
    if (!capsule_row(sg.a.head<2>(), sg.b.head<2>(), R, y, x0, x1)) continue;
    const long i0 = std::max(0L, static_cast<long>(std::ceil((x0 - g.lo.x()) / g.cell)));
    const long i1 = std::min(g.nx - 1, static_cast<long>(std::floor((x1 - g.lo.x()) / g.cell)));
    double* row = zc.data() + static_cast<std::size_t>(j) * g.nx;
    if (point_like) {
      for (long i = i0; i <= i1; ++i) {
        const double z = swept_ball_bottom(sg.a, sg.b, R, {g.lo.x() + i * g.cell, y});
        if (z < row[i]) row[i] = z;
      }
      continue;
    }
    const double wy = y - sg.a.y();
    for (long i = i0; i <= i1; ++i) {
      const double wx = g.lo.x() + i * g.cell - sg.a.x();
      const double perp = e.x() * wy - e.y() * wx;
      const double r2 = R2 - perp * perp;
      if (!(r2 > 0)) continue;
      const double dz = zmin - row[i];
      if (dz >= 0 && dz * dz >= r2) continue;
      const double sigma0 = wx * e.x() + wy * e.y();
      const double r = std::sqrt(r2);
      const double s_star = sigma0 - m * r / k;
      double z;
      if (s_star >= 0 && s_star <= l) {
        z = sg.a.z() + m * sigma0 - r * k;
      } else {
        const double sc = s_star < 0 ? 0.0 : l;
        const double ds = sc - sigma0;
        const double q = r2 - ds * ds;
        if (!(q > 0)) continue;
        z = sg.a.z() + m * sc - std::sqrt(q);
      }
      if (z < row[i]) row[i] = z;
    }
  }
}

// The cut height at every node: the lowest the ball reaches there along all moves (+inf where it
// never passes). Rows in blocks of 8, each block swept in parallel by the moves that reach it.
std::vector<double> cut_heights(const std::vector<Segment>& segs, const Grid& g, double R, int threads) {
  std::vector<double> zc(g.size(), kInf);
  constexpr long kRowsPerBlock = 8;
  const std::size_t blocks = static_cast<std::size_t>((g.ny + kRowsPerBlock - 1) / kRowsPerBlock);
  std::vector<std::vector<int>> block_segs(blocks);
  for (std::size_t s = 0; s < segs.size(); ++s) {
    const double y0 = std::min(segs[s].a.y(), segs[s].b.y()) - R, y1 = std::max(segs[s].a.y(), segs[s].b.y()) + R;
    const long j0 = std::max(0L, static_cast<long>(std::ceil((y0 - g.lo.y()) / g.cell)));
    const long j1 = std::min(g.ny - 1, static_cast<long>(std::floor((y1 - g.lo.y()) / g.cell)));
    for (long b = j0 / kRowsPerBlock; j0 <= j1 && b <= j1 / kRowsPerBlock; ++b) block_segs[static_cast<std::size_t>(b)].push_back(static_cast<int>(s));
  }
  geometry::parallel_for(blocks, threads, [&](std::size_t b) {
    const long jb0 = static_cast<long>(b) * kRowsPerBlock, jb1 = std::min(g.ny - 1, jb0 + kRowsPerBlock - 1);
    for (int s : block_segs[b]) sweep_rows(segs[static_cast<std::size_t>(s)], g, R, jb0, jb1, zc);
  });
  return zc;
}

// The grid figures of ZmapResult; `excess` gets (normal excess, node) of every machined node.
ZmapResult compare_at_nodes(const SurfaceSamples& s, const std::vector<double>& zc, const Grid& g, double stock_mm,
                            std::vector<std::pair<double, std::size_t>>& excess) {
  ZmapResult res;
  res.cell_mm = g.cell;
  const std::vector<double>& zs = s.z;
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (!std::isfinite(zs[k])) continue;
    ++res.nodes;
    if (!std::isfinite(zc[k])) {
      ++res.unmachined;
      continue;
    }
    const double dz = zc[k] - zs[k];
    const double e = dz * s.nz[k] - stock_mm;
    res.max_excess_z_mm = std::max(res.max_excess_z_mm, dz);
    excess.push_back({e, k});
    if (e > res.grid_max_scallop_mm) res.grid_max_scallop_mm = e, res.max_scallop_at = {g.node_xy(k).x(), g.node_xy(k).y(), zs[k]};
    if (-e > res.grid_max_gouge_mm) res.grid_max_gouge_mm = -e, res.max_gouge_at = {g.node_xy(k).x(), g.node_xy(k).y(), zs[k]};
  }
  res.max_scallop_mm = res.grid_max_scallop_mm;
  res.max_gouge_mm = res.grid_max_gouge_mm;
  return res;
}

// Refinement between nodes: the cut height at any (x, y) from the moves near it (buckets of
// side R), the surface's by Newton from the node's (u, v); a compass search from each of the
// worst nodes (kept at least 4 cells apart) climbs to the local extreme.
class ExtremeSearch {
public:
  ExtremeSearch(const BSplineSurface& surface, const SurfaceInverter& inv, const std::vector<Segment>& segs,
                const Grid& g, const ZmapOptions& o)
      : surface_(surface), inv_(inv), segs_(segs), g_(g), o_(o), R_(o.tool_radius_mm), bsize_(R_) {
    const double R = R_;
    bx_ = std::max(1, static_cast<int>(std::ceil((g.hi.x() - g.lo.x() + 2 * R) / bsize_)));
    by_ = std::max(1, static_cast<int>(std::ceil((g.hi.y() - g.lo.y() + 2 * R) / bsize_)));
    blo_ = g.lo - Eigen::Vector2d(R, R);
    buckets_.resize(static_cast<std::size_t>(bx_) * by_);
    for (std::size_t s = 0; s < segs.size(); ++s) {
      const Eigen::Vector2d mn = segs[s].a.head<2>().cwiseMin(segs[s].b.head<2>()) - Eigen::Vector2d(R, R);
      const Eigen::Vector2d mx = segs[s].a.head<2>().cwiseMax(segs[s].b.head<2>()) + Eigen::Vector2d(R, R);
      const int x0 = std::max(0, static_cast<int>(std::floor((mn.x() - blo_.x()) / bsize_)));
      const int x1 = std::min(bx_ - 1, static_cast<int>(std::floor((mx.x() - blo_.x()) / bsize_)));
      const int y0 = std::max(0, static_cast<int>(std::floor((mn.y() - blo_.y()) / bsize_)));
      const int y1 = std::min(by_ - 1, static_cast<int>(std::floor((mx.y() - blo_.y()) / bsize_)));
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) buckets_[static_cast<std::size_t>(y) * bx_ + x].push_back(static_cast<int>(s));
      }
    }
  }

  // Climbs from the worst nodes of `excess` (sign = +1: scallop, -1: gouge; partially sorted
  // here); raises best (and best_at) to the largest signed excess found.
  void refine(double sign, std::vector<std::pair<double, std::size_t>>& excess, const std::vector<Eigen::Vector2d>& uvs,
              double& best, Eigen::Vector3d& best_at) const {
    const std::size_t K = static_cast<std::size_t>(o_.refine_candidates);
    const std::size_t pool = std::min(excess.size(), K * 200);
    auto cmp = [&](const auto& a, const auto& b) { return sign * a.first > sign * b.first; };
    std::partial_sort(excess.begin(), excess.begin() + static_cast<long>(pool), excess.end(), cmp);
    std::vector<Eigen::Vector2d> picked;
    const double apart2 = 16 * o_.cell_mm * o_.cell_mm;
    for (std::size_t c = 0; c < pool && picked.size() < K; ++c) {
      const std::size_t k = excess[c].second;
      const Eigen::Vector2d xy = g_.node_xy(k);
      if (std::any_of(picked.begin(), picked.end(), [&](const Eigen::Vector2d& p) { return (p - xy).squaredNorm() < apart2; })) continue;
      picked.push_back(xy);
      Eigen::Vector2d uv = uvs[k];
      Eigen::Vector3d at = Eigen::Vector3d::Zero();
      Eigen::Vector2d x = xy;
      double f = value_at(x, uv, sign, at);
      if (!std::isfinite(f)) continue;
      Eigen::Vector3d f_at = at;
      for (double step = 0.5 * o_.cell_mm; step > 1e-5; step *= 0.5) {
        for (bool moved = true; moved;) {
          moved = false;
          for (int d = 0; d < 8; ++d) {
            const double ang = d * 0.7853981633974483;
            const Eigen::Vector2d y = x + step * Eigen::Vector2d(std::cos(ang), std::sin(ang));
            Eigen::Vector2d uv2 = uv;
            const double fy = value_at(y, uv2, sign, at);
            if (fy > f) {
              f = fy, x = y, uv = uv2, f_at = at, moved = true;
            }
          }
        }
      }
      if (f > best) best = f, best_at = f_at;
    }
  }

private:
  double cut_at(const Eigen::Vector2d& xy) const {
    const int x = static_cast<int>(std::floor((xy.x() - blo_.x()) / bsize_));
    const int y = static_cast<int>(std::floor((xy.y() - blo_.y()) / bsize_));
    if (x < 0 || y < 0 || x >= bx_ || y >= by_) return kInf;
    double z = kInf;
    for (int s : buckets_[static_cast<std::size_t>(y) * bx_ + x]) {
      z = std::min(z, swept_ball_bottom(segs_[static_cast<std::size_t>(s)].a, segs_[static_cast<std::size_t>(s)].b, R_, xy));
    }
    return z;
  }

  // Signed excess at xy (sign = +1: scallop, -1: gouge), -inf where undefined.
  double value_at(const Eigen::Vector2d& xy, Eigen::Vector2d& uv, double sign, Eigen::Vector3d& at) const {
    const Eigen::Vector2d& lo = g_.lo;
    const Eigen::Vector2d& hi = g_.hi;
    if (xy.x() < lo.x() || xy.y() < lo.y() || xy.x() > hi.x() || xy.y() > hi.y()) return -kInf;  // the window
    SurfaceInverter::Jacobian jac;
    double z = 0, nz = 0;
    Eigen::Vector2d trial = uv;
    if (!inv_.solve(xy, trial, jac, z, &nz)) return -kInf;
    if (!surface_.boundary_uv.empty() && !inside_polygon(surface_.boundary_uv, trial)) return -kInf;
    const double c = cut_at(xy);
    if (!std::isfinite(c)) return -kInf;
    uv = trial;
    at = {xy.x(), xy.y(), z};
    return sign * ((c - z) * nz - o_.stock_mm);
  }

  const BSplineSurface& surface_;
  const SurfaceInverter& inv_;
  const std::vector<Segment>& segs_;
  const Grid& g_;
  const ZmapOptions& o_;
  double R_, bsize_;
  int bx_ = 1, by_ = 1;
  Eigen::Vector2d blo_;
  std::vector<std::vector<int>> buckets_;
};

}  // namespace

// The x interval of the row y = const within horizontal distance R of the segment [a, b]
// (a convex stadium, so the union of its two discs and its rectangle is one interval).
bool capsule_row(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double R, double y, double& x0, double& x1) {
  x0 = kInf, x1 = -kInf;
  for (const Eigen::Vector2d& c : {a, b}) {
    const double dy = y - c.y();
    if (dy * dy < R * R) {
      const double h = std::sqrt(R * R - dy * dy);
      x0 = std::min(x0, c.x() - h), x1 = std::max(x1, c.x() + h);
    }
  }
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  if (len > 0) {
    const Eigen::Vector2d e = d / len;
    // sigma(x) = (x - a_x) e_x + (y - a_y) e_y in [0, len]; perp(x) = -(x - a_x) e_y + (y - a_y) e_x in [-R, R].
    double lo = -kInf, hi = kInf;
    const auto clip = [&](double coef, double offset, double vmin, double vmax) {
      // vmin <= coef * (x - a_x) + offset <= vmax
      if (std::abs(coef) < 1e-15) {
        if (offset < vmin || offset > vmax) lo = kInf, hi = -kInf;
        return;
      }
      double p = (vmin - offset) / coef + a.x(), q = (vmax - offset) / coef + a.x();
      if (p > q) std::swap(p, q);
      lo = std::max(lo, p), hi = std::min(hi, q);
    };
    clip(e.x(), (y - a.y()) * e.y(), 0.0, len);
    clip(-e.y(), (y - a.y()) * e.x(), -R, R);
    if (lo <= hi) x0 = std::min(x0, lo), x1 = std::max(x1, hi);
  }
  return x0 <= x1;
}

double swept_ball_bottom(const Eigen::Vector3d& A, const Eigen::Vector3d& B, double R, const Eigen::Vector2d& xy) {
  const auto sphere = [&](const Eigen::Vector3d& c) {
    const double d2 = (c.head<2>() - xy).squaredNorm();
    return d2 < R * R ? c.z() - std::sqrt(R * R - d2) : kInf;
  };
  const Eigen::Vector2d b = B.head<2>() - A.head<2>();
  const double l = b.norm();
  if (l < 1e-12) return std::min(sphere(A), sphere(B));
  const Eigen::Vector2d e = b / l;
  const Eigen::Vector2d w = xy - A.head<2>();
  const double sigma0 = w.dot(e);
  const double perp = e.x() * w.y() - e.y() * w.x();
  const double r2 = R * R - perp * perp;
  if (!(r2 > 0)) return kInf;
  const double r = std::sqrt(r2);
  const double m = (B.z() - A.z()) / l;
  const double k = std::sqrt(1 + m * m);
  const double s_star = sigma0 - m * r / k;
  if (s_star >= 0 && s_star <= l) return A.z() + m * sigma0 - r * k;
  const double s = std::clamp(s_star, 0.0, l);
  const double ds = s - sigma0;
  return ds * ds < r2 ? A.z() + m * s - std::sqrt(r2 - ds * ds) : kInf;
}

void sample_surface_heights(const BSplineSurface& surface, HeightGrid& hg, int threads) {
  if (!(hg.cell_mm > 0) || !std::isfinite(hg.cell_mm) || hg.nx <= 0 || hg.ny <= 0) throw UsageError("height grid: empty or cell <= 0");
  if (static_cast<double>(hg.nx) * static_cast<double>(hg.ny) > 1e8) throw GeometryError("height grid over 100 million nodes");
  const SurfaceInverter inv(surface);
  Grid g;
  g.lo = hg.lo, g.cell = hg.cell_mm, g.nx = hg.nx, g.ny = hg.ny;
  g.hi = g.node_xy(g.nx - 1, g.ny - 1);
  hg.z = sample_surface(surface, inv, g, geometry::thread_count(threads)).z;
}

std::pair<Eigen::Vector2d, Eigen::Vector2d> surface_xy_extent(const BSplineSurface& surface) {
  const SurfaceInverter inv(surface);
  return {inv.lo(), inv.hi()};
}

double cutter_lift(const Cutter& c, double rho) {
  const double rc = c.corner_radius_mm, flat = c.radius_mm - rc;
  if (rho <= flat) return 0;
  const double t = std::min(rho - flat, rc);
  return rc - std::sqrt(std::max(0.0, rc * rc - t * t));
}

double swept_cutter_bottom(const Eigen::Vector3d& A, const Eigen::Vector3d& B, const Cutter& c, const Eigen::Vector2d& xy) {
  const double R = c.radius_mm, rc = c.corner_radius_mm;
  if (rc >= R) {
    const Eigen::Vector3d up(0, 0, R);
    return swept_ball_bottom(A + up, B + up, R, xy);
  }
  const Eigen::Vector2d b = B.head<2>() - A.head<2>();
  const double l = b.norm();
  const auto lift = [&](double rho) { return cutter_lift(c, rho); };
  if (l < 1e-12) {
    const double rho = (xy - A.head<2>()).norm();
    return rho > R ? kInf : std::min(A.z(), B.z()) + lift(rho);
  }
  const Eigen::Vector2d e = b / l;
  const Eigen::Vector2d w = xy - A.head<2>();
  const double sigma0 = w.dot(e);
  const double perp = e.x() * w.y() - e.y() * w.x();
  const double r2 = R * R - perp * perp;
  if (!(r2 >= 0)) return kInf;
  const double r = std::sqrt(r2);
  double s0 = std::max(0.0, sigma0 - r), s1 = std::min(l, sigma0 + r);
  if (s0 > s1) return kInf;
  const double m = (B.z() - A.z()) / l;
  const auto at = [&](double sigma) {
    const double ds = sigma - sigma0;
    return A.z() + m * sigma + lift(std::min(R, std::sqrt(perp * perp + ds * ds)));
  };
  if (rc <= 0) return A.z() + m * (m > 0 ? s0 : s1);
  // Golden-section search of the convex z(sigma) on [s0, s1].
  constexpr double kG = 0.6180339887498949;
  double x1 = s1 - kG * (s1 - s0), x2 = s0 + kG * (s1 - s0);
  double f1 = at(x1), f2 = at(x2);
  for (int it = 0; it < 60 && s1 - s0 > 1e-9; ++it) {
    if (f1 < f2) {
      s1 = x2, x2 = x1, f2 = f1;
      x1 = s1 - kG * (s1 - s0);
      f1 = at(x1);
    } else {
      s0 = x1, x1 = x2, f1 = f2;
      x2 = s0 + kG * (s1 - s0);
      f2 = at(x2);
    }
  }
  return std::min({f1, f2, at(s0), at(s1)});
}

double cut_move_rows(HeightGrid& m, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Cutter& c, long j_first, long j_last,
                     Eigen::Vector2d* deepest_at) {
  const double R = c.radius_mm;
  const double zlow = std::min(a.z(), b.z());
  const double ylo = std::min(a.y(), b.y()) - R, yhi = std::max(a.y(), b.y()) + R;
  const long j0 = std::max({0L, j_first, static_cast<long>(std::ceil((ylo - m.lo.y()) / m.cell_mm))});
  const long j1 = std::min({m.ny - 1, j_last, static_cast<long>(std::floor((yhi - m.lo.y()) / m.cell_mm))});
  double deepest = 0;
  for (long j = j0; j <= j1; ++j) {
    const double y = m.lo.y() + j * m.cell_mm;
    double x0, x1;
    if (!capsule_row(a.head<2>(), b.head<2>(), R, y, x0, x1)) continue;
    const long i0 = std::max(0L, static_cast<long>(std::ceil((x0 - m.lo.x()) / m.cell_mm)));
    const long i1 = std::min(m.nx - 1, static_cast<long>(std::floor((x1 - m.lo.x()) / m.cell_mm)));
    double* row = m.z.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(m.nx);
    for (long i = i0; i <= i1; ++i) {
      if (zlow >= row[i]) continue;  // this move cannot reach below the material here
      const double z = swept_cutter_bottom(a, b, c, {m.lo.x() + i * m.cell_mm, y});
      if (z < row[i]) {
        if (row[i] - z > deepest) {
          deepest = row[i] - z;
          if (deepest_at) *deepest_at = {m.lo.x() + i * m.cell_mm, y};
        }
        row[i] = z;
      }
    }
  }
  return deepest;
}

void cut_material(HeightGrid& mat, const ClData& cl, const Cutter& c, int threads) {
  if (!(c.radius_mm > 0) || !(c.corner_radius_mm >= 0)) throw UsageError("cutter radius must be > 0");
  Grid g;
  g.lo = mat.lo, g.cell = mat.cell_mm, g.nx = mat.nx, g.ny = mat.ny;
  const double R = c.radius_mm;
  constexpr long kRowsPerBlock = 8;
  const std::size_t blocks = static_cast<std::size_t>((g.ny + kRowsPerBlock - 1) / kRowsPerBlock);
  std::vector<std::vector<int>> block_moves(blocks);
  for (std::size_t k = 1; k < cl.moves.size(); ++k) {
    const Eigen::Vector3d& a = cl.moves[k - 1].tip_mm;
    const Eigen::Vector3d& b = cl.moves[k].tip_mm;
    const double y0 = std::min(a.y(), b.y()) - R, y1 = std::max(a.y(), b.y()) + R;
    const long j0 = std::max(0L, static_cast<long>(std::ceil((y0 - g.lo.y()) / g.cell)));
    const long j1 = std::min(g.ny - 1, static_cast<long>(std::floor((y1 - g.lo.y()) / g.cell)));
    for (long bk = j0 / kRowsPerBlock; j0 <= j1 && bk <= j1 / kRowsPerBlock; ++bk) block_moves[static_cast<std::size_t>(bk)].push_back(static_cast<int>(k));
  }
  geometry::parallel_for(blocks, threads, [&](std::size_t bk) {
    const long jb0 = static_cast<long>(bk) * kRowsPerBlock, jb1 = std::min(g.ny - 1, jb0 + kRowsPerBlock - 1);
    for (int k : block_moves[bk]) {
      cut_move_rows(mat, cl.moves[static_cast<std::size_t>(k) - 1].tip_mm, cl.moves[static_cast<std::size_t>(k)].tip_mm, c, jb0, jb1);
    }
  });
}

ZmapResult simulate_zmap(const BSplineSurface& surface, const ClData& cl, const ZmapOptions& o) {
  if (!(o.cell_mm > 0) || !std::isfinite(o.cell_mm)) throw UsageError("z-map cell must be > 0");
  if (!(o.tool_radius_mm > 0)) throw UsageError("z-map tool radius must be > 0");
  const auto t_start = std::chrono::steady_clock::now();
  const int threads = geometry::thread_count(o.threads);
  const SurfaceInverter inv(surface);
  const Grid grid = make_grid(inv, o);
  const SurfaceSamples samples = sample_surface(surface, inv, grid, threads);
  // Sweep the ball along every move.
  const std::vector<Segment> segs = ball_segments(cl, o.tool_radius_mm);
  const std::vector<double> zc = cut_heights(segs, grid, o.tool_radius_mm, threads);
  std::vector<std::pair<double, std::size_t>> excess;  // (normal excess, node)
  ZmapResult res = compare_at_nodes(samples, zc, grid, o.stock_mm, excess);
  if (!excess.empty() && o.refine_candidates > 0) {
    const ExtremeSearch search(surface, inv, segs, grid, o);
    double best_s = res.max_scallop_mm;
    search.refine(+1.0, excess, samples.uv, best_s, res.max_scallop_at);
    res.max_scallop_mm = best_s;
    if (res.grid_max_gouge_mm > 0) {
      double best_g = res.max_gouge_mm;
      search.refine(-1.0, excess, samples.uv, best_g, res.max_gouge_at);
      res.max_gouge_mm = best_g;
    }
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return res;
}

}  // namespace photomill::toolpath
