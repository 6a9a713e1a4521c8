// The reconstruction state shared by triangulate's steps: images with their poses, tracks with
// their 3D points, and every observation linking the two (indices, not ids, for speed).
// Built once from the input tables; poses and points are filled in as the steps proceed.
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"
#include "geometry/camera_model.hpp"
#include "geometry/rotation.hpp"

namespace photomill::triangulate {

// The camera and pose geometry are photomill's one model (geometry/).
using geometry::CameraModel;
using geometry::Intrinsics;
using geometry::ModelShape;
using geometry::PoseBlock;
using geometry::centre_of;
using geometry::compose;
using geometry::distort_to_pixel;
using geometry::make_pose;
using geometry::project;
using geometry::project_point;
using geometry::rotation_of;
using geometry::shape_of;
using geometry::to_camera;
using geometry::to_camera_model;
using geometry::translation_of;
using geometry::undistort;
using enum geometry::IntrinsicIndex;

// Classes of observations with their own noise level, estimated separately (variance components):
// coded targets (marker and board corners, control points), measured to a few hundredths of a
// pixel, and natural features, measured to a few tenths.
enum class ObservationClass { Coded = 0, Natural = 1 };
constexpr std::size_t kObservationClasses = 2;
const char* to_string(ObservationClass c);

// One image measurement of one track.
struct ObservationRef {
  std::size_t image = 0;          // index into Scene::images
  std::size_t track = 0;          // index into Scene::tracks
  Eigen::Vector2d uv_px;          // measured pixel, OpenCV convention
  Eigen::Vector2d xy;             // undistorted normalised coordinates (x/z, y/z) of uv_px
  ObservationClass cls = ObservationClass::Natural;
  // The observation's noise relative to its class's: sigma = sigma_class * rel_sigma. 1 unless the
  // track gives the feature's size (see build_scene).
  double rel_sigma = 1;
  bool usable = true;             // false if the distortion could not be inverted at uv_px
  bool inlier = true;             // false once removed as an outlier
  // When removed: -1 while triangulating or growing the model, k >= 1 in the final adjustment's
  // outlier round k; and its reprojection error then, pixels.
  int removed_round = 0;
  double removed_residual_px = 0;
};

struct SceneImage {
  std::string name;
  std::size_t camera = 0;                 // index into Scene::cameras
  std::vector<std::size_t> observations;  // indices into Scene::observations
  bool registered = false;
  PoseBlock cam_from_world{};             // valid when registered
  // The rig's frame it was taken in (index into SceneRig::frames), or -1: not taken with a rig.
  std::ptrdiff_t frame = -1;
};

// Cameras fixed to one another (--rig) photographing several frames: the photos of a frame share
// the rig's pose, and camera k's pose in the rig is the same in every frame, so
//   cam_from_world(image) = cam_from_rig[camera] * rig_from_world[frame].
// The adjustment that uses the rig (BundleSetup::use_rig) takes these as its parameters and
// writes the composed poses back into the images.
struct SceneRig {
  std::vector<std::string> frames;          // frame keys (image names without the camera prefix)
  std::vector<PoseBlock> rig_from_world;    // per frame
  std::vector<char> frame_placed;           // per frame: rig_from_world is set
  std::vector<PoseBlock> cam_from_rig;      // per camera
};

enum class TrackState {
  Pending,        // not (yet) triangulated
  Triangulated,   // xyz_mm estimated from its observations
  Rejected,       // given up for good (issue says why)
};

// Why a track is not (or no longer) in the reconstruction; the last reason found is kept.
enum class TrackIssue {
  None,
  SeenOnce,          // observed in fewer than two images
  NotRegistered,     // fewer than two of its images got a pose
  SmallAngle,        // its rays meet at less than the minimum triangulation angle
  BehindCamera,      // the intersection lies behind a camera that sees it
  LargeError,        // its reprojection error stays above the limit
  TooFewInliers,     // fewer than two observations left after outlier removal
};
const char* to_string(TrackIssue issue);

struct SceneTrack {
  TrackId id = 0;
  std::vector<std::size_t> observations;  // indices into Scene::observations
  TrackState state = TrackState::Pending;
  TrackIssue issue = TrackIssue::None;
  Eigen::Vector3d xyz_mm = Eigen::Vector3d::Zero();  // world (or model) frame, mm
  // Control point: its known world coordinates and, if given, their sigma (else held fixed).
  std::optional<Eigen::Vector3d> control_mm;
  std::optional<double> control_sigma_mm;
  // True once xyz_mm is in the world frame of the control points (set to the control value).
  bool at_control = false;
};

struct Scene {
  std::vector<CameraModel> cameras;       // one per camera; each image names its own
  const CameraModel& camera_of(std::size_t image) const { return cameras[images[image].camera]; }
  std::vector<SceneImage> images;         // in order of first appearance in the tracks
  std::vector<SceneTrack> tracks;         // in order of first appearance
  std::vector<ObservationRef> observations;
  std::unordered_map<TrackId, std::size_t> track_by_id;  // id -> index into tracks
  std::optional<SceneRig> rig;            // photos taken with a rig (see SceneRig)

  // Index of a track by id, or nullopt.
  std::optional<std::size_t> find_track(TrackId id) const;
  // Observations of a track in registered images that are usable inliers.
  std::vector<std::size_t> active_observations(std::size_t track) const;
  std::size_t registered_count() const;
};

// Builds the scene: indexes tracks and images, undistorts every observation and attaches control
// points to the tracks of the same id. Control points that no track observes are ignored.
// Observations of tracks with an id below `coded_id_limit`, and of control points, are Coded.
// With `weight_by_size`, an observation with a feature size s (tracks' size_px) gets
//   rel_sigma = max(s / median_s, kMinRelativeSigma),
// median_s the median size of its class's observations that have one: a scale-space feature's
// position error grows in proportion to its scale (Lowe 2004, sec. 4, locates the extremum to a
// fraction of the sample spacing of its octave; ORB-SLAM, Mur-Artal et al. 2015, weights each
// observation by its pyramid level the same way). Measured on the demo: the 3D error of natural
// points grows about linearly with their features' size (docs/measurements/triangulate.md).
constexpr double kMinRelativeSigma = 0.25;
Scene build_scene(const std::vector<TrackObservation>& tracks, const CameraModel& camera,
                  const std::vector<ControlPoint>& control_points, TrackId coded_id_limit = 4096,
                  bool weight_by_size = true);
// Several cameras: `camera_of_image` gives the index into `cameras` of each image name.
Scene build_scene(const std::vector<TrackObservation>& tracks, const std::vector<CameraModel>& cameras,
                  const std::function<std::size_t(const std::string&)>& camera_of_image,
                  const std::vector<ControlPoint>& control_points, TrackId coded_id_limit = 4096,
                  bool weight_by_size = true);

// The pose block as the poses file's row.
Pose to_pose(const std::string& image, const PoseBlock& pose);

}  // namespace photomill::triangulate
