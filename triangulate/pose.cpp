// Absolute and relative pose estimation (see pose.hpp).
#include "triangulate/pose.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/LU>  // determinant
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "geometry/linear_algebra.hpp"
#include "triangulate/residuals.hpp"

namespace photomill::triangulate {
namespace {

template <int N>
bool collinear_impl(const std::vector<Eigen::Matrix<double, N, 1>>& points, double tolerance) {
  if (points.size() < 3) return true;
  Eigen::Matrix<double, N, 1> c = Eigen::Matrix<double, N, 1>::Zero();
  for (const auto& p : points) c += p;
  c /= static_cast<double>(points.size());
  Eigen::MatrixXd A(static_cast<Eigen::Index>(points.size()), N);
  for (std::size_t i = 0; i < points.size(); ++i) A.row(static_cast<Eigen::Index>(i)) = (points[i] - c).transpose();
  const Eigen::VectorXd s = geometry::singular_values(A);
  return !(s(1) > tolerance * s(0));
}

}  // namespace

bool collinear(const std::vector<Eigen::Vector3d>& points, double tolerance) { return collinear_impl<3>(points, tolerance); }
bool collinear(const std::vector<Eigen::Vector2d>& points, double tolerance) { return collinear_impl<2>(points, tolerance); }

PoseBlock refine_pose(const CameraModel& camera, const std::vector<Correspondence>& correspondences,
                      const PoseBlock& initial) {
  PoseBlock pose = initial;
  std::vector<Eigen::Vector3d> points;
  points.reserve(correspondences.size());
  for (const auto& c : correspondences) points.push_back(c.xyz_mm);
  ceres::Problem problem;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    problem.AddResidualBlock(ReprojectionError::create(&camera, correspondences[i].uv_px, 1.0), nullptr,
                             pose.data(), points[i].data());
    problem.SetParameterBlockConstant(points[i].data());
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 50;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return summary.IsSolutionUsable() ? pose : initial;
}

std::optional<AbsolutePose> estimate_absolute_pose(const CameraModel& camera,
                                                   const std::vector<Correspondence>& correspondences,
                                                   const RansacOptions& ransac, std::size_t min_inliers,
                                                   double collinear_tolerance) {
  if (correspondences.size() < std::max<std::size_t>(min_inliers, 4)) return std::nullopt;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& c : correspondences) {
    object.emplace_back(c.xyz_mm.x(), c.xyz_mm.y(), c.xyz_mm.z());
    image.emplace_back(c.xy.x(), c.xy.y());
  }
  const double focal = 0.5 * (camera.params[kFx] + camera.params[kFy]);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  const bool ok = cv::solvePnPRansac(object, image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec, false,
                                     ransac.max_iterations, static_cast<float>(ransac.threshold_px / focal),
                                     ransac.confidence, inliers, cv::SOLVEPNP_AP3P);
  if (!ok || inliers.size() < min_inliers) return std::nullopt;

  AbsolutePose out;
  for (int k = 0; k < 3; ++k) {
    out.cam_from_world[static_cast<std::size_t>(k)] = rvec.at<double>(k);
    out.cam_from_world[static_cast<std::size_t>(k + 3)] = tvec.at<double>(k);
  }
  std::vector<Correspondence> inlying;
  std::vector<Eigen::Vector3d> inlier_points;
  for (int i : inliers) {
    inlying.push_back(correspondences[static_cast<std::size_t>(i)]);
    inlier_points.push_back(correspondences[static_cast<std::size_t>(i)].xyz_mm);
  }
  if (collinear(inlier_points, collinear_tolerance)) return std::nullopt;
  out.cam_from_world = refine_pose(camera, inlying, out.cam_from_world);
  // Inliers again with the refined pose, in pixels.
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const auto uv = project_point(camera, out.cam_from_world.data(), correspondences[i].xyz_mm);
    if (uv && (*uv - correspondences[i].uv_px).norm() <= ransac.threshold_px) out.inliers.push_back(i);
  }
  if (out.inliers.size() < min_inliers) return std::nullopt;
  return out;
}

std::optional<RelativePose> estimate_relative_pose(const std::vector<Eigen::Vector2d>& xy1,
                                                   const std::vector<Eigen::Vector2d>& xy2,
                                                   double focal_px, const RansacOptions& ransac) {
  if (xy1.size() < 5 || xy1.size() != xy2.size()) return std::nullopt;
  std::vector<cv::Point2d> p1, p2;
  for (std::size_t i = 0; i < xy1.size(); ++i) {
    p1.emplace_back(xy1[i].x(), xy1[i].y());
    p2.emplace_back(xy2[i].x(), xy2[i].y());
  }
  cv::Mat mask;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  const cv::Mat E = cv::findEssentialMat(p1, p2, K, cv::RANSAC, ransac.confidence,
                                       ransac.threshold_px / focal_px, ransac.max_iterations, mask);
  if (E.rows != 3 || E.cols != 3) return std::nullopt;  // several solutions or none: degenerate
  cv::Mat R, t;
  const int good = cv::recoverPose(E, p1, p2, K, R, t, mask);
  if (good < 5) return std::nullopt;
  Eigen::Matrix3d Re;
  Eigen::Vector3d te;
  cv::cv2eigen(R, Re);
  cv::cv2eigen(t, te);
  RelativePose out;
  out.second_from_first = make_pose(Re, te.normalized());
  for (int i = 0; i < mask.rows; ++i) {
    if (mask.at<unsigned char>(i)) out.inliers.push_back(static_cast<std::size_t>(i));
  }
  return out;
}

double rotation_only_median_residual(const std::vector<Eigen::Vector2d>& xy1, const std::vector<Eigen::Vector2d>& xy2) {
  if (xy1.empty() || xy1.size() != xy2.size()) return 0;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector3d> b1, b2;
  for (std::size_t i = 0; i < xy1.size(); ++i) {
    b1.push_back(xy1[i].homogeneous().normalized());
    b2.push_back(xy2[i].homogeneous().normalized());
    H += b1.back() * b2.back().transpose();
  }
  const geometry::Svd svd = geometry::svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.U, V = svd.V;
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (V * U.transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d R = V * D * U.transpose();
  std::vector<double> angles;
  for (std::size_t i = 0; i < b1.size(); ++i) angles.push_back(std::acos(std::clamp((R * b1[i]).dot(b2[i]), -1.0, 1.0)));
  std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(angles.size() / 2), angles.end());
  return angles[angles.size() / 2];
}

}  // namespace photomill::triangulate
