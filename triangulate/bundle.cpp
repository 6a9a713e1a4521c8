// Bundle adjustment (see bundle.hpp).
#include "triangulate/bundle.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <set>

#include "geometry/parallel.hpp"
#include "triangulate/residuals.hpp"

namespace photomill::triangulate {
namespace {

// Ceres' loss functions take ownership semantics from the Problem; the problem deletes them.
ceres::LossFunction* make_loss(LossKind kind, double scale) {
  switch (kind) {
    case LossKind::Trivial: return nullptr;
    case LossKind::Huber: return new ceres::HuberLoss(scale);
    case LossKind::Cauchy: return new ceres::CauchyLoss(scale);
    case LossKind::SoftL1: return new ceres::SoftLOneLoss(scale);
  }
  return nullptr;
}

ceres::LinearSolverType choose_solver(const BundleOptions& o, std::size_t images) {
  switch (o.solver) {
    case SolverKind::DenseSchur: return ceres::DENSE_SCHUR;
    case SolverKind::SparseSchur: return ceres::SPARSE_SCHUR;
    case SolverKind::IterativeSchur: return ceres::ITERATIVE_SCHUR;
    case SolverKind::Auto: break;
  }
  if (images <= static_cast<std::size_t>(o.dense_schur_max_images)) return ceres::DENSE_SCHUR;
  if (images <= static_cast<std::size_t>(o.sparse_schur_max_images)) return ceres::SPARSE_SCHUR;
  return ceres::ITERATIVE_SCHUR;
}

}  // namespace

const char* to_string(LossKind loss) {
  switch (loss) {
    case LossKind::Trivial: return "none";
    case LossKind::Huber: return "huber";
    case LossKind::Cauchy: return "cauchy";
    case LossKind::SoftL1: return "soft-l1";
  }
  return "unknown";
}

const char* to_string(SolverKind solver) {
  switch (solver) {
    case SolverKind::Auto: return "auto";
    case SolverKind::DenseSchur: return "dense-schur";
    case SolverKind::SparseSchur: return "sparse-schur";
    case SolverKind::IterativeSchur: return "iterative-schur";
  }
  return "unknown";
}

const char* to_string(IntrinsicsRefinement level) {
  switch (level) {
    case IntrinsicsRefinement::None: return "none";
    case IntrinsicsRefinement::Focal: return "focal";
    case IntrinsicsRefinement::FocalPrincipalPoint: return "focal-pp";
    case IntrinsicsRefinement::All: return "all";
  }
  return "unknown";
}

std::vector<int> constant_intrinsics(IntrinsicsRefinement level, int distortion_count) {
  std::set<int> varying;
  if (level != IntrinsicsRefinement::None) varying.insert({kFx, kFy});
  if (level == IntrinsicsRefinement::FocalPrincipalPoint || level == IntrinsicsRefinement::All) {
    varying.insert({kCx, kCy});
  }
  if (level == IntrinsicsRefinement::All) {
    if (distortion_count >= 4) varying.insert({kK1, kK2, kP1, kP2});
    if (distortion_count >= 5) varying.insert(kK3);
    if (distortion_count >= 8) varying.insert({kK4, kK5, kK6});
    if (distortion_count >= 12) varying.insert({kS1, kS2, kS3, kS4});
    if (distortion_count >= 14) varying.insert({kTauX, kTauY});
  }
  std::vector<int> constant;
  for (int i = 0; i < kIntrinsicCount; ++i) {
    if (!varying.count(i)) constant.push_back(i);
  }
  return constant;
}

int intrinsics_block_size(IntrinsicsRefinement level, int distortion_count) {
  const std::vector<int> constant = constant_intrinsics(level, distortion_count);
  int size = intrinsics_read(geometry::shape_of_count(distortion_count));
  for (int i = 0; i < kIntrinsicCount; ++i) {
    if (std::find(constant.begin(), constant.end(), i) == constant.end()) size = std::max(size, i + 1);
  }
  for (int s : {static_cast<int>(kK4), static_cast<int>(kS1), static_cast<int>(kTauX)}) {
    if (size <= s) return s;
  }
  return kIntrinsicCount;
}

bool in_adjustment(const Scene& scene, std::size_t track, std::size_t active) {
  const SceneTrack& t = scene.tracks[track];
  if (t.at_control) return active >= 1;
  return t.state == TrackState::Triangulated && active >= 2;
}

double reprojection_error_px(const Scene& scene, std::size_t observation) {
  const ObservationRef& ob = scene.observations[observation];
  const auto uv = project_point(scene.camera_of(ob.image), scene.images[ob.image].cam_from_world.data(),
                                scene.tracks[ob.track].xyz_mm);
  return uv ? (*uv - ob.uv_px).norm() : std::numeric_limits<double>::infinity();
}

AdjustmentLayout adjustment_layout(const Scene& scene, const BundleSetup& setup, int threads) {
  AdjustmentLayout l;
  l.active.resize(scene.tracks.size());
  l.in_ba.assign(scene.tracks.size(), 0);
  l.in_bar.assign(scene.tracks.size(), 0);
  l.image_used.assign(scene.images.size(), 0);
  geometry::parallel_blocks(scene.tracks.size(), threads, 64, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t t = begin; t < end; ++t) {
      l.active[t] = scene.active_observations(t);
      l.in_ba[t] = in_adjustment(scene, t, l.active[t].size()) ? 1 : 0;
    }
  });
  for (std::size_t t = 0; t < scene.tracks.size(); ++t) {
    if (!l.in_ba[t]) continue;
    for (std::size_t o : l.active[t]) l.image_used[scene.observations[o].image] = 1;
  }
  // Points that appear in a scale bar cannot be eliminated with the others (a residual may hold
  // only one eliminated block), so they join the cameras in the second elimination group.
  for (const ScaleConstraint& b : setup.scale_bars) {
    if (l.in_ba[b.track_a] && l.in_ba[b.track_b] && b.track_a != b.track_b) {
      l.bars.push_back(&b);
      l.in_bar[b.track_a] = l.in_bar[b.track_b] = 1;
    }
  }
  return l;
}

std::shared_ptr<ceres::ParameterBlockOrdering> build_problem(Scene& scene, const BundleSetup& setup,
                                                             const BundleOptions& options, ceres::Problem& problem,
                                                             BundleSummary& out) {
  const bool refine_intrinsics = options.refine_intrinsics != IntrinsicsRefinement::None;
  // Each camera's refined intrinsics: the first block_size of its parameters (the rest held
  // fixed), shared by the photos taken with it.
  std::vector<int> block_size(scene.cameras.size());
  for (std::size_t k = 0; k < scene.cameras.size(); ++k) {
    block_size[k] = intrinsics_block_size(options.refine_intrinsics, scene.cameras[k].distortion_count);
  }

  const AdjustmentLayout layout = adjustment_layout(scene, setup, options.threads);
  const auto& active = layout.active;
  const auto& in_ba = layout.in_ba;
  const auto& in_bar = layout.in_bar;
  const auto& bars = layout.bars;
  const auto& image_used = layout.image_used;

  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (std::size_t t = 0; t < scene.tracks.size(); ++t) {
    if (!in_ba[t]) continue;
    SceneTrack& track = scene.tracks[t];
    double* X = track.xyz_mm.data();
    for (std::size_t o : active[t]) {
      const ObservationRef& ob = scene.observations[o];
      double* pose = scene.images[ob.image].cam_from_world.data();
      const std::size_t cam = scene.images[ob.image].camera;
      // The loss acts on whitened residuals: its scale in pixels divided by the same sigma.
      ceres::LossFunction* loss = make_loss(options.loss, options.loss_scale_px / setup.sigma_of(ob));
      if (setup.in_rig(scene, ob.image)) {
        double* rig_pose = scene.rig->rig_from_world[static_cast<std::size_t>(scene.images[ob.image].frame)].data();
        double* cam_pose = scene.rig->cam_from_rig[cam].data();
        ceres::CostFunction* rig_cost =
            rig_reprojection_error(scene.cameras[cam], refine_intrinsics ? block_size[cam] : 0, ob.uv_px, setup.sigma_of(ob));
        if (refine_intrinsics) {
          problem.AddResidualBlock(rig_cost, loss, rig_pose, cam_pose, X, scene.cameras[cam].params.data());
        } else {
          problem.AddResidualBlock(rig_cost, loss, rig_pose, cam_pose, X);
        }
        continue;
      }
      ceres::CostFunction* cost =
          refine_intrinsics ? reprojection_error_with_intrinsics(block_size[cam], shape_of(scene.cameras[cam]), ob.uv_px, setup.sigma_of(ob))
                            : ReprojectionError::create(&scene.camera_of(ob.image), ob.uv_px, setup.sigma_of(ob));
      if (refine_intrinsics) {
        problem.AddResidualBlock(cost, loss, pose, X, scene.cameras[cam].params.data());
      } else {
        problem.AddResidualBlock(cost, loss, pose, X);
      }
    }
    bool constant = false;
    if (track.at_control) {
      if (track.control_sigma_mm) {
        problem.AddResidualBlock(ControlPointPrior::create(*track.control_mm, *track.control_sigma_mm), nullptr, X);
      } else {
        problem.SetParameterBlockConstant(X);
        constant = true;
      }
    }
    // Constant blocks leave the problem before solving; keep them out of the eliminated group so
    // that its emptiness below says whether anything is left to eliminate.
    ordering->AddElementToGroup(X, in_bar[t] || constant ? 1 : 0);
    ++out.points;
  }
  for (const ScaleConstraint* b : bars) {
    problem.AddResidualBlock(ScaleBarError::create(b->distance_mm, b->sigma_mm), nullptr,
                             scene.tracks[b->track_a].xyz_mm.data(), scene.tracks[b->track_b].xyz_mm.data());
  }
  for (std::size_t i = 0; i < scene.images.size(); ++i) {
    if (!image_used[i]) continue;
    if (setup.in_rig(scene, i)) {
      ++out.images;
      continue;  // posed by its frame and camera, below
    }
    double* pose = scene.images[i].cam_from_world.data();
    ordering->AddElementToGroup(pose, 1);
    ++out.images;
    const KnownPose* known = setup.known_pose(i);
    if (setup.pose_fixed(i)) {
      problem.SetParameterBlockConstant(pose);
    } else if (known) {
      problem.AddResidualBlock(PosePrior::create(known->cam_from_world, known->sigma_mm, known->sigma_rad), nullptr, pose);
    } else if (setup.fixed_translation && setup.fixed_translation->first == i) {
      problem.SetManifold(pose, new ceres::SubsetManifold(6, {3 + setup.fixed_translation->second}));
    }
  }
  if (setup.use_rig && scene.rig) {
    SceneRig& rig = *scene.rig;
    for (std::size_t f = 0; f < rig.rig_from_world.size(); ++f) {
      double* block = rig.rig_from_world[f].data();
      if (!problem.HasParameterBlock(block)) continue;
      ordering->AddElementToGroup(block, 1);
      if (f == setup.rig_reference_frame || setup.fix_poses) problem.SetParameterBlockConstant(block);
    }
    for (std::size_t k = 0; k < rig.cam_from_rig.size(); ++k) {
      double* block = rig.cam_from_rig[k].data();
      if (!problem.HasParameterBlock(block)) continue;
      ordering->AddElementToGroup(block, 1);
      const bool prior = k > 0 && k < setup.cam_from_rig_sigma.size() && setup.cam_from_rig_sigma[k] && !setup.fix_poses;
      if (prior) {
        problem.AddResidualBlock(RigPosePrior::create(setup.cam_from_rig_given[k], *setup.cam_from_rig_sigma[k]), nullptr, block);
      } else {
        problem.SetParameterBlockConstant(block);
      }
    }
  }
  for (std::size_t cam = 0; refine_intrinsics && cam < scene.cameras.size(); ++cam) {
    double* intrinsics = scene.cameras[cam].params.data();
    if (!problem.HasParameterBlock(intrinsics)) continue;
    ordering->AddElementToGroup(intrinsics, 1);
    std::vector<int> constant;
    for (int k : constant_intrinsics(options.refine_intrinsics, scene.cameras[cam].distortion_count)) {
      if (k < block_size[cam]) constant.push_back(k);
    }
    if (!constant.empty()) problem.SetManifold(intrinsics, new ceres::SubsetManifold(block_size[cam], constant));
  }
  out.residual_blocks = static_cast<std::size_t>(problem.NumResidualBlocks());
  return ordering;
}

BundleSummary bundle_adjust(Scene& scene, const BundleSetup& setup, const BundleOptions& options) {
  BundleSummary out;
  ceres::Problem problem;
  const auto ordering = build_problem(scene, setup, options, problem, out);
  if (out.residual_blocks == 0) return out;

  ceres::Solver::Options so;
  so.linear_solver_type = choose_solver(options, out.images);
  so.preconditioner_type = ceres::SCHUR_JACOBI;
  // With every pose (and the intrinsics) constant, nothing is left once the points are
  // eliminated, which the Schur solvers cannot take: each point is then its own small problem.
  bool any_free_camera = false;
  if (const auto g = ordering->group_to_elements().find(1); g != ordering->group_to_elements().end()) {
    for (double* block : g->second) any_free_camera = any_free_camera || !problem.IsParameterBlockConstant(block);
  }
  if (ordering->GroupSize(0) > 0 && any_free_camera) {
    so.linear_solver_ordering = ordering;
  } else if (ordering->GroupSize(0) > 0) {
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  } else {
    // Nothing to eliminate (every point is in a scale bar): a plain sparse solve.
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  }
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  // One thread when the intrinsics are refined: their block is in every residual, and Ceres 2.1's
  // Schur eliminator locks each block of the reduced system a point updates, so two threads
  // queue on that block for every point and are slower than one (docs/measurements/triangulate.md,
  // session 53). Without a shared block the threads asked for.
  bool shared_block = false;
  for (const CameraModel& camera : scene.cameras) {
    shared_block = shared_block || (options.refine_intrinsics != IntrinsicsRefinement::None &&
                                    problem.HasParameterBlock(camera.params.data()));
  }
  so.num_threads = shared_block ? 1 : geometry::thread_count(options.threads);
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  // The photos taken with the rig get the poses its frame and camera give.
  for (std::size_t i = 0; i < scene.images.size(); ++i) {
    if (!setup.in_rig(scene, i)) continue;
    SceneImage& im = scene.images[i];
    const SceneRig& rig = *scene.rig;
    if (!rig.frame_placed[static_cast<std::size_t>(im.frame)]) continue;
    im.cam_from_world = compose(rig.cam_from_rig[im.camera], rig.rig_from_world[static_cast<std::size_t>(im.frame)]);
  }
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  out.seconds = summary.total_time_in_seconds;
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.usable = summary.IsSolutionUsable();
  out.solver = ceres::LinearSolverTypeToString(summary.linear_solver_type_used);
  out.threads = so.num_threads;
  out.message = summary.message;
  out.timing = "preprocessor " + std::to_string(summary.preprocessor_time_in_seconds) + " s, residuals " +
               std::to_string(summary.residual_evaluation_time_in_seconds) + " s, jacobians " +
               std::to_string(summary.jacobian_evaluation_time_in_seconds) + " s, linear solver " +
               std::to_string(summary.linear_solver_time_in_seconds) + " s, postprocessor " +
               std::to_string(summary.postprocessor_time_in_seconds) + " s";
  return out;
}

}  // namespace photomill::triangulate
