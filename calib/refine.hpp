// Refinement of intrinsics, distortion and every pose by minimising the sum of squared
// reprojection errors (model.hpp), with one of three optimisers, and the uncertainty of the result.
//   lm:      Levenberg-Marquardt (Ceres, dense Schur complement over the poses)
//   simplex: Nelder-Mead downhill simplex on the same cost (the paper's method, section 3.3)
//   opencv:  cv::calibrateCamera (Zhang's initialisation + OpenCV's own Levenberg-Marquardt)
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "calib/model.hpp"
#include "calib/simplex.hpp"

namespace photomill::calib {

struct LmOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-12;   // relative change of the cost
  double parameter_tolerance = 1e-12;  // relative change of the parameters
  double gradient_tolerance = 1e-14;   // max-norm of the projected gradient
};

struct RefineStats {
  std::string optimizer;     // "lm", "simplex", "opencv"
  long iterations = -1;      // LM iterations, simplex steps; -1 if the optimiser does not say
  long evaluations = -1;     // evaluations of the cost (simplex) or of the residuals (LM)
  int restarts = 0;          // simplex restarts
  double seconds = 0;        // wall time
  double initial_rms_px = 0;  // NaN when the optimiser makes its own initial estimate
  double final_rms_px = 0;
  bool converged = false;
  std::string message;       // the optimiser's own termination message
};

RefineStats refine_lm(const std::vector<View>& views, const ModelOptions& model, const LmOptions& options,
                      Parameters& p);
// How the simplex's coordinates are scaled (the cost and its minimum do not change):
//   Diagonal: each parameter by a fixed step (a few % of f, of the image side, of the distance...)
//   Jacobian: whitened by the Gauss-Newton curvature J^T J at the start of each run
enum class SimplexScaling { Diagonal, Jacobian };

struct SimplexRefineOptions {
  SimplexOptions simplex;
  SimplexScaling scaling = SimplexScaling::Jacobian;
  double whitened_step = 10;  // Jacobian scaling: initial simplex step in whitened units
};

RefineStats refine_simplex(const std::vector<View>& views, const ModelOptions& model,
                           const SimplexRefineOptions& options, cv::Size image_size, Parameters& p);
// With use_guess = false the control points must lie on z = 0 and OpenCV makes its own initial
// estimate (this reproduces calibrateCamera exactly); with true it starts from `p`.
RefineStats refine_opencv(const std::vector<View>& views, const ModelOptions& model, const LmOptions& options,
                          cv::Size image_size, bool use_guess, Parameters& p);

// Standard deviations from the Jacobian J of all residuals with respect to all free parameters
// (intrinsics, distortion, poses) at the solution: Cov = s^2 (J^T J)^-1, s^2 = SSE / (m - n) with
// m residuals and n free parameters (as OpenCV's calibrateCameraExtended). Fixed parameters get 0.
struct Uncertainty {
  std::array<double, kIntrinsics> intrinsics_sigma{};
  std::array<double, kDistortion> distortion_sigma{};
  double sigma_px = 0;                 // s: a-posteriori standard deviation of one coordinate
  int degrees_of_freedom = 0;          // m - n
  std::vector<std::string> undetermined;  // parameters the data do not fix (J^T J singular there)
  // How far the camera's projection of a ray may be off (1 sigma, px, the larger axis of its error
  // ellipse) once a small rotation of the camera has taken up what it can (refine.cpp): at the
  // image centre, the worst of the four edge midpoints and of the four corners; at the worst
  // corner, the free parameter whose own sigma moves it most.
  double projection_sigma_centre_px = 0;
  double projection_sigma_edges_px = 0;
  double projection_sigma_corners_px = 0;
  std::string corner_sigma_parameter;        // e.g. "k3"
  double corner_sigma_parameter_px = 0;      // that parameter's sigma times its pixel effect there
};
Uncertainty estimate_uncertainty(const std::vector<View>& views, const ModelOptions& model, const Parameters& p,
                                 int width_px, int height_px);

}  // namespace photomill::calib
