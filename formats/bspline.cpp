#include "formats/bspline.hpp"

#include <algorithm>
#include <stdexcept>

namespace photomill {

int find_span(int n, int p, double u, const std::vector<double>& U) {
  // A2.1, with the end of the domain mapped to the last non-empty span.
  if (u >= U[static_cast<std::size_t>(n + 1)]) {
    int span = n;
    while (span > p && U[static_cast<std::size_t>(span)] == U[static_cast<std::size_t>(span + 1)]) --span;
    return span;
  }
  if (u <= U[static_cast<std::size_t>(p)]) {
    int span = p;
    while (span < n && U[static_cast<std::size_t>(span + 1)] <= u) ++span;
    return span;
  }
  int low = p;
  int high = n + 1;
  int mid = (low + high) / 2;
  while (u < U[static_cast<std::size_t>(mid)] || u >= U[static_cast<std::size_t>(mid + 1)]) {
    if (u < U[static_cast<std::size_t>(mid)]) high = mid;
    else low = mid;
    mid = (low + high) / 2;
  }
  return mid;
}

void basis_funs(int i, double u, int p, const std::vector<double>& U, double* N) {
  // A2.2: N[0] = 1; N[j] from the triangular recurrence with left[j] = u - U[i+1-j],
  // right[j] = U[i+j] - u.
  std::array<double, kMaxBSplineDegree + 2> left, right;  // entries 1..p written before use
  N[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[static_cast<std::size_t>(j)] = u - U[static_cast<std::size_t>(i + 1 - j)];
    right[static_cast<std::size_t>(j)] = U[static_cast<std::size_t>(i + j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double denom = right[static_cast<std::size_t>(r + 1)] + left[static_cast<std::size_t>(j - r)];
      const double temp = denom == 0.0 ? 0.0 : N[r] / denom;
      N[r] = saved + right[static_cast<std::size_t>(r + 1)] * temp;
      saved = left[static_cast<std::size_t>(j - r)] * temp;
    }
    N[j] = saved;
  }
}

void ders_basis_funs(int i, double u, int p, int nd, const std::vector<double>& U, double* ders) {
  // A2.3: ndu holds the basis functions (upper triangle) and knot differences (lower);
  // a holds the two most recent rows of coefficients a_{k,j}.
  constexpr int M = kMaxBSplineDegree + 1;
  // Not value-initialised: the algorithm reads only entries it has written, and zeroing 27x26
  // doubles per call dominated toolpath's pass planning.
  std::array<std::array<double, M>, M> ndu;
  std::array<std::array<double, M>, 2> a;
  std::array<double, M + 1> left, right;
  const auto S = [](int k) { return static_cast<std::size_t>(k); };
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[S(j)] = u - U[S(i + 1 - j)];
    right[S(j)] = U[S(i + j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[S(j)][S(r)] = right[S(r + 1)] + left[S(j - r)];  // lower triangle
      const double temp = ndu[S(j)][S(r)] == 0.0 ? 0.0 : ndu[S(r)][S(j - 1)] / ndu[S(j)][S(r)];
      ndu[S(r)][S(j)] = saved + right[S(r + 1)] * temp;    // upper triangle
      saved = left[S(j - r)] * temp;
    }
    ndu[S(j)][S(j)] = saved;
  }
  const int stride = p + 1;
  for (int j = 0; j <= p; ++j) ders[j] = ndu[S(j)][S(p)];
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= nd; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[S(s2)][0] = ndu[S(pk + 1)][S(rk)] == 0.0 ? 0.0 : a[S(s1)][0] / ndu[S(pk + 1)][S(rk)];
        d = a[S(s2)][0] * ndu[S(rk)][S(pk)];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        const double den = ndu[S(pk + 1)][S(rk + j)];
        a[S(s2)][S(j)] = den == 0.0 ? 0.0 : (a[S(s1)][S(j)] - a[S(s1)][S(j - 1)]) / den;
        d += a[S(s2)][S(j)] * ndu[S(rk + j)][S(pk)];
      }
      if (r <= pk) {
        const double den = ndu[S(pk + 1)][S(r)];
        a[S(s2)][S(k)] = den == 0.0 ? 0.0 : -a[S(s1)][S(k - 1)] / den;
        d += a[S(s2)][S(k)] * ndu[S(r)][S(pk)];
      }
      ders[k * stride + r] = d;
      std::swap(s1, s2);
    }
  }
  int r = p;
  for (int k = 1; k <= nd; ++k) {
    for (int j = 0; j <= p; ++j) ders[k * stride + j] *= r;
    r *= (p - k);
  }
}

std::pair<double, double> domain_u(const BSplineSurface& s) {
  return {s.knots_u[static_cast<std::size_t>(s.degree_u)], s.knots_u[static_cast<std::size_t>(s.num_poles_u)]};
}
std::pair<double, double> domain_v(const BSplineSurface& s) {
  return {s.knots_v[static_cast<std::size_t>(s.degree_v)], s.knots_v[static_cast<std::size_t>(s.num_poles_v)]};
}

BasisRow basis_row(int n, int p, double u, const std::vector<double>& U) {
  BasisRow row;
  const int span = find_span(n, p, u, U);
  u = std::clamp(u, U[static_cast<std::size_t>(p)], U[static_cast<std::size_t>(n + 1)]);
  basis_funs(span, u, p, U, row.values.data());
  row.first = span - p;
  return row;
}

Eigen::Vector3d surface_point(const BSplineSurface& s, double u, double v) {
  // A3.5 (A4.3 in homogeneous coordinates when rational): S = sum_k sum_l Nu[k] Nv[l] P[..].
  const BasisRow bu = basis_row(s.num_poles_u - 1, s.degree_u, u, s.knots_u);
  const BasisRow bv = basis_row(s.num_poles_v - 1, s.degree_v, v, s.knots_v);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double w = 0.0;
  for (int k = 0; k <= s.degree_u; ++k) {
    const int i = bu.first + k;
    Eigen::Vector3d row = Eigen::Vector3d::Zero();
    double row_w = 0.0;
    for (int l = 0; l <= s.degree_v; ++l) {
      const int j = bv.first + l;
      const double b = bv.values[static_cast<std::size_t>(l)];
      if (s.rational()) {
        const double wij = s.weights[static_cast<std::size_t>(i) * s.num_poles_v + j];
        row += b * wij * s.pole(i, j);
        row_w += b * wij;
      } else {
        row += b * s.pole(i, j);
      }
    }
    sum += bu.values[static_cast<std::size_t>(k)] * row;
    w += bu.values[static_cast<std::size_t>(k)] * row_w;
  }
  return s.rational() ? Eigen::Vector3d(sum / w) : sum;
}

Eigen::Vector3d SurfaceDerivatives::normal() const {
  const Eigen::Vector3d n = su.cross(sv);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

SurfaceDerivatives surface_derivatives(const BSplineSurface& s, double u, double v) {
  // A3.6 on homogeneous points (x w, y w, z w, w); then A4.4's quotient rule for the rational
  // case: SKL = (Akl - sum_{i,j} binom * w_ij * SKL_{k-i,l-j}) / w.
  constexpr int d = 2;
  const int p = s.degree_u, q = s.degree_v;
  const int nu = s.num_poles_u - 1, nv = s.num_poles_v - 1;
  const auto [u0, u1] = domain_u(s);
  const auto [v0, v1] = domain_v(s);
  u = std::clamp(u, u0, u1);
  v = std::clamp(v, v0, v1);
  const int su = find_span(nu, p, u, s.knots_u);
  const int sv = find_span(nv, q, v, s.knots_v);
  std::array<double, 3 * (kMaxBSplineDegree + 1)> Nu, Nv;  // rows 0..du / 0..dv are written
  const int du = std::min(d, p), dv = std::min(d, q);
  ders_basis_funs(su, u, p, du, s.knots_u, Nu.data());
  ders_basis_funs(sv, v, q, dv, s.knots_v, Nv.data());
  // A[k][l] = homogeneous derivative d^{k+l}/du^k dv^l.
  Eigen::Vector4d A[3][3];
  for (auto& row : A) {
    for (auto& x : row) x.setZero();
  }
  for (int k = 0; k <= du; ++k) {
    for (int r = 0; r <= p; ++r) {
      const int i = su - p + r;
      const double nk = Nu[static_cast<std::size_t>(k * (p + 1) + r)];
      if (nk == 0.0) continue;
      for (int l = 0; l <= std::min(dv, d - k); ++l) {
        Eigen::Vector4d acc = Eigen::Vector4d::Zero();
        for (int c = 0; c <= q; ++c) {
          const int j = sv - q + c;
          const double w = s.rational() ? s.weights[static_cast<std::size_t>(i) * s.num_poles_v + j] : 1.0;
          const Eigen::Vector3d& P = s.pole(i, j);
          acc += Nv[static_cast<std::size_t>(l * (q + 1) + c)] * Eigen::Vector4d(P.x() * w, P.y() * w, P.z() * w, w);
        }
        A[k][l] += nk * acc;
      }
    }
  }
  Eigen::Vector3d S[3][3];
  const double w0 = A[0][0].w();
  static constexpr int binom[3][3] = {{1, 0, 0}, {1, 1, 0}, {1, 2, 1}};
  for (int k = 0; k <= d; ++k) {
    for (int l = 0; l <= d - k; ++l) {
      Eigen::Vector3d v3 = A[k][l].head<3>();
      for (int j = 1; j <= l; ++j) v3 -= binom[l][j] * A[0][j].w() * S[k][l - j];
      for (int i = 1; i <= k; ++i) {
        v3 -= binom[k][i] * A[i][0].w() * S[k - i][l];
        Eigen::Vector3d v2 = Eigen::Vector3d::Zero();
        for (int j = 1; j <= l; ++j) v2 += binom[l][j] * A[i][j].w() * S[k - i][l - j];
        v3 -= binom[k][i] * v2;
      }
      S[k][l] = v3 / w0;
    }
  }
  return {S[0][0], S[1][0], S[0][1], S[2][0], S[1][1], S[0][2]};
}

std::vector<double> clamped_uniform_knots(int num_poles, int degree, double a, double b) {
  if (num_poles < degree + 1 || degree < 1 || !(a < b)) throw std::invalid_argument("clamped_uniform_knots: bad arguments");
  std::vector<double> U;
  U.reserve(static_cast<std::size_t>(num_poles + degree + 1));
  for (int k = 0; k <= degree; ++k) U.push_back(a);
  const int interior = num_poles - degree - 1;
  for (int k = 1; k <= interior; ++k) U.push_back(a + (b - a) * k / (interior + 1));
  for (int k = 0; k <= degree; ++k) U.push_back(b);
  return U;
}

}  // namespace photomill
