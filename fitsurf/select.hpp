// Selecting the part in a point cloud before fitting: the part usually stands on a plate or table
// carrying markers, whose points must not be fitted. Four filters, applied in this order:
// keep inside a box, keep above a plane, drop the dominant plane (RANSAC) and what lies beyond it,
// and, where the part stands on walls, drop the walls and the floor at their foot (walls.hpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/walls.hpp"

namespace photomill::fitsurf {

// The plane normal . x + offset_mm = 0 (unit normal); signed distance normal . x + offset_mm.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double offset_mm = 0;
  double distance_mm(const Eigen::Vector3d& x) const { return normal.dot(x) + offset_mm; }
};

struct SelectOptions {
  // Keep points with min <= x <= max per axis: {x_min, y_min, z_min, x_max, y_max, z_max}, mm.
  std::optional<std::array<double, 6>> keep_box_mm;
  // Keep points strictly on the side of this plane its normal points to.
  std::optional<Plane> keep_above;
  // Drop the dominant plane's points (within plane_threshold_mm) and everything on its far side
  // (the side with fewer of the remaining points: under the plate).
  bool drop_plane = false;
  double plane_threshold_mm = 0.5;
  // RANSAC (Fischler & Bolles 1981): planes through 3 random points, scored by their inliers
  // among a random subset of ransac_sample_size points; the iteration count adapts to the best
  // inlier ratio e as log(1 - confidence) / log(1 - e^3), at most ransac_max_iterations.
  int ransac_max_iterations = 2000;
  double ransac_confidence = 0.999;
  std::size_t ransac_sample_size = 20000;
  // The dominant plane must hold at least this fraction of the points to be dropped.
  double min_plane_fraction = 0.05;
  std::uint64_t seed = 1;
  WallOptions walls;
};

struct Selection {
  std::vector<std::size_t> kept;  // indices into the input, increasing
  std::size_t dropped_box = 0;
  std::size_t dropped_below = 0;        // by keep_above
  std::size_t dropped_plane = 0;        // inliers of the dominant plane
  std::size_t dropped_beyond_plane = 0; // on its far side
  std::optional<Plane> plane;           // the dominant plane, normal towards the kept side
  std::optional<WallSummary> walls;     // set when the part stands on walls
};

// Throws GeometryError when a filter leaves nothing, when no dominant plane is found, or when
// the cloud is only that plane (nothing stands on it). `normals`: the cloud's own, one per point,
// or empty (split_walls).
Selection select_part(const std::vector<Eigen::Vector3d>& points, const SelectOptions& options,
                      const std::vector<Eigen::Vector3d>& normals = {});

// The dominant plane of points[indices] by RANSAC, refined by least squares on its inliers.
// Throws GeometryError if no plane holds min_plane_fraction of them.
Plane dominant_plane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& indices,
                     const SelectOptions& options);

}  // namespace photomill::fitsurf
