// Multi-view triangulation of one point: normalised linear least squares over all its views,
// checks (intersection angle, cheirality, reprojection error), then nonlinear refinement of the
// reprojection error in pixels with the poses held fixed. And the same for every track of a scene.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "triangulate/scene.hpp"

namespace photomill::triangulate {

struct TriangulationOptions {
  // Rays must meet at this angle or more (the largest angle over pairs of views): smaller
  // angles give depth errors of ~ sigma / angle. COLMAP uses 1.5 degrees too.
  double min_angle_deg = 1.5;
  // A view whose reprojection error exceeds this after refinement is dropped from the track
  // (the worst first) while at least two views remain.
  double max_reproj_px = 4;
  // Gauss-Newton steps of the refinement, and its stopping size (relative to the point's
  // distance from the cameras).
  int refine_iterations = 10;
  double refine_step_tolerance = 1e-12;
};

// One view of a point: the camera's pose and the observation in it.
struct PointView {
  const PoseBlock* cam_from_world = nullptr;
  const CameraModel* camera = nullptr;  // the view's camera; null: the `camera` the functions are given
  Eigen::Matrix3d R;          // rotation of cam_from_world
  Eigen::Vector3d t;          // translation, mm
  Eigen::Vector3d centre_mm;  // C = -R^T t
  Eigen::Vector2d xy;         // undistorted normalised coordinates
  Eigen::Vector2d uv_px;      // measured pixel
};

enum class TriangulationStatus { Ok, TooFewViews, Degenerate, SmallAngle, BehindCamera, LargeError };

struct PointEstimate {
  TriangulationStatus status = TriangulationStatus::TooFewViews;
  Eigen::Vector3d xyz_mm = Eigen::Vector3d::Zero();
  double max_angle_deg = 0;               // largest intersection angle over pairs of views
  std::vector<std::size_t> dropped;       // indices into the views that were dropped
  std::vector<double> dropped_error_px;   // their reprojection errors when dropped
};

// Linear triangulation (Hartley & Zisserman, "Multiple View Geometry", 2nd ed., sec. 12.2, DLT;
// the paper's two-ray least squares B X = D, section 3.2, generalised to n views). With
// normalised image coordinates (x_j, y_j) and P_j = [R_j | t_j], every view adds two rows
//   x_j P_j^3 - P_j^1,   y_j P_j^3 - P_j^2
// to A, and X is the right singular vector of the smallest singular value of A (4 x 1,
// homogeneous). Normalisation (H&Z sec. 4.4.4): world coordinates are shifted to the centroid of
// the camera centres and scaled by their RMS distance from it before the SVD, so that A is well
// conditioned whatever the units and the position of the origin. Each row pair is divided by its
// norm so that every view weighs the same. nullopt if X is at infinity (parallel rays).
std::optional<Eigen::Vector3d> triangulate_linear(const std::vector<PointView>& views);

// Largest angle, in degrees, between the rays from the camera centres to X over pairs of views.
double max_intersection_angle_deg(const std::vector<PointView>& views, const Eigen::Vector3d& xyz_mm);

// Gauss-Newton refinement of X minimising sum_j |pi_j(X) - uv_j|^2 (pixels) with the poses fixed;
// Jacobians by automatic differentiation of geometry/camera_model.hpp's project().
Eigen::Vector3d refine_point(const CameraModel& camera, const std::vector<PointView>& views,
                             Eigen::Vector3d xyz_mm, const TriangulationOptions& options);

// The whole procedure for one point: linear estimate, angle and cheirality checks, refinement,
// then dropping views whose error exceeds max_reproj_px (worst first, re-estimating each time).
PointEstimate triangulate_point(const CameraModel& camera, std::vector<PointView> views,
                                const TriangulationOptions& options);

// Triangulates every Pending track that has two or more usable inlier observations in
// registered images (control tracks already placed at their control value are skipped; with
// `retriangulate`, Triangulated tracks are estimated again too). Failed tracks stay Pending with
// their issue recorded (more images may register later). Views dropped as outliers are marked
// inlier = false. Returns the number of tracks newly triangulated. Runs on `threads` threads.
std::size_t triangulate_tracks(Scene& scene, const TriangulationOptions& options, int threads,
                               bool retriangulate = false);

// Builds the views of one track from its active observations.
std::vector<PointView> views_of(const Scene& scene, const std::vector<std::size_t>& observations);

}  // namespace photomill::triangulate
