// Drop cutter for a ball-end tool against a triangle mesh (a whole CAD solid, tessellated), the
// mesh counterpart of DropCutter (cutter.hpp), to check tool paths against the part: the lowest
// height of the ball's centre at a horizontal position at which the ball cuts into no triangle.
// As OpenCAMLib's BallCutter::dropCutter: per triangle the vertex, edge and facet contacts,
// exact (closed forms, no sampling); a uniform grid of buckets over (x, y) finds the triangles.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace photomill::toolpath {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;          // mm
  std::vector<std::array<int, 3>> triangles;      // indices into vertices
};

class MeshDropCutter {
public:
  // Throws GeometryError (formats/error.hpp) for a non-finite vertex, an index out of range, a
  // non-positive/non-finite radius, or a mesh with no triangles, and for a bucket grid beyond the
  // memory bounds (more than 4e7 buckets or 2e8 triangle registrations). Degenerate (zero-area)
  // triangles are kept for their edges and vertices only. The mesh is copied: it need not outlive
  // the cutter.
  MeshDropCutter(const TriangleMesh& mesh, double ball_radius_mm);

  // Lowest height of the ball's CENTRE above horizontal position xy at which it touches no
  // triangle from above:
  //   max over the mesh's points q with |q_xy - xy| <= r of q_z + sqrt(r^2 - |q_xy - xy|^2);
  // -infinity where no point of the mesh is within r horizontally; NaN for a non-finite xy.
  // const and free of shared scratch: safe to call from several threads at once.
  double centre_z(const Eigen::Vector2d& xy) const;

  double ball_radius_mm() const { return r_; }
  double top_z() const { return top_z_; }  // highest vertex z
  // Bounding box of the vertices (all of them, referenced by a triangle or not).
  Eigen::Vector2d min_xy() const { return min_xy_; }
  Eigen::Vector2d max_xy() const { return max_xy_; }
  std::size_t triangle_count() const { return tris_.size(); }

private:
  // A triangle with what its contact tests need precomputed (mesh_drop.cpp states the formulas).
  struct Tri {
    Eigen::Vector3d a, b, c;     // the corners
    Eigen::Vector2d lo, hi;      // horizontal bounding box
    double zmax;                 // highest corner
    Eigen::Vector2d facet_shift; // r n_xy, n the upward unit normal
    double inv_area2;            // 1 / ((b - a) x (c - a))_z; 0: no facet test
    bool facet_decides;          // a facet contact inside is the maximum (the normal is accurate)
    std::array<double, 3> inv_len2_xy;  // edges a->b, b->c, c->a: 1 / L^2 (0: vertical edge)
    std::array<double, 3> rise;         // e_z / (|e| L)
  };
  static double triangle_max(const Tri& t, const Eigen::Vector2d& p, double r2);

  double r_;
  double top_z_ = 0;
  Eigen::Vector2d min_xy_, max_xy_;
  std::vector<Tri> tris_;
  // Buckets: square cells of side cell_ from origin_ (the vertices' box grown by r on all sides),
  // nx_ by ny_, CSR layout; each bucket's triangles sorted by zmax, highest first.
  Eigen::Vector2d origin_;
  double cell_ = 0;
  int nx_ = 0, ny_ = 0;
  std::vector<std::uint32_t> bucket_start_;  // at most 2e8 registrations
  std::vector<int> bucket_items_;
};

}  // namespace photomill::toolpath
