// Epipolar geometry of image pairs for match: the fundamental matrix from known poses or
// estimated robustly (OpenCV's USAC with MAGSAC++ scoring), the Sampson distance of a
// correspondence, and lens undistortion so that a pinhole F fits. Hartley & Zisserman, "Multiple
// View Geometry", 2nd ed.: F = K^-T [t]x R K^-1 (eq. 9.2 with E = [t]x R, sec. 9.6), Sampson
// distance (eq. 11.9), plane and parallax (sec. 13.3); Barath, Noskova, Ivashechkin & Matas,
// "MAGSAC++", CVPR 2020 (OpenCV's USAC); Chum, Werner & Matas, "Two-view geometry estimation
// unaffected by a dominant plane", CVPR 2005.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::match {

// F of the pair (a, b) with x_b^T F x_a = 0 for undistorted pixels x (homogeneous), from the
// poses cam_from_world of both images and the camera matrix K (shared by both):
//   R = R_b R_a^T, t = t_b - R t_a (b_from_a), F = K^-T [t]x R K^-1.
Eigen::Matrix3d fundamental_from_poses(const Eigen::Matrix3d& K, const Pose& a, const Pose& b);

// First-order geometric error of x_a <-> x_b under F (Hartley & Zisserman eq. 11.9), pixels:
//   d = |x_b^T F x_a| / sqrt((F x_a)_1^2 + (F x_a)_2^2 + (F^T x_b)_1^2 + (F^T x_b)_2^2).
double sampson_distance_px(const Eigen::Matrix3d& F, const Eigen::Vector2d& xa, const Eigen::Vector2d& xb);

struct RobustFitOptions {
  double threshold_px = 1.0;   // inlier threshold on the Sampson distance (and MAGSAC++'s)
  double confidence = 0.9999;  // RANSAC confidence
  int max_iterations = 10000;
  int min_inliers = 15;        // fewer: the pair is not verified
  double min_inlier_ratio = 0.2;
};

// F estimated from putative correspondences: cv::findFundamentalMat(..., USAC_MAGSAC, ...); then,
// when a dominant plane holds most of them, the plane-and-parallax estimate F = [e']x H if it
// explains more (see epipolar.cpp: RANSAC on F alone tends to return a plane-consistent F with a
// wrong epipole, which rejects every point off the plane); then least squares on the inliers
// (normalised 8-point) while it explains no fewer. Inliers: Sampson distance <= threshold.
// nullopt if there are fewer than 8 points, no F is found, or the inliers are too few.
struct RobustFit {
  Eigen::Matrix3d F;
  std::vector<bool> inliers;
  int inlier_count = 0;
};
std::optional<RobustFit> estimate_fundamental(const std::vector<Eigen::Vector2d>& a,
                                              const std::vector<Eigen::Vector2d>& b, const RobustFitOptions& options);

// Maps observed pixels to the pixels of the ideal pinhole camera with the same K (OpenCV's
// undistortPoints with P = K; geometry's Newton inversion of the one camera model), so that
// epipolar geometry holds; the identity without a camera. A pixel the distortion cannot be
// inverted at (beyond a fold of the model) maps to NaN: callers leave such points out.
class Undistorter {
public:
  explicit Undistorter(const std::optional<Camera>& camera = std::nullopt);
  std::vector<Eigen::Vector2d> apply(const std::vector<Eigen::Vector2d>& pixels) const;
  bool active() const { return camera_.has_value(); }

private:
  std::optional<geometry::CameraModel> camera_;
};

}  // namespace photomill::match
