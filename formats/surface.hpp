// Tensor-product B-spline (optionally rational) surfaces: photomill's own small text format.
// Notation of The NURBS Book (Piegl & Tiller): degrees p, q; knot vectors U (r+1 knots) and
// V (s+1 knots); control net P[i][j], i = 0..n along u, j = 0..m along v, with r = n + p + 1 and
// s = m + q + 1. STEP and IGES go through Open CASCADE (formats/cad.hpp).
#pragma once

#include <cstddef>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill {

// The units a surface may have: its poles in mm, or in the arbitrary unit of a reconstruction
// without a datum.
inline constexpr const char* kSurfaceUnitMm = "mm";
inline constexpr const char* kSurfaceUnitArbitrary = "arbitrary";

struct BSplineSurface {
  int degree_u = 3;                  // p
  int degree_v = 3;                  // q
  std::vector<double> knots_u;       // U, non-decreasing, size num_poles_u + p + 1
  std::vector<double> knots_v;       // V, non-decreasing, size num_poles_v + q + 1
  int num_poles_u = 0;               // n + 1
  int num_poles_v = 0;               // m + 1
  std::vector<Eigen::Vector3d> poles_mm;  // P[i][j] at index i * num_poles_v + j, world mm (see units)
  std::vector<double> weights;       // empty: non-rational; else one positive weight per pole
  // Optional outline of the data in parameter space: a simple closed polygon (first vertex not
  // repeated), counter-clockwise. Empty: the whole domain.
  std::vector<Eigen::Vector2d> boundary_uv;
  // The unit of the poles: "mm", or "arbitrary" for a surface fitted to a cloud oriented without
  // a datum (PointCloud::units; its first camera baseline is 1), which no tool path may take as
  // mm. The text format writes a `units arbitrary` line; a file without one is in mm.
  std::string units = "mm";

  Eigen::Vector3d& pole(int i, int j) { return poles_mm[static_cast<std::size_t>(i) * num_poles_v + j]; }
  const Eigen::Vector3d& pole(int i, int j) const {
    return poles_mm[static_cast<std::size_t>(i) * num_poles_v + j];
  }
  bool rational() const { return !weights.empty(); }
  bool in_mm() const { return units == kSurfaceUnitMm; }
  bool operator==(const BSplineSurface&) const = default;
};

// Checks sizes, knot order, finite values, positive weights, a non-degenerate domain, a known unit
// (kSurfaceUnits).
// Throws InputError(source, 0, problem).
void validate_surface(const BSplineSurface& s, const std::string& source);

BSplineSurface read_surface(std::istream& in, const std::string& source);
void write_surface(std::ostream& out, const BSplineSurface& surface);

}  // namespace photomill
