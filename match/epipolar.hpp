// Epipolar geometry of image pairs for match: the fundamental matrix from known poses or
// estimated robustly (OpenCV's USAC with MAGSAC++ scoring), the Sampson distance of a
// correspondence, and lens undistortion so that a pinhole F fits. Hartley & Zisserman, "Multiple
// View Geometry", 2nd ed.: F = K^-T [t]x R K^-1 (eq. 9.2 with E = [t]x R, sec. 9.6), Sampson
// distance (eq. 11.9), plane and parallax (sec. 13.3); Barath, Noskova, Ivashechkin & Matas,
// "MAGSAC++", CVPR 2020 (OpenCV's USAC); Chum, Werner & Matas, "Two-view geometry estimation
// unaffected by a dominant plane", CVPR 2005.
#pragma once

#include <algorithm>
#include <cstddef>
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
// The same for two cameras: F = K_b^-T [t]x R K_a^-1.
Eigen::Matrix3d fundamental_from_poses(const Eigen::Matrix3d& K_a, const Eigen::Matrix3d& K_b, const Pose& a,
                                       const Pose& b);

// First-order geometric error of x_a <-> x_b under F (Hartley & Zisserman eq. 11.9), pixels:
//   d = |x_b^T F x_a| / sqrt((F x_a)_1^2 + (F x_a)_2^2 + (F^T x_b)_1^2 + (F^T x_b)_2^2).
double sampson_distance_px(const Eigen::Matrix3d& F, const Eigen::Vector2d& xa, const Eigen::Vector2d& xb);

// Image b's points indexed by the epipolar line of F they lie on, to find every point x_b within a
// Sampson distance of x_a (guided matching) without looking at the others. All epipolar lines
// of b pass through the epipole e (F^T e = 0, |e| = 1): with l1, l2 an orthonormal basis of the
// lines through e (3-vectors orthogonal to e), the line of angle phi is l(phi) = l1 cos phi +
// l2 sin phi, and a point x = (x, y, 1) lies on the line of angle phi_x, where
//   (l1 . x, l2 . x) = rho_x (-sin phi_x, cos phi_x),  rho_x = |e x x|.
// For a line l = F x_a = c l(phi_a) + (l . e) e (c = |l - (l . e) e|; the last term is zero for
// an F of rank 2, kept for one that is not quite):
//   l . x = c rho_x sin(phi_a - phi_x) + (l . e)(e . x).
// The Sampson test d^2 <= thr^2 ((F x_a)_1^2 + (F x_a)_2^2 + (F^T x_b)_1^2 + (F^T x_b)_2^2)
// (Hartley & Zisserman eq. 11.9) then needs
//   |sin(phi_a - phi_x)| <= (thr sqrt(|(F x_a)_12|^2 + |(F^T x_b)_12|^2) + |l . e| |e . x|) / (c rho_x).
// The points are kept in bands of rho (each a factor 2 wide), each sorted by phi (mod pi, lines
// having no direction); a query bounds that sine over each band by its smallest rho and largest
// |(F^T x_b)_12| and |e . x|, and walks only the band's points within the angle. This holds for
// an epipole inside the image, far outside it or at infinity alike (no case is special), and
// every point that passes the exact test is visited; the caller applies the test.
class EpipolarPencil {
 public:
  // `pts`: b's points (undistorted pixels); non-finite ones are left out.
  EpipolarPencil(const std::vector<Eigen::Vector2d>& pts, const Eigen::Matrix3d& F);

  // Calls visit(k) for each point k of `pts` that may lie within Sampson distance `threshold_px`
  // of x_a (with some more: visit applies the exact test), where fa = F x_a.
  template <class Visit>
  void near(const Eigen::Vector3d& fa, double threshold_px, Visit&& visit) const;

  // (F^T x_b)_1^2 + (F^T x_b)_2^2 of point k, for the exact test.
  double ftb2(std::size_t k) const { return ftb2_[k]; }

 private:
  struct Entry {
    double phi;  // angle of the point's epipolar line, [0, pi)
    int index;   // in pts
  };
  struct Band {
    std::size_t begin = 0, end = 0;  // entries_[begin, end), sorted by phi
    double min_rho = 0, max_ftb2 = 0, max_e_dot_x = 0;
  };
  template <class Visit>
  void walk(const Band& band, double from, double to, Visit& visit) const;

  Eigen::Vector3d e_, l1_, l2_;
  std::vector<double> ftb2_;
  std::vector<Entry> entries_;
  std::vector<Band> bands_;
};

template <class Visit>
void EpipolarPencil::walk(const Band& band, double from, double to, Visit& visit) const {
  const auto first = entries_.begin() + static_cast<std::ptrdiff_t>(band.begin);
  const auto last = entries_.begin() + static_cast<std::ptrdiff_t>(band.end);
  auto it = std::lower_bound(first, last, from, [](const Entry& en, double v) { return en.phi < v; });
  for (; it != last && it->phi <= to; ++it) visit(static_cast<std::size_t>(it->index));
}

template <class Visit>
void EpipolarPencil::near(const Eigen::Vector3d& fa, double threshold_px, Visit&& visit) const {
  constexpr double kPi = 3.14159265358979323846;
  const double along_e = fa.dot(e_);
  const double c = (fa - along_e * e_).norm();
  const double fa2 = fa.head<2>().squaredNorm();
  double phi_a = std::atan2(fa.dot(l2_), fa.dot(l1_));
  if (phi_a < 0) phi_a += kPi;
  for (const Band& band : bands_) {
    if (band.begin == band.end) continue;
    const double reach = threshold_px * std::sqrt(fa2 + band.max_ftb2) + std::abs(along_e) * band.max_e_dot_x;
    // The bound on |sin|, widened by a millionth for the rounding of the angles.
    const double s = reach / (c * band.min_rho) * (1 + 1e-6) + 1e-12;
    if (!(s < 1)) {  // (also a band at the epipole, rho 0, or a line through it, c 0)
      walk(band, -1.0, 4.0, visit);
      continue;
    }
    const double delta = std::asin(s);
    const double from = phi_a - delta, to = phi_a + delta;
    walk(band, from, to, visit);
    if (from < 0) walk(band, from + kPi, kPi, visit);
    if (to >= kPi) walk(band, 0.0, to - kPi, visit);
  }
}

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
