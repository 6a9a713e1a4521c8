// How well each part of the fitted surface is measured: a standard deviation of its height on a
// grid over the data's x, y (formats/uncertainty.hpp), for toolpath --stock-uncertainty (issue #24,
// "uncertainty-aware stock"). docs/fitsurf.md, "Uncertainty".
//
// At a node c, with its n nearest fitted points (in x, y; outliers of the robust step left out):
//   s_loc(c)^2 = max( mean(r_k^2), mean(sigma_k^2), mean(e_k^2) )
//     r_k: the points' residuals (signed orthogonal distance to the surface), sigma_k: their own
//     standard deviation (the cloud's sigma_mm, triangulate's; 0 when the cloud has none): the
//     error of one point there, as the data scatter about the fit or as they were measured,
//     whichever is larger (a point the fit follows closely has a small residual, a gross two-view
//     point a small sigma); e_k: their leave-one-out errors (each point's height predicted from
//     its n nearest others, uncertainty.cpp), large in a thinly sampled curved stretch;
//   sigma(c)^2 = s_loc(c)^2 * ( 1 / max(1, m(c)) + (d(c) / rho)^2 )
//     m(c): the points within rho of c, rho: the surface's resolution (its knot span, mm), d(c):
//     the distance from c to the nearest point. The first term is the standard error of a mean
//     of the m points the surface averages near c (a smoothing spline's height is a local
//     weighted mean of the points within about a knot span), counted as independent errors:
//     points matched with overlapping windows (densify's, `window_mm` w: the window's
//     half-width) share the pixels and the texture that make their errors, so m(c) is at most
//     the number of such windows that tile the disc, pi rho^2 / (2 w)^2 (w the mean over the
//     n points), and at least 1 (the effective number of observations of a correlated mean:
//     a mean of m points whose errors are equal within one window's footprint has the variance
//     of a mean over the footprints it spans); the second the interpolation error
//     where it has no data: an interpolant's error grows with the distance to the nearest datum,
//     as the power function of a thin-plate spline (Wendland, Scattered Data Approximation, 2005,
//     ch. 11; the kriging variance of a linear variogram behaves alike), linearly in d for d >>
//     rho. Densely measured: s_loc / sqrt(m); a gap of radius d: about s_loc * d / rho.
// This is a model, not a measured error: it is not a leave-one-out of the B-spline (the kernel
// prefit's leave-one-out RMS is used as a floor of the residuals, UncertaintyOptions), a bias the
// data share (a wrong calibration) is not in it, and heights are the orthogonal residuals taken
// as vertical (exact on flat stretches, too small by cos(slope) on slopes).
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "formats/uncertainty.hpp"

namespace photomill::fitsurf {

struct UncertaintyOptions {
  double cell_mm = 1;          // node spacing of the grid
  std::size_t neighbours = 12; // n: the points s_loc is taken over
  double resolution_mm = 0;    // rho; 0: 3 times the median distance between nearest points
  // Each residual counts as at least this (the kernel prefit interpolates its points, so their
  // residuals are 0: fitsurf passes its leave-one-out RMS, the error expected between points).
  double residual_floor_mm = 0;
  // A point whose n nearest others' centroid lies more than this many of their standard
  // deviations from it (Mahalanobis distance) is not surrounded by them: it has no leave-one-out
  // error (uncertainty.cpp).
  double loo_max_extrapolation = 3;
  // The leave-one-out quadratic (else plane) is used only if its prediction at the point carries
  // the neighbours' noise at most this many times (uncertainty.cpp); else the next simpler model.
  double loo_max_noise_gain = 10;
};

struct UncertaintySummary {
  double spacing_mm = 0;       // the median distance from a point to its nearest neighbour
  double resolution_mm = 0;    // rho used
  double min_mm = 0, median_mm = 0, p95_mm = 0, max_mm = 0;  // of sigma over the nodes
};

// points: the fitted points (world mm); residual_mm and weight: per point as FitResult gives them
// (weight 0: an outlier, left out); point_sigma_mm and point_window_mm: per point, or empty (a
// window of 0: a point whose error is its own). The grid covers the
// points' x, y bounding box. Throws GeometryError for fewer than 2 points kept, UsageError for a
// cell or a neighbour count out of range, or a grid of more than kMaxUncertaintyNodes nodes.
UncertaintyGrid surface_uncertainty(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& residual_mm,
                                    const std::vector<double>& weight, const std::vector<double>& point_sigma_mm,
                                    const std::vector<double>& point_window_mm, const UncertaintyOptions& options,
                                    UncertaintySummary* summary = nullptr);

}  // namespace photomill::fitsurf
