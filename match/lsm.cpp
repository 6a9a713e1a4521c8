#include "match/lsm.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace photomill::match {
namespace {

bool sample(const cv::Mat& im, double x, double y, double& v) {
  double gx, gy;
  return sample_cubic(im, x, y, v, gx, gy);
}

bool window_samples(const cv::Mat& f, const Eigen::Vector2d& ref_px, int h, std::vector<double>& out) {
  out.clear();
  for (int dy = -h; dy <= h; ++dy) {
    for (int dx = -h; dx <= h; ++dx) {
      double v;
      if (!sample(f, ref_px.x() + dx, ref_px.y() + dy, v)) return false;
      out.push_back(v);
    }
  }
  return true;
}

// Normalised cross-correlation of the reference window and the search image's samples at
// map(dx, dy), on every `stride`-th offset; nullopt where a sample leaves an image.
template <typename Map>
std::optional<double> window_correlation_of_map(const cv::Mat& f, const Eigen::Vector2d& ref_px, int h, const cv::Mat& g,
                                                Map map, int stride = 1) {
  std::vector<double> a, b;
  for (int dy = -h; dy <= h; dy += stride) {
    for (int dx = -h; dx <= h; dx += stride) {
      const Eigen::Vector2d x = map(dx, dy);
      double u, v;
      if (!sample(f, ref_px.x() + dx, ref_px.y() + dy, u) || !sample(g, x.x(), x.y(), v)) return std::nullopt;
      a.push_back(u);
      b.push_back(v);
    }
  }
  return correlation_of(a, b);
}

// One Gauss-Newton step's normal equations of lsm_align (see there) with n = 8 or 14 unknowns:
//   N = sum J J^T, b = sum J e
// over the window's samples, J and e as lsm_align states them. The sums are kept in plain arrays
// of compile-time size (the lower triangle of N, as Eigen's rank-one update of a lower
// selfadjoint view would add them, in the same order): a dynamic-size rank update per sample was
// a fifth of match's time. False if a sample leaves the search image.
template <int n>
bool normal_equations(const cv::Mat& g, const std::vector<double>& fv, int h, const Eigen::Matrix2d& B,
                      const Eigen::Vector2d& t, const Eigen::Matrix<double, 2, 3>& C, double r0, double r1,
                      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 14, 14>& N,
                      Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 14, 1>& b) {
  static_assert(n == 8 || n == 14);
  double Nl[n][n] = {};
  double bl[n] = {};
  const double scale = static_cast<double>(h);
  std::size_t k = 0;
  for (int dy = -h; dy <= h; ++dy) {
    for (int dx = -h; dx <= h; ++dx, ++k) {
      const Eigen::Vector2d d(dx / scale, dy / scale);
      const Eigen::Vector3d m(d.x() * d.x(), d.x() * d.y(), d.y() * d.y());
      const Eigen::Vector2d x = B * d + t + C * m;
      double v, gx, gy;
      if (!sample_cubic(g, x.x(), x.y(), v, gx, gy)) return false;
      double J[n];
      J[0] = r1 * gx * d.x();
      J[1] = r1 * gx * d.y();
      J[2] = r1 * gy * d.x();
      J[3] = r1 * gy * d.y();
      J[4] = r1 * gx;
      J[5] = r1 * gy;
      J[6] = 1.0;
      J[7] = v;
      if constexpr (n == 14) {
        for (int q = 0; q < 3; ++q) {
          J[8 + q] = r1 * gx * m[q];
          J[11 + q] = r1 * gy * m[q];
        }
      }
      const double e = fv[k] - r0 - r1 * v;
      for (int i = 0; i < n; ++i) {
        for (int j = i; j < n; ++j) Nl[i][j] += J[i] * J[j];
        bl[i] += J[i] * e;
      }
    }
  }
  for (int i = 0; i < n; ++i) {
    b[i] = bl[i];
    for (int j = i; j < n; ++j) N(i, j) = N(j, i) = Nl[i][j];
  }
  return true;
}

}  // namespace

double correlation_of(std::span<const double> a, std::span<const double> b) {
  const double n = static_cast<double>(a.size());
  double sa = 0, sb = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    sa += a[k];
    sb += b[k];
  }
  const double ma = sa / n, mb = sb / n;
  double saa = 0, sbb = 0, sab = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double da = a[k] - ma, db = b[k] - mb;
    saa += da * da;
    sbb += db * db;
    sab += da * db;
  }
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 0.0;
}

const char* to_string(LsmFailure f) {
  switch (f) {
    case LsmFailure::None: return "none";
    case LsmFailure::Border: return "window leaves the image";
    case LsmFailure::Singular: return "no texture";
    case LsmFailure::NotConverged: return "not converged";
    case LsmFailure::Shift: return "moved too far";
    case LsmFailure::Zoom: return "window distorted";
    case LsmFailure::Correlation: return "low correlation";
  }
  return "?";
}

int half_window_for(double ref_size_px, const LsmOptions& o) {
  const double h = std::round(o.window_per_size * ref_size_px);
  return static_cast<int>(std::clamp(h, static_cast<double>(o.min_half_window_px), static_cast<double>(o.max_half_window_px)));
}

std::optional<double> window_correlation(const cv::Mat& f, const Eigen::Vector2d& ref_px, int h, const cv::Mat& g,
                                         const Eigen::Matrix2d& A, const Eigen::Vector2d& t, int stride) {
  return window_correlation_of_map(
      f, ref_px, h, g, [&](int dx, int dy) { return Eigen::Vector2d(A * Eigen::Vector2d(dx, dy) + t); }, stride);
}

// Gauss-Newton on the 8 parameters p = (a11, a12, a21, a22, t1, t2, r0, r1) of
//   e(d) = f(p_ref + d) - r0 - r1 * g(A d + t),
// with the Jacobian of the model r0 + r1 g(A d + t):
//   d/da_ij = r1 * dg/dx_i * d_j,  d/dt_i = r1 * dg/dx_i,  d/dr0 = 1,  d/dr1 = g,
// and the normal equations (J^T J) dp = J^T e solved by LDL^T (Gruen 1985, eq. 8-12).
// With `quadratic`, six more: g is sampled at A d + t + C m, m = (dx^2, dx dy, dy^2), and
//   d/dc_ik = r1 * dg/dx_i * m_k (Bethmann & Luhmann 2010).
// The offsets d are scaled by 1/h inside the solve so the unknowns are of similar size.
std::optional<LsmResult> lsm_align(const cv::Mat& f, const Eigen::Vector2d& ref_px, int h, const cv::Mat& g,
                                   const Eigen::Matrix2d& A0, const Eigen::Vector2d& t0, const LsmOptions& o,
                                   LsmFailure* why) {
  auto fail = [&](LsmFailure w) -> std::optional<LsmResult> {
    if (why) *why = w;
    return std::nullopt;
  };
  std::vector<double> fv;
  if (!window_samples(f, ref_px, h, fv)) return fail(LsmFailure::Border);
  const double scale = static_cast<double>(h);
  // B = A * h: maps scaled offsets (d / h) to search-image offsets.
  Eigen::Matrix2d B = A0 * scale;
  Eigen::Vector2d t = t0;
  double r0 = 0, r1 = 1;
  {
    // Start the radiometry from the two windows' means and spreads.
    std::vector<double> gv;
    for (int dy = -h; dy <= h; ++dy) {
      for (int dx = -h; dx <= h; ++dx) {
        const Eigen::Vector2d x = A0 * Eigen::Vector2d(dx, dy) + t0;
        double v;
        if (!sample(g, x.x(), x.y(), v)) return fail(LsmFailure::Border);
        gv.push_back(v);
      }
    }
    double mf = 0, mg = 0, sf = 0, sg = 0;
    for (std::size_t k = 0; k < fv.size(); ++k) {
      mf += fv[k];
      mg += gv[k];
    }
    mf /= static_cast<double>(fv.size());
    mg /= static_cast<double>(fv.size());
    for (std::size_t k = 0; k < fv.size(); ++k) {
      sf += (fv[k] - mf) * (fv[k] - mf);
      sg += (gv[k] - mg) * (gv[k] - mg);
    }
    if (!(sf > 0 && sg > 0)) return fail(LsmFailure::Singular);
    r1 = std::sqrt(sf / sg);
    r0 = mf - r1 * mg;
  }
  const double zoom0 = std::sqrt(std::abs(A0.determinant()));
  // The quadratic terms C (2 x 3, on the scaled offsets' monomials dx^2, dx dy, dy^2) start at 0.
  using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 14, 14>;
  using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 14, 1>;
  // With `quadratic`, the affine model converges first and the quadratic terms are added from
  // there (each stage with max_iterations): fewer alignments left unconverged than with all 14
  // unknowns from the start (on the demo 7 551 refused instead of 12 545).
  int n = 8;
  Eigen::Matrix<double, 2, 3> C = Eigen::Matrix<double, 2, 3>::Zero();
  bool converged = false;
  int it = 0;
  for (int stage_it = 0; stage_it < o.max_iterations && !converged; ++it, ++stage_it) {
    Mat N(n, n);
    Vec b(n);
    const bool inside = n == 14 ? normal_equations<14>(g, fv, h, B, t, C, r0, r1, N, b)
                                : normal_equations<8>(g, fv, h, B, t, C, r0, r1, N, b);
    if (!inside) return fail(LsmFailure::Border);
    const Eigen::LDLT<Mat> ldlt(N);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * ldlt.vectorD().maxCoeff())) {
      return fail(LsmFailure::Singular);
    }
    const Vec dp = ldlt.solve(b);
    if (!dp.allFinite()) return fail(LsmFailure::Singular);
    B(0, 0) += dp[0];
    B(0, 1) += dp[1];
    B(1, 0) += dp[2];
    B(1, 1) += dp[3];
    t += dp.segment<2>(4);
    r0 += dp[6];
    r1 += dp[7];
    double bend = 0;  // the quadratic part's largest move at a window corner (|m| <= 1 each)
    if (n == 14) {
      C.row(0) += dp.segment<3>(8).transpose();
      C.row(1) += dp.segment<3>(11).transpose();
      bend = dp.tail<6>().cwiseAbs().maxCoeff() * 3;
    }
    // The largest move of any window corner (|d / h| <= sqrt 2) and of the point.
    const double corner = std::sqrt(2.0) * dp.head<4>().cwiseAbs().maxCoeff() + bend;
    converged = dp.segment<2>(4).norm() < o.converged_px && corner < o.converged_px;
    if (converged && o.quadratic && n == 8) {
      n = 14;
      converged = false;
      stage_it = -1;
    }
    if ((t - t0).norm() > o.max_shift_px) return fail(LsmFailure::Shift);
  }
  if (!converged) return fail(LsmFailure::NotConverged);
  const Eigen::Matrix2d A = B / scale;
  const double zoom = std::sqrt(std::abs(A.determinant())) / zoom0;
  if (!(A.determinant() * A0.determinant() > 0) || zoom > o.max_zoom || zoom < 1 / o.max_zoom) {
    return fail(LsmFailure::Zoom);
  }
  const auto c = window_correlation_of_map(f, ref_px, h, g, [&](int dx, int dy) {
    const Eigen::Vector2d d(dx / scale, dy / scale);
    return Eigen::Vector2d(B * d + t + C * Eigen::Vector3d(d.x() * d.x(), d.x() * d.y(), d.y() * d.y()));
  });
  if (!c) return fail(LsmFailure::Border);
  if (*c < o.min_correlation) return fail(LsmFailure::Correlation);
  if (why) *why = LsmFailure::None;
  return LsmResult{t, A, *c, it};
}

}  // namespace photomill::match
