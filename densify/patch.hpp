// One surface patch measured by multi-image least-squares matching with a geometric constraint:
// a small plane seen in a reference photo and matched in every other view at once, its position
// bound to the reference pixel's ray (Gruen & Baltsavias 1988, "Geometrically constrained
// multiphoto matching", PE&RS 54(5); the plane-induced map between the views replaces their
// affine shaping terms, as in Furukawa & Ponce's PMVS patches, 2010).
//
// Model. In the reference camera's frame a plane is n . X = 1 (n = normal / distance, 3
// parameters). The reference pixel x_ref + d (d the window offset) sees the undistorted ray
// r(d) = (x, y, 1), which meets the plane at X(d) = r(d) / (n . r(d)); view j sees it at
//   u_j(d) = pi_j(R_j X(d) + t_j)
// (R_j, t_j the view's pose relative to the reference, pi_j the full camera model of
// geometry/camera_model.hpp). The grey values obey
//   f(x_ref + d) = a_j + b_j g_j(u_j(d)) + e
// and n, a_j, b_j (3 + 2 m parameters for m views) minimise sum e^2 by Gauss-Newton. The
// point is X(0), the plane's normal is n / |n|.
//
// u_j(d) is evaluated exactly on a 3 x 3 grid of window offsets (corners, edge midpoints, centre)
// and interpolated between them by a quadratic in d, as are its derivatives with respect to n:
// over a window of 15 px, the map's third-order terms (perspective and lens distortion) stay
// below 1e-4 px. Samples of g_j use cubic convolution with its analytic gradient (match's
// sample_cubic).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "geometry/camera_model.hpp"

namespace photomill::densify {

// A photo as the patches see it.
struct PatchView {
  cv::Mat grey;              // CV_32F
  Eigen::Matrix3d rotation;  // cam_from_world
  Eigen::Vector3d translation_mm;
};

struct PatchOptions {
  int half_window_px = 9;
  // The window is sampled every this many pixels (from -half_window_px to +half_window_px).
  int window_stride_px = 2;
  // Curvature terms: the inverse depth along the window's rays is n . r(d) + c . (x^2, x y, y^2)
  // (x, y the offset in half-windows), so that a curved surface does not pull the plane fitted
  // over the window off the centre's true point (as match's quadratic LSM: Bethmann & Luhmann 2010).
  bool quadratic = true;
  int max_iterations = 20;
  // Converged when the window centre moves by less than this in every view in one iteration.
  double converged_px = 0.01;
  // A view whose aligned window correlates below this is dropped; the patch needs
  // min_views - 1 views besides the reference.
  double min_correlation = 0.95;
  // ... and the window's central square of 2 centre_half_window_px + 1 pixels at least this
  // (a centre that sees past a depth edge while the window matches on the near face).
  int centre_half_window_px = 3;
  double min_centre_correlation = 0.8;
  int min_views = 3;
  // Refused when the centre moved farther than this in some view from where it started (it
  // found another texture), or when the plane is seen more obliquely than this from the
  // reference.
  double max_shift_px = 3;
  double max_obliquity_deg = 80;
  // Refused when the fitted surface's normal turns by more than this across the window (patch.cpp):
  // a window across a crease. 180: no check.
  double max_bend_deg = 20;
  // ... unless a window of this half-width (every pixel sampled), measured from the bent patch,
  // bends by at most bend_shrink_ratio of its bend and by at most max_bend_deg (a curved
  // surface's bend shrinks with the window, about as 5/9 from 9 px to 5; a crease's does not):
  // then its point is kept. 0: no second window.
  int bend_check_half_window_px = 5;
  double bend_shrink_ratio = 0.8;
  // Refused when the point's reprojection error (PatchResult::reprojection_px: the views' free
  // matches against its projection) is above this, px (0: no check).
  double max_reprojection_px = 0;
};

// Why a patch was refused (for the summary).
enum class PatchFailure { None, Behind, Border, Singular, NotConverged, Shift, Oblique, Bent, Correlation, Views, Reprojection, Count };
const char* to_string(PatchFailure f);

struct PatchResult {
  Eigen::Vector3d plane = Eigen::Vector3d::Zero();  // n, reference camera frame: n . X = 1
  Eigen::Vector3d point_ref = Eigen::Vector3d::Zero();  // X(0), reference camera frame
  double sigma_along_ray = 0;   // standard deviation of X(0) along its ray (same unit as poses)
  double correlation = 0;       // mean correlation over the views kept
  std::vector<int> views;       // indices into `views` of the views kept (reference excluded)
  int iterations = 0;
  // A patch refused as bent: the planes (n . X = 1, reference frame) of its window's quadrants,
  // from which the neighbouring cells can start (the faces on each side of a crease).
  std::vector<Eigen::Vector3d> bend_planes;
  // The largest angle between the normals of the window's quadrants (with the curvature terms).
  double bend_deg = 0;
  // The point's reprojection error, px: the RMS over its observations of the distance from where
  // the point projects to where the reference window matches each view freely (a 2D shift of
  // the fitted window, patch.cpp); the reference's own observation is its pixel, whose ray the
  // point lies on (0).
  double reprojection_px = 0;
  // The half-width of the window that measured it (PatchOptions::half_window_px, or the bend
  // check's smaller window when that one gave the point).
  int half_window_px = 0;
};

// The matcher for one reference photo: its camera, and the quadratic interpolation of the window.
class PatchMatcher {
public:
  PatchMatcher(const geometry::CameraModel& camera, const PatchOptions& options);

  // Measures the patch at integer pixel `centre` of reference view `ref`, starting from plane
  // `plane0` (reference frame), matched in `candidates` (indices into views). Returns
  // PatchFailure::None and fills *out on success.
  PatchFailure measure(const std::vector<PatchView>& views, int ref, const Eigen::Vector2i& centre,
                       const Eigen::Vector3d& plane0, const std::vector<int>& candidates, PatchResult* out) const;

  const PatchOptions& options() const { return options_; }

private:
  geometry::CameraModel camera_;
  geometry::ModelShape shape_;
  PatchOptions options_;
  // Quadratic basis (1, dx, dy, dx^2, dx dy, dy^2) at every window pixel, row-major.
  std::vector<std::array<double, 6>> basis_;
  std::vector<Eigen::Vector2i> offsets_;
  // Least-squares fit of the 6 quadratic coefficients from values at the 3 x 3 grid: coef = fit_ * values.
  Eigen::Matrix<double, 6, 9> fit_;
  std::array<Eigen::Vector2i, 9> grid_;
  // The smaller window that tells a crease from a tight curve (PatchOptions::bend_check_half_window_px).
  std::shared_ptr<const PatchMatcher> small_;
};

}  // namespace photomill::densify
