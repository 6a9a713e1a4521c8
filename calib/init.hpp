// Initial estimates of the camera before refinement: the normalised DLT per image with an RQ
// decomposition (Hartley & Zisserman, "Multiple View Geometry", 2nd ed., alg. 7.1 and sec. 6.2.4,
// A4.1.1) for control points off a plane, and Zhang's planar method (Zhang 2000, through OpenCV's
// initCameraMatrix2D) for boards. Both start with zero distortion.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "calib/model.hpp"

namespace photomill::calib {

// P = K [R | t] of one image from >= 6 world/image correspondences.
struct DltCamera {
  Eigen::Matrix<double, 3, 4> P;  // scaled so that ||P|| = 1 and det(P[:, :3]) > 0
  Eigen::Matrix3d K;              // upper triangular, positive diagonal, K(2,2) = 1 (skew kept)
  Eigen::Matrix3d R;              // cam_from_world rotation, det = +1
  Eigen::Vector3d t;              // cam_from_world translation, mm
  double rms_px = 0;              // reprojection RMS of P itself
};

// Flatness of a point set: the smallest over the largest singular value of the centred points
// (0 for coplanar points, ~1 for a well-spread cloud; 0 too for fewer than 3 distinct points).
double flatness(const std::vector<Eigen::Vector3d>& points);

// The normalised DLT (H&Z alg. 7.1): points translated to their centroid and scaled to a mean
// distance of sqrt(3) (world) and sqrt(2) (image); p = the right singular vector of the 2n x 12
// system A p = 0 with the smallest singular value; P = T_img^-1 P~ T_world. Throws GeometryError
// naming `image` for fewer than 6 points or points flatter than `min_flatness`.
DltCamera dlt_camera(const std::vector<Eigen::Vector3d>& world_mm, const std::vector<Eigen::Vector2d>& image_px,
                     const std::string& image, double min_flatness);

// M = K R with K upper triangular with a positive diagonal and R a rotation (H&Z A4.1.1, done
// with Givens rotations). Requires det(M) > 0.
void rq_decomposition(const Eigen::Matrix3d& M, Eigen::Matrix3d& K, Eigen::Matrix3d& R);

// Initial parameters from the DLT of every view: K = the per-view medians of fx, fy, cx, cy
// (with the model's fixed values applied), each view's pose re-estimated with that K. A view that
// allows no DLT (fewer than 6 points, or flat) gets its pose by PnP with that K and a line in
// `notes`; if no view allows a DLT, the first view's GeometryError is thrown.
Parameters initial_from_dlt(const std::vector<View>& views, const ModelOptions& model, cv::Size image_size,
                            double min_flatness, std::vector<std::string>* notes = nullptr);

// Initial parameters for planar control points (z = 0 in `views`): Zhang's closed form through
// cv::initCameraMatrix2D (principal point at the image centre), then each pose by PnP.
Parameters initial_from_plane(const std::vector<View>& views, const ModelOptions& model, cv::Size image_size);

// The views' points as OpenCV's calibration functions take them: one list per view, in float;
// with `flatten`, z = 0 (the plane's own coordinates, as cv::initCameraMatrix2D reads them).
struct OpenCvPoints {
  std::vector<std::vector<cv::Point3f>> object;  // world_mm
  std::vector<std::vector<cv::Point2f>> image;   // observed_px
};
OpenCvPoints opencv_points(const std::vector<View>& views, bool flatten);

// The principal point OpenCV assumes before calibration, ((w - 1) / 2, (h - 1) / 2).
Eigen::Vector2d image_centre(cv::Size image_size);

}  // namespace photomill::calib
