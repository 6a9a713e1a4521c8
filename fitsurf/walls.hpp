// A part that stands on vertical (or nearly vertical) walls: its top is a height field, the walls
// and the plate at their foot are not. fitsurf fits the top alone and reports the walls.
//
// Found from the data in the machine frame (z up, the control points' frame), at the scale
// r = max(radius_mm, radius_spacings x the points' mean spacing over their xy box):
// 1. Each point's normal is its own where the cloud has normals (densify's), else that of the
//    best-fit plane of its neighbours within r (PCA of their 3 x 3 covariance, at least
//    min_neighbours of them). A point whose normal is more than slope_deg from z is on a wall's face.
// 2. The other points are joined into regions: two points within r of each other, joined by a
//    segment no steeper than slope_deg, are in the same region. A wall (higher than r, or steeper
//    than slope_deg) separates the top from the floor at its foot, with or without points on
//    its face; a blended part, however steep its flanks, stays one region.
// 3. A region of at least min_region_points is floor when at least min_step_points of its points
//    lie under another such region, higher (median) than it: a point of it within r in x, y,
//    higher by min_height_mm and by tan(step_slope_deg) times their horizontal distance (the
//    step may be seen across a gap where the top hid the wall's foot from the camera).
//    A region of which half the points or more lie right under the higher one (within a mean
//    spacing in x, y) is not beside the top but under it, the underside of an overhang: not floor
//    (the fold check judges it). Regions at the floor's height (median within min_height_mm of
//    the floor's) are floor too: the plate where a sparse cloud splits it into several regions.
//    Floor regions and wall faces are dropped, every other point kept.
//    No floor: no walls (the selection is unchanged).
// 4. Near what was dropped (within r in x, y), a point lower than the plane of its kept
//    neighbours within r predicts, by rim_step_mm plus three robust deviations about it, is
//    on a wall's face just under the rim (or a feature straddling the edge): dropped too, or it
//    pulls the top's edge down.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace photomill::fitsurf {

struct WallOptions {
  bool enabled = true;
  double slope_deg = 80;               // a face or a link steeper than this is a wall's
  double radius_mm = 2;                // r: the neighbourhood, at least this...
  double radius_spacings = 2.5;        // ...and at least this many mean point spacings
  std::size_t min_neighbours = 5;      // a normal from fewer neighbours is not judged
  double step_slope_deg = 60;          // a step from a region up to another is steeper than this...
  double min_height_mm = 2;            // ...and at least this high
  std::size_t min_region_points = 50;  // smaller regions are neither floor nor top (noise, a marker)
  std::size_t min_step_points = 20;    // a floor has at least this many points under a step
  double rim_step_mm = 0.25;           // near the walls, a point this far under its neighbours'
                                       // plane (plus 3 robust sigma) is on a wall's face under the rim
};

struct WallSummary {
  std::size_t wall_points = 0;       // points on the walls' faces
  std::size_t dropped_floor = 0;     // points of the floor regions at their foot
  std::size_t top_points = 0;        // points kept
  double radius_mm = 0;              // r used
  double floor_z_mm = 0;             // the floor's median height
  double wall_top_z_mm = 0;          // the walls' highest points (0.95 quantile of their heights)
  Eigen::Vector2d box_min = Eigen::Vector2d::Zero(), box_max = Eigen::Vector2d::Zero();  // the top's xy extent
};

// Splits points[kept] (world mm, z up). Returns nothing when no wall is found (kept unchanged);
// else removes the walls' and the floor's points from kept. `normals` (one per point, or empty):
// the cloud's own normals (densify measures each point's), which decide step 1 for the points
// that have a finite, non-zero one instead of their neighbourhood's plane: at a dense cloud's
// rim a neighbourhood of r holds both the top and the wall's face, and its plane is neither's.
std::optional<WallSummary> split_walls(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& kept,
                                       const WallOptions& options, const std::vector<Eigen::Vector3d>& normals = {});

}  // namespace photomill::fitsurf
