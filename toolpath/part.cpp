#include "toolpath/part.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "formats/error.hpp"
#include "formats/bspline.hpp"

#include <Eigen/Geometry>
#include "geometry/parallel.hpp"
#include "toolpath/iso_passes.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string num(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// The face's facing (iso_passes.hpp) and the bounding box of a 24 x 24 grid of its points inside
// its boundary polygon.
PartFace classify(const BSplineSurface& face, std::size_t index, double wall_share) {
  PartFace f;
  f.index = index;
  const SurfaceFacing facing = surface_facing(face);
  f.area_mm2 = facing.area_mm2;
  const double area = std::max(facing.area_mm2, 1e-300);
  f.up_share = facing.up_mm2 / area;
  f.down_share = facing.down_mm2 / area;
  if (f.up_share + f.down_share < wall_share) {
    f.kind = PartFace::Kind::Wall;
  } else if (facing.up_mm2 < facing.down_mm2) {
    f.kind = PartFace::Kind::Down;
  }
  constexpr int kGrid = 24;
  const auto [u0, u1] = domain_u(face);
  const auto [v0, v1] = domain_v(face);
  f.min_mm = Eigen::Vector3d::Constant(kInf);
  f.max_mm = -f.min_mm;
  for (int i = 0; i <= kGrid; ++i) {
    for (int j = 0; j <= kGrid; ++j) {
      const Eigen::Vector2d uv(u0 + (u1 - u0) * i / kGrid, v0 + (v1 - v0) * j / kGrid);
      if (!face.boundary_uv.empty() && !inside_uv_polygon(face.boundary_uv, uv)) continue;
      const Eigen::Vector3d p = surface_point(face, uv.x(), uv.y());
      f.min_mm = f.min_mm.cwiseMin(p);
      f.max_mm = f.max_mm.cwiseMax(p);
    }
  }
  if (!f.min_mm.allFinite()) f.min_mm = f.max_mm = Eigen::Vector3d::Zero();
  return f;
}

// The whole-part check of one feed move from tip a (already checked) to tip b (raised to the
// mesh's drop height): the ball's straight move between two positions that both clear the part
// can still cut into it between them (a neighbouring face's edge). The move is sampled every
// `piece` mm of its 3D length - half the chord of sagitta tol on a ball of radius r,
// l = sqrt(8 r tol) / 2 - and where a sample lies more than tol below the drop height, the worst one
// is raised onto it and both halves are checked again (at most kMaxDepth levels deep).
void split_move(const MeshDropCutter& drop, double tool_radius_mm, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                double piece, double tol, int depth, std::vector<Eigen::Vector3d>& out) {
  constexpr int kMaxDepth = 40;
  const double len = (b - a).norm();  // 3D: over a steep flank of the envelope a short step climbs far
  if (len <= piece || depth >= kMaxDepth) return;
  const int n = static_cast<int>(std::ceil(len / piece));
  double worst = tol;
  Eigen::Vector3d worst_point = Eigen::Vector3d::Zero();
  for (int k = 1; k < n; ++k) {
    const Eigen::Vector3d q = a + (b - a) * (static_cast<double>(k) / n);
    const double tip = drop.centre_z(q.head<2>()) - tool_radius_mm;
    if (tip - q.z() > worst) worst = tip - q.z(), worst_point = {q.x(), q.y(), tip};
  }
  if (worst <= tol) return;
  split_move(drop, tool_radius_mm, a, worst_point, piece, tol, depth + 1, out);
  out.push_back(worst_point);
  split_move(drop, tool_radius_mm, worst_point, b, piece, tol, depth + 1, out);
}

// The point of triangle abc closest to p (Ericson, Real-Time Collision Detection, 5.1.5: the
// Voronoi regions of the vertices, then of the edges, else the face's interior by barycentric
// coordinates).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return a;  // a degenerate triangle: its edges are covered by its neighbours
  return a + ab * (vb / denom) + ac * (vc / denom);
}

// Triangles bucketed by their xy bounding box grown by the ball radius (cells of that size):
// the triangles within reach of a ball centred over a cell are those of its bucket.
class TriangleBuckets {
public:
  TriangleBuckets(const TriangleMesh& mesh, double reach_mm) : mesh_(&mesh), cell_(reach_mm) {
    lo_ = Eigen::Vector2d::Constant(kInf);
    Eigen::Vector2d hi = -lo_;
    for (const auto& v : mesh.vertices) lo_ = lo_.cwiseMin(v.head<2>()), hi = hi.cwiseMax(v.head<2>());
    lo_ -= Eigen::Vector2d::Constant(reach_mm);
    hi += Eigen::Vector2d::Constant(reach_mm);
    nx_ = std::max(1L, static_cast<long>(std::ceil((hi.x() - lo_.x()) / cell_)));
    ny_ = std::max(1L, static_cast<long>(std::ceil((hi.y() - lo_.y()) / cell_)));
    if (static_cast<double>(nx_) * static_cast<double>(ny_) > 4e7) throw GeometryError("z-map: the part is too large for the tool radius");
    buckets_.resize(static_cast<std::size_t>(nx_ * ny_));
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      Eigen::Vector2d a = Eigen::Vector2d::Constant(kInf), b = -a;
      for (const int v : mesh.triangles[t]) {
        a = a.cwiseMin(mesh.vertices[static_cast<std::size_t>(v)].head<2>());
        b = b.cwiseMax(mesh.vertices[static_cast<std::size_t>(v)].head<2>());
      }
      const long i0 = cell_of(a.x() - reach_mm, lo_.x(), nx_), i1 = cell_of(b.x() + reach_mm, lo_.x(), nx_);
      const long j0 = cell_of(a.y() - reach_mm, lo_.y(), ny_), j1 = cell_of(b.y() + reach_mm, lo_.y(), ny_);
      for (long j = j0; j <= j1; ++j) {
        for (long i = i0; i <= i1; ++i) buckets_[static_cast<std::size_t>(j * nx_ + i)].push_back(static_cast<int>(t));
      }
    }
  }
  // The mesh point nearest to p among the triangles of p's bucket, and its distance (inf: none).
  double nearest(const Eigen::Vector3d& p, Eigen::Vector3d& at) const {
    const long i = cell_of(p.x(), lo_.x(), nx_), j = cell_of(p.y(), lo_.y(), ny_);
    double best2 = kInf;
    for (const int t : buckets_[static_cast<std::size_t>(j * nx_ + i)]) {
      const auto& tri = mesh_->triangles[static_cast<std::size_t>(t)];
      const Eigen::Vector3d q = closest_on_triangle(p, mesh_->vertices[static_cast<std::size_t>(tri[0])],
                                                    mesh_->vertices[static_cast<std::size_t>(tri[1])],
                                                    mesh_->vertices[static_cast<std::size_t>(tri[2])]);
      const double d2 = (q - p).squaredNorm();
      if (d2 < best2) best2 = d2, at = q;
    }
    return std::sqrt(best2);
  }

private:
  long cell_of(double x, double lo, long n) const { return std::clamp(static_cast<long>(std::floor((x - lo) / cell_)), 0L, n - 1); }
  const TriangleMesh* mesh_;
  double cell_;
  Eigen::Vector2d lo_;
  long nx_ = 0, ny_ = 0;
  std::vector<std::vector<int>> buckets_;
};

}  // namespace

namespace {

// The whole-part check of one face's moves against `others` (the other faces' triangles), in
// two parallel sweeps: every feed point raised to the drop height (rapids below the safe plane -
// the drop to the clearance height over a pass - kept at least the clearance above it); then
// every feed move split where it would cut in between (split_move). Appends to `out`.
void check_against(const MeshDropCutter& others, std::vector<ClMove> moves, const ToolpathOptions& o, double safe_z,
                   double tol, PartToolpathResult& result, std::vector<ClMove>& out) {
  const double R = o.tool_radius_mm;
  const int threads = geometry::thread_count(o.threads);
  std::vector<double> lift(moves.size(), 0.0);
  geometry::parallel_for(moves.size(), threads, [&](std::size_t k) {
    ClMove& m = moves[k];
    if (m.kind == ClMove::Kind::Rapid && m.tip_mm.z() >= safe_z) return;
    const double c = others.centre_z(m.tip_mm.head<2>());
    if (!std::isfinite(c)) return;
    const double floor = c - R + (m.kind == ClMove::Kind::Rapid ? o.clearance_mm : 0.0);
    if (floor > m.tip_mm.z()) lift[k] = floor - m.tip_mm.z(), m.tip_mm.z() = floor;
  });
  const double piece = 0.5 * std::sqrt(8 * others.ball_radius_mm() * tol);
  std::vector<std::vector<Eigen::Vector3d>> inserted(moves.size());
  geometry::parallel_for(moves.size(), threads, [&](std::size_t k) {
    if (k == 0 || moves[k].kind != ClMove::Kind::Feed) return;
    split_move(others, R, moves[k - 1].tip_mm, moves[k].tip_mm, piece, tol, 0, inserted[k]);
  });
  for (std::size_t k = 0; k < moves.size(); ++k) {
    for (const Eigen::Vector3d& q : inserted[k]) out.push_back({ClMove::Kind::Feed, q, std::nullopt, moves[k].feed_mm_per_min});
    result.mesh_split_points += inserted[k].size();
    if (lift[k] > tol) ++result.mesh_lifted_points;
    result.max_mesh_lift_mm = std::max(result.max_mesh_lift_mm, lift[k]);
    out.push_back(moves[k]);
  }
}

}  // namespace

PartToolpathResult generate_part_toolpath(const std::vector<BSplineSurface>& faces, const TriangleMesh& mesh,
                                          const std::vector<int>& triangle_face, const PartToolpathOptions& options,
                                          const PartProgress& progress) {
  const auto start = std::chrono::steady_clock::now();
  const ToolpathOptions& o = options.toolpath;
  validate(o);
  if (!(options.wall_share > 0 && options.wall_share < 1)) throw UsageError("the wall share must be in (0, 1)");
  if (!(options.mesh_gouge_tol_mm > 0) || !std::isfinite(options.mesh_gouge_tol_mm)) {
    throw UsageError("the whole-part gouge tolerance must be > 0");
  }
  if (triangle_face.size() != mesh.triangles.size()) throw UsageError("one face index per mesh triangle is needed");
  const double r = o.tool_radius_mm + o.stock_mm;

  PartToolpathResult result;
  double top = -kInf;
  for (const Eigen::Vector3d& v : mesh.vertices) top = std::max(top, v.z());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    result.faces.push_back(classify(faces[i], i, options.wall_share));
    const PartFace& f = result.faces.back();
    top = std::max(top, f.max_mm.z());
    (f.kind == PartFace::Kind::Machined ? result.machined : f.kind == PartFace::Kind::Wall ? result.walls : result.down)++;
  }
  if (result.machined == 0) {
    throw GeometryError("no face of the part faces up (" + std::to_string(result.walls) + " vertical walls, " +
                        std::to_string(result.down) + " facing down): nothing a ball end from above can finish");
  }
  // One safe plane for the whole part: each face's own (the top of its surface samples and path
  // plus --retract-mm, or --safe-z-mm, which each face checks), the highest of them and of the
  // mesh's top plus --retract-mm; each face's rapids on its own plane are moved up to it.
  if (o.safe_z_mm && *o.safe_z_mm < top) {
    throw UsageError("--safe-z-mm " + num(*o.safe_z_mm) + " is below the top of the part (" + num(top) + " mm)");
  }
  std::vector<ToolpathResult> per_face(faces.size());
  result.safe_z_mm = o.safe_z_mm ? *o.safe_z_mm : top + o.retract_mm;
  for (PartFace& f : result.faces) {
    if (f.kind != PartFace::Kind::Machined) continue;
    per_face[f.index] = generate_toolpath(faces[f.index], o);
    f.stats = per_face[f.index].stats;
    f.gouge_runs = per_face[f.index].gouges.size();
    result.safe_z_mm = std::max(result.safe_z_mm, f.stats.safe_z_mm);
  }
  std::vector<ClMove> all_moves;
  for (PartFace& f : result.faces) {
    if (f.kind == PartFace::Kind::Machined) {
      ToolpathResult& r_face = per_face[f.index];
      std::vector<ClMove> moves = std::move(r_face.cl.moves);
      r_face.cl.moves.clear();
      result.cl = r_face.cl;  // the header (tool, spindle, coolant, part name)
      for (ClMove& m : moves) {
        if (m.kind == ClMove::Kind::Rapid && m.tip_mm.z() == f.stats.safe_z_mm) m.tip_mm.z() = result.safe_z_mm;
      }
      TriangleMesh others;
      others.vertices = mesh.vertices;
      for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        if (triangle_face[t] != static_cast<int>(f.index)) others.triangles.push_back(mesh.triangles[t]);
      }
      if (others.triangles.empty()) {
        all_moves.insert(all_moves.end(), moves.begin(), moves.end());
      } else {
        check_against(MeshDropCutter(others, r), std::move(moves), o, result.safe_z_mm, options.mesh_gouge_tol_mm, result,
                      all_moves);
      }
    }
    if (progress) progress(f, faces.size());
  }
  result.cl.moves = std::move(all_moves);
  for (std::size_t k = 1; k < result.cl.moves.size(); ++k) {
    const double len = (result.cl.moves[k].tip_mm - result.cl.moves[k - 1].tip_mm).norm();
    (result.cl.moves[k].kind == ClMove::Kind::Feed ? result.feed_length_mm : result.rapid_length_mm) += len;
  }
  for (const PartFace& f : result.faces) result.cl_points += f.stats.cl_points;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

PartZmapResult verify_part_zmap(const TriangleMesh& mesh, const std::vector<int>& triangle_face,
                                const std::vector<PartFace>& report, const ClData& cl, double tool_radius_mm,
                                double cell_mm, int threads) {
  if (!(cell_mm > 0) || !(tool_radius_mm > 0)) throw UsageError("z-map: cell and tool radius must be > 0");
  if (triangle_face.size() != mesh.triangles.size()) throw UsageError("z-map: one face index per triangle is needed");
  const auto machined_face = [&](int f) {
    return f >= 0 && static_cast<std::size_t>(f) < report.size() && report[static_cast<std::size_t>(f)].kind == PartFace::Kind::Machined;
  };
  // The window: the machined faces' triangles.
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(kInf), hi = -lo;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (!machined_face(triangle_face[t])) continue;
    for (const int v : mesh.triangles[t]) {
      lo = lo.cwiseMin(mesh.vertices[static_cast<std::size_t>(v)].head<2>());
      hi = hi.cwiseMax(mesh.vertices[static_cast<std::size_t>(v)].head<2>());
    }
  }
  if (!lo.allFinite()) throw GeometryError("z-map: no machined face");
  HeightGrid part;
  part.lo = lo;
  part.cell_mm = cell_mm;
  part.nx = static_cast<long>(std::floor((hi.x() - lo.x()) / cell_mm)) + 1;
  part.ny = static_cast<long>(std::floor((hi.y() - lo.y()) / cell_mm)) + 1;
  if (static_cast<double>(part.nx) * static_cast<double>(part.ny) > 1e8) {
    throw GeometryError("z-map: " + std::to_string(part.nx) + " x " + std::to_string(part.ny) + " nodes of " + num(cell_mm) +
                        " mm exceed 100 million");
  }
  const std::size_t n = static_cast<std::size_t>(part.nx * part.ny);
  part.z.assign(n, -kInf);
  std::vector<int> top_face(n, -1);
  std::vector<double> top_nz(n, 1.0);
  // Each triangle that is not vertical over the nodes inside it (barycentric coordinates of the
  // node's xy, a closed triangle), at the height of its plane; the highest wins.
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3d& a = mesh.vertices[static_cast<std::size_t>(mesh.triangles[t][0])];
    const Eigen::Vector3d& b = mesh.vertices[static_cast<std::size_t>(mesh.triangles[t][1])];
    const Eigen::Vector3d& c = mesh.vertices[static_cast<std::size_t>(mesh.triangles[t][2])];
    const Eigen::Vector2d e1 = (b - a).head<2>(), e2 = (c - a).head<2>();
    const double det = e1.x() * e2.y() - e1.y() * e2.x();
    if (std::abs(det) < 1e-14) continue;
    const Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
    const long i0 = std::max(0L, static_cast<long>(std::ceil((std::min({a.x(), b.x(), c.x()}) - lo.x()) / cell_mm)));
    const long i1 = std::min(part.nx - 1, static_cast<long>(std::floor((std::max({a.x(), b.x(), c.x()}) - lo.x()) / cell_mm)));
    const long j0 = std::max(0L, static_cast<long>(std::ceil((std::min({a.y(), b.y(), c.y()}) - lo.y()) / cell_mm)));
    const long j1 = std::min(part.ny - 1, static_cast<long>(std::floor((std::max({a.y(), b.y(), c.y()}) - lo.y()) / cell_mm)));
    constexpr double kEdge = -1e-12;  // nodes on an edge belong to both triangles
    for (long j = j0; j <= j1; ++j) {
      for (long i = i0; i <= i1; ++i) {
        const Eigen::Vector2d d = part.node_xy(i, j) - a.head<2>();
        const double s1 = (d.x() * e2.y() - d.y() * e2.x()) / det, s2 = (e1.x() * d.y() - e1.y() * d.x()) / det;
        if (s1 < kEdge || s2 < kEdge || s1 + s2 > 1 - kEdge) continue;
        const double z = a.z() + s1 * (b.z() - a.z()) + s2 * (c.z() - a.z());
        const std::size_t k = static_cast<std::size_t>(j * part.nx + i);
        if (z > part.z[k]) part.z[k] = z, top_face[k] = triangle_face[t], top_nz[k] = std::abs(normal.z());
      }
    }
  }
  HeightGrid material = part;
  std::fill(material.z.begin(), material.z.end(), kInf);
  cut_material(material, cl, Cutter{tool_radius_mm, tool_radius_mm}, threads);
  PartZmapResult out;
  out.cell_mm = cell_mm;
  std::vector<double> left, left_normal;
  for (long j = 0; j < part.ny; ++j) {
    for (long i = 0; i < part.nx; ++i) {
      const std::size_t k = static_cast<std::size_t>(j * part.nx + i);
      if (!std::isfinite(part.z[k])) continue;
      const Eigen::Vector2d xy = part.node_xy(i, j);
      const Eigen::Vector3d at(xy.x(), xy.y(), part.z[k]);
      const double gouge = part.z[k] - material.z[k];
      if (gouge > out.max_gouge_mm) out.max_gouge_mm = gouge, out.max_gouge_at = at;
      out.max_gouge_normal_mm = std::max(out.max_gouge_normal_mm, gouge * top_nz[k]);
      if (!machined_face(top_face[k])) continue;
      ++out.nodes;
      const double l = material.z[k] - part.z[k], ln = l * top_nz[k];
      left.push_back(l);
      left_normal.push_back(ln);
      if (l > out.max_left_mm) out.max_left_mm = l, out.max_left_at = at;
      if (ln > out.max_left_normal_mm) out.max_left_normal_mm = ln, out.max_left_normal_at = at;
    }
  }
  // The swept ball in 3D: ball centres every `step` mm along each move below the part's top plus
  // R (a ball higher up reaches nothing). Between two samples a centre is at most step / 2 from
  // one, so a penetration is missed by at most step / 2; step = 0.02 mm.
  constexpr double kPenetrationStep = 0.02;
  out.penetration_step_mm = kPenetrationStep;
  const TriangleBuckets buckets(mesh, tool_radius_mm);
  double top = -kInf;
  for (const auto& v : mesh.vertices) top = std::max(top, v.z());
  std::vector<double> pen(cl.moves.size(), 0.0);
  std::vector<Eigen::Vector3d> pen_at(cl.moves.size(), Eigen::Vector3d::Zero());
  geometry::parallel_for(cl.moves.size(), geometry::thread_count(threads), [&](std::size_t k) {
    if (k == 0) return;
    const Eigen::Vector3d a = cl.moves[k - 1].tip_mm + Eigen::Vector3d(0, 0, tool_radius_mm);
    const Eigen::Vector3d b = cl.moves[k].tip_mm + Eigen::Vector3d(0, 0, tool_radius_mm);
    if (std::min(a.z(), b.z()) > top + tool_radius_mm) return;
    const int steps = std::max(1, static_cast<int>(std::ceil((b - a).norm() / kPenetrationStep)));
    for (int s = 0; s <= steps; ++s) {
      const Eigen::Vector3d c = a + (b - a) * (static_cast<double>(s) / steps);
      Eigen::Vector3d at = Eigen::Vector3d::Zero();
      const double d = buckets.nearest(c, at);
      if (tool_radius_mm - d > pen[k]) pen[k] = tool_radius_mm - d, pen_at[k] = at;
    }
  });
  for (std::size_t k = 0; k < pen.size(); ++k) {
    if (pen[k] > out.max_penetration_mm) out.max_penetration_mm = pen[k], out.max_penetration_at = pen_at[k];
  }
  const auto p95 = [](std::vector<double>& v) {
    if (v.empty()) return 0.0;
    const std::size_t q = static_cast<std::size_t>(0.95 * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + static_cast<long>(q), v.end());
    return v[q];
  };
  out.p95_left_mm = p95(left);
  out.p95_left_normal_mm = p95(left_normal);
  return out;
}

}  // namespace photomill::toolpath
