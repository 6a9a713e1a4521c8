// Two-view points checked against their neighbours (issue 24).
//
// A point seen in two photos only is the intersection of two rays, and its reprojection error
// says nothing about where along them it lies: a wrong match that happens to lie on (or near) the
// epipolar line triangulates to a wrong depth with a tiny reprojection error. A third view
// checks the depth; without one, the point's neighbours seen in three or more views do, since
// the photographed object is a surface:
//   1. Reference points: the result's points with `min_views` (3) or more views, and the control
//      points. Their typical spacing D is the median, over them, of the distance from each to
//      its k-th nearest other reference point (k = `neighbours`).
//   2. A two-view point P whose k-th nearest reference point is farther than `reach` x D is
//      unsupported (nothing seen three times is near it): removed.
//   3. Otherwise its k nearest reference points give the local surface: their plane (total least
//      squares: the centroid c and the normal n, the eigenvector of their scatter matrix with the
//      smallest eigenvalue; Pearson 1901, Hoppe et al. 1992 for point-cloud normals) and, with 10
//      or more of them, the quadric of their heights over it, w = a + b u + c v + d u^2 + e uv +
//      f v^2 (least squares; the local jet of the surface, Cazals & Pouget 2005), so that a curved
//      surface's sagitta is not taken for an offset. Their spread about it is
//      s = 1.4826 MAD(residuals) sqrt(k / (k - m)) (robust standard deviation, Hampel 1974,
//      corrected for the m terms fitted), the prediction at P has variance s^2 (1 + m / k) (the
//      mean leverage), and P's offset d = n.(P - c) - w(u_P, v_P) has the standard deviation
//      sqrt(s^2 (1 + m / k) + n^T Sigma_P n) (Sigma_P the point's covariance from the
//      adjustment, along the normal). P agrees with its neighbours when
//        |d| <= max(tolerance_mm, sigmas x sqrt(s^2 (1 + m / k) + n^T Sigma_P n))
//      (a k-sigma test as in data snooping, Baarda 1968), and is removed otherwise.
// Points with a third view are kept; so are all points when fewer than k + 1 points other than
// control points have a third view (e.g. two photos only: then nothing can check them; control
// points on a plate alone would judge the part by the plate's plane).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill::triangulate {

struct TwoViewOptions {
  bool enabled = true;
  std::size_t min_views = 3;      // points with this many views or more are the references
  std::size_t neighbours = 16;    // k: reference points whose local surface judges a two-view point
  double reach = 4;               // unsupported beyond this many typical spacings (k-th neighbour)
  double sigmas = 5;              // the test's k-sigma factor
  double tolerance_mm = 0.1;      // |d| up to this always agrees (model error of the local surface)
  int threads = 0;
};

enum class TwoViewVerdict { NotChecked, Kept, Unsupported, OffNeighbours };

// One point for the check: where it is, in how many views, its covariance (mm^2; zero for a
// fixed control point).
struct CheckedPoint {
  Eigen::Vector3d xyz_mm = Eigen::Vector3d::Zero();
  std::size_t views = 0;
  Eigen::Matrix3d covariance_mm2 = Eigen::Matrix3d::Zero();
  bool control = false;  // a control point: a reference whatever its views, never checked
};

struct TwoViewCheck {
  bool ran = false;                    // false: disabled, or too few reference points
  std::size_t reference_points = 0;
  double spacing_mm = 0;               // D
  std::size_t checked = 0;             // two-view points judged
  std::size_t unsupported = 0;         // removed: no reference point near
  std::size_t off_neighbours = 0;      // removed: off their neighbours' surface
  std::vector<TwoViewVerdict> verdict; // per point
  std::vector<double> distance_mm;     // per checked point: |d| (NaN when unsupported or not checked)
  std::vector<double> allowed_mm;      // per checked point: the bound on |d|
};

// Judges every point with fewer than options.min_views views (and at least two) against the
// others. Pure function of its input; never throws on empty input.
TwoViewCheck check_two_view_points(const std::vector<CheckedPoint>& points, const TwoViewOptions& options);

}  // namespace photomill::triangulate
