// photomill's CSV tables: 2D observations, control points, tracks, camera poses and scale bars.
// Each has a header row naming its columns (see docs/formats.md); readers find columns by name,
// ignore extra columns, and throw InputError("source:line: problem") on malformed input.
// Units: millimetres in the world, pixels in images. Pixel convention: OpenCV's, the centre of
// the top-left pixel is (0, 0).
#pragma once

#include <cstdint>
#include <istream>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace photomill {

// Identifies a physical point (a marker corner, a board corner, a clicked point). Non-negative.
using PointId = std::int64_t;
// Identifies a track (one 3D point seen in several images). Tracks of coded points reuse the
// point id, so control points and scale bars refer to them directly. Non-negative.
using TrackId = std::int64_t;

// One measured image position of an identified point (detect -> match, detect -> calib).
struct Observation {
  std::string image;   // image name as given to detect (a path or a file name)
  PointId point_id = 0;
  double u_px = 0;     // column, pixels, OpenCV convention
  double v_px = 0;     // row, pixels, OpenCV convention
  bool operator==(const Observation&) const = default;
};

// A point with known world coordinates (board corner, control frame target).
struct ControlPoint {
  PointId point_id = 0;
  Eigen::Vector3d xyz_mm = Eigen::Vector3d::Zero();  // world frame, mm
  std::optional<double> sigma_mm;                     // standard deviation per axis, if known
  bool operator==(const ControlPoint&) const = default;
};

// One image measurement of a track (match -> triangulate).
struct TrackObservation {
  TrackId track_id = 0;
  std::string image;
  double u_px = 0;
  double v_px = 0;
  // Optional column size_px: the detected feature's size (a SIFT keypoint's diameter), which
  // triangulate uses to weight the observation (a feature's position error grows with its size).
  std::optional<double> size_px = std::nullopt;
  bool operator==(const TrackObservation&) const = default;
};

// Pose of one image: x_cam = R * X_world + t (cam_from_world). R is stored as a unit quaternion
// (w, x, y, z; Hamilton convention, as COLMAP and Eigen), t in mm.
struct Pose {
  std::string image;
  Eigen::Quaterniond cam_from_world_rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d cam_from_world_translation_mm = Eigen::Vector3d::Zero();

  Eigen::Matrix3d rotation() const { return cam_from_world_rotation.normalized().toRotationMatrix(); }
  // Camera centre in world coordinates: C = -R^T t.
  Eigen::Vector3d centre_mm() const { return -rotation().transpose() * cam_from_world_translation_mm; }
  bool operator==(const Pose& o) const {
    return image == o.image && cam_from_world_rotation.coeffs() == o.cam_from_world_rotation.coeffs() &&
           cam_from_world_translation_mm == o.cam_from_world_translation_mm;
  }
};

// A known distance between two points (a scale bar, a measured marker side).
struct ScaleBar {
  PointId point_a = 0;
  PointId point_b = 0;
  double distance_mm = 0;            // > 0
  std::optional<double> sigma_mm;    // standard deviation of the distance, if known
  bool operator==(const ScaleBar&) const = default;
};

std::vector<Observation> read_observations(std::istream& in, const std::string& source);
// The same; `run_of_image` receives, for each image whose rows follow a stamp with a run id
// (formats/run.hpp), that run (a file joined from per-photo files holds a stamp per photo).
std::vector<Observation> read_observations_with_runs(std::istream& in, const std::string& source,
                                                     std::map<std::string, std::string>* run_of_image);
void write_observations(std::ostream& out, const std::vector<Observation>& observations);

std::vector<ControlPoint> read_control_points(std::istream& in, const std::string& source);
void write_control_points(std::ostream& out, const std::vector<ControlPoint>& points);

std::vector<TrackObservation> read_tracks(std::istream& in, const std::string& source);
void write_tracks(std::ostream& out, const std::vector<TrackObservation>& tracks);

std::vector<Pose> read_poses(std::istream& in, const std::string& source);
// The same; `lines` receives each pose's line in the file (for errors found later).
std::vector<Pose> read_poses_numbered(std::istream& in, const std::string& source, std::vector<std::size_t>* lines);
void write_poses(std::ostream& out, const std::vector<Pose>& poses);

std::vector<ScaleBar> read_scale_bars(std::istream& in, const std::string& source);
void write_scale_bars(std::ostream& out, const std::vector<ScaleBar>& bars);

}  // namespace photomill
