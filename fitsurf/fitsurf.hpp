// fitsurf as one library call: select the part in a point cloud, choose the net (fixed, or by
// --tolerance), fit the B-spline surface, outline the data in (u,v), check that the surface does
// not fold, and summarise the residuals. The fitsurf executable reads, calls this, and writes.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "fitsurf/fit.hpp"
#include "fitsurf/kernel.hpp"
#include "fitsurf/outline.hpp"
#include "fitsurf/select.hpp"
#include "fitsurf/tolerance.hpp"
#include "formats/point_cloud.hpp"

namespace photomill::fitsurf {

// Sparse clouds (a few hundred markers): first interpolate the points by a radial kernel chosen
// by leave-one-out cross-validation (kernel.hpp), then fit the B-spline to that interpolant
// sampled densely inside the points' hull. With fewer points than poles the B-spline's smoothing
// term, not the data, shapes the surface between the points; the kernel that best predicts each
// point from the others does it better (docs/measurements/fitsurf.md, sparse markers: 150 markers 10 mm apart
// on a wave, 0.03-0.10 mm from the truth instead of 0.17-0.45).
enum class Prefit { Auto, Kernel, None };

struct PrefitOptions {
  Prefit mode = Prefit::Auto;
  // Auto: the kernel when the part has at most auto_max_points points (the search costs
  // O(n^3) per candidate) and fewer points than the net has poles; never with a tolerance, a
  // noise level or sigma weights (the kernel interpolates; the spline's smoothing takes those).
  std::size_t auto_max_points = 400;
  // Samples of the interpolant per knot span in each direction, on a grid covering the points'
  // convex hull grown by one grid step.
  double samples_per_span = 4;
  // With robust reweighting on: a point whose standardised leave-one-out residual (each divided
  // by its prediction's standard deviation, so a point on the hull's edge, extrapolated from one
  // side, is not suspect for that alone) exceeds this many robust standard deviations (1.4826 MAD
  // of all of them), and whose residual exceeds this many FitOptions::robust_min_scale_mm, is an
  // outlier, left out one at a time (worst first) and the kernel chosen again.
  double outlier_threshold = 10;
  double max_outlier_fraction = 0.2;  // left out at most (beyond it fitsurf warns and keeps the rest)
  KernelOptions kernel;
};

struct PrefitSummary {
  KernelModel model;        // the kernel chosen
  double loo_rms_mm = 0;    // RMS leave-one-out residual of the points kept: the error expected between points
  std::size_t candidates = 0;
  std::size_t samples = 0;  // points of the interpolant the B-spline was fitted to
  std::size_t outliers = 0;
  double outlier_cutoff_mm = 0;
};

struct Options {
  SelectOptions select;
  FitOptions fit;
  PrefitOptions prefit;
  OutlineOptions outline;
  std::optional<ToleranceOptions> tolerance;  // set: choose the net by tolerance
  // Weight each point by 1 / max(sigma_mm, sigma_floor_mm)^2 from the cloud's sigma_mm property
  // (triangulate's standard deviation of the point), normalised to mean 1: least squares with the
  // points' a-priori variances (Gauss-Markov), so a two-view point counts less than one seen by 8.
  bool weight_by_sigma = false;
  double sigma_floor_mm = 0.005;
  // When parameter correction stops before a round that would curl the surface over
  // (FitOptions::stop_before_fold), the fit is repeated with the smoothing raised by steps of
  // sqrt(10), up to this factor, while the correction still stops; the fit closest to the data
  // is kept (smoothing_ladder). On a range scan's steep flanks a stiffer surface lets the points
  // slide to their feet without curling it: the bunny's body patch at 12 poles, 0.493 mm RMS
  // stopped at round 7 with 0.01 mm^4, 0.353 mm at 1 (docs/measurements/fitsurf.md). 1 = never;
  // not with a tolerance (its net is chosen at the smoothing given), --noise-mm or the kernel prefit.
  double max_smoothing_factor = 100;
};

// One fit of the smoothing ladder (Options::max_smoothing_factor).
struct SmoothingTrial {
  double smoothing = 0;      // lambda, in the fit's unit (mm^4, or mm^6 for order 3)
  int rounds = 0;            // rounds kept
  bool stopped = false;      // the correction stopped before a curl
  double score_rms_mm = 0;   // RMS distance over the points the first fit kept (the comparison)
  std::string refused;       // non-empty: the fit failed with this error
};

// Statistics of the signed orthogonal residuals d (mm) of the fitted points.
struct ResidualStats {
  std::size_t count = 0;
  double rms_mm = 0;        // sqrt(mean d^2) over all points
  double mean_mm = 0;       // mean d (a bias above/below the surface)
  double max_abs_mm = 0;
  double p50_mm = 0, p90_mm = 0, p95_mm = 0, p99_mm = 0;  // percentiles of |d| (nearest rank)
  std::size_t inliers = 0;  // points not flagged as outliers by the robust weighting
  double inlier_rms_mm = 0;
};
ResidualStats residual_stats(const std::vector<double>& d, const FitResult& fit);

struct Result {
  std::size_t input_points = 0;
  std::string units = "mm";  // the cloud's (PointCloud::units): "arbitrary" warns that nothing is in mm
  // The largest side of the input cloud's axis-aligned bounding box, in its unit: what a length
  // option is compared with when the cloud is not in mm (length_options_warning).
  double extent = 0;
  Selection selection;
  std::optional<ToleranceSearch> tolerance;
  std::optional<PrefitSummary> prefit;  // set when the kernel prefit was used
  // fit.surface carries the outline as boundary_uv, and the cloud's unit: "mm", else "arbitrary"
  // (BSplineSurface::units), so that no tool path takes it as mm.
  FitResult fit;
  // The fits tried when the correction stopped before a curl, the requested smoothing's first;
  // empty when it did not stop (or the ladder was off).
  std::vector<SmoothingTrial> smoothing_ladder;
  ResidualStats stats;
  double seconds = 0;       // wall time of fit_point_cloud
};

// source names the cloud in errors (a cloud without sigma_mm for weight_by_sigma). With a
// tolerance, the net is chosen without the sigma weights; the final fit uses them.
Result fit_point_cloud(const PointCloud& cloud, const Options& options, const std::string& source = "input");

// The fitted points with their input properties and two more scalar fields: residual_mm (signed
// orthogonal distance to the surface, positive on the side of its normal) and weight (robust
// weight of the last round, 0 for rejected outliers).
PointCloud residual_cloud(const PointCloud& input, const Result& result);

}  // namespace photomill::fitsurf
