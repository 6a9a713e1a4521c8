// Normal equations of the B-spline least-squares fit (see normal_equations.hpp for the formulas).
#include "fitsurf/normal_equations.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "geometry/parallel.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {

BandedSymmetric::BandedSymmetric(const SplineSpace& s)
    : nu_(s.nu), nv_(s.nv), p_(s.p), q_(s.q),
      stencil_(static_cast<std::size_t>((s.p + 1) * (2 * s.q + 1))),
      values_(static_cast<std::size_t>(s.num_poles()) * stencil_, 0.0) {}

void BandedSymmetric::add(const BandedSymmetric& other, double scale) {
  if (other.values_.size() != values_.size()) throw std::invalid_argument("BandedSymmetric::add: size mismatch");
  for (std::size_t k = 0; k < values_.size(); ++k) values_[k] += scale * other.values_[k];
}

double BandedSymmetric::entry(int g, int g2) const {
  if (g2 < g) std::swap(g, g2);
  const int i = g / nv_, j = g % nv_, i2 = g2 / nv_, j2 = g2 % nv_;
  const int di = i2 - i, dj = j2 - j;
  if (di > p_ || dj > q_ || dj < -q_) return 0.0;
  return at(g, di, dj);
}

DataNormalEquations accumulate_normal_equations(const SplineSpace& space,
                                                const std::vector<Eigen::Vector2d>& uv,
                                                const std::vector<Eigen::Vector3d>& points,
                                                const std::vector<double>& weights, int threads) {
  if (uv.size() != points.size() || (!weights.empty() && weights.size() != points.size())) {
    throw std::invalid_argument("accumulate_normal_equations: sizes differ");
  }
  const int p = space.p, q = space.q, nv = space.nv;
  const int workers = geometry::block_count(points.size(), threads, 2048);
  std::vector<DataNormalEquations> partial(static_cast<std::size_t>(workers), DataNormalEquations(space));
  geometry::parallel_blocks(points.size(), threads, 2048, [&](std::size_t begin, std::size_t end, int worker) {
    DataNormalEquations& ne = partial[static_cast<std::size_t>(worker)];
    std::vector<double>& M = ne.matrix.values();
    const std::size_t stencil = static_cast<std::size_t>((p + 1) * (2 * q + 1));
    // n_ab = N_{fu+a}(u) N_{fv+b}(v): the point's (p+1) x (q+1) tensor-product basis values.
    std::array<double, (kMaxBSplineDegree + 1) * (kMaxBSplineDegree + 1)> n{};
    for (std::size_t k = begin; k < end; ++k) {
      const double w = weights.empty() ? 1.0 : weights[k];
      if (w == 0.0) continue;
      const BasisRow bu = basis_row(space.nu - 1, p, uv[k].x(), space.U);
      const BasisRow bv = basis_row(space.nv - 1, q, uv[k].y(), space.V);
      for (int a = 0; a <= p; ++a) {
        for (int b = 0; b <= q; ++b) {
          n[static_cast<std::size_t>(a * (q + 1) + b)] =
              bu.values[static_cast<std::size_t>(a)] * bv.values[static_cast<std::size_t>(b)];
        }
      }
      const Eigen::Vector3d wq = w * points[k];
      for (int a = 0; a <= p; ++a) {
        for (int b = 0; b <= q; ++b) {
          const int g = (bu.first + a) * nv + bv.first + b;
          const double wn = w * n[static_cast<std::size_t>(a * (q + 1) + b)];
          ne.rhs[static_cast<std::size_t>(g)] += n[static_cast<std::size_t>(a * (q + 1) + b)] * wq;
          // Row g of the stencil: partners (a2, b2) with g' >= g, i.e. a2 > a, or a2 == a, b2 >= b.
          double* row = M.data() + static_cast<std::size_t>(g) * stencil + static_cast<std::size_t>(q - b);
          for (int a2 = a; a2 <= p; ++a2) {
            double* dst = row + static_cast<std::size_t>((a2 - a) * (2 * q + 1));
            const double* src = n.data() + static_cast<std::size_t>(a2 * (q + 1));
            for (int b2 = (a2 == a ? b : 0); b2 <= q; ++b2) dst[b2] += wn * src[b2];
          }
        }
      }
      ne.weight_sum += w;
    }
  });
  DataNormalEquations total = std::move(partial[0]);
  for (std::size_t w = 1; w < partial.size(); ++w) {
    total.matrix.add(partial[w].matrix);
    for (std::size_t g = 0; g < total.rhs.size(); ++g) total.rhs[g] += partial[w].rhs[g];
    total.weight_sum += partial[w].weight_sum;
  }
  return total;
}

void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights) {
  // Roots of P_n by Newton from the Chebyshev-like guess cos(pi (i + 0.75) / (n + 0.5)); P_n and
  // P_n' from the three-term recurrence (j+1) P_{j+1} = (2j+1) x P_j - j P_{j-1};
  // weight_i = 2 / ((1 - x_i^2) P_n'(x_i)^2).
  nodes.assign(static_cast<std::size_t>(n), 0.0);
  weights.assign(static_cast<std::size_t>(n), 0.0);
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 0;
    for (int iter = 0; iter < 100; ++iter) {
      double p0 = 1.0, p1 = 0.0;
      for (int j = 0; j < n; ++j) {
        const double p2 = p1;
        p1 = p0;
        p0 = ((2.0 * j + 1.0) * x * p1 - j * p2) / (j + 1.0);
      }
      dp = n * (x * p0 - p1) / (x * x - 1.0);
      const double dx = p0 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-15) break;
    }
    const std::size_t lo = static_cast<std::size_t>(i), hi = static_cast<std::size_t>(n - 1 - i);
    nodes[lo] = -x;
    nodes[hi] = x;
    weights[lo] = weights[hi] = 2.0 / ((1.0 - x * x) * dp * dp);
  }
}

namespace {

// Gram matrices G0 .. G3 of one direction, dense nb x nb (nb = number of basis functions; a
// few hundred at most, and only used to fill the stencil). Derivatives above the degree are 0.
std::array<Eigen::MatrixXd, 4> gram_matrices(int nb, int p, const std::vector<double>& U) {
  std::array<Eigen::MatrixXd, 4> G;
  for (auto& g : G) g = Eigen::MatrixXd::Zero(nb, nb);
  std::vector<double> x, w;
  gauss_legendre(p + 1, x, w);
  const int nd = std::min(3, p);
  std::vector<double> ders(static_cast<std::size_t>((nd + 1) * (p + 1)), 0.0);
  for (int span = p; span < nb; ++span) {
    const double a = U[static_cast<std::size_t>(span)], b = U[static_cast<std::size_t>(span + 1)];
    if (!(b > a)) continue;
    const double half = 0.5 * (b - a);
    for (std::size_t g = 0; g < x.size(); ++g) {
      const double u = 0.5 * (a + b) + half * x[g];
      std::fill(ders.begin(), ders.end(), 0.0);
      ders_basis_funs(span, u, p, nd, U, ders.data());
      for (int d = 0; d <= nd; ++d) {
        const double* row = ders.data() + d * (p + 1);
        for (int r = 0; r <= p; ++r) {
          for (int r2 = 0; r2 <= p; ++r2) {
            G[static_cast<std::size_t>(d)](span - p + r, span - p + r2) += w[g] * half * row[r] * row[r2];
          }
        }
      }
    }
  }
  return G;
}

}  // namespace

BandedSymmetric thin_plate_matrix(const SplineSpace& s, double length_u_mm, double length_v_mm, int order) {
  if (order < 2 || order > 3) throw UsageError("smoothing order must be 2 or 3");
  const auto Gu = gram_matrices(s.nu, s.p, s.U);
  const auto Gv = gram_matrices(s.nv, s.q, s.V);
  // E_m = sum_k C(m, k) integral (d^m S / dx^(m-k) dy^k)^2 dx dy with x = L_u u, y = L_v v:
  // term k is C(m, k) / (L_u^(2(m-k)) L_v^(2k)) G_(m-k),u (x) G_k,v.
  const int binomial[2][4] = {{1, 2, 1, 0}, {1, 3, 3, 1}};
  std::array<double, 4> c{};
  for (int k = 0; k <= order; ++k) {
    c[static_cast<std::size_t>(k)] = binomial[order - 2][k] / (std::pow(length_u_mm, 2 * (order - k)) *
                                                               std::pow(length_v_mm, 2 * k));
  }
  BandedSymmetric K(s);
  for (int i = 0; i < s.nu; ++i) {
    for (int j = 0; j < s.nv; ++j) {
      const int g = i * s.nv + j;
      for (int di = 0; di <= s.p && i + di < s.nu; ++di) {
        for (int dj = (di == 0 ? 0 : -s.q); dj <= s.q; ++dj) {
          const int i2 = i + di, j2 = j + dj;
          if (j2 < 0 || j2 >= s.nv) continue;
          double e = 0;
          for (int k = 0; k <= order; ++k) {
            const auto ku = static_cast<std::size_t>(order - k), kv = static_cast<std::size_t>(k);
            e += c[kv] * Gu[ku](i, i2) * Gv[kv](j, j2);
          }
          K.at(g, di, dj) = e;
        }
      }
    }
  }
  return K;
}

Eigen::SparseMatrix<double> assemble_sparse(const BandedSymmetric& data, double scale_data,
                                            const BandedSymmetric& smooth, double scale_smooth) {
  const int nu = data.nu(), nv = data.nv(), p = data.p(), q = data.q();
  const int n = nu * nv;
  Eigen::SparseMatrix<double> A(n, n);
  A.reserve(Eigen::VectorXi::Constant(n, (2 * p + 1) * (2 * q + 1)));
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const int col = i * nv + j;
      // Rows in increasing order: di major, dj minor.
      for (int i2 = std::max(0, i - p); i2 <= std::min(nu - 1, i + p); ++i2) {
        for (int j2 = std::max(0, j - q); j2 <= std::min(nv - 1, j + q); ++j2) {
          const int row = i2 * nv + j2;
          const int lo = std::min(row, col);
          const int di = std::abs(i2 - i);
          const int dj = row >= col ? j2 - j : j - j2;
          A.insert(row, col) = scale_data * data.at(lo, di, dj) + scale_smooth * smooth.at(lo, di, dj);
        }
      }
    }
  }
  A.makeCompressed();
  return A;
}

}  // namespace photomill::fitsurf
