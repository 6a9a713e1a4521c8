// Rig calibration (see rig.hpp).
#include "calib/rig.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <ceres/ceres.h>

#include "formats/error.hpp"
#include "formats/json.hpp"
#include "formats/text.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::calib {
namespace {

constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

// Camera k's view of one frame: the board points it saw and the observed pixels.
struct FrameView {
  std::string image;
  std::vector<Eigen::Vector3d> world_mm;
  std::vector<Eigen::Vector2d> observed_px;
  Eigen::Isometry3d cam_from_world = Eigen::Isometry3d::Identity();  // from the camera's own calibration
  bool kept = false;                                                  // by the camera's own calibration
};

struct Frame {
  std::string key;
  std::vector<FrameView> views;  // one per camera (empty image: none)
};

Eigen::Isometry3d isometry(const Pose& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = p.rotation();
  t.translation() = p.cam_from_world_translation_mm;
  return t;
}

// The rotation nearest (Frobenius) to M: U diag(1, 1, det(U V^T)) V^T.
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() > 0 ? 1 : -1;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

// Residual of camera k's observation of board point X in one frame:
//   x_cam = q_k (R_f X + t_f) + t_k,  r = project(K_k, d_k, x_cam) - uv
// board = [angle-axis, t] (rig_from_board of the frame), q_k the Eigen quaternion (x, y, z, w) and
// t_k the translation of cam_k_from_rig; intrinsics[4] and distortion[8] in calib's layout
// (model.hpp), the projection photomill's one camera model.
struct RigResidual {
  Eigen::Vector3d world_mm;
  Eigen::Vector2d observed_px;
  ModelOptions model;

  template <typename T>
  bool operator()(const T* board, const T* q, const T* t, const T* intrinsics, const T* distortion, T* residual) const {
    const T X[3] = {T(world_mm.x()), T(world_mm.y()), T(world_mm.z())};
    T p_rig[3];
    geometry::transform_point(board, X, p_rig);
    const Eigen::Map<const Eigen::Quaternion<T>> rotation(q);
    const Eigen::Matrix<T, 3, 1> p = rotation * Eigen::Matrix<T, 3, 1>(p_rig[0], p_rig[1], p_rig[2]) +
                                     Eigen::Matrix<T, 3, 1>(t[0], t[1], t[2]);
    if (!(p[2] > T(0.0))) return false;
    T uv[2];
    project_in_camera(intrinsics, distortion, model, p.data(), uv);
    residual[0] = uv[0] - T(observed_px.x());
    residual[1] = uv[1] - T(observed_px.y());
    return true;
  }
};
using RigCost = ceres::AutoDiffCostFunction<RigResidual, 2, 6, 4, 3, kIntrinsics, kDistortion>;

// A camera's intrinsics in calib's blocks.
struct Blocks {
  std::array<double, kIntrinsics> intrinsics{};
  std::array<double, kDistortion> distortion{};
};

Blocks blocks_of(const Camera& c) {
  Blocks b;
  b.intrinsics = {c.fx(), c.fy(), c.cx(), c.cy()};
  for (std::size_t i = 0; i < c.distortion.size() && i < b.distortion.size(); ++i) b.distortion[i] = c.distortion[i];
  return b;
}

struct RigPose {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  // cam_from_rig
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

std::array<double, 6> to_block(const Eigen::Isometry3d& t) {
  std::array<double, 6> b{};
  const Eigen::AngleAxisd aa(t.linear());
  const Eigen::Vector3d v = aa.angle() * aa.axis();
  b = {v.x(), v.y(), v.z(), t.translation().x(), t.translation().y(), t.translation().z()};
  return b;
}

struct Adjustment {
  double sse = 0;
  std::size_t residuals = 0;  // scalar residuals
  int iterations = 0;
  bool converged = false;
  std::string message;
};

// The residual vectors of frame f's views with the given poses.
std::vector<Eigen::Vector2d> frame_residuals(const Frame& f, const std::array<double, 6>& board,
                                             const std::vector<RigPose>& cams, const std::vector<Blocks>& blocks,
                                             const ModelOptions& model) {
  std::vector<Eigen::Vector2d> out;
  for (std::size_t k = 0; k < f.views.size(); ++k) {
    const FrameView& v = f.views[k];
    if (!v.kept) continue;
    for (std::size_t i = 0; i < v.world_mm.size(); ++i) {
      const RigResidual r{v.world_mm[i], v.observed_px[i], model};
      double res[2] = {1e6, 1e6};
      r(board.data(), cams[k].q.coeffs().data(), cams[k].t.data(), blocks[k].intrinsics.data(),
        blocks[k].distortion.data(), res);
      out.emplace_back(res[0], res[1]);
    }
  }
  return out;
}

}  // namespace

std::vector<std::vector<Observation>> split_by_camera(const std::vector<Observation>& observations,
                                                     const std::vector<std::string>& prefixes,
                                                     const std::string& source) {
  std::vector<std::vector<Observation>> out(prefixes.size());
  for (const Observation& o : observations) {
    const auto m = match_rig_prefix(prefixes, o.image);
    if (!m) {
      std::string list;
      for (const auto& p : prefixes) list += (list.empty() ? "'" : ", '") + p + "'";
      throw InputError(source, 0, "image '" + o.image + "' starts with none of the rig's prefixes (" + list +
                                      "): every photo must be taken by one of the rig's cameras");
    }
    out[m->camera].push_back(o);
  }
  for (std::size_t k = 0; k < prefixes.size(); ++k) {
    if (out[k].empty()) {
      throw InputError(source, 0, "no image starts with camera " + std::to_string(k) + "'s prefix '" + prefixes[k] +
                                      "': a rig camera needs its own board views");
    }
  }
  return out;
}

RigResult calibrate_rig(const std::vector<Observation>& observations, const std::vector<ControlPoint>& control,
                        const std::vector<std::string>& prefixes, const std::vector<cv::Size>& image_sizes,
                        const RigCalibOptions& options, const std::string& source) {
  if (prefixes.size() < 2) throw UsageError("a rig has two cameras or more (one image name prefix each)");
  if (image_sizes.size() != prefixes.size()) throw UsageError("one image size per rig camera");
  const auto by_camera = split_by_camera(observations, prefixes, source);
  const std::size_t n_cams = prefixes.size();
  RigResult result;

  // 1. Each camera on its own.
  const ModelOptions& model = options.camera.model;
  std::vector<Blocks> blocks;
  for (std::size_t k = 0; k < n_cams; ++k) {
    try {
      result.cameras.push_back(calibrate(by_camera[k], control, image_sizes[k], options.camera));
    } catch (const GeometryError& e) {
      throw GeometryError("camera " + std::to_string(k) + " ('" + prefixes[k] + "'): " + e.what());
    }
    blocks.push_back(blocks_of(result.cameras[k].camera));
    for (const auto& w : result.cameras[k].warnings) {
      result.warnings.push_back("camera " + std::to_string(k) + " ('" + prefixes[k] + "'): " + w);
    }
  }

  // The frames: every camera's views grouped by the image name less the prefix.
  std::map<PointId, Eigen::Vector3d> world;
  for (const auto& c : control) world[c.point_id] = c.xyz_mm;
  std::map<std::string, Frame> frames;
  for (std::size_t k = 0; k < n_cams; ++k) {
    std::map<std::string, const ViewReport*> reports;
    for (const auto& v : result.cameras[k].views) reports[v.image] = &v;
    for (const Observation& o : by_camera[k]) {
      const auto it = world.find(o.point_id);
      if (it == world.end()) continue;
      const std::string key = match_rig_prefix(prefixes, o.image)->frame;
      Frame& f = frames[key];
      f.key = key;
      f.views.resize(n_cams);
      FrameView& v = f.views[k];
      if (v.image.empty()) {
        v.image = o.image;
        const auto r = reports.find(o.image);
        if (r != reports.end() && !r->second->rejected) {
          v.kept = true;
          v.cam_from_world = isometry(r->second->cam_from_world);
        }
      } else if (v.image != o.image) {
        throw InputError(source, 0, "images '" + v.image + "' and '" + o.image + "' are one frame ('" + key +
                                        "') of camera " + std::to_string(k) + ": frames need one photo per camera");
      }
      v.world_mm.push_back(it->second);
      v.observed_px.emplace_back(o.u_px, o.v_px);
    }
  }

  // 2. Initial poses of the cameras in the rig (camera 0's frame).
  std::vector<RigPose> cams(n_cams);
  for (std::size_t k = 1; k < n_cams; ++k) {
    Eigen::Matrix3d sum_r = Eigen::Matrix3d::Zero();
    Eigen::Vector3d sum_t = Eigen::Vector3d::Zero();
    int n = 0;
    for (const auto& [key, f] : frames) {
      if (!f.views[0].kept || !f.views[k].kept) continue;
      const Eigen::Isometry3d k_from_0 = f.views[k].cam_from_world * f.views[0].cam_from_world.inverse();
      sum_r += k_from_0.linear();
      sum_t += k_from_0.translation();
      ++n;
    }
    if (n == 0) {
      throw GeometryError("camera " + std::to_string(k) + " ('" + prefixes[k] + "') shares no frame with camera 0 ('" +
                          prefixes[0] + "'): its pose in the rig is unknown; photograph the board with both at once "
                          "(photos named alike but for the prefix)");
    }
    cams[k].q = Eigen::Quaterniond(nearest_rotation(sum_r / n)).normalized();
    cams[k].t = sum_t / n;
  }

  // The frames seen by two cameras or more, with their initial board pose (rig_from_board).
  std::vector<Frame> used;
  std::vector<std::array<double, 6>> boards;
  for (auto& [key, f] : frames) {
    RigFrameReport report;
    report.frame = key;
    for (const auto& v : f.views) {
      report.images.push_back(v.image);
      report.cameras += v.kept;
      if (v.kept) report.points += static_cast<int>(v.world_mm.size());
    }
    if (report.cameras < 2) {
      report.reason = report.cameras == 1 ? "seen by one camera only (with a view its calibration kept)"
                                          : "no view kept by the cameras' own calibrations";
      result.frames.push_back(report);
      continue;
    }
    std::size_t k = 0;
    while (!f.views[k].kept) ++k;
    Eigen::Isometry3d cam_from_rig = Eigen::Isometry3d::Identity();
    cam_from_rig.linear() = cams[k].q.toRotationMatrix();
    cam_from_rig.translation() = cams[k].t;
    boards.push_back(to_block(cam_from_rig.inverse() * f.views[k].cam_from_world));
    used.push_back(f);
    report.used = true;
    result.frames.push_back(report);
  }
  const int min_frames = std::max(1, options.camera.min_views);
  if (used.empty()) {
    throw GeometryError("no frame is seen by two cameras of the rig: the board must be photographed by the "
                        "cameras at once, in photos named alike but for the prefix");
  }

  // 3. The adjustment, leaving out the worst frame while it is an outlier.
  std::vector<bool> active(used.size(), true);
  auto frame_index = [&](const std::string& key) {
    for (auto& r : result.frames) {
      if (r.frame == key) return &r;
    }
    return static_cast<RigFrameReport*>(nullptr);
  };
  // The adjustment's problem over the active frames: every camera's pose in the rig (camera 0's
  // held at the identity) and, unless fixed, its intrinsics (what calib's model frees).
  const auto ci = [&] {
    std::vector<int> out;
    const auto f = free_intrinsics(model);
    for (int i = 0; i < kIntrinsics; ++i) if (!f[static_cast<std::size_t>(i)]) out.push_back(i);
    return out;
  }();
  const auto cd = [&] {
    std::vector<int> out;
    const auto f = free_distortion(model);
    for (int i = 0; i < kDistortion; ++i) if (!f[static_cast<std::size_t>(i)]) out.push_back(i);
    return out;
  }();
  // fn(f, k, residual) for every observation of the active frames (views their cameras kept).
  auto each_observation = [&](const auto& fn) {
    for (std::size_t f = 0; f < used.size(); ++f) {
      if (!active[f]) continue;
      for (std::size_t k = 0; k < n_cams; ++k) {
        const FrameView& v = used[f].views[k];
        if (!v.kept) continue;
        for (std::size_t i = 0; i < v.world_mm.size(); ++i) fn(f, k, RigResidual{v.world_mm[i], v.observed_px[i], model});
      }
    }
  };
  auto build = [&](ceres::Problem& problem) -> std::size_t {
    std::size_t residuals = 0;
    for (std::size_t k = 0; k < n_cams; ++k) {
      problem.AddParameterBlock(cams[k].q.coeffs().data(), 4, new ceres::EigenQuaternionManifold);
      problem.AddParameterBlock(cams[k].t.data(), 3);
      problem.AddParameterBlock(blocks[k].intrinsics.data(), kIntrinsics);
      problem.AddParameterBlock(blocks[k].distortion.data(), kDistortion);
    }
    each_observation([&](std::size_t f, std::size_t k, const RigResidual& r) {
      problem.AddResidualBlock(new RigCost(new RigResidual(r)), nullptr, boards[f].data(), cams[k].q.coeffs().data(),
                               cams[k].t.data(), blocks[k].intrinsics.data(), blocks[k].distortion.data());
      residuals += 2;
    });
    problem.SetParameterBlockConstant(cams[0].q.coeffs().data());
    problem.SetParameterBlockConstant(cams[0].t.data());
    for (std::size_t k = 0; k < n_cams; ++k) {
      if (options.fix_intrinsics || static_cast<int>(ci.size()) == kIntrinsics) {
        problem.SetParameterBlockConstant(blocks[k].intrinsics.data());
      } else if (!ci.empty()) {
        problem.SetManifold(blocks[k].intrinsics.data(), new ceres::SubsetManifold(kIntrinsics, ci));
      }
      if (options.fix_intrinsics || static_cast<int>(cd.size()) == kDistortion) {
        problem.SetParameterBlockConstant(blocks[k].distortion.data());
      } else if (!cd.empty()) {
        problem.SetManifold(blocks[k].distortion.data(), new ceres::SubsetManifold(kDistortion, cd));
      }
    }
    return residuals;
  };
  std::size_t free_intrinsic_count = 0;
  if (!options.fix_intrinsics) free_intrinsic_count = n_cams * (kIntrinsics - ci.size() + kDistortion - cd.size());
  Adjustment adj;
  for (bool first = true;; first = false) {
    ceres::Problem problem;
    adj = {};
    adj.residuals = build(problem);
    ceres::Solver::Options o;
    o.minimizer_type = ceres::TRUST_REGION;
    o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    o.linear_solver_type = ceres::DENSE_SCHUR;
    o.max_num_iterations = options.lm.max_iterations;
    o.function_tolerance = options.lm.function_tolerance;
    o.parameter_tolerance = options.lm.parameter_tolerance;
    o.gradient_tolerance = options.lm.gradient_tolerance;
    o.num_threads = 1;
    o.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(o, &problem, &summary);
    adj.sse = 2 * summary.final_cost;
    adj.iterations = static_cast<int>(summary.iterations.size());
    adj.converged = summary.termination_type == ceres::CONVERGENCE;
    adj.message = summary.message;
    if (model.fix_aspect_ratio) {
      for (auto& b : blocks) b.intrinsics[1] = b.intrinsics[0];
    }
    if (!std::isfinite(adj.sse)) throw GeometryError("the rig adjustment diverged: " + summary.message);

    // Per-frame RMS; the worst frame is left out while it is an outlier.
    std::vector<double> rms(used.size(), 0);
    std::vector<double> active_rms;
    for (std::size_t f = 0; f < used.size(); ++f) {
      const auto res = frame_residuals(used[f], boards[f], cams, blocks, model);
      double ss = 0, mx = 0;
      for (const auto& r : res) ss += r.squaredNorm(), mx = std::max(mx, r.norm());
      rms[f] = std::sqrt(ss / static_cast<double>(res.size()));
      RigFrameReport* rep = frame_index(used[f].key);
      rep->rms_px = rms[f];
      rep->max_px = mx;
      if (active[f]) active_rms.push_back(rms[f]);
    }
    const double total_points = static_cast<double>(adj.residuals) / 2;
    if (first) result.first_rms_px = std::sqrt(adj.sse / total_points);
    std::vector<double> sorted = active_rms;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::size_t worst = used.size();
    for (std::size_t f = 0; f < used.size(); ++f) {
      if (active[f] && (worst == used.size() || rms[f] > rms[worst])) worst = f;
    }
    const bool outlier = options.camera.reject_factor > 0 && rms[worst] > options.camera.reject_factor * median &&
                         rms[worst] > options.camera.reject_min_px &&
                         static_cast<int>(active_rms.size()) > min_frames;
    if (!outlier) break;
    active[worst] = false;
    RigFrameReport* rep = frame_index(used[worst].key);
    rep->used = false;
    std::ostringstream why;
    why.precision(3);
    why << std::fixed << "RMS " << rms[worst] << " px > " << options.camera.reject_factor << " x median " << median
        << " px (the board moved between the cameras' shots, or a view is blurred)";
    rep->reason = why.str();
  }
  const int n_used = static_cast<int>(std::count(active.begin(), active.end(), true));
  if (n_used < min_frames) {
    result.warnings.push_back("only " + std::to_string(n_used) + " frames seen by two cameras or more (fewer than " +
                              std::to_string(min_frames) + "): the cameras' poses in the rig rest on little data");
  }
  result.points = adj.residuals / 2;
  result.rms_px = std::sqrt(adj.sse / static_cast<double>(result.points));
  result.iterations = adj.iterations;
  const std::size_t n_params = 6 * static_cast<std::size_t>(n_used) + 6 * (n_cams - 1) + free_intrinsic_count;
  const double dof = static_cast<double>(adj.residuals) - static_cast<double>(n_params);
  result.sigma_px = dof > 0 ? std::sqrt(adj.sse / dof) : 0;
  if (!adj.converged) result.warnings.push_back("the rig adjustment stopped before converging: " + adj.message);

  // 4. Covariance of every camera's pose (a fresh problem on the final frames).
  std::vector<std::optional<Eigen::Matrix<double, 6, 1>>> sigmas(n_cams);
  result.baseline_sigma_mm.assign(n_cams, std::numeric_limits<double>::quiet_NaN());
  if (dof > 0) {
    ceres::Problem problem;
    build(problem);
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;
    co.num_threads = 1;
    ceres::Covariance covariance(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (std::size_t k = 1; k < n_cams; ++k) {
      blocks.emplace_back(cams[k].q.coeffs().data(), cams[k].q.coeffs().data());
      blocks.emplace_back(cams[k].t.data(), cams[k].t.data());
    }
    if (covariance.Compute(blocks, &problem)) {
      const double s2 = adj.sse / dof;
      for (std::size_t k = 1; k < n_cams; ++k) {
        Eigen::Matrix3d cq, ct;
        covariance.GetCovarianceBlockInTangentSpace(cams[k].q.coeffs().data(), cams[k].q.coeffs().data(), cq.data());
        covariance.GetCovarianceBlock(cams[k].t.data(), cams[k].t.data(), ct.data());
        Eigen::Matrix<double, 6, 1> s;
        // EigenQuaternionManifold's tangent: q' = exp(delta) q, a small rotation about the camera's axes.
        for (int i = 0; i < 3; ++i) s[i] = std::sqrt(std::max(0.0, s2 * cq(i, i))) * kDegPerRad;
        for (int i = 0; i < 3; ++i) s[3 + i] = std::sqrt(std::max(0.0, s2 * ct(i, i)));
        sigmas[k] = s;
        // The baseline |t| (the distance between the camera centres): sigma^2 = u^T Cov_t u, u = t / |t|.
        const Eigen::Vector3d u = cams[k].t.normalized();
        result.baseline_sigma_mm[k] = std::sqrt(std::max(0.0, s2 * u.dot(ct * u)));
      }
    } else {
      result.warnings.push_back("the covariance of the cameras' poses in the rig cannot be computed (the "
                                "adjustment's normal matrix is singular): no standard deviations");
    }
  }

  // Each camera's RMS over the frames used, with the adjusted intrinsics.
  std::vector<double> camera_rms(n_cams, 0);
  {
    std::vector<double> ss(n_cams, 0), n(n_cams, 0);
    each_observation([&](std::size_t f, std::size_t k, const RigResidual& r) {
      double res[2];
      r(boards[f].data(), cams[k].q.coeffs().data(), cams[k].t.data(), blocks[k].intrinsics.data(),
        blocks[k].distortion.data(), res);
      ss[k] += res[0] * res[0] + res[1] * res[1];
      n[k] += 1;
    });
    for (std::size_t k = 0; k < n_cams; ++k) camera_rms[k] = n[k] > 0 ? std::sqrt(ss[k] / n[k]) : 0;
  }
  for (std::size_t k = 0; k < n_cams; ++k) {
    RigCamera c;
    c.prefix = prefixes[k];
    c.camera = result.cameras[k].camera;
    c.camera.camera_matrix(0, 0) = blocks[k].intrinsics[0];
    c.camera.camera_matrix(1, 1) = blocks[k].intrinsics[1];
    c.camera.camera_matrix(0, 2) = blocks[k].intrinsics[2];
    c.camera.camera_matrix(1, 2) = blocks[k].intrinsics[3];
    for (std::size_t i = 0; i < c.camera.distortion.size() && i < blocks[k].distortion.size(); ++i) {
      c.camera.distortion[i] = blocks[k].distortion[i];
    }
    c.camera.avg_reprojection_error_px = camera_rms[k];
    c.cam_from_rig_rotation = cams[k].q.normalized().toRotationMatrix();
    c.cam_from_rig_translation_mm = cams[k].t;
    if (k > 0) c.cam_from_rig_sigma = sigmas[k];
    result.rig.cameras.push_back(c);
  }
  result.rig.avg_reprojection_error_px = result.rms_px;
  return result;
}

std::vector<std::string> rig_text_report(const RigResult& r) {
  std::vector<std::string> lines;
  auto fixed = [](double v, int digits) {
    std::ostringstream s;
    s.precision(digits);
    s << std::fixed << v;
    return s.str();
  };
  for (std::size_t k = 0; k < r.rig.cameras.size(); ++k) {
    const CalibResult& c = r.cameras[k];
    int kept = 0;
    for (const auto& v : c.views) kept += !v.rejected;
    lines.push_back("camera " + std::to_string(k) + " ('" + r.rig.cameras[k].prefix + "'): " + std::to_string(kept) +
                    " of " + std::to_string(c.views.size()) + " views kept, RMS " + fixed(c.rms_px, 5) + " px, fx " +
                    fixed(c.camera.fx(), 3) + " fy " + fixed(c.camera.fy(), 3) + " cx " + fixed(c.camera.cx(), 3) +
                    " cy " + fixed(c.camera.cy(), 3));
  }
  lines.push_back("frames:");
  for (const auto& f : r.frames) {
    std::string images;
    for (const auto& i : f.images) images += (images.empty() ? "" : " + ") + (i.empty() ? std::string("-") : i);
    lines.push_back("  " + images + ": " + std::to_string(f.points) + " points" +
                    (f.cameras >= 2 ? ", RMS " + fixed(f.rms_px, 3) + " px, max " + fixed(f.max_px, 3) + " px" : "") +
                    (f.used ? "" : " (left out: " + f.reason + ")"));
  }
  for (std::size_t k = 1; k < r.rig.cameras.size(); ++k) {
    const RigCamera& c = r.rig.cameras[k];
    const Eigen::AngleAxisd aa(c.cam_from_rig_rotation);
    const Eigen::Vector3d& t = c.cam_from_rig_translation_mm;
    std::string line = "camera " + std::to_string(k) + " ('" + c.prefix + "') from camera 0: rotation " +
                       fixed(aa.angle() * kDegPerRad, 4) + " degrees about (" + fixed(aa.axis().x(), 3) + ", " +
                       fixed(aa.axis().y(), 3) + ", " + fixed(aa.axis().z(), 3) + "), translation (" + fixed(t.x(), 5) +
                       ", " + fixed(t.y(), 5) + ", " + fixed(t.z(), 5) + ") mm, baseline " + fixed(t.norm(), 5) + " mm";
    if (c.cam_from_rig_sigma) {
      const auto& s = *c.cam_from_rig_sigma;
      line += " +- " + fixed(r.baseline_sigma_mm[k], 5) + " (sigma: rotation " + fixed(s[0], 4) + " " + fixed(s[1], 4) + " " +
              fixed(s[2], 4) + " degrees, translation " + fixed(s[3], 5) + " " + fixed(s[4], 5) + " " + fixed(s[5], 5) +
              " mm)";
    }
    lines.push_back(line);
  }
  int used = 0;
  for (const auto& f : r.frames) used += f.used;
  lines.push_back("rig RMS " + fixed(r.rms_px, 5) + " px over " + std::to_string(used) + " frames, " +
                  std::to_string(r.points) + " points (" + fixed(r.first_rms_px, 5) +
                  " px in the first adjustment); a-posteriori sigma of one coordinate " + fixed(r.sigma_px, 4) + " px");
  return lines;
}

void write_rig_json_report(std::ostream& out, const RigResult& r) {
  JsonWriter j(out);
  j.begin_object();
  j.field("rms_px", r.rms_px).field("first_rms_px", r.first_rms_px).field("points", r.points);
  j.field("sigma_px", r.sigma_px).field("iterations", r.iterations);
  j.key("cameras").begin_array();
  for (std::size_t k = 0; k < r.rig.cameras.size(); ++k) {
    const RigCamera& c = r.rig.cameras[k];
    const CalibResult& cal = r.cameras[k];
    j.begin_object();
    j.field("prefix", c.prefix).field("calibration_rms_px", cal.rms_px);
    j.field("fx", c.camera.fx()).field("fy", c.camera.fy()).field("cx", c.camera.cx()).field("cy", c.camera.cy());
    j.key("distortion").begin_array();
    for (double d : c.camera.distortion) j.value(d);
    j.end_array();
    const Eigen::AngleAxisd aa(c.cam_from_rig_rotation);
    j.field("rotation_deg", aa.angle() * kDegPerRad);
    j.key("rotation_axis").begin_array().value(aa.axis().x()).value(aa.axis().y()).value(aa.axis().z()).end_array();
    const Eigen::Vector3d& t = c.cam_from_rig_translation_mm;
    j.key("translation_mm").begin_array().value(t.x()).value(t.y()).value(t.z()).end_array();
    j.field("baseline_mm", t.norm());
    if (k > 0) j.field("baseline_sigma_mm", r.baseline_sigma_mm[k]);
    if (c.cam_from_rig_sigma) {
      j.key("sigma_rotation_deg").begin_array();
      for (int i = 0; i < 3; ++i) j.value((*c.cam_from_rig_sigma)[i]);
      j.end_array().key("sigma_translation_mm").begin_array();
      for (int i = 3; i < 6; ++i) j.value((*c.cam_from_rig_sigma)[i]);
      j.end_array();
    }
    j.key("views").begin_array();
    for (const auto& v : cal.views) {
      j.begin_object().field("image", v.image).field("rms_px", v.rms_px).field("rejected", v.rejected);
      if (v.rejected) j.field("reason", v.reason);
      j.end_object();
    }
    j.end_array();
    j.end_object();
  }
  j.end_array();
  j.key("frames").begin_array();
  for (const auto& f : r.frames) {
    j.begin_object().field("frame", f.frame);
    j.key("images").begin_array();
    for (const auto& i : f.images) j.value(i);
    j.end_array();
    j.field("cameras", f.cameras).field("points", f.points).field("used", f.used);
    if (f.cameras >= 2) j.field("rms_px", f.rms_px).field("max_px", f.max_px);
    if (!f.used) j.field("reason", f.reason);
    j.end_object();
  }
  j.end_array();
  j.key("warnings").begin_array();
  for (const auto& w : r.warnings) j.value(w);
  j.end_array();
  j.end_object();
  out << "\n";
}

}  // namespace photomill::calib
