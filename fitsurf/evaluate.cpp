// Non-rational surface evaluation from the shared basis functions (evaluate.hpp).
#include "fitsurf/evaluate.hpp"

#include <algorithm>
#include <array>

namespace photomill::fitsurf {

SurfaceDerivatives evaluate(const BSplineSurface& s, double u, double v, int order) {
  // A3.6 with w = 1: S^(k,l)(u,v) = sum_r sum_c N^(k)_{span_u-p+r}(u) N^(l)_{span_v-q+c}(v) P[..][..].
  const int p = s.degree_u, q = s.degree_v;
  const auto [u0, u1] = domain_u(s);
  const auto [v0, v1] = domain_v(s);
  u = std::clamp(u, u0, u1);
  v = std::clamp(v, v0, v1);
  const int su = find_span(s.num_poles_u - 1, p, u, s.knots_u);
  const int sv = find_span(s.num_poles_v - 1, q, v, s.knots_v);
  const int du = std::min(order, p), dv = std::min(order, q);
  std::array<double, 3 * (kMaxBSplineDegree + 1)> Nu, Nv;
  std::fill(Nu.begin(), Nu.begin() + 3 * (p + 1), 0.0);
  std::fill(Nv.begin(), Nv.begin() + 3 * (q + 1), 0.0);
  ders_basis_funs(su, u, p, du, s.knots_u, Nu.data());
  ders_basis_funs(sv, v, q, dv, s.knots_v, Nv.data());
  // Row sums T_l[r] = sum_c N^(l)(v)_c P[su-p+r][sv-q+c] for l = 0..dv, then combine along u.
  SurfaceDerivatives d;
  d.p = d.su = d.sv = d.suu = d.suv = d.svv = Eigen::Vector3d::Zero();
  for (int r = 0; r <= p; ++r) {
    const Eigen::Vector3d* row = &s.poles_mm[static_cast<std::size_t>(su - p + r) * s.num_poles_v + (sv - q)];
    Eigen::Vector3d t0 = Eigen::Vector3d::Zero(), t1 = Eigen::Vector3d::Zero(), t2 = Eigen::Vector3d::Zero();
    for (int c = 0; c <= q; ++c) {
      t0 += Nv[static_cast<std::size_t>(c)] * row[c];
      if (dv >= 1) t1 += Nv[static_cast<std::size_t>(q + 1 + c)] * row[c];
      if (dv >= 2) t2 += Nv[static_cast<std::size_t>(2 * (q + 1) + c)] * row[c];
    }
    const double n0 = Nu[static_cast<std::size_t>(r)];
    const double n1 = Nu[static_cast<std::size_t>(p + 1 + r)];
    const double n2 = Nu[static_cast<std::size_t>(2 * (p + 1) + r)];
    d.p += n0 * t0;
    d.su += n1 * t0;
    d.sv += n0 * t1;
    d.suu += n2 * t0;
    d.suv += n1 * t1;
    d.svv += n0 * t2;
  }
  return d;
}

}  // namespace photomill::fitsurf
