#include "toolpath/mesh_drop.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "formats/error.hpp"
#include "formats/text.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kNegInf = -std::numeric_limits<double>::infinity();
constexpr double kMaxBuckets = 4e7;
constexpr double kMaxRegistrations = 2e8;
// Facets steeper than this (|n_z| of the unit normal) have no facet contact; their edges bound
// them from above.
constexpr double kMinFacetNz = 1e-12;

std::string num(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return format_double(v);
}

double cross2(const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

// f(q) = q_z + sqrt(r^2 - |q_xy - p|^2): the centre height of a ball over p that touches q. For
// a point q at horizontal distance exactly r (up to rounding) the root is 0.
double ball_over(const Eigen::Vector3d& q, const Eigen::Vector2d& p, double r2) {
  const double dx = q.x() - p.x(), dy = q.y() - p.y();
  return q.z() + std::sqrt(std::max(0.0, r2 - (dx * dx + dy * dy)));
}

}  // namespace

// Highest centre of a ball of radius r over p touching the triangle (a, b, c): the maximum over
// the triangle's points q with |q_xy - p| <= r of f(q) = q_z + sqrt(r^2 - |q_xy - p|^2), or -inf.
// (The constructor precomputes r n_xy, 1 / ((b - a) x (c - a))_z, and per edge 1 / L^2 and
// e_z / (|e| L).)
//
// f is concave on the triangle's plane (q_z is linear there, the root concave), and its gradient
// is infinite inwards at the rim |q_xy - p| = r, so the maximum over the (convex) part of the
// triangle under the ball lies at one of three kinds of candidates (OpenCAMLib's vertex, facet and
// edge tests), and the answer is the largest candidate:
//
// (1) Vertex v with d = |v_xy - p| <= r:  v_z + sqrt(r^2 - d^2).
//
// (2) Edge A -> B, e = B - A, horizontal length L = |e_xy| > 0 (a vertical edge is covered by its
//     upper vertex). Work in the vertical plane through the edge, s the horizontal coordinate
//     along it from A: s_foot = (p - A_xy) . e_xy / L is the foot of p on the edge's line,
//     h = |(p - A_xy) x e_xy| / L the horizontal distance from p to that line (h > r: out of
//     reach), and the ball cuts that plane in a circle of radius rho = sqrt(r^2 - h^2) centred
//     over s_foot. With slope m = e_z / L, the height of a centre touching the line at s is
//     z_line(s) + sqrt(rho^2 - (s - s_foot)^2); its derivative m - (s - s_foot) / sqrt(...) is 0 at
//       s* = s_foot + m rho / sqrt(1 + m^2),   giving   centre_z = z_line(s_foot) + rho sqrt(1 + m^2).
//     As sqrt(1 + m^2) = |e| / L, the contact is at the fraction of the edge
//       sigma = s* / L = (p - A_xy) . e_xy / L^2 + rho e_z / (|e| L),
//     and counts only for 0 <= sigma <= 1 (otherwise the maximum along the edge is at a vertex,
//     which (1) covers).
//
// (3) Facet: with unit normal n oriented n_z > 0 (facets with n_z <= 1e-12, vertical or
//     degenerate, are skipped: their edges cover them), the ball touches the plane from above
//     when its centre c = (p, c_z) lies at distance r from it along n, so the contact point is
//     q = c - r n:
//       q_xy = p - r n_xy,   centre_z = q_z + r n_z = z_plane(p) + r / n_z
//     (with the plane's slope (a, b) = -n_xy / n_z, q_z = z_plane(p) + (a, b) . (q_xy - p) =
//     z_plane(p) + r |n_xy|^2 / n_z, and r |n_xy|^2 / n_z + r n_z = r (|n_xy|^2 + n_z^2) / n_z =
//     r / n_z); this is where f is stationary on the plane. It counts only when q lies inside
//     the triangle: its barycentric coordinates in the triangle's xy projection,
//       l1 = ((q - a) x (c - a))_z / ((b - a) x (c - a))_z,  l2 = ((b - a) x (q - a))_z / (same),
//     and 1 - l1 - l2, all >= 0 (a contact on the boundary is found by (1) or (2) as well). As f is
//     concave on the plane, a facet contact inside the triangle is the triangle's maximum and the
//     edges and vertices are not tested then (unless the triangle is a sliver whose computed
//     normal is inaccurate).
//
// (2) and (3) locate the contact point q in the triangle with the formulas above and then
// evaluate f(q) directly: equal to the closed forms in exact arithmetic, but never above the true
// maximum by more than the rounding of f itself (f is stationary at the contact, so an error in
// q changes the value only to second order), and on a steep facet it avoids the cancellation of
// z_plane(p) against r / n_z.
double MeshDropCutter::triangle_max(const Tri& t, const Eigen::Vector2d& p, double r2) {
  double best = kNegInf;
  // (3) facet, first: a contact inside is the triangle's maximum.
  if (t.inv_area2 != 0) {
    const Eigen::Vector2d ab = (t.b - t.a).head<2>(), ac = (t.c - t.a).head<2>();
    const Eigen::Vector2d qa = p - t.facet_shift - t.a.head<2>();  // q_xy - a_xy, q_xy = p - r n_xy
    const double l1 = cross2(qa, ac) * t.inv_area2;
    const double l2 = cross2(ab, qa) * t.inv_area2;
    if (l1 >= 0 && l2 >= 0 && 1 - l1 - l2 >= 0) {
      best = ball_over(t.a + l1 * (t.b - t.a) + l2 * (t.c - t.a), p, r2);
      if (t.facet_decides) return best;
    }
  }
  // (1) vertices.
  for (const Eigen::Vector3d* v : {&t.a, &t.b, &t.c}) {
    const double d2 = (v->head<2>() - p).squaredNorm();
    if (d2 <= r2) best = std::max(best, v->z() + std::sqrt(r2 - d2));
  }
  // (2) edges.
  const std::array<const Eigen::Vector3d*, 4> corner{&t.a, &t.b, &t.c, &t.a};
  for (std::size_t k = 0; k < 3; ++k) {
    if (t.inv_len2_xy[k] == 0) continue;
    const Eigen::Vector3d& A = *corner[k];
    const Eigen::Vector3d e = *corner[k + 1] - A;
    const Eigen::Vector2d w = p - A.head<2>();
    const double cr = cross2(e.head<2>(), w);
    const double h2 = cr * cr * t.inv_len2_xy[k];
    if (h2 > r2) continue;
    const double rho = std::sqrt(r2 - h2);
    const double sigma = w.dot(e.head<2>()) * t.inv_len2_xy[k] + rho * t.rise[k];
    if (!(sigma >= 0 && sigma <= 1)) continue;
    best = std::max(best, ball_over(A + sigma * e, p, r2));
  }
  return best;
}

MeshDropCutter::MeshDropCutter(const TriangleMesh& mesh, double ball_radius_mm) : r_(ball_radius_mm) {
  if (!(std::isfinite(r_) && r_ > 0 && std::isfinite(r_ * r_))) {
    throw GeometryError("mesh drop cutter: the ball radius must be finite and > 0 (got " + num(r_) + " mm)");
  }
  if (mesh.triangles.empty()) throw GeometryError("mesh drop cutter: the mesh has no triangles");
  if (mesh.triangles.size() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw GeometryError("mesh drop cutter: too many triangles (" + std::to_string(mesh.triangles.size()) + ")");
  }
  min_xy_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  max_xy_ = -min_xy_;
  top_z_ = kNegInf;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3d& v = mesh.vertices[i];
    if (!v.allFinite()) {
      throw GeometryError("mesh drop cutter: vertex " + std::to_string(i) + " is not finite (" + num(v.x()) + ", " +
                          num(v.y()) + ", " + num(v.z()) + ")");
    }
    min_xy_ = min_xy_.cwiseMin(v.head<2>());
    max_xy_ = max_xy_.cwiseMax(v.head<2>());
    top_z_ = std::max(top_z_, v.z());
  }
  const std::size_t nv = mesh.vertices.size();
  tris_.reserve(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const std::array<int, 3>& idx = mesh.triangles[t];
    for (int k : idx) {
      if (k < 0 || static_cast<std::size_t>(k) >= nv) {
        throw GeometryError("mesh drop cutter: triangle " + std::to_string(t) + " has vertex index " +
                            std::to_string(k) + ", out of range for " + std::to_string(nv) + " vertices");
      }
    }
    Tri tri;
    tri.a = mesh.vertices[static_cast<std::size_t>(idx[0])];
    tri.b = mesh.vertices[static_cast<std::size_t>(idx[1])];
    tri.c = mesh.vertices[static_cast<std::size_t>(idx[2])];
    tri.lo = tri.a.head<2>().cwiseMin(tri.b.head<2>()).cwiseMin(tri.c.head<2>());
    tri.hi = tri.a.head<2>().cwiseMax(tri.b.head<2>()).cwiseMax(tri.c.head<2>());
    tri.zmax = std::max({tri.a.z(), tri.b.z(), tri.c.z()});
    const Eigen::Vector3d normal = (tri.b - tri.a).cross(tri.c - tri.a);
    const double nn = normal.norm();
    tri.facet_shift.setZero();
    tri.inv_area2 = 0;
    tri.facet_decides = false;
    if (nn > 0 && std::abs(normal.z()) / nn > kMinFacetNz && std::isfinite(1 / normal.z())) {
      tri.facet_shift = (normal.z() > 0 ? r_ : -r_) / nn * normal.head<2>();
      tri.inv_area2 = 1 / normal.z();
      // The cross product's rounding is about 1e-16 |b - a| |c - a|: on a sliver (corner angles
      // near 0 or 180 degrees) the normal is inaccurate and the facet contact only one candidate
      // among the others (still a point of the triangle, so never too high).
      tri.facet_decides = nn > 1e-6 * (tri.b - tri.a).norm() * (tri.c - tri.a).norm();
    }
    const std::array<const Eigen::Vector3d*, 4> corner{&tri.a, &tri.b, &tri.c, &tri.a};
    for (std::size_t k = 0; k < 3; ++k) {
      const Eigen::Vector3d e = *corner[k + 1] - *corner[k];
      const double L2 = e.head<2>().squaredNorm();
      tri.inv_len2_xy[k] = 0;  // a vertical edge (or one too short for 1 / L^2): no edge test
      tri.rise[k] = 0;
      if (L2 > 0 && std::isfinite(1 / L2)) {
        const double rise = e.z() / (e.norm() * std::sqrt(L2));
        if (std::isfinite(rise)) tri.inv_len2_xy[k] = 1 / L2, tri.rise[k] = rise;
      }
    }
    tris_.push_back(tri);
  }

  // The grid covers the vertices' box grown by r (plus a hair for rounding): every position with
  // a mesh point within r horizontally is inside it. Cell side: r, or larger when the mesh is
  // sparse (about as many buckets as triangles: sqrt(area / T), and max(width, height) / T for a
  // box that is nearly a line), since a bucket much smaller than the triangles only repeats them.
  const double pad = r_ + 1e-9 * (r_ + std::max(min_xy_.cwiseAbs().maxCoeff(), max_xy_.cwiseAbs().maxCoeff()));
  origin_ = min_xy_ - Eigen::Vector2d::Constant(pad);
  const Eigen::Vector2d extent = (max_xy_ - min_xy_) + Eigen::Vector2d::Constant(2 * pad);
  if (!extent.allFinite()) {
    throw GeometryError("mesh drop cutter: the mesh's extent overflows (" + num(min_xy_.x()) + " .. " + num(max_xy_.x()) +
                        " x " + num(min_xy_.y()) + " .. " + num(max_xy_.y()) + " mm)");
  }
  const double T = static_cast<double>(tris_.size());
  cell_ = std::max({r_, std::sqrt(extent.x() * extent.y() / T), extent.maxCoeff() / T});
  const double fx = std::max(1.0, std::ceil(extent.x() / cell_));
  const double fy = std::max(1.0, std::ceil(extent.y() / cell_));
  if (!(fx * fy <= kMaxBuckets)) {
    throw GeometryError("mesh drop cutter: the bucket grid would have " + num(fx) + " x " + num(fy) +
                        " buckets (cell " + num(cell_) + " mm over " + num(extent.x()) + " x " + num(extent.y()) +
                        " mm), more than " + num(kMaxBuckets));
  }
  nx_ = static_cast<int>(fx);
  ny_ = static_cast<int>(fy);
  // Each triangle goes into every bucket its horizontal box grown by r touches (then a query
  // visits only its own bucket).
  struct Range {
    int x0, x1, y0, y1;
  };
  const auto range_of = [&](const Tri& t) {
    const auto index = [&](double v, double o, int n) {
      return static_cast<int>(std::clamp(std::floor((v - o) / cell_), 0.0, static_cast<double>(n - 1)));
    };
    return Range{index(t.lo.x() - pad, origin_.x(), nx_), index(t.hi.x() + pad, origin_.x(), nx_),
                 index(t.lo.y() - pad, origin_.y(), ny_), index(t.hi.y() + pad, origin_.y(), ny_)};
  };
  double registrations = 0;
  for (const Tri& t : tris_) {
    const Range g = range_of(t);
    registrations += static_cast<double>(g.x1 - g.x0 + 1) * static_cast<double>(g.y1 - g.y0 + 1);
  }
  if (registrations > kMaxRegistrations) {
    throw GeometryError("mesh drop cutter: " + std::to_string(tris_.size()) + " triangles would take " +
                        num(registrations) + " bucket registrations (" + std::to_string(nx_) + " x " +
                        std::to_string(ny_) + " buckets of " + num(cell_) + " mm, ball radius " + num(r_) +
                        " mm), more than " + num(kMaxRegistrations));
  }
  const std::size_t nbuckets = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  bucket_start_.assign(nbuckets + 1, 0);
  for (const Tri& t : tris_) {
    const Range g = range_of(t);
    for (int y = g.y0; y <= g.y1; ++y) {
      for (int x = g.x0; x <= g.x1; ++x) ++bucket_start_[static_cast<std::size_t>(y) * nx_ + x + 1];
    }
  }
  for (std::size_t b = 1; b <= nbuckets; ++b) bucket_start_[b] += bucket_start_[b - 1];
  bucket_items_.resize(bucket_start_[nbuckets]);
  std::vector<std::uint32_t> fill(bucket_start_.begin(), bucket_start_.end() - 1);
  // Triangles in order of zmax, highest first, so that every bucket comes out sorted.
  std::vector<int> order(tris_.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int i, int j) {
    return tris_[static_cast<std::size_t>(i)].zmax > tris_[static_cast<std::size_t>(j)].zmax;
  });
  for (int i : order) {
    const Range g = range_of(tris_[static_cast<std::size_t>(i)]);
    for (int y = g.y0; y <= g.y1; ++y) {
      for (int x = g.x0; x <= g.x1; ++x) bucket_items_[fill[static_cast<std::size_t>(y) * nx_ + x]++] = i;
    }
  }
}

double MeshDropCutter::centre_z(const Eigen::Vector2d& xy) const {
  if (!xy.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  const double fx = std::floor((xy.x() - origin_.x()) / cell_);
  const double fy = std::floor((xy.y() - origin_.y()) / cell_);
  if (!(fx >= 0 && fx < nx_ && fy >= 0 && fy < ny_)) return kNegInf;
  const std::size_t b = static_cast<std::size_t>(fy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(fx);
  const double r2 = r_ * r_;
  double best = kNegInf;
  for (std::uint32_t k = bucket_start_[b]; k < bucket_start_[b + 1]; ++k) {
    const Tri& t = tris_[static_cast<std::size_t>(bucket_items_[k])];
    // No point of the triangle gives more than zmax + sqrt(r^2 - d^2), d the horizontal distance
    // from xy to its box; the bucket is sorted by zmax, so once zmax + r cannot win, none can.
    // The bounds carry a slack of 1e-12 (|zmax| + r) so that rounding never lets them drop a
    // triangle whose computed value would still win by an ulp.
    const double slack = 1e-12 * (std::abs(t.zmax) + r_);
    if (t.zmax + r_ + slack <= best) break;
    const double dx = std::max({t.lo.x() - xy.x(), 0.0, xy.x() - t.hi.x()});
    const double dy = std::max({t.lo.y() - xy.y(), 0.0, xy.y() - t.hi.y()});
    const double d2 = dx * dx + dy * dy;
    if (d2 > r2 || t.zmax + std::sqrt(r2 - d2) + slack <= best) continue;
    best = std::max(best, triangle_max(t, xy, r2));
  }
  return best;
}

}  // namespace photomill::toolpath
