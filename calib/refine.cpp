// The three refinements and the covariance of the intrinsics (see refine.hpp).
#include "calib/refine.hpp"

#include <chrono>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <ceres/ceres.h>
#include <opencv2/calib3d.hpp>

#include "calib/init.hpp"
#include "formats/error.hpp"
#include "geometry/linear_algebra.hpp"

namespace photomill::calib {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double rms(const std::vector<View>& views, const Parameters& p, const ModelOptions& model) {
  const auto n = static_cast<double>(point_count(views));
  return n > 0 ? std::sqrt(sum_squared_error(views, p, model) / n) : 0.0;
}

template <std::size_t N>
std::vector<int> constant_indices(const std::array<bool, N>& is_free) {
  std::vector<int> out;
  for (std::size_t i = 0; i < N; ++i) {
    if (!is_free[i]) out.push_back(static_cast<int>(i));
  }
  return out;
}

using ResidualCost = ceres::AutoDiffCostFunction<ReprojectionResidual, 2, kIntrinsics, kDistortion, kPose>;

// The free parameters as one vector, in the order: free intrinsics, free distortion, every pose.
struct Packing {
  std::array<bool, kIntrinsics> fi;
  std::array<bool, kDistortion> fd;
  std::size_t views;

  Eigen::Index size() const {
    Eigen::Index n = static_cast<Eigen::Index>(6 * views);
    for (bool b : fi) n += b;
    for (bool b : fd) n += b;
    return n;
  }
  Eigen::VectorXd pack(const Parameters& p) const {
    Eigen::VectorXd x(size());
    Eigen::Index k = 0;
    for (int i = 0; i < kIntrinsics; ++i) {
      if (fi[i]) x(k++) = p.intrinsics[i];
    }
    for (int i = 0; i < kDistortion; ++i) {
      if (fd[i]) x(k++) = p.distortion[i];
    }
    for (const auto& pose : p.poses) {
      for (double v : pose) x(k++) = v;
    }
    return x;
  }
  void unpack(const Eigen::VectorXd& x, Parameters& p, bool fix_aspect) const {
    Eigen::Index k = 0;
    for (int i = 0; i < kIntrinsics; ++i) {
      if (fi[i]) p.intrinsics[i] = x(k++);
    }
    if (fix_aspect) p.intrinsics[1] = p.intrinsics[0];
    for (int i = 0; i < kDistortion; ++i) {
      if (fd[i]) p.distortion[i] = x(k++);
    }
    for (auto& pose : p.poses) {
      for (double& v : pose) v = x(k++);
    }
  }
};

}  // namespace

RefineStats refine_lm(const std::vector<View>& views, const ModelOptions& model, const LmOptions& options,
                      Parameters& p) {
  const auto t0 = Clock::now();
  RefineStats s;
  s.optimizer = "lm";
  s.initial_rms_px = rms(views, p, model);
  ceres::Problem problem;
  for (std::size_t v = 0; v < views.size(); ++v) {
    for (std::size_t i = 0; i < views[v].world_mm.size(); ++i) {
      problem.AddResidualBlock(
          new ResidualCost(new ReprojectionResidual{views[v].world_mm[i], views[v].observed_px[i], model}),
          nullptr, p.intrinsics.data(), p.distortion.data(), p.poses[v].data());
    }
  }
  const auto ci = constant_indices(free_intrinsics(model));
  const auto cd = constant_indices(free_distortion(model));
  if (!ci.empty()) problem.SetManifold(p.intrinsics.data(), new ceres::SubsetManifold(kIntrinsics, ci));
  if (static_cast<int>(cd.size()) == kDistortion) {
    problem.SetParameterBlockConstant(p.distortion.data());
  } else if (!cd.empty()) {
    problem.SetManifold(p.distortion.data(), new ceres::SubsetManifold(kDistortion, cd));
  }
  ceres::Solver::Options o;
  o.minimizer_type = ceres::TRUST_REGION;
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.linear_solver_type = ceres::DENSE_SCHUR;
  o.max_num_iterations = options.max_iterations;
  o.function_tolerance = options.function_tolerance;
  o.parameter_tolerance = options.parameter_tolerance;
  o.gradient_tolerance = options.gradient_tolerance;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  if (model.fix_aspect_ratio) p.intrinsics[1] = p.intrinsics[0];
  s.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  s.evaluations = summary.num_residual_evaluations;
  s.converged = summary.termination_type == ceres::CONVERGENCE;
  s.message = summary.message;
  s.final_rms_px = rms(views, p, model);
  s.seconds = seconds_since(t0);
  return s;
}

namespace {

// J of all residuals with respect to the packed free parameters (dense, m x n), by the same
// autodiff residual the LM uses.
Eigen::MatrixXd packed_jacobian(const std::vector<View>& views, const ModelOptions& model, const Parameters& p,
                                const Packing& packing) {
  Eigen::Index nc = 0;
  std::array<Eigen::Index, kIntrinsics + kDistortion> column{};
  column.fill(-1);
  for (int i = 0; i < kIntrinsics; ++i) {
    if (packing.fi[i]) column[i] = nc++;
  }
  for (int i = 0; i < kDistortion; ++i) {
    if (packing.fd[i]) column[kIntrinsics + i] = nc++;
  }
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(2 * point_count(views)), packing.size());
  Eigen::Index row = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    for (std::size_t i = 0; i < views[v].world_mm.size(); ++i, row += 2) {
      const ResidualCost cost(new ReprojectionResidual{views[v].world_mm[i], views[v].observed_px[i], model});
      double r[2];
      Eigen::Matrix<double, 2, kIntrinsics, Eigen::RowMajor> Ji;
      Eigen::Matrix<double, 2, kDistortion, Eigen::RowMajor> Jd;
      Eigen::Matrix<double, 2, kPose, Eigen::RowMajor> Jp;
      const double* params[3] = {p.intrinsics.data(), p.distortion.data(), p.poses[v].data()};
      double* jac[3] = {Ji.data(), Jd.data(), Jp.data()};
      cost.Evaluate(params, r, jac);
      for (int k = 0; k < kIntrinsics; ++k) {
        if (column[k] >= 0) J.block<2, 1>(row, column[k]) = Ji.col(k);
      }
      if (model.fix_aspect_ratio) J.block<2, 1>(row, column[0]) += Ji.col(1);  // fy = fx
      for (int k = 0; k < kDistortion; ++k) {
        if (column[kIntrinsics + k] >= 0) J.block<2, 1>(row, column[kIntrinsics + k]) = Jd.col(k);
      }
      J.block<2, kPose>(row, nc + static_cast<Eigen::Index>(kPose * v)) = Jp;
    }
  }
  return J;
}

// Whitening map L with L^T (J^T J) L = I (eigenvalues below 1e-12 of the largest are clamped), so
// that the cost in z, with x = x0 + L z, is near the minimum a sphere of unit curvature.
Eigen::MatrixXd whitening(const Eigen::MatrixXd& J) {
  const Eigen::MatrixXd A = J.transpose() * J;
  const Eigen::VectorXd d = A.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(d.asDiagonal() * A * d.asDiagonal());
  const double floor = 1e-12 * eig.eigenvalues().maxCoeff();
  const Eigen::VectorXd inv_sqrt = eig.eigenvalues().cwiseMax(floor).cwiseSqrt().cwiseInverse();
  return d.asDiagonal() * eig.eigenvectors() * inv_sqrt.asDiagonal();
}

}  // namespace

RefineStats refine_simplex(const std::vector<View>& views, const ModelOptions& model,
                           const SimplexRefineOptions& refine, cv::Size image_size, Parameters& p) {
  const SimplexOptions& options = refine.simplex;
  const auto t0 = Clock::now();
  RefineStats s;
  s.optimizer = "simplex";
  s.initial_rms_px = rms(views, p, model);
  const Packing packing{free_intrinsics(model), free_distortion(model), views.size()};
  Parameters work = p;
  if (refine.scaling == SimplexScaling::Diagonal) {
    // Initial simplex steps: roughly how far each parameter may be from the minimum after the
    // initial estimate (3 % of f and of the image side, 0.03 for k_i, 0.003 for p_i, 0.03 rad, 3 %
    // of the distance). On the opencv-chessboard left set, steps 3x to 30x of these all need ~2 M
    // evaluations, 0.1x more than 4 M (docs/measurements/calib.md).
    Parameters step;
    const double f = p.intrinsics[0];
    const double side = std::max(image_size.width, image_size.height);
    step.intrinsics = {0.03 * f, 0.03 * f, 0.03 * side, 0.03 * side};
    step.distortion = {0.03, 0.03, 0.003, 0.003, 0.03, 0.03, 0.03, 0.03};
    for (const auto& pose : p.poses) {
      const double d = std::max(1e-9, Eigen::Vector3d(pose[3], pose[4], pose[5]).norm());
      step.poses.push_back({0.03, 0.03, 0.03, 0.03 * d, 0.03 * d, 0.03 * d});
    }
    auto cost = [&](const Eigen::VectorXd& x) {
      packing.unpack(x, work, model.fix_aspect_ratio);
      return sum_squared_error(views, work, model);
    };
    const SimplexResult r = minimize_simplex(cost, packing.pack(p), packing.pack(step), options);
    packing.unpack(r.x, p, model.fix_aspect_ratio);
    s.iterations = r.iterations;
    s.evaluations = r.evaluations;
    s.restarts = r.restarts;
    s.converged = r.converged;
  } else {
    // Jacobian scaling: each run works in whitened coordinates z, x = x0 + L z, with L from the
    // Gauss-Newton curvature J^T J at its start point x0, and initial steps of `whitened_step`
    // (each raises the cost by about whitened_step^2 px^2; 3 to 100 all need ~40-50 k evaluations
    // on the chessboard and synth sets, docs/measurements/calib.md). The simplex itself still uses cost values only; L is an affine change
    // of variables, so the cost and its minimum are the same. Each restart re-whitens at the best
    // point so far.
    SimplexOptions once = options;
    once.max_restarts = 0;
    s.iterations = 0;
    s.evaluations = 0;
    double best = sum_squared_error(views, p, model);
    for (int run = 0;; ++run) {
      const Eigen::VectorXd x0 = packing.pack(p);
      const Eigen::MatrixXd L = whitening(packed_jacobian(views, model, p, packing));
      auto cost = [&](const Eigen::VectorXd& z) {
        packing.unpack(x0 + L * z, work, model.fix_aspect_ratio);
        return sum_squared_error(views, work, model);
      };
      once.max_evaluations = options.max_evaluations - s.evaluations;
      const Eigen::VectorXd z0 = Eigen::VectorXd::Zero(x0.size());
      const SimplexResult r = minimize_simplex(cost, z0, Eigen::VectorXd::Constant(x0.size(), refine.whitened_step),
                                               once);
      s.iterations += r.iterations;
      s.evaluations += r.evaluations;
      s.restarts = run;
      s.converged = r.converged;
      const double before = best;
      if (r.f < best) {
        best = r.f;
        packing.unpack(x0 + L * r.x, p, model.fix_aspect_ratio);
      }
      if (!r.converged || run >= options.max_restarts ||
          before - best <= options.restart_improvement * before + options.tiny) {
        break;
      }
    }
  }
  s.message = s.converged ? "converged after " + std::to_string(s.restarts) + " restarts"
                          : "stopped at the evaluation limit (" + std::to_string(options.max_evaluations) + ")";
  s.final_rms_px = rms(views, p, model);
  s.seconds = seconds_since(t0);
  return s;
}

RefineStats refine_opencv(const std::vector<View>& views, const ModelOptions& model, const LmOptions& options,
                          cv::Size image_size, bool use_guess, Parameters& p) {
  const auto t0 = Clock::now();
  RefineStats s;
  s.optimizer = "opencv";
  const OpenCvPoints points = opencv_points(views, false);
  cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat D = cv::Mat::zeros(model.rational ? 8 : 5, 1, CV_64F);
  int flags = 0;
  s.initial_rms_px = std::numeric_limits<double>::quiet_NaN();  // OpenCV starts from its own estimate
  if (use_guess) {
    s.initial_rms_px = rms(views, p, model);
    flags |= cv::CALIB_USE_INTRINSIC_GUESS;
    K.at<double>(0, 0) = p.intrinsics[0];
    K.at<double>(1, 1) = model.fix_aspect_ratio ? p.intrinsics[0] : p.intrinsics[1];
    K.at<double>(0, 2) = p.intrinsics[2];
    K.at<double>(1, 2) = p.intrinsics[3];
    for (int i = 0; i < D.rows; ++i) D.at<double>(i) = p.distortion[i];
  }
  if (model.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;  // keeps fx / fy = 1 (from K)
  if (model.fix_principal_point) flags |= cv::CALIB_FIX_PRINCIPAL_POINT;
  if (model.zero_tangent) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  if (model.fix_k3) flags |= cv::CALIB_FIX_K3;
  if (model.rational) flags |= cv::CALIB_RATIONAL_MODEL;
  std::vector<cv::Mat> rvecs;
  std::vector<cv::Mat> tvecs;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, options.max_iterations,
                                  std::numeric_limits<double>::epsilon());
  try {
    cv::calibrateCamera(points.object, points.image, image_size, K, D, rvecs, tvecs, flags, criteria);
  } catch (const cv::Exception& e) {
    throw GeometryError(std::string("OpenCV's calibrateCamera failed: ") + e.err);
  }
  p.intrinsics = {K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2)};
  p.distortion.fill(0);
  for (int i = 0; i < D.rows * D.cols && i < kDistortion; ++i) p.distortion[i] = D.at<double>(i);
  p.poses.clear();
  for (std::size_t v = 0; v < views.size(); ++v) {
    const cv::Mat r = rvecs[v].reshape(1, 3);
    const cv::Mat t = tvecs[v].reshape(1, 3);
    p.poses.push_back({r.at<double>(0), r.at<double>(1), r.at<double>(2), t.at<double>(0), t.at<double>(1),
                       t.at<double>(2)});
  }
  s.converged = true;  // OpenCV does not say; the caller checks the residuals
  s.message = "cv::calibrateCamera";
  s.final_rms_px = rms(views, p, model);
  s.seconds = seconds_since(t0);
  return s;
}

namespace {

// Projection uncertainty: first-order propagation of the camera block's marginal covariance C to
// the pixel of a ray fixed in the camera frame (Hartley & Zisserman, 2nd ed., 5.2.6), after the
// part of the change a rotation of the camera absorbs is removed: a principal point or focal
// length a little off is mostly the same image as the camera turned a little, which the poses of
// the photos to be measured take up. This is the idea of mrcal's projection uncertainty (the
// perturbed camera compared after the best transform between the two), here to first order and
// for rays at infinity (a rotation): with J_i = d(uv_i)/d(camera block) and
// R_i = d(uv_i)/d(rotation) at the pixels i of a grid over the image, the best rotation for a
// change dc is w = -A dc, A = (sum R_i^T R_i)^-1 sum R_i^T J_i, and the pixel moves by
// (J_i - R_i A) dc: Sigma_uv = (J - R A) C (J - R A)^T.
// One observation's residual (px) with its Jacobians: the free camera columns `cols` (ambient
// indices, intrinsics 0..3 then distortion) and the pose block. The uncertainty's normal
// equations and the projection sigma both evaluate it.
struct ObservationJacobians {
  Eigen::Vector2d residual;
  Eigen::MatrixXd camera;  // 2 x cols.size()
  Eigen::Matrix<double, 2, kPose> pose;
};
ObservationJacobians observation_jacobians(const ModelOptions& model, const Parameters& p, const double* pose,
                                           const Eigen::Vector3d& world_mm, const Eigen::Vector2d& observed_px,
                                           const std::vector<int>& cols) {
  const ResidualCost cost(new ReprojectionResidual{world_mm, observed_px, model});
  double r[2];
  Eigen::Matrix<double, 2, kIntrinsics, Eigen::RowMajor> Ji;
  Eigen::Matrix<double, 2, kDistortion, Eigen::RowMajor> Jd;
  Eigen::Matrix<double, 2, kPose, Eigen::RowMajor> Jp;
  const double* params[3] = {p.intrinsics.data(), p.distortion.data(), pose};
  double* jac[3] = {Ji.data(), Jd.data(), Jp.data()};
  cost.Evaluate(params, r, jac);
  ObservationJacobians out;
  out.residual = {r[0], r[1]};
  out.camera.resize(2, static_cast<Eigen::Index>(cols.size()));
  for (std::size_t k = 0; k < cols.size(); ++k) {
    const int c = cols[k];
    out.camera.col(static_cast<Eigen::Index>(k)) = c < kIntrinsics ? Eigen::Vector2d(Ji.col(c)) : Eigen::Vector2d(Jd.col(c - kIntrinsics));
  }
  out.pose = Jp;
  return out;
}

struct RayJacobians {
  Eigen::MatrixXd J;  // 2 x camera columns
  Eigen::Matrix<double, 2, 3> R;
  bool ok = false;
};
RayJacobians ray_jacobians(const ModelOptions& model, const Parameters& p, const std::vector<int>& cols,
                           const Eigen::Vector2d& pixel) {
  geometry::CameraModel camera;
  to_model_block(p.intrinsics.data(), p.distortion.data(), model.fix_aspect_ratio, camera.params.data());
  camera.distortion_count = model.rational ? 8 : 5;
  RayJacobians out;
  const auto ray = geometry::undistort(camera, pixel);
  if (!ray) return out;  // the model folds there
  const std::array<double, kPose> identity{};
  const ObservationJacobians j =
      observation_jacobians(model, p, identity.data(), Eigen::Vector3d(ray->x(), ray->y(), 1.0), pixel, cols);
  out.J = j.camera;
  out.R = j.pose.leftCols<3>();
  out.ok = true;
  return out;
}

struct ProjectionSigma {
  double sigma_px = 0;        // larger axis of the 1-sigma ellipse
  int worst_column = -1;      // the camera column whose own sigma moves the pixel most
  double worst_column_px = 0;
};
ProjectionSigma projection_sigma(const RayJacobians& ray, const Eigen::MatrixXd& A, const Eigen::MatrixXd& cov) {
  if (!ray.ok) return {std::numeric_limits<double>::infinity(), -1, 0};
  const Eigen::MatrixXd Jc = ray.J - ray.R * A;
  const Eigen::Matrix2d S = Jc * cov * Jc.transpose();
  ProjectionSigma out;
  out.sigma_px = std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(S).eigenvalues().maxCoeff()));
  for (Eigen::Index k = 0; k < Jc.cols(); ++k) {
    const double px = Jc.col(k).norm() * std::sqrt(std::max(0.0, cov(k, k)));
    if (px > out.worst_column_px) {
      out.worst_column_px = px;
      out.worst_column = static_cast<int>(k);
    }
  }
  return out;
}

// Fills u.projection_sigma_* (see Uncertainty) from the camera block's covariance.
void add_projection_sigma(const ModelOptions& model, const Parameters& p, const std::vector<int>& cols,
                          const Eigen::MatrixXd& cov, int width_px, int height_px, Uncertainty& u) {
  const double w = width_px - 1.0, h = height_px - 1.0;  // centres of the outermost pixels
  const auto nc = static_cast<Eigen::Index>(cols.size());
  // The rotation that best absorbs a change of the camera, fitted over a 9 x 7 grid.
  Eigen::Matrix3d RtR = Eigen::Matrix3d::Zero();
  Eigen::MatrixXd RtJ = Eigen::MatrixXd::Zero(3, nc);
  for (int gy = 0; gy < 7; ++gy) {
    for (int gx = 0; gx < 9; ++gx) {
      const RayJacobians ray = ray_jacobians(model, p, cols, {w * gx / 8.0, h * gy / 6.0});
      if (!ray.ok) continue;
      RtR += ray.R.transpose() * ray.R;
      RtJ += ray.R.transpose() * ray.J;
    }
  }
  const Eigen::MatrixXd A = geometry::solve_least_norm(RtR, RtJ);
  auto at = [&](double x, double y) { return projection_sigma(ray_jacobians(model, p, cols, {x, y}), A, cov); };
  u.projection_sigma_centre_px = at(w / 2, h / 2).sigma_px;
  u.projection_sigma_edges_px = 0;
  for (const auto& e : {std::pair{w / 2, 0.0}, std::pair{w / 2, h}, std::pair{0.0, h / 2}, std::pair{w, h / 2}}) {
    u.projection_sigma_edges_px = std::max(u.projection_sigma_edges_px, at(e.first, e.second).sigma_px);
  }
  u.projection_sigma_corners_px = 0;
  for (const auto& c : {std::pair{0.0, 0.0}, std::pair{w, 0.0}, std::pair{0.0, h}, std::pair{w, h}}) {
    const ProjectionSigma s = at(c.first, c.second);
    if (s.sigma_px < u.projection_sigma_corners_px) continue;
    u.projection_sigma_corners_px = s.sigma_px;
    if (s.worst_column >= 0) {
      const int col = cols[static_cast<std::size_t>(s.worst_column)];
      u.corner_sigma_parameter = col < kIntrinsics ? intrinsic_names()[col] : distortion_names()[col - kIntrinsics];
      u.corner_sigma_parameter_px = s.worst_column_px;
    }
  }
}

}  // namespace

Uncertainty estimate_uncertainty(const std::vector<View>& views, const ModelOptions& model, const Parameters& p,
                                 int width_px, int height_px) {
  // Normal equations with the camera block c (free intrinsics + distortion) and one pose block per
  // view; the poses are eliminated by the Schur complement, which gives the camera block's
  // marginal covariance exactly: Cov_c = s^2 (A_cc - sum_v A_cv A_vv^-1 A_vc)^-1.
  const auto fi = free_intrinsics(model);
  const auto fd = free_distortion(model);
  std::vector<int> cols;  // ambient index 0..11 of each camera column
  for (int i = 0; i < kIntrinsics; ++i) {
    if (fi[i]) cols.push_back(i);
  }
  for (int i = 0; i < kDistortion; ++i) {
    if (fd[i]) cols.push_back(kIntrinsics + i);
  }
  const auto nc = static_cast<Eigen::Index>(cols.size());
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(nc, nc);
  double sse = 0;
  std::size_t m = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    Eigen::MatrixXd Acv = Eigen::MatrixXd::Zero(nc, kPose);
    Eigen::Matrix<double, kPose, kPose> Avv = Eigen::Matrix<double, kPose, kPose>::Zero();
    for (std::size_t i = 0; i < views[v].world_mm.size(); ++i) {
      const ObservationJacobians j =
          observation_jacobians(model, p, p.poses[v].data(), views[v].world_mm[i], views[v].observed_px[i], cols);
      sse += j.residual.squaredNorm();
      m += 2;
      S += j.camera.transpose() * j.camera;
      Acv += j.camera.transpose() * j.pose;
      Avv += j.pose.transpose() * j.pose;
    }
    S -= Acv * geometry::pseudo_inverse(Avv) * Acv.transpose();
  }
  Uncertainty u;
  const long n = static_cast<long>(nc) + static_cast<long>(kPose * views.size());
  u.degrees_of_freedom = static_cast<int>(static_cast<long>(m) - n);
  u.sigma_px = u.degrees_of_freedom > 0 ? std::sqrt(sse / u.degrees_of_freedom) : std::numeric_limits<double>::quiet_NaN();
  // Jacobi scaling so that one threshold fits focal lengths (~1e3 px) and k3 (~1e-1) alike.
  Eigen::VectorXd d = S.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd Ss = d.asDiagonal() * S * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Ss);
  const double tol = 1e-12 * eig.eigenvalues().cwiseAbs().maxCoeff();
  Eigen::MatrixXd inv = Eigen::MatrixXd::Zero(nc, nc);
  Eigen::VectorXd null_weight = Eigen::VectorXd::Zero(nc);
  for (Eigen::Index k = 0; k < nc; ++k) {
    const double ev = eig.eigenvalues()(k);
    const Eigen::VectorXd e = eig.eigenvectors().col(k);
    if (ev > tol) {
      inv += e * e.transpose() / ev;
    } else {
      null_weight = null_weight.cwiseMax(e.cwiseAbs());
    }
  }
  const Eigen::MatrixXd cov = u.sigma_px * u.sigma_px * d.asDiagonal() * inv * d.asDiagonal();
  for (Eigen::Index k = 0; k < nc; ++k) {
    const bool undetermined = null_weight(k) > 0.1;
    const double sd = undetermined ? std::numeric_limits<double>::infinity() : std::sqrt(std::max(0.0, cov(k, k)));
    const int c = cols[k];
    if (c < kIntrinsics) {
      u.intrinsics_sigma[c] = sd;
      if (undetermined) u.undetermined.push_back(intrinsic_names()[c]);
    } else {
      u.distortion_sigma[c - kIntrinsics] = sd;
      if (undetermined) u.undetermined.push_back(distortion_names()[c - kIntrinsics]);
    }
  }
  if (model.fix_aspect_ratio) u.intrinsics_sigma[1] = u.intrinsics_sigma[0];
  add_projection_sigma(model, p, cols, cov, width_px, height_px, u);
  return u;
}

}  // namespace photomill::calib
