// Initial camera estimates: normalised DLT + RQ, and Zhang's planar method (see init.hpp).
#include "calib/init.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Geometry>
#include <Eigen/QR>
#include <opencv2/calib3d.hpp>

#include "formats/error.hpp"
#include "geometry/linear_algebra.hpp"

namespace photomill::calib {
namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::array<double, kPose> pose_from(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  const Eigen::AngleAxisd aa(R);
  const Eigen::Vector3d r = aa.angle() * aa.axis();
  return {r.x(), r.y(), r.z(), t.x(), t.y(), t.z()};
}

// Pose of one view for a given K (no distortion): OpenCV's iterative PnP (Levenberg-Marquardt on
// the reprojection error), started from `guess` when there is one (the DLT's pose), else from
// SQPnP (Terzakis & Lourakis 2020), which takes any 3 or more points, coplanar or not.
std::array<double, kPose> solve_pose(const View& view, const Eigen::Matrix3d& K, const std::array<double, kPose>* guess) {
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (std::size_t i = 0; i < view.world_mm.size(); ++i) {
    obj.emplace_back(view.world_mm[i].x(), view.world_mm[i].y(), view.world_mm[i].z());
    img.emplace_back(view.observed_px[i].x(), view.observed_px[i].y());
  }
  const cv::Matx33d Kcv(K(0, 0), K(0, 1), K(0, 2), K(1, 0), K(1, 1), K(1, 2), K(2, 0), K(2, 1), K(2, 2));
  cv::Vec3d rvec;
  cv::Vec3d tvec;
  if (guess) {
    rvec = {(*guess)[0], (*guess)[1], (*guess)[2]};
    tvec = {(*guess)[3], (*guess)[4], (*guess)[5]};
  }
  try {
    if (!guess && !cv::solvePnP(obj, img, Kcv, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_SQPNP)) {
      throw GeometryError(view.image + ": no camera pose fits its control points");
    }
    cv::solvePnP(obj, img, Kcv, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
  } catch (const cv::Exception& e) {
    throw GeometryError(view.image + ": no camera pose fits its control points (" + e.err + ")");
  }
  return {rvec[0], rvec[1], rvec[2], tvec[0], tvec[1], tvec[2]};
}

void apply_fixed(const ModelOptions& model, cv::Size image_size, Parameters& p) {
  if (model.fix_aspect_ratio) {
    const double f = 0.5 * (p.intrinsics[0] + p.intrinsics[1]);
    p.intrinsics[0] = p.intrinsics[1] = f;
  }
  if (model.fix_principal_point) {
    const Eigen::Vector2d c = image_centre(image_size);
    p.intrinsics[2] = c.x();
    p.intrinsics[3] = c.y();
  }
  p.distortion.fill(0);
}

}  // namespace

Eigen::Vector2d image_centre(cv::Size s) { return {(s.width - 1) * 0.5, (s.height - 1) * 0.5}; }

double flatness(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 3) return 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::MatrixXd A(points.size(), 3);
  for (std::size_t i = 0; i < points.size(); ++i) A.row(static_cast<Eigen::Index>(i)) = (points[i] - mean).transpose();
  const Eigen::Vector3d s = geometry::singular_values(A);
  return s(0) > 0 ? s(2) / s(0) : 0;
}

void rq_decomposition(const Eigen::Matrix3d& M, Eigen::Matrix3d& K, Eigen::Matrix3d& R) {
  // With the reversal permutation J (J = J^T = J^-1): QR of (J M)^T = Q U gives
  // M = (J U^T J) (J Q^T), where J U^T J is upper triangular and J Q^T orthogonal.
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J(0, 2) = J(1, 1) = J(2, 0) = 1;
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((J * M).transpose());
  const Eigen::Matrix3d Q = qr.householderQ();
  const Eigen::Matrix3d U = qr.matrixQR().triangularView<Eigen::Upper>();
  K = J * U.transpose() * J;
  R = J * Q.transpose();
  // Make K's diagonal positive: K D and D R with D = diag(+-1), D^2 = I.
  for (int i = 0; i < 3; ++i) {
    if (K(i, i) < 0) {
      K.col(i) *= -1;
      R.row(i) *= -1;
    }
  }
}

DltCamera dlt_camera(const std::vector<Eigen::Vector3d>& world, const std::vector<Eigen::Vector2d>& image,
                     const std::string& name, double min_flatness) {
  const std::size_t n = world.size();
  if (n < 6) {
    throw GeometryError(name + ": " + std::to_string(n) +
                        " control points; the DLT needs at least 6 (11 unknowns, 2 equations per point)");
  }
  const double flat = flatness(world);
  if (flat < min_flatness) {
    throw GeometryError(name + ": its control points are (nearly) coplanar (flatness " + std::to_string(flat) +
                        " < " + std::to_string(min_flatness) +
                        "); the DLT needs points off a plane: use --method planar, or add points off the plane");
  }
  // Hartley normalisation: centroid to the origin, mean distance sqrt(3) (3D) and sqrt(2) (2D).
  Eigen::Vector3d cw = Eigen::Vector3d::Zero();
  Eigen::Vector2d ci = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    cw += world[i];
    ci += image[i];
  }
  cw /= static_cast<double>(n);
  ci /= static_cast<double>(n);
  double dw = 0;
  double di = 0;
  for (std::size_t i = 0; i < n; ++i) {
    dw += (world[i] - cw).norm();
    di += (image[i] - ci).norm();
  }
  const double sw = std::sqrt(3.0) * static_cast<double>(n) / dw;
  const double si = std::sqrt(2.0) * static_cast<double>(n) / di;
  Eigen::Matrix4d Tw = Eigen::Matrix4d::Identity();
  Tw.topLeftCorner<3, 3>() *= sw;
  Tw.topRightCorner<3, 1>() = -sw * cw;
  Eigen::Matrix3d Ti = Eigen::Matrix3d::Identity();
  Ti.topLeftCorner<2, 2>() *= si;
  Ti.topRightCorner<2, 1>() = -si * ci;
  // H&Z (7.2): for each point, [0^T, -w X^T, y X^T] and [w X^T, 0^T, -x X^T] (w = 1) times p = 0.
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(2 * n), 12);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector4d X = Tw * world[i].homogeneous();
    const Eigen::Vector2d x = (Ti * image[i].homogeneous()).hnormalized();
    const auto r = static_cast<Eigen::Index>(2 * i);
    A.block<1, 4>(r, 4) = -X.transpose();
    A.block<1, 4>(r, 8) = x.y() * X.transpose();
    A.block<1, 4>(r + 1, 0) = X.transpose();
    A.block<1, 4>(r + 1, 8) = -x.x() * X.transpose();
  }
  const Eigen::VectorXd p = geometry::svd(A, Eigen::ComputeFullV).V.col(11);
  Eigen::Matrix<double, 3, 4> Pn;
  Pn << p.segment<4>(0).transpose(), p.segment<4>(4).transpose(), p.segment<4>(8).transpose();
  DltCamera cam;
  cam.P = Ti.inverse() * Pn * Tw;
  if (cam.P.leftCols<3>().determinant() < 0) cam.P *= -1;
  cam.P /= cam.P.norm();
  const Eigen::Matrix3d M = cam.P.leftCols<3>();
  if (!(std::abs(M.determinant()) > 0)) throw GeometryError(name + ": the DLT camera is singular");
  Eigen::Matrix3d K;
  rq_decomposition(M, K, cam.R);
  const double scale = K(2, 2);  // P = scale * K_normalised [R | t]
  cam.K = K / scale;
  cam.t = cam.K.inverse() * cam.P.col(3) / scale;
  double sse = 0;
  for (std::size_t i = 0; i < n; ++i) {
    sse += ((cam.P * world[i].homogeneous()).hnormalized() - image[i]).squaredNorm();
  }
  cam.rms_px = std::sqrt(sse / static_cast<double>(n));
  return cam;
}

Parameters initial_from_dlt(const std::vector<View>& views, const ModelOptions& model, cv::Size image_size,
                            double min_flatness, std::vector<std::string>* notes) {
  // Views whose points do not allow a DLT (too few, or coplanar) get their pose from PnP with the
  // K of the others; only when no view allows a DLT is that an error.
  std::vector<std::optional<DltCamera>> cams(views.size());
  std::array<std::vector<double>, 4> k;
  std::optional<GeometryError> first_error;
  for (std::size_t v = 0; v < views.size(); ++v) {
    try {
      cams[v] = dlt_camera(views[v].world_mm, views[v].observed_px, views[v].image, min_flatness);
    } catch (const GeometryError& e) {
      if (!first_error) first_error = e;
      if (notes) notes->push_back(std::string(e.what()) + "; its pose comes from PnP with the other views' camera");
      continue;
    }
    k[0].push_back(cams[v]->K(0, 0));
    k[1].push_back(cams[v]->K(1, 1));
    k[2].push_back(cams[v]->K(0, 2));
    k[3].push_back(cams[v]->K(1, 2));
  }
  if (k[0].empty()) throw *first_error;
  Parameters p;
  for (int i = 0; i < kIntrinsics; ++i) p.intrinsics[i] = median(k[i]);
  apply_fixed(model, image_size, p);
  const Eigen::Matrix3d K = camera_matrix(p);
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (cams[v]) {
      const auto guess = pose_from(cams[v]->R, cams[v]->t);
      p.poses.push_back(solve_pose(views[v], K, &guess));
    } else {
      p.poses.push_back(solve_pose(views[v], K, nullptr));
    }
  }
  return p;
}

OpenCvPoints opencv_points(const std::vector<View>& views, bool flatten) {
  OpenCvPoints out;
  for (const auto& v : views) {
    out.object.emplace_back();
    out.image.emplace_back();
    for (std::size_t i = 0; i < v.world_mm.size(); ++i) {
      const Eigen::Vector3d& X = v.world_mm[i];
      out.object.back().emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()),
                                     flatten ? 0.f : static_cast<float>(X.z()));
      out.image.back().emplace_back(static_cast<float>(v.observed_px[i].x()), static_cast<float>(v.observed_px[i].y()));
    }
  }
  return out;
}

Parameters initial_from_plane(const std::vector<View>& views, const ModelOptions& model, cv::Size image_size) {
  const OpenCvPoints points = opencv_points(views, true);
  cv::Mat K0;
  try {
    K0 = cv::initCameraMatrix2D(points.object, points.image, image_size, model.fix_aspect_ratio ? 1.0 : 0.0);
  } catch (const cv::Exception& e) {
    throw GeometryError(std::string("Zhang's initial estimate failed (") + e.err + "): the board views are degenerate");
  }
  Parameters p;
  p.intrinsics = {K0.at<double>(0, 0), K0.at<double>(1, 1), K0.at<double>(0, 2), K0.at<double>(1, 2)};
  apply_fixed(model, image_size, p);
  const Eigen::Matrix3d K = camera_matrix(p);
  for (const auto& v : views) p.poses.push_back(solve_pose(v, K, nullptr));
  return p;
}

}  // namespace photomill::calib
