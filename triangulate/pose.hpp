// Camera poses from correspondences: absolute pose from 2D-3D pairs (PnP: RANSAC, then refined
// by least squares on the inliers) and relative pose of two images from the essential matrix.
// Both work on undistorted normalised coordinates (so OpenCV's estimators see an ideal pinhole
// with K = I); the refinement minimises the reprojection error in pixels with the full model.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "triangulate/scene.hpp"

namespace photomill::triangulate {

struct RansacOptions {
  double threshold_px = 2;       // inlier threshold, pixels (converted to normalised units by f)
  double confidence = 0.9999;    // probability of drawing one outlier-free sample
  int max_iterations = 10000;
};

// One 2D-3D correspondence.
struct Correspondence {
  Eigen::Vector3d xyz_mm;   // world point
  Eigen::Vector2d xy;       // undistorted normalised coordinates of its observation
  Eigen::Vector2d uv_px;    // the observation itself
};

struct AbsolutePose {
  PoseBlock cam_from_world{};
  std::vector<std::size_t> inliers;   // indices into the correspondences
};

// True if the points lie on a line: the second singular value of their centred coordinates is
// below `tolerance` times the first (scale-free). Fewer than 3 points count as collinear.
bool collinear(const std::vector<Eigen::Vector3d>& points, double tolerance);
bool collinear(const std::vector<Eigen::Vector2d>& points, double tolerance);

// PnP (Hartley & Zisserman sec. 7.3 / Ke & Roumeliotis' AP3P as the RANSAC minimal solver,
// OpenCV solvePnPRansac), then Levenberg-Marquardt (Ceres) on the inliers' reprojection error:
//   min over pose of sum_i |pi(R X_i + t) - u_i|^2 / sigma^2,  X_i fixed.
// nullopt if fewer than `min_inliers` inliers, or the inliers' 3D points are collinear.
std::optional<AbsolutePose> estimate_absolute_pose(const CameraModel& camera,
                                                   const std::vector<Correspondence>& correspondences,
                                                   const RansacOptions& ransac, std::size_t min_inliers,
                                                   double collinear_tolerance);

// Refines a pose by least squares on the given correspondences (points held fixed).
PoseBlock refine_pose(const CameraModel& camera, const std::vector<Correspondence>& correspondences,
                      const PoseBlock& initial);

struct RelativePose {
  PoseBlock second_from_first{};      // |t| = 1
  std::vector<std::size_t> inliers;   // indices into the pairs, in front of both cameras
};

// Relative pose from the essential matrix (H&Z sec. 9.6; Nister's five-point solver in RANSAC,
// OpenCV findEssentialMat, then recoverPose's cheirality test): x2^T E x1 = 0, E = [t]x R.
// nullopt if OpenCV finds no essential matrix.
std::optional<RelativePose> estimate_relative_pose(const std::vector<Eigen::Vector2d>& xy1,
                                                   const std::vector<Eigen::Vector2d>& xy2,
                                                   double focal_px, const RansacOptions& ransac);

// Test for a pure rotation between two images (no baseline): the rotation R that best maps the
// bearings b1 = (x1, y1, 1)/|.| onto b2 (Kabsch / Horn: R = V diag(1, 1, det(V U^T)) U^T from the
// SVD U S V^T of sum b1 b2^T), and the median angle (radians) between R b1 and b2. Near zero,
// a rotation alone explains the pair: it has no baseline to triangulate from.
double rotation_only_median_residual(const std::vector<Eigen::Vector2d>& xy1, const std::vector<Eigen::Vector2d>& xy2);

}  // namespace photomill::triangulate
