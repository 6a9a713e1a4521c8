// Camera intrinsics in OpenCV's FileStorage YAML, with OpenCV's own key names (camera_matrix,
// distortion_coefficients, image_width, image_height, avg_reprojection_error), so files from
// OpenCV's calibration samples read here and files written here read in cv::FileStorage.
// Lives in its own library (photomill_camera) because it links OpenCV's core.
#pragma once

#include <istream>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill {

// Pinhole camera with OpenCV's distortion model. Pixel convention: OpenCV's (centre of the
// top-left pixel at (0, 0)).
struct Camera {
  int image_width_px = 0;
  int image_height_px = 0;
  // [fx s cx; 0 fy cy; 0 0 1], pixels.
  Eigen::Matrix3d camera_matrix = Eigen::Matrix3d::Identity();
  // OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]; 4, 5, 8, 12 or 14 values
  // (or none: no distortion).
  std::vector<double> distortion;
  std::optional<double> avg_reprojection_error_px;

  double fx() const { return camera_matrix(0, 0); }
  double fy() const { return camera_matrix(1, 1); }
  double cx() const { return camera_matrix(0, 2); }
  double cy() const { return camera_matrix(1, 2); }
  bool operator==(const Camera&) const = default;
};

struct CameraYamlLimits {
  // A camera file is a few kB; anything far larger is not one (and must not be parsed whole).
  std::size_t max_bytes = 1 << 20;
};

// Throws InputError naming `source` on a missing key, a wrong matrix size, a non-finite value,
// a non-positive focal length or image size.
Camera read_camera_yaml(std::istream& in, const std::string& source, CameraYamlLimits limits = {});
void write_camera_yaml(std::ostream& out, const Camera& camera);

// A rig: cameras fixed to one another (a stereo pair, a multi-camera head), each with the image
// name prefix of the photos it took and its pose in the rig's frame. Photos whose names differ
// only in the prefix were taken at once (one "frame", as COLMAP's rig configuration has it).
struct RigCamera {
  std::string prefix;
  Camera camera;
  Eigen::Matrix3d cam_from_rig_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d cam_from_rig_translation_mm = Eigen::Vector3d::Zero();
  // One standard deviation of the pose: rotation about the camera's x, y, z (degrees), then
  // translation (mm), from the rig calibration's covariance; absent for a given (fixed) pose.
  std::optional<Eigen::Matrix<double, 6, 1>> cam_from_rig_sigma;
  bool operator==(const RigCamera&) const = default;
};

struct Rig {
  std::vector<RigCamera> cameras;
  std::optional<double> avg_reprojection_error_px;  // RMS over every camera, from the calibration
  bool operator==(const Rig&) const = default;
};

// rig.yaml: OpenCV FileStorage YAML with flat keys (docs/formats.md). Throws InputError naming
// `source` and the line on anything a camera file would be refused for, a missing camera, two
// cameras with one prefix, a rotation that is not one.
Rig read_rig_yaml(std::istream& in, const std::string& source, CameraYamlLimits limits = {});
void write_rig_yaml(std::ostream& out, const Rig& rig);

// Which prefix an image name starts with, and its frame key (the name without the prefix). A
// prefix with '/' starts the whole name; one without starts the file name after the directories
// (frame key: the directories + the rest of the file name). The longest matching prefix wins;
// nullopt if none matches.
struct RigMatch {
  std::size_t camera = 0;
  std::string frame;
  bool operator==(const RigMatch&) const = default;
};
std::optional<RigMatch> match_rig_prefix(const std::vector<std::string>& prefixes, const std::string& image);

// The fields of view a camera file may give (across the image's width for fx, its height for
// fy): a focal length outside is a typo or junk, not a lens.
inline constexpr double kMinFieldOfViewDeg = 0.1;
inline constexpr double kMaxFieldOfViewDeg = 179;

// Checks the camera for sanity (positive focal lengths within the fields of view above, a
// principal point at most an image size outside the image, a plausible image size, finite
// values, a supported number of distortion coefficients). Throws InputError(source, 0, ...).
void validate_camera(const Camera& camera, const std::string& source);

}  // namespace photomill
