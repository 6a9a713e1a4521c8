// triangulate's one library call: from tracks, the camera and the datum (control points, scale
// bars, a marker side) to camera poses, 3D points with their uncertainty, and a report.
//   1. poses: the known poses if given; else PnP from control points in every image that sees
//      enough of them; otherwise incremental: the best image pair from the essential matrix;
//      then further images by PnP;
//   2. multi-view triangulation of every track (triangulation.hpp);
//   3. bundle adjustment with the datum inside it, outlier removal and re-solving (bundle.hpp);
//   4. point uncertainty from the adjustment (covariance.hpp);
//   5. two-view points checked against their neighbours (two_view.hpp).
// Throws GeometryError with an explanation for degenerate input, UsageError when no datum for
// the scale was given.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "formats/camera.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "triangulate/bundle.hpp"
#include "triangulate/covariance.hpp"
#include "triangulate/pose.hpp"
#include "triangulate/report.hpp"
#include "triangulate/scene.hpp"
#include "triangulate/triangulation.hpp"
#include "triangulate/two_view.hpp"

namespace photomill::triangulate {

struct ScaleOptions {
  // Side length of the square markers (black border included); adds a scale bar along each side
  // of every marker in marker_ids whose corner tracks (id = marker_id * 4 + corner) exist.
  std::optional<double> marker_side_mm;
  double marker_side_sigma_mm = 0.01;
  // Inclusive ranges of marker ids the side applies to (default: 0..1023, every id of the
  // largest ArUco dictionary; natural-feature track ids lie above 4095).
  std::vector<std::pair<std::int64_t, std::int64_t>> marker_ids = {{0, 1023}};
  // Marker sides whose length (after a first scaling) differs from the median by more than this
  // fraction are left out: markers of another size, or draped over a curved part.
  double marker_side_tolerance = 0.05;
  // Sigma of scale bars whose file gives none.
  double default_bar_sigma_mm = 0.01;
  // Without control points, scale bars or a marker side: refuse (false) or go on with the
  // arbitrary scale of the first image pair (true).
  bool allow_arbitrary_scale = false;
};

struct OutlierOptions {
  // An observation is removed when its reprojection error exceeds
  //   clamp(sigmas * sigma_hat, min_px, max_px),
  // sigma_hat the robust noise estimate of its class in the current adjustment; then the
  // problem is solved again, at most `rounds` times.
  double sigmas = 6;
  double min_px = 0.05;
  double max_px = 2;
  int rounds = 4;
  // An image left with fewer inlier observations loses its pose.
  std::size_t min_image_observations = 6;
};

struct ReconstructOptions {
  TriangulationOptions triangulation;
  BundleOptions bundle;
  // Work limit (--max-total-iterations): Ceres iterations summed over every bundle adjustment of
  // the run (one per registered image, the outlier rounds, the final one). More is an error
  // naming the option, not a run without end; each adjustment gets at most what is left.
  long long max_total_iterations = 50'000;
  // The adjustments while images are still being registered, and those of the outlier rounds,
  // stop at this relative decrease of the cost (Ceres' own default), or at
  // bundle.function_tolerance if that is looser: their result is only the start of the next
  // registration or round; the last adjustment runs to bundle.function_tolerance. On the Sceaux castle the incremental adjustments at 1e-10 took
  // 100 iterations each for no change in the final model (docs/measurements/triangulate.md).
  double intermediate_function_tolerance = 1e-6;
  RansacOptions ransac;
  CovarianceOptions covariance;
  // After the final adjustment: two-view points that no third view checks are kept only where
  // they agree with their neighbours seen in three or more views (two_view.hpp).
  TwoViewOptions two_view;
  ScaleOptions scale;
  OutlierOptions outliers;
  // Standard deviation of an image measurement, pixels; nullopt: estimated from the residuals
  // (robustly, from their median) and updated after each adjustment, separately for coded
  // targets and natural features (scene.hpp's ObservationClass).
  std::optional<double> observation_sigma_px;
  // Tracks with an id below this are coded targets (ArUco marker corners marker_id * 4 + corner
  // of the largest dictionary, board corners), the others natural features.
  TrackId coded_id_limit = 4096;
  // Weight observations by their feature's size when the tracks give one (size_px): sigma of
  // an observation = its class's sigma * size / the class's median size (scene.hpp, build_scene).
  bool weight_by_feature_size = true;
  // PnP from control points needs this many of them visible in the image (not on a line).
  std::size_t control_min_points = 4;
  // PnP against triangulated points needs this many inliers.
  std::size_t pnp_min_inliers = 8;
  // An image that no PnP can place is registered from its relative pose to a registered image
  // (essential matrix from their shared tracks, min_shared_tracks or more inliers) when this many
  // triangulated points it sees fix the one unknown left, the baseline's length, within the
  // RANSAC threshold (0: never).
  std::size_t relative_min_scale_points = 3;
  // Incremental start: candidate pairs share this many tracks or more; the best
  // initial_pair_candidates of them (by shared tracks) are tried; the chosen pair's median
  // intersection angle must reach initial_min_angle_deg.
  std::size_t min_shared_tracks = 8;
  std::size_t initial_pair_candidates = 40;
  double initial_min_angle_deg = 3;
  // Points count as collinear when the second singular value of their centred coordinates is
  // below this fraction of the first.
  double collinear_tolerance = 1e-3;
  // While images are being added, adjust everything each time the number of registered images
  // has grown by this factor.
  double global_ba_growth = 1.25;
  // Known poses (ReconstructInput::known_poses): standard deviations of a camera centre (mm, per
  // axis) and of its rotation (degrees, per axis); nullopt: the poses are held fixed.
  std::optional<double> pose_sigma_mm;
  std::optional<double> pose_sigma_deg;
  int threads = 0;  // 0: all hardware threads
};

// One of several cameras: the photos whose names (or file names) start with `prefix` (formats/
// camera.hpp, match_rig_prefix) were taken with it.
struct PrefixCamera {
  std::string prefix;
  Camera camera;
  std::string source;
};

struct ReconstructInput {
  std::vector<TrackObservation> tracks;
  std::string tracks_source = "<tracks>";
  Camera camera;                        // every photo's, unless `cameras` is given
  std::string camera_source = "<camera>";
  std::vector<PrefixCamera> cameras;    // several cameras, by image name prefix (a rig's, --camera P=F)
  std::vector<ControlPoint> control_points;
  std::vector<ScaleBar> scale_bars;
  // Poses the user knows (a turntable, a robot, another tool's orientation), in the world frame
  // and mm; they replace the pose search for their images and are the datum. Each image name is
  // one of the tracks' (or, failing that, the only one with that file name); the line of each
  // pose in its file, for errors (0: unknown).
  std::vector<Pose> known_poses;
  std::vector<std::size_t> known_pose_lines;
  std::string known_poses_source = "<poses>";
  // A rig (--rig; `cameras` are its cameras, in its order): the photos of each frame (names
  // alike but for the camera prefix) share the rig's pose. The known poses place the reference
  // frame's photos by the rig (the rig's frame there is the world); the other frames are found
  // and the adjustment holds every frame to the rig (scene.hpp, SceneRig).
  std::optional<Rig> rig;
  std::string rig_reference_frame;
};

struct Reconstruction {
  Scene scene;                     // final poses, points, inlier flags
  Camera camera;                   // as given, or refined by self-calibration (the first of several)
  std::vector<Camera> cameras;     // every camera, in the order of ReconstructInput::cameras
  std::vector<double> sigma_mm;    // per track (see covariance.hpp); NaN outside the result
  std::vector<Eigen::Matrix3d> covariance_mm2;  // per track (see covariance.hpp); NaN outside the adjustment
  std::vector<char> in_result;     // per track: part of the output cloud
  BundleSetup setup;               // datum, gauge and sigmas of the final adjustment
  Report report;
};

Reconstruction reconstruct(const ReconstructInput& input, const ReconstructOptions& options);

// The output cloud: one vertex per reconstructed track with track_id, views, reproj_rms_px,
// sigma_mm and control (1 for control points).
PointCloud make_point_cloud(const Reconstruction& r);
// Poses of the registered images, in input order.
std::vector<Pose> registered_poses(const Reconstruction& r);

}  // namespace photomill::triangulate
