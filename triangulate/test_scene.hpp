// Synthetic ground truth for triangulate's tests and benchmark (not part of the tool): a known
// camera, views on rings around and above a part on a plate, control points on the plate and
// unknown points on a smooth height field, projected with OpenCV's cv::projectPoints (an
// implementation independent of triangulate's own camera model) plus Gaussian noise.
#pragma once

#include <cstdint>
#include <vector>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "triangulate/reconstruct.hpp"

namespace photomill::triangulate::test {

struct SceneOptions {
  int views = 12;
  std::vector<double> elevations_deg = {35, 55};  // cycled through the views
  double distance_mm = 450;                       // camera centre to the aim point
  int width_px = 2000, height_px = 1500;
  double focal_px = 2400;
  std::vector<double> distortion = {-0.08, 0.06, 0.0004, -0.0003, 0.0};
  double part_x_mm = 150, part_y_mm = 100, part_height_mm = 30;
  // Control points: a grid on the plate (z = 0) around the part, ids from 0.
  int plate_points_x = 10, plate_points_y = 8;
  double plate_x_mm = 300, plate_y_mm = 240;
  // > 0: each plate grid position is a square marker of this side instead of one point; its
  // corners get ids marker * 4 + corner (0 TL, 1 TR, 2 BR, 3 BL seen from above, +y up).
  double plate_marker_side_mm = 0;
  // Unknown points on the part: a grid, ids from part_id_offset.
  int part_points_x = 12, part_points_y = 8;
  std::int64_t part_id_offset = 100000;
  // Random points on the part instead of the grid (for large benchmarks), and the longest track
  // (a random subset of the views that see a point, as feature matching would give; 0 = all).
  std::size_t random_part_points = 0;
  std::size_t max_track_length = 0;
  // All views from one place (turning the camera only): no baseline.
  bool one_centre = false;
  double noise_px = 0.05;         // Gaussian, per coordinate
  double outlier_fraction = 0;    // observations moved by outlier_px in a random direction
  double outlier_px = 8;
  std::uint64_t seed = 1;
};

struct SceneTruth {
  Camera camera;
  std::vector<Pose> poses;                     // true cam_from_world, image names view_NN.png
  std::vector<ControlPoint> plate_points;      // true control points
  std::vector<ControlPoint> part_points;       // true unknown points
  std::vector<TrackObservation> tracks;        // noisy observations
  std::vector<TrackObservation> outliers;      // the observations made outliers (as written)
};

SceneTruth make_scene(const SceneOptions& options);

// A stereo rig photographing make_scene's plate and part from `frames` places (make_scene's views
// 0, 2, 4...): camera 0 ("left_", make_scene's camera) is the rig's frame; camera 1 ("right_",
// focal 2600 px, its own distortion) sits 80 mm to its right, turned 6 degrees towards it. The
// world is the rig's frame at frame 00 (left_00.png, right_00.png), as triangulate --rig makes it.
// `seed` draws the views (make_scene's) and the noise.
struct RigSceneTruth {
  Rig rig;                                  // the true rig
  std::vector<Pose> poses;                  // every photo's cam_from_world
  std::vector<ControlPoint> plate_points;   // in the world above
  std::vector<ControlPoint> part_points;
  std::vector<TrackObservation> tracks;     // with N(0, noise_px) per coordinate
};
RigSceneTruth make_rig_scene(int frames, double noise_px, unsigned seed);

// Feature sizes that tell good observations from bad: every third observation becomes a 12 px
// feature moved by N(0, 0.6 px) noise per axis (seeded), the rest 1 px features left exact.
void give_sizes_spoil_large(std::vector<TrackObservation>& tracks);

// How far a reconstruction is from the truth. With `similarity`, the reconstruction is first
// mapped onto the truth by the similarity (Umeyama) that best fits all its points.
struct Accuracy {
  std::size_t part_points = 0;     // part points reconstructed
  double part_rms_mm = 0;          // RMS 3D error of the part points
  double part_max_mm = 0;
  std::size_t cameras = 0;         // registered images
  double centre_rms_mm = 0;        // RMS error of the camera centres
  double centre_max_mm = 0;
  double scale = 1;                // scale of the similarity (1 without)
};
Accuracy evaluate(const Reconstruction& r, const SceneTruth& truth, bool similarity);

// X projected into view `view` of the scene (OpenCV's cv::projectPoints, no noise).
Eigen::Vector2d project(const SceneTruth& truth, std::size_t view, const Eigen::Vector3d& X);

// Adds a track `id` seen in views a and b only: X in view a, and in view b the point
// depth_mm farther along a's ray through X (on X's epipolar line in b: a wrong match that
// triangulates depth_mm along the ray from X with no reprojection error; 0: a true two-view
// point). No noise. Returns where the two rays meet.
Eigen::Vector3d add_two_view_track(SceneTruth& truth, TrackId id, std::size_t a, std::size_t b, const Eigen::Vector3d& X,
                                   double depth_mm);

// Height of the part surface at (x, y): a smooth bump on the plate (0 outside the part).
double part_height_mm(const SceneOptions& options, double x, double y);

}  // namespace photomill::triangulate::test
