// How steep the data themselves are over a parameter plane, cell by cell: what a fitted height
// field must be allowed to follow, and which plane holds the data best as a height field.
//
// The plane is cut into square cells of `cell_spacings` mean point spacings; the points of a cell
// with at least `min_points` of them get their own best-fit plane (principal component analysis
// of the cell's 3 x 3 covariance, its normal the eigenvector of the smallest eigenvalue) when they
// spread in two directions (middle eigenvalue at least `min_width_ratio`^2 times the largest:
// a cell holding one scan line has no normal). The cell's slope is the angle between that normal
// and the plane's normal, acos |n . e3|, 0-90 degrees.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/frame.hpp"

namespace photomill::fitsurf {

// Square cells over a parameter box, `spacings` mean point spacings wide (the mean spacing of n
// points over the box: sqrt(area / n)); points outside the box go to the nearest edge cell.
// The two-layer test (fit.cpp) and the slopes below cut the plane the same way.
struct CellGrid {
  double t1_min = 0, t2_min = 0, cell_mm = 1;
  int nx = 0, ny = 0;
  CellGrid() = default;
  CellGrid(const ParameterBox& box, std::size_t n, double spacings);
  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  std::size_t cell_of(const Eigen::Vector3d& local) const;
};

struct SlopeOptions {
  double cell_spacings = 4;
  std::size_t min_points = 6;
  double min_width_ratio = 0.1;
  // The score of a plane is this quantile of its cells' slopes: one noisy cell does not decide.
  double score_quantile = 0.99;
};

struct DataSlope {
  CellGrid grid;
  std::vector<float> slope_deg;  // per cell (CellGrid::cell_of); negative: no slope there
  double max_deg = 0;            // steepest cell (0 without any)
  Eigen::Vector3d max_at = Eigen::Vector3d::Zero();  // its points' centroid, local mm
  double score_deg = 0;          // SlopeOptions::score_quantile of the cells' slopes
  std::size_t cells = 0;         // cells with a slope

  // The steepest slope of the cells within radius_mm (at least the cell holding local (t1, t2)
  // and its 8 neighbours) of that point, in a square; negative: none.
  double near(double t1, double t2, double radius_mm = 0) const;
};

// The slope of the local points (frame coordinates: t3 the height) over the box's plane.
DataSlope data_slope(const std::vector<Eigen::Vector3d>& local, const ParameterBox& box, const SlopeOptions& options = {});

// The parameter plane for PlaneChoice::Auto: the best-fit plane (PCA) unless the world xy plane
// holds the data as a height field better, i.e. its steepest data slope (score) is lower by more
// than `prefer_pca_deg`. pca_score_deg / xy_score_deg receive the two scores when not null.
PlaneChoice choose_plane(const std::vector<Eigen::Vector3d>& points, const FrameOptions& frame_options,
                         const SlopeOptions& options, double prefer_pca_deg, double* pca_score_deg = nullptr,
                         double* xy_score_deg = nullptr);

}  // namespace photomill::fitsurf
