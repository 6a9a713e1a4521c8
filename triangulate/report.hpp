// What triangulate did, for people (stderr summary) and for tools (--report FILE, JSON).
// JSON keys are documented in docs/triangulate.md.
#pragma once

#include <array>
#include <cstddef>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "formats/tables.hpp"

namespace photomill::triangulate {

struct ImageReport {
  std::string image;
  bool registered = false;
  std::string registered_by;        // "known_pose", "control_pnp", "initial_pair", "pnp", "relative_pose"; empty if not registered
  std::size_t observations = 0;     // inlier observations in the final adjustment
  double rms_px = 0;                // RMS reprojection error over them
};

struct ScaleBarReport {
  PointId point_a = 0;
  PointId point_b = 0;
  std::string origin;               // "file" or "marker_side"
  double distance_mm = 0;           // given
  double sigma_mm = 0;              // used as its standard deviation
  bool used = false;                // both ends reconstructed
  double measured_mm = 0;           // |A - B| after the adjustment (when used)
};

struct ControlReport {
  PointId point_id = 0;
  bool fixed = false;               // held fixed (no sigma) or weighted by sigma_mm
  double sigma_mm = 0;
  double residual_mm = 0;           // |X_adjusted - X_control| (0 when fixed)
  std::size_t observations = 0;
};

struct RemovedObservation {
  TrackId track_id = 0;
  std::string image;
  double residual_px = 0;           // reprojection error when it was removed
  int round = 0;                    // final outlier round (1-based); -1: while building the model
};

// One class of observations (scene.hpp's ObservationClass).
struct ClassReport {
  std::size_t observations = 0;     // inliers in the final adjustment
  double sigma_px = 0;              // its sigma per coordinate (estimated or given)
};

// A two-view point removed by the check against its neighbours (two_view.hpp).
struct RemovedPoint {
  TrackId track_id = 0;
  double xyz_mm[3] = {0, 0, 0};
  std::string reason;               // "unsupported" or "off_neighbours"
  double distance_mm = 0;           // |d| off the neighbours' plane (NaN: unsupported)
  double allowed_mm = 0;            // its bound (NaN: unsupported)
};

// The check of two-view points against their neighbours (two_view.hpp), and its options.
struct TwoViewReport {
  bool enabled = true;
  bool ran = false;                 // false: disabled, no two-view point, or too few references
  std::size_t reference_points = 0; // seen in min_views or more, and control points
  double spacing_mm = 0;            // D, the references' median k-th neighbour distance
  std::size_t checked = 0;          // two-view points judged
  std::size_t removed_unsupported = 0;
  std::size_t removed_off_neighbours = 0;
  std::size_t neighbours = 0;
  double reach = 0, sigmas = 0, tolerance_mm = 0;
  std::vector<RemovedPoint> removed;
};

// A rig's frames and each camera's pose in the rig as adjusted (--rig).
struct RigCameraReport {
  std::string prefix;
  bool refined = false;              // held by its calibration's sigma (else constant)
  double rotation_change_deg = 0;    // angle between the adjusted and the given rotation
  double translation_change_mm = 0;  // |t - t_given|
  std::array<double, 3> translation_mm{};  // adjusted cam_from_rig translation
  double baseline_mm = 0;            // distance of the camera's centre from the rig's origin
};
struct RigReport {
  std::size_t frames = 0;
  std::size_t frames_placed = 0;
  std::string reference_frame;
  std::vector<RigCameraReport> cameras;
};

struct Report {
  // Datum: "known_poses", "known_poses+control_points", "control_points", "scale_bars",
  // "marker_side", "scale_bars+marker_side", "arbitrary_scale".
  std::string datum;
  // Known poses given (--known-poses): how many, and their prior sigmas (nullopt: held fixed).
  std::size_t known_poses = 0;
  std::optional<double> pose_sigma_mm, pose_sigma_deg;
  std::string pose_initialisation;  // "known_poses", "control_pnp", "incremental", "incremental+control_alignment"
  std::optional<std::string> reference_image;  // pose held fixed (datum without control points)
  std::size_t images = 0;
  std::size_t registered_images = 0;
  std::size_t tracks = 0;
  std::size_t points = 0;           // in the output cloud
  std::size_t observations_used = 0;
  std::map<std::string, ClassReport> observation_classes;  // "coded", "natural"
  bool observation_sigma_estimated = false;
  double initial_rms_px = 0;        // before the final adjustment
  double final_rms_px = 0;          // sqrt(mean |r|^2) over the inlier observations
  int adjustments = 0;              // bundle adjustments run
  int final_iterations = 0;         // Ceres iterations of the last adjustment
  int total_iterations = 0;         // Ceres iterations of all adjustments (--max-total-iterations counts them)
  double adjustment_seconds = 0;    // time in all bundle adjustments
  double total_seconds = 0;
  std::string solver;
  std::string loss;
  double loss_scale_px = 0;
  std::string refine_intrinsics;
  int threads = 0;
  std::string sigma_method;         // "full_covariance" or "per_point_fixed_poses"
  double variance_factor = 1;
  std::vector<ImageReport> per_image;
  std::vector<RemovedObservation> removed;
  std::map<std::string, std::size_t> tracks_dropped;   // by reason
  TwoViewReport two_view;
  std::vector<ScaleBarReport> scale_bars;
  std::vector<ControlReport> control_points;
  std::vector<std::string> warnings;
  // Intrinsics after self-calibration (when refined): fx fy cx cy and distortion, OpenCV order.
  std::vector<double> refined_camera;
  std::optional<RigReport> rig;  // with --rig
  // The same per camera when there are several (--camera-for, --rig): (prefix, values).
  std::vector<std::pair<std::string, std::vector<double>>> refined_cameras;
};

void write_report_json(std::ostream& out, const Report& report);
// The summary on stderr (photomill::log): a few lines at normal verbosity, per-image figures
// and removed observations with -v.
void log_report(const Report& report);

}  // namespace photomill::triangulate
