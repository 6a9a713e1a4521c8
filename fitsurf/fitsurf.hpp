// fitsurf as one library call: select the part in a point cloud, choose the net (fixed, or by
// --tolerance), fit the B-spline surface, outline the data in (u,v), check that the surface does
// not fold, and summarise the residuals. The fitsurf executable reads, calls this, and writes.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "fitsurf/fit.hpp"
#include "fitsurf/outline.hpp"
#include "fitsurf/select.hpp"
#include "fitsurf/tolerance.hpp"
#include "formats/point_cloud.hpp"

namespace photomill::fitsurf {

struct Options {
  SelectOptions select;
  FitOptions fit;
  OutlineOptions outline;
  std::optional<ToleranceOptions> tolerance;  // set: choose the net by tolerance
  // Weight each point by 1 / max(sigma_mm, sigma_floor_mm)^2 from the cloud's sigma_mm property
  // (triangulate's standard deviation of the point), normalised to mean 1: least squares with the
  // points' a-priori variances (Gauss-Markov), so a two-view point counts less than one seen by 8.
  bool weight_by_sigma = false;
  double sigma_floor_mm = 0.005;
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
  Selection selection;
  std::optional<ToleranceSearch> tolerance;
  FitResult fit;            // fit.surface carries the outline as boundary_uv
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
