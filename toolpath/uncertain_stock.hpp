// Uncertainty-aware stock (issue #24): extra material left where the surface is not well measured.
// fitsurf --uncertainty gives the standard deviation sigma(x, y) of the fitted height on a grid
// (formats/uncertainty.hpp); toolpath then machines, instead of the surface S, the surface offset
// up (along the machine's z) by k sigma, so the ball stays above S + k sigma, and the finishing pass
// leaves k sigma of material where the photos measured the part poorly and hardly any where they
// measured it well.
//
// The offset surface S' keeps S's knots and has each pole P_ij raised by
//   k * sigma_ij,  sigma_ij = the largest sigma of the grid cell under S(u*_i, v*_j)
// (u*_i, v*_j: the pole's Greville abscissae, where the pole acts most). S' - S = sum N_ij k sigma_ij
// is the spline of those raises, a weighted mean of them (the basis functions are >= 0 and sum to
// 1), so it is k sigma smoothed over about a knot span: exact where sigma varies slowly compared
// with the net, below it by part of a narrow peak's height. The ball's own clearance over S is
// toolpath's usual drop-cutter and gouge check, now against S'. Outside the grid sigma is its
// nearest edge node's. docs/toolpath.md, "Uncertainty-aware stock".
#pragma once

#include <cstddef>

#include "formats/surface.hpp"
#include "formats/uncertainty.hpp"

namespace photomill::toolpath {

struct UncertainStockStats {
  double k = 0;                  // sigmas of stock
  double sigma_max_mm = 0;       // largest sigma of the grid
  double max_mm = 0;             // largest raise of a pole (the offset's largest value)
  double mean_mm = 0;            // mean raise of the poles
  double area_mm2 = 0;           // area of the grid where k sigma exceeds threshold_mm
  double threshold_mm = 0;       // (the scallop height: below it the extra stock is within the finish's own)
};

// S' as above. Throws UsageError for k < 0 or not finite.
BSplineSurface offset_by_uncertainty(const BSplineSurface& surface, const UncertaintyGrid& grid, double k,
                                     double threshold_mm, UncertainStockStats* stats = nullptr);

}  // namespace photomill::toolpath
