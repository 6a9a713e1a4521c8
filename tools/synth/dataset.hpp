// A whole synthetic data set: the part scene, the camera, the view poses, the rendered images and
// every truth file, written into one folder (file list in docs/synth.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "formats/camera.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "tools/synth/render.hpp"
#include "tools/synth/scene.hpp"

namespace photomill::synth {

// Views of the part: a ring around it, cycling through the elevations.
struct ViewOptions {
  int count = 12;
  std::vector<double> elevations_deg = {35, 55};  // above the plate
  double distance_mm = 450;                       // camera centre to the aim point
  double azimuth_offset_deg = 10;                 // azimuth of the first view (0 = from +x)
  double jitter = 1;  // scale of the random perturbations (0: an exact ring): +-5 deg azimuth,
                      // +-3 deg elevation, +-5 % distance, +-10 mm aim point
};

// Views of the ChArUco board for calibration.
struct CalibrationOptions {
  int count = 10;
  BoardSpec board;
  double min_tilt_deg = 10;   // angle between the optical axis and the board normal
  double max_tilt_deg = 40;
  double min_fill = 0.45;     // board width as a fraction of the image (the larger of x, y)
  double max_fill = 0.75;
  double max_roll_deg = 20;
};

struct SynthOptions {
  // The part and its plate.
  std::string shape = "bumps";
  double part_x_mm = 150;
  double part_y_mm = 100;
  double part_height_mm = 30;
  double edge_blend_mm = 20;
  std::string dictionary = "DICT_4X4_100";
  LayoutOptions layout;
  double speckle_mm = 1.2;
  // The camera (true intrinsics; image size inside).
  Camera camera;
  ViewOptions views;
  CalibrationOptions calibration;
  RenderOptions render;
  std::string image_format = "jpg";  // "jpg" or "png"
  int jpeg_quality = 90;
  double surface_step_mm = 1.0;      // grid spacing of surface.ply
  std::uint64_t seed = 1;            // everything random derives from it
  std::string command_line;          // recorded in scene.txt so the set can be remade
};

struct DatasetSummary {
  int part_images = 0;
  int board_images = 0;
  std::size_t observations = 0;        // visible marker corners over all part views
  std::size_t board_observations = 0;  // visible ChArUco corners over all board views
  double render_seconds = 0;           // wall time spent rendering
  std::size_t bytes = 0;               // total size of the files written
  std::vector<std::string> files;      // names, relative to the folder
};

// Derived scene and poses (pure functions of the options, used by write_dataset and tests).
PartScene make_part_scene(const SynthOptions& options);
std::vector<Pose> part_view_poses(const SynthOptions& options);
std::vector<Pose> board_view_poses(const SynthOptions& options);
std::string part_image_name(const SynthOptions& options, int view);
std::string board_image_name(const SynthOptions& options, int view);

// Render options for board views: the light is mirrored to the board's printed side.
RenderOptions board_render_options(const SynthOptions& options);

// True image positions of every visible marker corner (point_id = marker_id * 4 + corner).
std::vector<Observation> marker_observations(const PartRayScene& scene, const Camera& camera,
                                             const Pose& pose);
// True image positions of every visible ChArUco corner (point_id = charuco corner id).
std::vector<Observation> board_observations(const BoardTexture& board, const Camera& camera,
                                            const Pose& pose);
// Dense sample of the height field over the part rectangle, with normals (nx, ny, nz).
PointCloud surface_samples(const HeightField& field, double step_mm);

// Encodes a grey image as JPEG (quality 1..100) or PNG.
std::vector<std::uint8_t> encode_image(const cv::Mat& image, const std::string& format, int jpeg_quality);

// Renders and writes everything into `folder` (created if missing; files in it are replaced).
// Throws std::invalid_argument for bad options, InputError if a file cannot be written.
DatasetSummary write_dataset(const SynthOptions& options, const std::string& folder);

}  // namespace photomill::synth
