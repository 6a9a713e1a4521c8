// Point uncertainty from the normal equations (see covariance.hpp).
#include "triangulate/covariance.hpp"

#include <cmath>
#include <limits>

#include <ceres/jet.h>
#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include "geometry/parallel.hpp"
#include "triangulate/residuals.hpp"

namespace photomill::triangulate {
namespace {

constexpr int kPoseJetSize = 6 + 3;
constexpr int kFullJetSize = 6 + 3 + kIntrinsicCount;

// Whitened reprojection residual r (2) and its Jacobian with respect to [pose 6 | point 3 |
// intrinsics 18 (only when `with_intrinsics`)], by dual numbers (geometry/camera_model.hpp's project()).
template <int N>
bool observation_jacobian(const Scene& scene, const ObservationRef& ob, double inv_sigma,
                          Eigen::Matrix<double, 2, Eigen::Dynamic>& J, Eigen::Vector2d& r) {
  using Jet = ceres::Jet<double, N>;
  const PoseBlock& pose = scene.images[ob.image].cam_from_world;
  const Eigen::Vector3d& X = scene.tracks[ob.track].xyz_mm;
  Jet p[6], x[3], k[kIntrinsicCount], uv[2];
  for (int i = 0; i < 6; ++i) p[i] = Jet(pose[static_cast<std::size_t>(i)], i);
  for (int i = 0; i < 3; ++i) x[i] = Jet(X[i], 6 + i);
  for (int i = 0; i < kIntrinsicCount; ++i) {
    const double value = scene.camera_of(ob.image).params[static_cast<std::size_t>(i)];
    k[i] = N == kFullJetSize ? Jet(value, 9 + i) : Jet(value);
  }
  if (!project(shape_of(scene.camera_of(ob.image)), k, p, x, uv)) return false;
  J.resize(2, N);
  for (int i = 0; i < 2; ++i) J.row(i) = uv[i].v.transpose() * inv_sigma;
  r << (uv[0].a - ob.uv_px.x()) * inv_sigma, (uv[1].a - ob.uv_px.y()) * inv_sigma;
  return true;
}

// Column bookkeeping: global column of each local parameter in the reduced (f) system, -1 when
// the parameter is constant or eliminated.
struct Columns {
  std::vector<std::array<int, 6>> pose;                // per image
  std::vector<std::array<int, kIntrinsicCount>> intrinsics;  // per camera
  std::vector<std::array<int, 3>> point;               // per track, f-points only
  std::vector<char> eliminated;                        // per track: an e-point
  std::vector<char> variable;                          // per track: point is a free parameter
  int f = 0;                                           // size of the reduced system
  std::size_t e_points = 0;
};

Columns assign_columns(const Scene& scene, const BundleSetup& setup, const BundleOptions& bundle,
                       const AdjustmentLayout& layout) {
  Columns c;
  c.pose.assign(scene.images.size(), {-1, -1, -1, -1, -1, -1});
  std::array<int, kIntrinsicCount> none{};
  none.fill(-1);
  c.intrinsics.assign(scene.cameras.size(), none);
  c.point.assign(scene.tracks.size(), {-1, -1, -1});
  c.eliminated.assign(scene.tracks.size(), 0);
  c.variable.assign(scene.tracks.size(), 0);
  for (std::size_t i = 0; i < scene.images.size(); ++i) {
    if (!layout.image_used[i] || setup.pose_fixed(i)) continue;
    for (int k = 0; k < 6; ++k) {
      const bool fixed = setup.fixed_translation && setup.fixed_translation->first == i &&
                         k == 3 + setup.fixed_translation->second;
      if (!fixed) c.pose[i][static_cast<std::size_t>(k)] = c.f++;
    }
  }
  if (bundle.refine_intrinsics != IntrinsicsRefinement::None) {
    // Each camera seen by an image in the adjustment has its own columns.
    std::vector<char> camera_used(scene.cameras.size(), 0);
    for (std::size_t i = 0; i < scene.images.size(); ++i) {
      if (layout.image_used[i]) camera_used[scene.images[i].camera] = 1;
    }
    for (std::size_t cam = 0; cam < scene.cameras.size(); ++cam) {
      if (!camera_used[cam]) continue;
      std::vector<char> constant(kIntrinsicCount, 0);
      for (int k : constant_intrinsics(bundle.refine_intrinsics, scene.cameras[cam].distortion_count)) {
        constant[static_cast<std::size_t>(k)] = 1;
      }
      for (int k = 0; k < kIntrinsicCount; ++k) {
        if (!constant[static_cast<std::size_t>(k)]) c.intrinsics[cam][static_cast<std::size_t>(k)] = c.f++;
      }
    }
  }
  for (std::size_t t = 0; t < scene.tracks.size(); ++t) {
    if (!layout.in_ba[t]) continue;
    const SceneTrack& track = scene.tracks[t];
    if (track.at_control && !track.control_sigma_mm) continue;  // fixed
    c.variable[t] = 1;
    if (layout.in_bar[t]) {
      for (int k = 0; k < 3; ++k) c.point[t][static_cast<std::size_t>(k)] = c.f++;
    } else {
      c.eliminated[t] = 1;
      ++c.e_points;
    }
  }
  return c;
}

// One observation's Jacobian split into its reduced-system columns (idx, Jf) and its point
// columns (Jp, zero-size unless the point is variable).
struct SplitJacobian {
  std::vector<int> idx;
  Eigen::Matrix<double, 2, Eigen::Dynamic> Jf;
  Eigen::Matrix<double, 2, 3> Jp = Eigen::Matrix<double, 2, 3>::Zero();
  Eigen::Vector2d r = Eigen::Vector2d::Zero();
  bool ok = false;
};

SplitJacobian split(const Scene& scene, const Columns& c, bool with_intrinsics, std::size_t o, const BundleSetup& setup) {
  SplitJacobian s;
  const ObservationRef& ob = scene.observations[o];
  const double inv_sigma = 1.0 / setup.sigma_of(ob);
  Eigen::Matrix<double, 2, Eigen::Dynamic> J;
  s.ok = with_intrinsics ? observation_jacobian<kFullJetSize>(scene, ob, inv_sigma, J, s.r)
                         : observation_jacobian<kPoseJetSize>(scene, ob, inv_sigma, J, s.r);
  if (!s.ok) return s;
  std::vector<int> local;
  for (int k = 0; k < 6; ++k) {
    const int col = c.pose[ob.image][static_cast<std::size_t>(k)];
    if (col >= 0) {
      s.idx.push_back(col);
      local.push_back(k);
    }
  }
  for (int k = 0; k < 3; ++k) {
    const int col = c.point[ob.track][static_cast<std::size_t>(k)];
    if (col >= 0) {
      s.idx.push_back(col);
      local.push_back(6 + k);
    }
  }
  if (with_intrinsics) {
    for (int k = 0; k < kIntrinsicCount; ++k) {
      const int col = c.intrinsics[scene.images[ob.image].camera][static_cast<std::size_t>(k)];
      if (col >= 0) {
        s.idx.push_back(col);
        local.push_back(9 + k);
      }
    }
  }
  s.Jf.resize(2, static_cast<Eigen::Index>(local.size()));
  for (std::size_t k = 0; k < local.size(); ++k) s.Jf.col(static_cast<Eigen::Index>(k)) = J.col(local[k]);
  if (c.eliminated[ob.track]) s.Jp = J.block<2, 3>(0, 6);
  return s;
}

void scatter_add(Eigen::MatrixXd& S, const std::vector<int>& idx, const Eigen::MatrixXd& block) {
  for (std::size_t a = 0; a < idx.size(); ++a) {
    for (std::size_t b = 0; b < idx.size(); ++b) {
      S(idx[a], idx[b]) += block(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
    }
  }
}

// The e-point's normal-equation blocks: V (3x3) and W stacked over its observations (rows idx).
struct PointBlocks {
  Eigen::Matrix3d V = Eigen::Matrix3d::Zero();
  std::vector<int> idx;
  Eigen::MatrixXd W;  // idx.size() x 3
};

// What both passes read: the problem, its layout and the columns of the reduced system.
struct Problem {
  const Scene& scene;
  const BundleSetup& setup;
  const AdjustmentLayout& layout;
  const Columns& cols;
  bool with_intrinsics = false;
};

// Blocks of one e-point (also used for the second pass).
// With `U`, also adds each observation's J_f^T J_f to it.
PointBlocks point_blocks(const Problem& pr, std::size_t t, double* sum_r2, std::size_t* residuals, Eigen::MatrixXd* U) {
  PointBlocks pb;
  std::vector<Eigen::MatrixXd> parts;
  for (std::size_t o : pr.layout.active[t]) {
    const SplitJacobian s = split(pr.scene, pr.cols, pr.with_intrinsics, o, pr.setup);
    if (!s.ok) continue;
    if (sum_r2) *sum_r2 += s.r.squaredNorm();
    if (residuals) *residuals += 2;
    if (U) scatter_add(*U, s.idx, s.Jf.transpose() * s.Jf);
    pb.V += s.Jp.transpose() * s.Jp;
    pb.idx.insert(pb.idx.end(), s.idx.begin(), s.idx.end());
    parts.push_back(s.Jf.transpose() * s.Jp);
  }
  const SceneTrack& track = pr.scene.tracks[t];
  if (track.at_control && track.control_sigma_mm) {
    const double w = 1.0 / (*track.control_sigma_mm * *track.control_sigma_mm);
    pb.V += w * Eigen::Matrix3d::Identity();
    if (sum_r2) *sum_r2 += (track.xyz_mm - *track.control_mm).squaredNorm() * w;
    if (residuals) *residuals += 3;
  }
  pb.W.resize(static_cast<Eigen::Index>(pb.idx.size()), 3);
  Eigen::Index row = 0;
  for (const auto& p : parts) {
    pb.W.middleRows(row, p.rows()) = p;
    row += p.rows();
  }
  return pb;
}

// Pass 1's sums: S = U - sum_i W_i V_i^-1 W_i^T (f x f, only for the full method, else empty),
// the whitened residuals' sum of squares and count, and each e-point's V_i^-1.
struct ReducedSystem {
  Eigen::MatrixXd S;
  double sum_r2 = 0;
  std::size_t residuals = 0;
  std::vector<Eigen::Matrix3d> Vinv;
};

// The tracks' reprojection and control-point residuals into `sys`.
void add_points(const Problem& pr, bool full, ReducedSystem& sys) {
  const Columns& cols = pr.cols;
  for (std::size_t t = 0; t < pr.scene.tracks.size(); ++t) {
    if (!pr.layout.in_ba[t]) continue;
    if (cols.eliminated[t]) {
      const PointBlocks pb = point_blocks(pr, t, &sys.sum_r2, &sys.residuals, full ? &sys.S : nullptr);
      sys.Vinv[t] = pb.V.inverse();
      if (full) scatter_add(sys.S, pb.idx, -(pb.W * sys.Vinv[t] * pb.W.transpose()));
      continue;
    }
    // Fixed control points and scale-bar points: everything goes to U.
    for (std::size_t o : pr.layout.active[t]) {
      const SplitJacobian s = split(pr.scene, cols, pr.with_intrinsics, o, pr.setup);
      if (!s.ok) continue;
      sys.sum_r2 += s.r.squaredNorm();
      sys.residuals += 2;
      if (full) scatter_add(sys.S, s.idx, s.Jf.transpose() * s.Jf);
    }
    const SceneTrack& track = pr.scene.tracks[t];
    if (track.at_control && track.control_sigma_mm) {
      const double w = 1.0 / (*track.control_sigma_mm * *track.control_sigma_mm);
      sys.sum_r2 += (track.xyz_mm - *track.control_mm).squaredNorm() * w;
      sys.residuals += 3;
      if (full && cols.point[t][0] >= 0) {
        for (int k = 0; k < 3; ++k) sys.S(cols.point[t][static_cast<std::size_t>(k)], cols.point[t][static_cast<std::size_t>(k)]) += w;
      }
    }
  }
}

// Scale bars: r = (|A - B| - distance) / sigma into `sys`.
void add_scale_bars(const Problem& pr, bool full, ReducedSystem& sys) {
  for (const ScaleConstraint* b : pr.layout.bars) {
    const Eigen::Vector3d d = pr.scene.tracks[b->track_a].xyz_mm - pr.scene.tracks[b->track_b].xyz_mm;
    const double r = (d.norm() - b->distance_mm) / b->sigma_mm;
    sys.sum_r2 += r * r;
    sys.residuals += 1;
    if (!full) continue;
    const Eigen::Vector3d g = d.normalized() / b->sigma_mm;  // dr/dA = g^T, dr/dB = -g^T
    std::vector<int> idx;
    std::vector<double> values;
    for (int end = 0; end < 2; ++end) {
      const std::size_t t = end == 0 ? b->track_a : b->track_b;
      for (int k = 0; k < 3; ++k) {
        const int col = pr.cols.point[t][static_cast<std::size_t>(k)];
        if (col < 0) continue;
        idx.push_back(col);
        values.push_back(end == 0 ? g[k] : -g[k]);
      }
    }
    const Eigen::VectorXd j = Eigen::Map<Eigen::VectorXd>(values.data(), static_cast<Eigen::Index>(values.size()));
    scatter_add(sys.S, idx, j * j.transpose());
  }
}

// Pose priors (residuals.hpp's PosePrior), their Jacobian by dual numbers, into the pose's columns.
void add_pose_priors(const Problem& pr, bool full, ReducedSystem& sys) {
  for (const KnownPose& k : pr.setup.known_poses) {
    if (k.fixed() || k.image >= pr.scene.images.size() || !pr.layout.image_used[k.image]) continue;
    using Jet = ceres::Jet<double, 6>;
    const PoseBlock& pose = pr.scene.images[k.image].cam_from_world;
    Jet p[6], r[6];
    for (int i = 0; i < 6; ++i) p[i] = Jet(pose[static_cast<std::size_t>(i)], i);
    const PosePrior prior(k.cam_from_world, k.sigma_mm, k.sigma_rad);
    prior(p, r);
    sys.residuals += 6;
    for (int i = 0; i < 6; ++i) sys.sum_r2 += r[i].a * r[i].a;
    if (!full) continue;
    std::vector<int> idx, local;
    for (int c = 0; c < 6; ++c) {
      const int col = pr.cols.pose[k.image][static_cast<std::size_t>(c)];
      if (col < 0) continue;
      idx.push_back(col);
      local.push_back(c);
    }
    Eigen::MatrixXd J(6, static_cast<Eigen::Index>(local.size()));
    for (int i = 0; i < 6; ++i) {
      for (std::size_t c = 0; c < local.size(); ++c) J(i, static_cast<Eigen::Index>(c)) = r[i].v[local[c]];
    }
    scatter_add(sys.S, idx, J.transpose() * J);
  }
}

// Pass 2: the marginal covariance of variable track t (before the variance factor), by `method`;
// `sigma_f` = S^-1 for the full method.
Eigen::Matrix3d point_covariance(const Problem& pr, std::size_t t, CovarianceMethod method,
                                 const Eigen::MatrixXd& sigma_f, const Eigen::Matrix3d& Vinv) {
  const Columns& cols = pr.cols;
  Eigen::Matrix3d cov;
  if (cols.eliminated[t]) {
    cov = Vinv;
    if (method == CovarianceMethod::Full && cols.f > 0) {
      const PointBlocks pb = point_blocks(pr, t, nullptr, nullptr, nullptr);
      const auto n = static_cast<Eigen::Index>(pb.idx.size());
      Eigen::MatrixXd sub(n, n);
      for (Eigen::Index a = 0; a < n; ++a) {
        for (Eigen::Index b = 0; b < n; ++b) sub(a, b) = sigma_f(pb.idx[static_cast<std::size_t>(a)], pb.idx[static_cast<std::size_t>(b)]);
      }
      cov += Vinv * (pb.W.transpose() * sub * pb.W) * Vinv;
    }
  } else if (method == CovarianceMethod::Full) {
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        cov(a, b) = sigma_f(cols.point[t][static_cast<std::size_t>(a)], cols.point[t][static_cast<std::size_t>(b)]);
      }
    }
  } else {
    // Per-point method for a scale-bar point: its own normal block with poses fixed.
    Eigen::Matrix3d V = Eigen::Matrix3d::Zero();
    for (std::size_t o : pr.layout.active[t]) {
      Eigen::Matrix<double, 2, Eigen::Dynamic> J;
      Eigen::Vector2d r;
      const ObservationRef& ob = pr.scene.observations[o];
      if (observation_jacobian<kPoseJetSize>(pr.scene, ob, 1.0 / pr.setup.sigma_of(ob), J, r)) {
        V += J.block<2, 3>(0, 6).transpose() * J.block<2, 3>(0, 6);
      }
    }
    const SceneTrack& track = pr.scene.tracks[t];
    if (track.at_control && track.control_sigma_mm) V += Eigen::Matrix3d::Identity() / (*track.control_sigma_mm * *track.control_sigma_mm);
    cov = V.inverse();
  }
  return cov;
}

}  // namespace

double largest_axis_sigma_mm(const Eigen::Matrix3d& covariance_mm2) {
  if (!covariance_mm2.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  // Symmetrised first: the Schur-complement sum is symmetric only to rounding.
  const Eigen::Matrix3d c = 0.5 * (covariance_mm2 + covariance_mm2.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(c, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eig.eigenvalues().maxCoeff()));
}

const char* to_string(CovarianceMethod method) {
  return method == CovarianceMethod::Full ? "full_covariance" : "per_point_fixed_poses";
}

PointUncertainty point_uncertainty(const Scene& scene, const BundleSetup& setup, const BundleOptions& bundle,
                                   const CovarianceOptions& options) {
  const AdjustmentLayout layout = adjustment_layout(scene, setup, options.threads);
  const Columns cols = assign_columns(scene, setup, bundle, layout);
  const Problem pr{scene, setup, layout, cols, bundle.refine_intrinsics != IntrinsicsRefinement::None};
  PointUncertainty out;
  out.sigma_mm.assign(scene.tracks.size(), std::numeric_limits<double>::quiet_NaN());
  out.covariance_mm2.assign(scene.tracks.size(),
                            Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  out.method = static_cast<std::size_t>(cols.f) <= options.max_reduced_parameters ? CovarianceMethod::Full
                                                                                   : CovarianceMethod::PerPoint;
  const bool full = out.method == CovarianceMethod::Full;

  // Pass 1: S = U - sum_i W_i V_i^-1 W_i^T, the residual sum and count.
  ReducedSystem sys;
  sys.S = Eigen::MatrixXd::Zero(full ? cols.f : 0, full ? cols.f : 0);
  sys.Vinv.assign(scene.tracks.size(), Eigen::Matrix3d::Zero());
  add_points(pr, full, sys);
  add_scale_bars(pr, full, sys);
  add_pose_priors(pr, full, sys);

  const std::size_t unknowns = static_cast<std::size_t>(cols.f) + 3 * cols.e_points;
  if (sys.residuals > unknowns) {
    out.redundancy = sys.residuals - unknowns;
    out.variance_factor = sys.sum_r2 / static_cast<double>(out.redundancy);
  }

  Eigen::MatrixXd sigma_f;
  if (full && cols.f > 0) {
    const Eigen::LLT<Eigen::MatrixXd> llt(sys.S);
    if (llt.info() == Eigen::Success) {
      sigma_f = llt.solve(Eigen::MatrixXd::Identity(cols.f, cols.f));
      if (!sigma_f.allFinite()) out.method = CovarianceMethod::PerPoint;
    } else {
      out.method = CovarianceMethod::PerPoint;  // the gauge is not fixed: no full covariance
    }
  }

  // Pass 2: per-point marginal covariances.
  const double s0 = out.variance_factor;
  geometry::parallel_blocks(scene.tracks.size(), options.threads, 64, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t t = begin; t < end; ++t) {
      if (!layout.in_ba[t]) continue;
      if (!cols.variable[t]) {
        out.sigma_mm[t] = 0;  // a fixed control point
        out.covariance_mm2[t].setZero();
        continue;
      }
      out.covariance_mm2[t] = s0 * point_covariance(pr, t, out.method, sigma_f, sys.Vinv[t]);
      out.sigma_mm[t] = largest_axis_sigma_mm(out.covariance_mm2[t]);
    }
  });
  return out;
}

}  // namespace photomill::triangulate
