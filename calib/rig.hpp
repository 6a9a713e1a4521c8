// Rig calibration: cameras fixed to one another (a stereo pair, a multi-camera head) that
// photograph a board at once. A photo's camera is the image name prefix it starts with; photos
// whose names differ only in the prefix form one frame (rig.yaml, formats/camera.hpp).
//
// Method (as OpenCV's stereoCalibrate, for any number of cameras):
//  1. each camera is calibrated on its own views (calibrate(): initial estimate, refinement,
//     rejection of outlier views);
//  2. each camera's pose in the rig (the frame of camera 0) starts from the mean over the frames
//     both saw of cam_k_from_board * cam_0_from_board^-1 (rotations: the chordal L2 mean, the
//     nearest rotation to the sum of the matrices; Hartley et al., "Rotation averaging", IJCV
//     2013, section 5.3);
//  3. the board's pose in every frame seen by two cameras or more, every camera's pose in the rig
//     and its intrinsics (those its model frees; held fixed with fix_intrinsics, as OpenCV's
//     CALIB_FIX_INTRINSIC) are adjusted together (Ceres, Levenberg-Marquardt) on the reprojection
//     error of every camera; the worst frame is left out while its RMS exceeds
//     reject_factor x the median frame RMS and reject_min_px (the same rule as calibrate()'s
//     views), and the adjustment is run again;
//  4. the standard deviations of each camera's pose: Cov = s^2 (J^T J)^-1 over the adjustment's
//     free parameters (the intrinsics' uncertainty included unless they are fixed), s^2 = SSE / (m - n) (as calibrate()'s intrinsics), rotation in the
//     tangent space of the camera's rotation (a small rotation about the camera's axes).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "calib/calibrate.hpp"
#include "formats/camera.hpp"

namespace photomill::calib {

struct RigCalibOptions {
  CalibOptions camera;  // each camera's own calibration; reject_factor, reject_min_px and
                        // min_views also apply to the frames of the adjustment
  LmOptions lm;
  // Hold each camera's intrinsics at its own calibration's (OpenCV's CALIB_FIX_INTRINSIC); by
  // default they are adjusted with the rig, which both makes them better (each frame's board pose
  // is shared by the cameras) and puts their uncertainty into the rig's.
  bool fix_intrinsics = false;
};

struct RigFrameReport {
  std::string frame;                 // the image names less their prefixes
  std::vector<std::string> images;   // one per camera, "" where that camera has no view
  int cameras = 0;                   // cameras with a view kept by their own calibration
  int points = 0;
  double rms_px = 0;                 // in the adjustment (a frame left out: its board pose when it was)
  double max_px = 0;
  bool used = false;                 // in the final adjustment
  std::string reason;                // why not
};

struct RigResult {
  Rig rig;                           // the cameras with their poses, sigmas and the rig RMS
  std::vector<CalibResult> cameras;  // each camera's own calibration, in the rig's order
  std::vector<RigFrameReport> frames;
  double rms_px = 0;                 // over the frames used, every camera
  double first_rms_px = 0;           // the first adjustment, every frame seen by two cameras
  std::size_t points = 0;
  double sigma_px = 0;               // a-posteriori standard deviation of one coordinate
  std::vector<double> baseline_sigma_mm;  // per camera: sigma of |t| (NaN for camera 0 or unknown)
  int iterations = 0;
  std::vector<std::string> warnings;
};

// `prefixes[k]` names camera k's photos, `image_sizes[k]` its image size. Throws InputError
// (naming `source`) for an image that matches no prefix or a camera without observations, and
// GeometryError when a camera cannot be calibrated or placed in the rig (no frame shared with
// camera 0).
RigResult calibrate_rig(const std::vector<Observation>& observations, const std::vector<ControlPoint>& control,
                        const std::vector<std::string>& prefixes, const std::vector<cv::Size>& image_sizes,
                        const RigCalibOptions& options, const std::string& source);

// The observations of camera k (by prefix); throws InputError for an image no prefix matches.
std::vector<std::vector<Observation>> split_by_camera(const std::vector<Observation>& observations,
                                                     const std::vector<std::string>& prefixes,
                                                     const std::string& source);

// Human-readable summary (stderr) and the JSON report (docs/calib.md, Rigs).
std::vector<std::string> rig_text_report(const RigResult& result);
void write_rig_json_report(std::ostream& out, const RigResult& result);

}  // namespace photomill::calib
