// calib's library entry point: observations + control points -> camera intrinsics, with per-view
// quality, automatic rejection of outlier views, uncertainties and warnings about weak geometry.
// The method follows the paper's section 3.3 (initial estimate, then least-squares refinement of
// intrinsics and extrinsics on the reprojection error, by LM or by the downhill simplex).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "calib/model.hpp"
#include "calib/refine.hpp"
#include "formats/camera.hpp"
#include "formats/tables.hpp"

namespace photomill::calib {

// How the initial estimate is made. Auto: Planar when the control points are coplanar, else Dlt.
enum class Method { Auto, Planar, Dlt };
// Which optimiser refines it. Auto: OpenCv for Planar, Lm for Dlt.
enum class Optimizer { Auto, OpenCv, Lm, Simplex };

std::string to_string(Method m);
std::string to_string(Optimizer o);

struct CalibOptions {
  Method method = Method::Auto;
  Optimizer optimizer = Optimizer::Auto;
  ModelOptions model;
  LmOptions lm;
  SimplexRefineOptions simplex;
  // A view needs this many observations of control points to be used (the DLT needs 6).
  int min_points_per_view = 6;
  // Fewer views than this draws a warning, and outlier rejection never leaves fewer.
  int min_views = 3;
  // Outlier views. After each calibration the worst view is rejected if its RMS exceeds both
  // reject_factor x the median view RMS and reject_min_px; then the camera is recalibrated
  // without it, one view at a time. A view several times worse than the typical view holds a
  // misdetection, motion blur or a board that moved, and drags every parameter; the absolute floor
  // keeps a very good calibration (median 0.05 px) from discarding views that are merely "worse".
  // reject_factor = 0 turns rejection off.
  double reject_factor = 3;
  double reject_min_px = 0.5;
  // Control points whose flatness (init.hpp) is below this are coplanar (a board).
  double coplanar_tolerance = 1e-6;
  // The DLT refuses a view flatter than this (H&Z: the DLT is degenerate for coplanar points).
  double dlt_min_flatness = 0.02;
  // Warnings about weak geometry.
  double min_tilt_deg = 10;                  // boards: all views tilted less = "fronto-parallel"
  double max_principal_point_sigma = 0.01;   // of the image diagonal
  double max_focal_sigma = 0.005;            // relative
  double min_coverage = 0.25;                // area fraction of the image covered by observations
  double max_corner_sigma_px = 1.0;          // projection sigma at the image corners (Uncertainty)
};

struct ViewReport {
  std::string image;
  int points = 0;
  double rms_px = 0;          // with the final camera (a rejected view: its own best pose)
  double max_px = 0;          // largest residual
  double first_rms_px = 0;    // in the first calibration, with every view
  double tilt_deg = 0;        // boards: angle between the board normal and the optical axis (else NaN)
  bool rejected = false;
  std::string reason;         // why it was rejected
  Pose cam_from_world;
};

struct PointResidual {
  std::string image;
  PointId point_id = 0;
  Eigen::Vector2d observed_px;
  Eigen::Vector2d residual_px;  // model - observed
  bool rejected_view = false;
};

struct CalibResult {
  Camera camera;
  Method method = Method::Auto;          // what was used
  Optimizer optimizer = Optimizer::Auto;
  double rms_px = 0;                     // over the views kept
  double rms_all_views_px = 0;           // first calibration, every view
  Camera camera_all_views;               // the camera of that first calibration
  std::size_t points_used = 0;
  std::size_t unmatched_observations = 0;  // observations of ids without a control point
  double coverage = 0;                   // fraction of the image inside the hull of the points
  std::vector<ViewReport> views;         // every view with enough points, in input order
  std::vector<std::string> skipped_views;  // too few points
  Uncertainty uncertainty;
  RefineStats stats;                     // of the final refinement
  std::vector<std::string> warnings;
  std::vector<PointResidual> residuals;
};

// Calibrates. Throws GeometryError when the data cannot give a camera (no usable view, coplanar
// points for the DLT, non-coplanar points for the planar method, a diverged solution).
CalibResult calibrate(const std::vector<Observation>& observations, const std::vector<ControlPoint>& control,
                      cv::Size image_size, const CalibOptions& options);

// The size shared by the images the observations name, read from the files; nullopt if one cannot
// be read. Throws InputError if the images differ in size.
std::optional<cv::Size> image_size_from_files(const std::vector<Observation>& observations);

}  // namespace photomill::calib
