// The linear least-squares core of fitsurf: the normal equations of a tensor-product B-spline fit
// with a thin-plate smoothing term, assembled sparse and solved with Eigen.
//
// Unknowns: the poles P_g, g = i * nv + j (i = 0..nu-1 along u, j = 0..nv-1 along v), three
// coordinates each (solved as three right-hand sides of one matrix). For points Q_k with
// parameters (u_k, v_k) and weights w_k, the fit minimises (Piegl & Tiller 9.4.1, the paper's
// section 4, plus a smoothing term):
//
//   F(P) = (1/W) sum_k w_k |Q_k - S(u_k, v_k)|^2  +  lambda * E(P) / (L_u L_v),   W = sum_k w_k,
//   E(P) = integral over the part of |S_xx|^2 + 2 |S_xy|^2 + |S_yy|^2 dx dy   (thin-plate energy)
//
// or, with smoothing order m = 3, E_3(P) = integral of |S_xxx|^2 + 3 |S_xxy|^2 + 3 |S_xyy|^2 +
// |S_yyy|^2 (the rotation-invariant energy of order 3, whose minimisers are Duchon's 1977
// polyharmonic splines of order 3; its null space is the quadrics, so smoothing does not flatten
// a curved part where the data are sparse), lambda then in mm^6.
//
// with x = L_u u, y = L_v v the parameter plane in mm (L_u, L_v: the data's extent), so lambda is
// in mm^4 and lambda^(1/4) is the length below which shape detail is smoothed away, whatever the
// number of points or the size of the part. Setting dF/dP = 0 gives  M P = B  with
//
//   M = (1/W) sum_k w_k N_k N_k^T + lambda K,    B = (1/W) sum_k w_k N_k Q_k^T,
//   N_k[g] = N_i^p(u_k) N_j^q(v_k),
//   K = c_uu G2_u (x) G0_v + 2 c_uv G1_u (x) G1_v + c_vv G0_u (x) G2_v,
//   Gd[i][i'] = integral_0^1 N_i^(d)(u) N_i'^(d)(u) du,  c_uu = 1/L_u^4, c_uv = 1/(L_u^2 L_v^2),
//   c_vv = 1/L_v^4   ((x) is the Kronecker product over (i, j)).
//
// Each point touches (p+1)(q+1) poles, so M has non-zeros only for |i - i'| <= p, |j - j'| <= q:
// it is stored as a stencil of (p+1)(2q+1) values per pole (the half with g' >= g), accumulated
// per point directly, by several threads into private stencils that are summed at the end.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "formats/bspline.hpp"

namespace photomill::fitsurf {

// Degrees, knot vectors and net size of the surface being fitted.
struct SplineSpace {
  int p = 3, q = 3;          // degrees in u and v
  int nu = 4, nv = 4;        // poles along u and v
  std::vector<double> U, V;  // knot vectors (nu + p + 1 and nv + q + 1 knots), domain [0, 1]
  int num_poles() const { return nu * nv; }
};

// The symmetric banded matrix of the normal equations, as a stencil per pole: entry (g, g') with
// g = (i, j), g' = (i + di, j + dj), di in 0..p, dj in -q..q, g' >= g, at
// values[g * stencil + di * (2q + 1) + dj + q]. Slots with g' < g (di = 0, dj < 0) stay zero.
class BandedSymmetric {
public:
  explicit BandedSymmetric(const SplineSpace& space);
  double& at(int g, int di, int dj) { return values_[index(g, di, dj)]; }
  double at(int g, int di, int dj) const { return values_[index(g, di, dj)]; }
  // this += scale * other (same space).
  void add(const BandedSymmetric& other, double scale = 1.0);
  // Entry (g, g') for any two poles (zero outside the band).
  double entry(int g, int g2) const;
  int nu() const { return nu_; }
  int nv() const { return nv_; }
  int p() const { return p_; }
  int q() const { return q_; }
  std::vector<double>& values() { return values_; }

private:
  std::size_t index(int g, int di, int dj) const {
    return static_cast<std::size_t>(g) * stencil_ + static_cast<std::size_t>(di * (2 * q_ + 1) + dj + q_);
  }
  int nu_, nv_, p_, q_;
  std::size_t stencil_;
  std::vector<double> values_;
};

// The data part of the normal equations: sum_k w_k N_k N_k^T, sum_k w_k N_k Q_k^T, W = sum w_k.
struct DataNormalEquations {
  BandedSymmetric matrix;
  std::vector<Eigen::Vector3d> rhs;  // one per pole
  double weight_sum = 0;
  explicit DataNormalEquations(const SplineSpace& space)
      : matrix(space), rhs(static_cast<std::size_t>(space.num_poles()), Eigen::Vector3d::Zero()) {}
};

// Accumulates the data normal equations of the points (local coordinates) at parameters uv, with
// weights (empty: all 1; a zero weight leaves the point out), using `threads` workers
// (0: every hardware thread).
DataNormalEquations accumulate_normal_equations(const SplineSpace& space,
                                                const std::vector<Eigen::Vector2d>& uv,
                                                const std::vector<Eigen::Vector3d>& points,
                                                const std::vector<double>& weights, int threads);

// The smoothing energy matrix K above (order 2: thin plate; order 3: third derivatives, term k
// C(3,k) / (L_u^(2(3-k)) L_v^(2k)) G(3-k)_u (x) Gk_v), for a parameter rectangle of
// length_u_mm x length_v_mm. The 1-D Gram matrices are integrated exactly, knot span by knot span,
// with (p+1)-point Gauss-Legendre quadrature (the integrands are polynomials of degree <= 2p
// there); derivatives above the degree are zero. Throws UsageError for other orders.
BandedSymmetric thin_plate_matrix(const SplineSpace& space, double length_u_mm, double length_v_mm, int order = 2);

// Gauss-Legendre nodes and weights on [-1, 1] (Newton's method on the Legendre polynomial, as in
// Press et al., Numerical Recipes, 3rd ed., 4.6.1 "gauleg").
void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights);

// The full symmetric sparse matrix scale_data * data + scale_smooth * smooth, column-major, with
// the complete band pattern (explicit zeros kept) so its sparsity pattern never changes between
// rounds and a factorisation's symbolic analysis can be reused.
Eigen::SparseMatrix<double> assemble_sparse(const BandedSymmetric& data, double scale_data,
                                            const BandedSymmetric& smooth, double scale_smooth);

}  // namespace photomill::fitsurf
