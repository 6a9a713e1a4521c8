// Evaluation of the B-spline surfaces that formats/surface.hpp reads and writes: basis functions
// and their derivatives, surface points, and derivatives up to second order, for polynomial and
// rational surfaces. The algorithms and notation are those of The NURBS Book (Piegl & Tiller,
// 2nd ed.): A2.1 FindSpan, A2.2 BasisFuns, A2.3 DersBasisFuns, A3.5 SurfacePoint,
// A3.6 SurfaceDerivsAlg1, A4.3/A4.4 for the rational case. Shared by fitsurf, toolpath and the
// tests, so everything that evaluates a surface agrees to the last bit.
#pragma once

#include <array>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "formats/surface.hpp"

namespace photomill {

// Highest degree supported (Open CASCADE's limit too).
constexpr int kMaxBSplineDegree = 25;

// A2.1: the knot span index i with U[i] <= u < U[i+1], for n+1 basis functions of degree p
// (U has n + p + 2 knots). u is clamped to the domain [U[p], U[n+1]]; u = U[n+1] returns n.
int find_span(int n, int p, double u, const std::vector<double>& U);

// A2.2: the p+1 non-vanishing basis functions N[span-p .. span] at u, into N[0..p].
void basis_funs(int span, double u, int p, const std::vector<double>& U, double* N);

// A2.3: derivatives 0..nd of those basis functions: ders[k][j] = k-th derivative of N[span-p+j].
// `ders` must hold (nd+1) rows of p+1 values (row-major, row stride p+1).
void ders_basis_funs(int span, double u, int p, int nd, const std::vector<double>& U, double* ders);

// Parameter domain [U[p], U[n+1]] and [V[q], V[m+1]].
std::pair<double, double> domain_u(const BSplineSurface& s);
std::pair<double, double> domain_v(const BSplineSurface& s);

// A3.5 / A4.3: S(u, v). Parameters outside the domain are clamped to it.
Eigen::Vector3d surface_point(const BSplineSurface& s, double u, double v);

// Position and partial derivatives up to second order at (u, v) (A3.6, A4.4 for rational).
struct SurfaceDerivatives {
  Eigen::Vector3d p, su, sv, suu, suv, svv;
  // Unit normal su × sv / |su × sv| (zero vector where the surface is singular).
  Eigen::Vector3d normal() const;
};
SurfaceDerivatives surface_derivatives(const BSplineSurface& s, double u, double v);

// Basis functions of one parameter direction at u, for assembling least-squares systems:
// the first index and the p+1 values. Avoids repeated span searches in callers.
struct BasisRow {
  int first = 0;                       // index of the first non-zero basis function
  std::array<double, kMaxBSplineDegree + 1> values{};
};
BasisRow basis_row(int n, int p, double u, const std::vector<double>& U);

// Clamped knot vector with uniform interior knots on [a, b]: p+1 copies of a, num_poles-p-1
// equally spaced interior knots, p+1 copies of b (The NURBS Book, eq. 2.x / the paper's U).
std::vector<double> clamped_uniform_knots(int num_poles, int degree, double a = 0.0, double b = 1.0);

}  // namespace photomill
