// Fast evaluation of the (non-rational) surfaces fitsurf builds, for its per-point loops (foot
// points, residuals): position and partial derivatives up to second order. The basis functions
// and their derivatives come from formats/bspline (A2.1 find_span, A2.3 ders_basis_funs), so they
// are the shared ones; only the tensor-product sum of A3.6 is specialised here to poles without
// weights, skipping the homogeneous coordinates surface_derivatives carries for rational
// surfaces. Agrees with surface_derivatives to rounding (evaluate_test).
#pragma once

#include "formats/bspline.hpp"
#include "formats/surface.hpp"

namespace photomill::fitsurf {

// S, S_u, S_v, S_uu, S_uv, S_vv at (u, v) clamped to the domain. `order` 0, 1 or 2: derivatives
// above it are left zero. The surface must be non-rational (fitsurf's always are).
SurfaceDerivatives evaluate(const BSplineSurface& s, double u, double v, int order = 2);

}  // namespace photomill::fitsurf
