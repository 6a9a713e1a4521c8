// Surfaces with geometry the toolpath tests and the bench control: a height field z = f(x, y)
// over a rectangle, interpolated by a bicubic B-spline through a grid of samples. Uniform
// parameters and knots by averaging (The NURBS Book, eq. 9.8; global surface interpolation,
// section 9.2.5) make x and y exactly linear in u and v (interpolation reproduces linear data),
// and z follows f between the samples.
#pragma once

#include <functional>
#include <string>

#include "formats/surface.hpp"

namespace photomill::toolpath::test {

BSplineSurface interpolate_height_field(const std::function<double(double, double)>& f, double x0, double x1, double y0,
                                        double y1, int nx, int ny, int degree = 3);

// 150 x 100 mm, 20-40 mm high, all concave radii well above 3 mm:
// three Gaussian bumps on z = 20 (peaks 20 + 16, radii of curvature >= 20 mm).
BSplineSurface bumps_surface();
// z = 30 + 6 sin(2 pi x / 75) cos(2 pi y / 50): saddles, ridges and bowls, radii >= 10 mm,
// slopes up to 37 degrees.
BSplineSurface wave_surface();
// A tilted plane z = 25 + 0.08 x with a narrow diagonal groove 3 mm deep, 1.2 mm sigma: its
// bottom's concave radius is about 0.5 mm, far tighter than a 3 mm ball.
BSplineSurface groove_surface();
// 60 x 30 mm strips whose cross-section across y is a circle arc of radius `radius_mm` (convex:
// a ridge, concave: a trough), straight along x; radius 0 gives a plane z = 20 + 0.3 y.
// (radius >= 16.7 mm, so the arc spans the strip.)
BSplineSurface cylinder_surface(double radius_mm, bool convex);
// The same ridge as an exact rational surface (degree 1 along x, a 90-degree circular arc of
// `radius_mm` across, weights 1, sqrt(2)/2, 1; The NURBS Book, section 7.3): y in +-r/sqrt(2).
BSplineSurface rational_ridge_surface(double radius_mm);
// A tent: degree 1 along u from an apex (0, 0, 30) - a collapsed edge, where the normal is only
// a limit - to a parabolic arch at x = 40 (y -20..20, z 10..20) along v. Its edges meet the
// passes at a slant in both directions.
BSplineSurface tent_surface();
// 60 x 30 mm: a trough along x whose bottom is a circle arc of `radius_mm` (over +-45 degrees),
// continued by 45-degree flanks: for radii below the ball's, a gouge trap.
BSplineSurface trough_surface(double radius_mm);

// The same by name ("bumps", "wave", "groove"), for the bench.
BSplineSurface named_surface(const std::string& name);

}  // namespace photomill::toolpath::test
