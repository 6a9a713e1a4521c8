// Distance from a point to the synthetic part's true surface (synth_accuracy's cloud figures,
// densify_check): the graph of the height field over the plate, a walled part's faces included.
#pragma once

#include <Eigen/Core>

#include "tools/synth/height_field.hpp"

namespace photomill::synth {

// Distance from c to the true part's surface (not the solid): the graph of H(x, y) = h(x, y) over
// the part's rectangle and 0 on the plate and beyond, with a walled part's faces (x = x_min...,
// from z = 0 up to the top at the wall). The vertical distance |c.z - H(c.x, c.y)| bounds it
// from above; when that is more than `within_mm`, the graph is sampled on a kPointGridMm grid
// over |x - c.x|, |y - c.y| <= kPointReachMm (overestimating the distance by about t^2 / (2 d),
// t <= 0.036 mm the offset of the nearest sample, d the distance: under 1 um for d >= 1 mm) and
// the walls' faces are measured exactly. Exact up to the reach; beyond it, an upper bound (at
// least kPointReachMm). At most `within_mm` vertically, the vertical distance (an upper bound).
constexpr double kPointGridMm = 0.05, kPointReachMm = 3;
double distance_to_surface(const HeightField& h, const Eigen::Vector3d& c, double within_mm);

// A walled part's top is judged from this far inside its walls (issue 24: "the true surface more
// than 2 mm in x, y from a wall's edge"; synth_accuracy, densify_check).
constexpr double kWallMarginMm = 2;

}  // namespace photomill::synth
