// Bundle adjustment with Ceres: camera poses, 3D points and optionally the intrinsics, minimising
// the whitened reprojection errors (robust loss) plus control-point priors and scale bars.
// Points are eliminated first (Schur complement), so hundreds of images and 100k points stay fast.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <ceres/problem.h>
#include <ceres/ordered_groups.h>

#include "triangulate/scene.hpp"

namespace photomill::triangulate {

enum class LossKind { Trivial, Huber, Cauchy, SoftL1 };
enum class SolverKind { Auto, DenseSchur, SparseSchur, IterativeSchur };
enum class IntrinsicsRefinement { None, Focal, FocalPrincipalPoint, All };

struct BundleOptions {
  // Robust loss on each reprojection residual and its scale, pixels: residuals up to about this
  // size count fully, larger ones less (Huber: linearly, Cauchy: logarithmically).
  LossKind loss = LossKind::Huber;
  double loss_scale_px = 1.0;
  // Linear solver. Auto: DENSE_SCHUR up to dense_schur_max_images images, SPARSE_SCHUR up to
  // sparse_schur_max_images, ITERATIVE_SCHUR (Schur-Jacobi preconditioner) beyond.
  SolverKind solver = SolverKind::Auto;
  int dense_schur_max_images = 50;
  int sparse_schur_max_images = 2000;
  // Stopping rules (Ceres' meaning): iterations, and relative decrease of the cost, gradient
  // size and step size below which the solver stops.
  int max_iterations = 100;
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  int threads = 0;  // 0: all hardware threads
  IntrinsicsRefinement refine_intrinsics = IntrinsicsRefinement::None;
};

// A known distance between two tracks (from a scale-bar file or a marker side).
struct ScaleConstraint {
  std::size_t track_a = 0;    // index into Scene::tracks
  std::size_t track_b = 0;
  double distance_mm = 0;
  double sigma_mm = 0;
};

// A camera pose given by the user (triangulate --known-poses): held constant when its sigmas are
// 0, else a prior with those standard deviations (residuals.hpp's PosePrior).
struct KnownPose {
  std::size_t image = 0;        // index into Scene::images
  PoseBlock cam_from_world{};
  double sigma_mm = 0;          // of the camera centre, per axis
  double sigma_rad = 0;         // of the rotation, per axis
  bool fixed() const { return sigma_mm == 0 || sigma_rad == 0; }
};

// The datum and weights of one adjustment.
struct BundleSetup {
  // Reprojection residuals are divided by the sigma of their observation's class (pixels) times
  // the observation's relative sigma (its feature size, see build_scene).
  std::array<double, kObservationClasses> observation_sigma_px{1, 1};
  double sigma_of(const ObservationRef& ob) const {
    return observation_sigma_px[static_cast<std::size_t>(ob.cls)] * ob.rel_sigma;
  }
  std::vector<ScaleConstraint> scale_bars;   // used when both tracks are in the adjustment
  std::optional<std::size_t> fixed_image;    // gauge: this image's pose is held constant
  // Gauge: one coordinate (0..2) of this image's translation is held constant (fixes the scale
  // of a reconstruction without any scale information, as COLMAP does).
  std::optional<std::pair<std::size_t, int>> fixed_translation;
  // Hold all poses constant (a structure-only adjustment).
  bool fix_poses = false;
  // Poses the user gave: held constant or held by a prior.
  std::vector<KnownPose> known_poses;
  // The known pose of an image, or nullptr.
  const KnownPose* known_pose(std::size_t image) const {
    for (const KnownPose& k : known_poses) {
      if (k.image == image) return &k;
    }
    return nullptr;
  }
  // The rig (Scene::rig): the photos of its frames are posed by rig_from_world x cam_from_rig.
  // The reference frame's rig pose is constant (the rig's frame there is the world), and so is
  // camera 0's pose in the rig (the rig's frame is camera 0's); another camera's pose in the rig
  // is held by RigPosePrior with its calibration's sigma, or constant without one.
  bool use_rig = false;
  std::size_t rig_reference_frame = 0;
  std::vector<PoseBlock> cam_from_rig_given;                                   // per camera
  std::vector<std::optional<Eigen::Matrix<double, 6, 1>>> cam_from_rig_sigma;  // deg x3, mm x3
  bool in_rig(const Scene& scene, std::size_t image) const {
    return use_rig && scene.rig && scene.images[image].frame >= 0;
  }
  // True if the image's pose is a constant of the adjustment.
  bool pose_fixed(std::size_t image) const {
    if (fix_poses || (fixed_image && *fixed_image == image)) return true;
    const KnownPose* k = known_pose(image);
    return k && k->fixed();
  }
};

struct BundleSummary {
  int iterations = 0;
  double seconds = 0;
  double initial_cost = 0;       // Ceres' cost 1/2 sum rho(r^2), whitened
  double final_cost = 0;
  bool usable = false;
  std::size_t residual_blocks = 0;
  std::size_t images = 0;        // poses in the adjustment
  std::size_t points = 0;        // points in the adjustment
  std::string solver;            // linear solver used
  int threads = 0;               // threads Ceres used
  std::string message;           // Ceres' termination message
  std::string timing;            // where the time went (preprocessing, Jacobians, linear solver)
};

// Which tracks take part: Triangulated ones with two or more active observations, and control
// tracks placed at their control value (at_control) with one or more (fixed when they have no
// sigma, else held by ControlPointPrior).
bool in_adjustment(const Scene& scene, std::size_t track, std::size_t active_observations);

// Who takes part in an adjustment (shared by bundle_adjust and the covariance).
struct AdjustmentLayout {
  std::vector<std::vector<std::size_t>> active;  // per track: its active observations
  std::vector<char> in_ba;                       // per track: in the adjustment
  std::vector<char> in_bar;                      // per track: end of a scale bar in use
  std::vector<char> image_used;                  // per image: has observations in the adjustment
  std::vector<const ScaleConstraint*> bars;      // scale bars with both ends in the adjustment
};
AdjustmentLayout adjustment_layout(const Scene& scene, const BundleSetup& setup, int threads);

// Builds the Ceres problem of an adjustment over the scene's own parameter blocks (poses,
// points, intrinsics); returns the elimination ordering (points first) for the Schur solvers.
// Counts the images and points taken into `summary`.
std::shared_ptr<ceres::ParameterBlockOrdering> build_problem(Scene& scene, const BundleSetup& setup,
                                                             const BundleOptions& options, ceres::Problem& problem,
                                                             BundleSummary& summary);

// Adjusts scene poses, points (and intrinsics, if asked) in place.
BundleSummary bundle_adjust(Scene& scene, const BundleSetup& setup, const BundleOptions& options);

// Indices into IntrinsicIndex that stay constant under a refinement level, for a camera with
// `distortion_count` coefficients from camera.yaml.
std::vector<int> constant_intrinsics(IntrinsicsRefinement level, int distortion_count);
// The size of the intrinsics block the adjustment refines: the first this many of IntrinsicIndex
// (9, 12, 16 or 18), the smallest that holds every intrinsic the level refines and every one the
// camera's model reads (the rest, which the projection ignores, stay outside the block).
int intrinsics_block_size(IntrinsicsRefinement level, int distortion_count);

// Reprojection error in pixels of one observation with the current estimates (infinity if the
// point is behind the camera).
double reprojection_error_px(const Scene& scene, std::size_t observation);

const char* to_string(LossKind loss);
const char* to_string(SolverKind solver);
const char* to_string(IntrinsicsRefinement level);

}  // namespace photomill::triangulate
