// ArUco marker detection and edge-model corner refinement (contract and model in markers.hpp).
#include "detect/markers.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>

#include <Eigen/Dense>
#include <opencv2/aruco.hpp>

#include "detect/boards.hpp"
#include "formats/error.hpp"

namespace photomill::detect {
namespace {

constexpr double kInvSqrt2 = 0.70710678118654752440;
constexpr double kInvSqrt2Pi = 0.39894228040143267794;
constexpr double kMinSigmaPx = 0.05;

double normal_pdf(double z) { return kInvSqrt2Pi * std::exp(-0.5 * z * z); }
double normal_cdf(double z) { return 0.5 * std::erfc(-z * kInvSqrt2); }

// Phi and phi by cubic Hermite interpolation in a table over [-8.5, 8.5] (step 1/64), using the
// known derivatives (Phi' = phi, phi' = -z phi): error below 1e-9, a sixth of libm's cost (the
// edge fit evaluates them tens of millions of times per photo set). Outside, Phi is 0 or 1.
class NormalTable {
public:
  NormalTable() {
    for (int k = 0; k < kSize; ++k) {
      const double z = kLow + k * kStep;
      cdf_[k] = normal_cdf(z);
      pdf_[k] = normal_pdf(z);
    }
  }
  // Phi(z) and phi(z).
  void operator()(double z, double& cdf, double& pdf) const {
    const double u = (z - kLow) / kStep;
    if (!(u >= 0)) {
      cdf = pdf = 0;
      return;
    }
    const int k = static_cast<int>(u);
    if (k >= kSize - 1) {
      cdf = 1;
      pdf = 0;
      return;
    }
    const double t = u - k, t2 = t * t, t3 = t2 * t;
    const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t, h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    const double z0 = kLow + k * kStep, z1 = z0 + kStep;
    cdf = h00 * cdf_[k] + h10 * kStep * pdf_[k] + h01 * cdf_[k + 1] + h11 * kStep * pdf_[k + 1];
    pdf = h00 * pdf_[k] - h10 * kStep * z0 * pdf_[k] + h01 * pdf_[k + 1] - h11 * kStep * z1 * pdf_[k + 1];
  }

private:
  static constexpr double kLow = -8.5, kStep = 1.0 / 64;
  static constexpr int kSize = 17 * 64 + 2;
  std::array<double, kSize> cdf_{}, pdf_{};
};

const NormalTable& normal_table() {
  static const NormalTable table;
  return table;
}

// The pixel-integrated blurred step R(x; sigma) and its derivatives. A unit pixel square seen
// across an edge of unit normal n is the convolution of two boxes of widths a = |n_x| and
// b = |n_y| (a trapezoid); with the Gaussian PSF and the step, integrated twice:
//   G0(x) = Phi(x/s),  G1(x) = x Phi(x/s) + s phi(x/s),  G2(x) = (x^2 + s^2)/2 Phi(x/s) + x s/2 phi(x/s)
//   R(x) = [G2(x + h1) - G2(x + h2) - G2(x - h2) + G2(x - h1)] / (a b),  h1 = (a + b)/2, h2 = (a - b)/2
//   dR/dx = the same second difference of G1 / (a b),  dR/ds = s (the same of G0) / (a b)
// (dG2/ds = s Phi(x/s)). For an edge along a pixel axis (b -> 0) the trapezoid is the unit box:
//   R(x) = G1(x + 1/2) - G1(x - 1/2),  dR/dx = G0(x + 1/2) - G0(x - 1/2),  dR/ds = phi(..) - phi(..).
struct Response {
  double r, dr_dx, dr_dsigma;
};
constexpr double kMinTrapezoid = 0.05;  // below this b the unit box is exact to ~1e-4 px
struct Footprint {
  double a = 1, b = 0;  // |n_x|, |n_y| ordered so that a >= b
  // The response's constants: whether it is the unit box (b < kMinTrapezoid), h1, h2, 1 / (a b).
  bool box = true;
  double h1 = 0.5, h2 = 0, inv_ab = 0;
  static Footprint across(const Eigen::Vector2d& n) {
    const double x = std::abs(n.x()), y = std::abs(n.y());
    Footprint fp;
    fp.a = std::max(x, y);
    fp.b = std::min(x, y);
    fp.box = fp.b < kMinTrapezoid;
    if (!fp.box) {
      fp.h1 = 0.5 * (fp.a + fp.b);
      fp.h2 = 0.5 * (fp.a - fp.b);
      fp.inv_ab = 1 / (fp.a * fp.b);
    }
    return fp;
  }
};

// `inv_sigma` = 1 / sigma (the callers evaluate many x for one sigma).
Response edge_response(double x, double sigma, double inv_sigma, const Footprint& fp) {
  const double h1 = fp.h1;
  // Beyond 6 sigma Phi is 0 or 1 to 1e-9 and phi below 6.1e-9, the table's own accuracy: the
  // pixel is plain white or black (to 1e-6 grey levels at any contrast).
  if ((x - h1) * inv_sigma > 6) return {1, 0, 0};
  if ((x + h1) * inv_sigma < -6) return {0, 0, 0};
  const NormalTable& normal = normal_table();
  if (fp.box) {
    double cp, cm, pp, pm;
    normal((x + 0.5) * inv_sigma, cp, pp);
    normal((x - 0.5) * inv_sigma, cm, pm);
    return {(x + 0.5) * cp + sigma * pp - (x - 0.5) * cm - sigma * pm, cp - cm, pp - pm};
  }
  const double h2 = fp.h2;
  const double offsets[4] = {h1, h2, -h2, -h1};
  const double signs[4] = {1, -1, -1, 1};
  double g0 = 0, g1 = 0, g2 = 0;
  for (int k = 0; k < 4; ++k) {
    const double u = x + offsets[k];
    double cdf, pdf;
    normal(u * inv_sigma, cdf, pdf);
    g0 += signs[k] * cdf;
    g1 += signs[k] * (u * cdf + sigma * pdf);
    g2 += signs[k] * (0.5 * (u * u + sigma * sigma) * cdf + 0.5 * u * sigma * pdf);
  }
  return {g2 * fp.inv_ab, g1 * fp.inv_ab, sigma * g0 * fp.inv_ab};
}

// One edge of the initial quadrilateral: t along it from `origin`, s across it, outwards.
struct EdgeFrame {
  Eigen::Vector2d origin, d, n;
  double length = 0;
};

// The fitted edge: s = f(tau), tau = t / length - 1/2, f a polynomial with coefficients c.
struct EdgeCurve {
  EdgeFrame frame;
  Eigen::VectorXd c;
  double sigma = 0, contrast = 0, rms = 0;
  std::array<double, 6> shading{};  // a0 a1 a2 b0 b1 b2 (the model's levels, fit_edge_model)
  double band_px = 0;  // the band's half-width in the last round
  double f(double tau) const {
    double v = 0;
    for (Eigen::Index j = c.size() - 1; j >= 0; --j) v = v * tau + c[j];
    return v;
  }
  double df(double tau) const {
    double v = 0;
    for (Eigen::Index j = c.size() - 1; j >= 1; --j) v = v * tau + static_cast<double>(j) * c[j];
    return v;
  }
  // Signed distance-like function, zero on the curve, and its gradient in the image.
  double g(const Eigen::Vector2d& p) const {
    const Eigen::Vector2d q = p - frame.origin;
    return frame.n.dot(q) - f(frame.d.dot(q) / frame.length - 0.5);
  }
  Eigen::Vector2d grad(const Eigen::Vector2d& p) const {
    const double tau = frame.d.dot(p - frame.origin) / frame.length - 0.5;
    return frame.n - df(tau) / frame.length * frame.d;
  }
};

// `inner`: how white the code cell inside the border is at this sample's place along the edge
// (0: a black cell or the border's own corner cells; 1: a white cell), `border_px` the border's
// width across the edge there. Both 0 where the code is unknown.
struct Sample {
  double tau, s, value;
  double inner = 0, border_px = 0;
};

// The code cells next to one edge's border, for the model's inner term (markers.hpp). Edge
// coordinates (a, d) in cells: a along the edge from its first corner, d inwards from its outer
// line; `image_from_edge` maps (a, d, 1) to image pixels (the homography through the marker's
// corners), `edge_from_image` back. `white[j]`: the code cell at a in [j + 1, j + 2], d in [1, 2].
struct InnerCode {
  Eigen::Matrix3d image_from_edge, edge_from_image;
  std::vector<double> white;
  double cell_px = 0;  // mean cell length along the edge, px
};

// The other edge at one end of an edge: the line through the corner along that edge, with its
// unit normal pointing into the marker, and the sine of the interior angle there.
struct NeighbourEdge {
  Eigen::Vector2d corner, inward;
  double sin_a = 1;
};

// Pixels (centres at integer coordinates) with t in [t0, t1] and |s - f(tau)| <= w, minus those the
// neighbouring edges' transitions reach: a pixel less than delta inside this edge (s - f < delta)
// must also lie delta or more inside each neighbouring edge (delta = blur reach). Near a corner
// this trims the inner side of the band only, so the transition itself is used up to delta /
// sin(alpha) from the corner.
using Levels = std::array<double, 256>;  // grey value -> intensity fitted (see EdgeFitOptions::gamma)

// With `code` (the marker's decoded cells), each sample also gets the code cell inside the border
// at its place along the edge and the border's width there (Sample); the cell's ends along the edge
// are blurred by sigma_px and the pixel (sqrt(sigma^2 + 1/12), the box's variance).
std::vector<Sample> band_samples(const cv::Mat& grey, const Levels& levels, const EdgeFrame& e, double t0, double t1,
                                 double w, const EdgeCurve* curve, const std::array<NeighbourEdge, 2>& neighbours,
                                 double delta, const InnerCode* code, double sigma_px) {
  double reach = w;
  if (curve) {
    for (double tau : {t0 / e.length - 0.5, 0.5 * (t0 + t1) / e.length - 0.5, t1 / e.length - 0.5}) {
      reach = std::max(reach, w + std::abs(curve->f(tau)));
    }
  }
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (double t : {t0, t1}) {
    for (double s : {-reach, reach}) {
      const Eigen::Vector2d p = e.origin + t * e.d + s * e.n;
      x_lo = std::min(x_lo, p.x()), x_hi = std::max(x_hi, p.x());
      y_lo = std::min(y_lo, p.y()), y_hi = std::max(y_hi, p.y());
    }
  }
  const int c0 = std::max(0, static_cast<int>(std::floor(x_lo))), c1 = std::min(grey.cols - 1, static_cast<int>(std::ceil(x_hi)));
  const int r0 = std::max(0, static_cast<int>(std::floor(y_lo))), r1 = std::min(grey.rows - 1, static_cast<int>(std::ceil(y_hi)));
  std::vector<Sample> out;
  out.reserve(static_cast<std::size_t>(r1 - r0 + 1) * static_cast<std::size_t>(c1 - c0 + 1));
  const double inv_cell_blur = 1 / std::sqrt(sigma_px * sigma_px + 1.0 / 12);
  // On row y, t = d.x (x - ox) + d.y (y - oy) and s = n.x (x - ox) + n.y (y - oy) are linear in x:
  // the columns with t in [t0, t1] and |s| <= reach are an interval, the only ones visited.
  auto narrow = [](double coef, double rest, double lo, double hi, double& x_min, double& x_max) {
    if (std::abs(coef) < 1e-12) {
      if (rest < lo || rest > hi) x_max = -1e300;  // no column of this row
      return;
    }
    double a = (lo - rest) / coef, b = (hi - rest) / coef;
    if (a > b) std::swap(a, b);
    x_min = std::max(x_min, a);
    x_max = std::min(x_max, b);
  };
  for (int y = r0; y <= r1; ++y) {
    const auto* row = grey.ptr<std::uint8_t>(y);
    double x_min = c0, x_max = c1;
    const double dy = y - e.origin.y();
    narrow(e.d.x(), e.d.y() * dy - e.d.x() * e.origin.x(), t0, t1, x_min, x_max);
    narrow(e.n.x(), e.n.y() * dy - e.n.x() * e.origin.x(), -reach, reach, x_min, x_max);
    if (!(x_min <= x_max)) continue;
    const int xa = std::max(c0, static_cast<int>(std::floor(x_min)) - 1);
    const int xb = std::min(c1, static_cast<int>(std::ceil(x_max)) + 1);
    for (int x = xa; x <= xb; ++x) {
      const Eigen::Vector2d p(x, y);
      const Eigen::Vector2d q = p - e.origin;
      const double t = e.d.dot(q);
      if (t < t0 || t > t1) continue;
      const double tau = t / e.length - 0.5;
      const double s = e.n.dot(q);
      const double across = s - (curve ? curve->f(tau) : 0.0);
      if (std::abs(across) > w) continue;
      if (across < delta && (neighbours[0].inward.dot(p - neighbours[0].corner) < delta ||
                             neighbours[1].inward.dot(p - neighbours[1].corner) < delta)) {
        continue;
      }
      Sample smp{tau, s, levels[row[x]]};
      if (code) {
        const Eigen::Vector3d h = code->edge_from_image * Eigen::Vector3d(x, y, 1);
        const double a = h.x() / h.z();
        const Eigen::Vector3d outer = code->image_from_edge * Eigen::Vector3d(a, 0, 1);
        const Eigen::Vector3d inner = code->image_from_edge * Eigen::Vector3d(a, 1, 1);
        smp.border_px = e.n.dot(outer.head<2>() / outer.z() - inner.head<2>() / inner.z());
        for (std::size_t j = 0; j < code->white.size(); ++j) {
          if (code->white[j] == 0) continue;
          const double lo = (a - static_cast<double>(j + 1)) * code->cell_px * inv_cell_blur;
          const double hi = (a - static_cast<double>(j + 2)) * code->cell_px * inv_cell_blur;
          smp.inner += code->white[j] * (normal_cdf(lo) - normal_cdf(hi));
        }
      }
      out.push_back(smp);
    }
  }
  return out;
}

// The model's value at a sample, for parameters laid out as below (NC = D + 1 curve coefficients).
// Shading: a = a0 + a1 tau + a2 s, b = b0 + b1 tau + b2 s (s in px): on a curved part the light
// changes along and across the edge, and an unmodelled slope across it would shift the edge.
template <int NC, typename Vec>
double model_value(const Vec& p, double inv_sigma, const Sample& smp, const Footprint& fp, Response* out = nullptr) {
  double f = 0;
  for (int j = NC - 1; j >= 0; --j) f = f * smp.tau + p[j];
  Response resp = edge_response(smp.s - f, p[NC], inv_sigma, fp);
  if (smp.inner > 0) {
    // The inner term: where the code cell inside the border is white, the intensity rises again
    // one border width further in (markers.hpp).
    const Response in = edge_response(smp.s - f + smp.border_px, p[NC], inv_sigma, fp);
    resp.r += smp.inner * (1 - in.r);
    resp.dr_dx -= smp.inner * in.dr_dx;
    resp.dr_dsigma -= smp.inner * in.dr_dsigma;
  }
  if (out) *out = resp;
  const double a = p[NC + 1] + p[NC + 2] * smp.tau + p[NC + 3] * smp.s;
  const double b = p[NC + 4] + p[NC + 5] * smp.tau + p[NC + 6] * smp.s;
  return a + b * resp.r;
}

// Levenberg-Marquardt fit of the edge model to the band samples. Parameter layout (NC = D + 1):
//   x[0..D] = c_0..c_D (px), x[NC] = sigma (px), x[NC+1..NC+3] = a0 a1 a2, x[NC+4..NC+6] = b0 b1 b2
// Residual r_i = I_i - m(tau_i, s_i; x); the Jacobian J = dm/dx:
//   dm/dc_j = -b R'(s - f) tau^j,  dm/dsigma = b dR/dsigma,
//   dm/d(a0, a1, a2) = (1, tau, s),  dm/d(b0, b1, b2) = (1, tau, s) R.
// Step: (J^T J + lambda diag(J^T J)) dx = J^T r (Marquardt's scaling); lambda is divided by 3 after
// a successful step and doubled after a failed one. Stops when the curve moves less than
// `tolerance_px`. `ok` is false if it cannot decrease the cost at all. `top_z` is the highest
// curve coefficient over its standard error, |c_D| / sqrt(s^2 [(J^T J)^-1]_DD) with
// s^2 = cost / (N - P): below ~3 the data do not need that degree.
struct ModelFit {
  bool ok = false;
  double top_z = 0;
  Eigen::MatrixXd normal;  // J^T J at the solution
  double cost = 0;         // sum of squared residuals there
  int iterations = 0;      // Levenberg-Marquardt iterations, rejected trials included
};

template <int NC>
ModelFit fit_edge_model(const std::vector<Sample>& samples, const Footprint& fp, int max_iterations, double max_sigma,
                        double tolerance_px, Eigen::VectorXd& x_io) {
  constexpr int P = NC + 7;
  using Vec = Eigen::Matrix<double, P, 1>;
  using Mat = Eigen::Matrix<double, P, P>;
  // The model's responses at every sample for parameters p, into `out`; returns the cost.
  auto responses = [&](const Vec& p, std::vector<Response>& out) {
    double cost = 0;
    const double inv_sigma = 1 / p[NC];
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const double r = samples[i].value - model_value<NC>(p, inv_sigma, samples[i], fp, &out[i]);
      cost += r * r;
    }
    return cost;
  };
  // J^T J and J^T r at p from its responses `rs`. A sample on a plateau of the model (R' = dR/dsigma
  // = 0: beyond the blur's reach of the edge, most of the band) has the row (0, .., 0, u, R u),
  // u = (1, tau, s), so its share of J^T J is u u^T, R u u^T and R^2 u u^T in the shading blocks:
  // those sums are kept as 3 x 3 moments (and r u, r R u for J^T r). The other samples' rows go
  // into `J_rows` for one symmetric rank update (Eigen's blocked, vectorised kernels).
  Eigen::Matrix<double, Eigen::Dynamic, P> J_rows(static_cast<Eigen::Index>(samples.size()), P);
  Eigen::VectorXd residuals(static_cast<Eigen::Index>(samples.size()));
  auto normal = [&](const Vec& p, const std::vector<Response>& rs, Mat& JtJ, Vec& Jtr) {
    // Plateau sums of the monomials (1, tau, s, tau^2, tau s, s^2) weighted by 1, R and R^2, and of
    // r (1, tau, s) and r R (1, tau, s).
    std::array<double, 6> w0{}, w1{}, w2{};
    std::array<double, 3> g0{}, g1{};
    Eigen::Index rows = 0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const Sample& smp = samples[i];
      const Response& resp = rs[i];
      const double a = p[NC + 1] + p[NC + 2] * smp.tau + p[NC + 3] * smp.s;
      const double b = p[NC + 4] + p[NC + 5] * smp.tau + p[NC + 6] * smp.s;
      const double r = smp.value - (a + b * resp.r);
      if (resp.dr_dx == 0 && resp.dr_dsigma == 0) {
        const std::array<double, 6> mono{1, smp.tau, smp.s, smp.tau * smp.tau, smp.tau * smp.s, smp.s * smp.s};
        for (std::size_t k = 0; k < 6; ++k) w0[k] += mono[k];
        for (std::size_t k = 0; k < 3; ++k) g0[k] += r * mono[k];
        if (resp.r != 0) {
          const double R2 = resp.r * resp.r, rR = r * resp.r;
          for (std::size_t k = 0; k < 6; ++k) w1[k] += resp.r * mono[k], w2[k] += R2 * mono[k];
          for (std::size_t k = 0; k < 3; ++k) g1[k] += rR * mono[k];
        }
        continue;
      }
      residuals[rows] = r;
      double tj = 1;
      for (int j = 0; j < NC; ++j, tj *= smp.tau) J_rows(rows, j) = -b * resp.dr_dx * tj;
      J_rows(rows, NC) = b * resp.dr_dsigma;
      J_rows(rows, NC + 1) = 1;
      J_rows(rows, NC + 2) = smp.tau;
      J_rows(rows, NC + 3) = smp.s;
      J_rows(rows, NC + 4) = resp.r;
      J_rows(rows, NC + 5) = smp.tau * resp.r;
      J_rows(rows, NC + 6) = smp.s * resp.r;
      ++rows;
    }
    JtJ.setZero();
    JtJ.template selfadjointView<Eigen::Lower>().rankUpdate(J_rows.topRows(rows).transpose());
    JtJ = JtJ.template selfadjointView<Eigen::Lower>();
    Jtr.noalias() = J_rows.topRows(rows).transpose() * residuals.head(rows);
    auto moments = [](const std::array<double, 6>& w) {
      Eigen::Matrix3d m;
      m << w[0], w[1], w[2], w[1], w[3], w[4], w[2], w[4], w[5];
      return m;
    };
    const Eigen::Matrix3d m1 = moments(w1);
    JtJ.template block<3, 3>(NC + 1, NC + 1) += moments(w0);
    JtJ.template block<3, 3>(NC + 4, NC + 1) += m1;
    JtJ.template block<3, 3>(NC + 1, NC + 4) += m1;
    JtJ.template block<3, 3>(NC + 4, NC + 4) += moments(w2);
    Jtr.template segment<3>(NC + 1) += Eigen::Vector3d(g0[0], g0[1], g0[2]);
    Jtr.template segment<3>(NC + 4) += Eigen::Vector3d(g1[0], g1[1], g1[2]);
  };
  // The responses at x are kept, so an accepted trial's are not computed again for its J.
  std::vector<Response> at_x(samples.size()), at_trial(samples.size());
  Vec x = x_io;
  Mat JtJ;
  Vec Jtr;
  double cost = responses(x, at_x);
  normal(x, at_x, JtJ, Jtr);
  bool normal_current = true;  // JtJ and Jtr are those of x
  double lambda = 1e-3;
  bool improved = false, converged = false;
  // How far a step moves the curve: |df(tau)| <= sum_j |dc_j| 2^-j over tau in [-1/2, 1/2].
  auto curve_movement = [](const Vec& step) {
    double m = 0;
    for (int j = 0; j < NC; ++j) m += std::abs(step[j]) * std::ldexp(1.0, -j);
    return m;
  };
  int iterations = 0;
  for (int it = 0; it < max_iterations; ++it, ++iterations) {
    Mat A = JtJ;
    A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
    Vec dx = A.ldlt().solve(Jtr);
    if (!dx.allFinite()) break;
    // A step that takes sigma out of its range [kMinSigmaPx, 2 max_sigma]: sigma's step is set
    // to reach the bound and the others solved for given it (the bound is active). Clamping
    // sigma after an unconstrained solve instead leaves the other parameters' step wrong, the
    // trial fails, and lambda grows until the step is nothing.
    const double sigma_to = std::clamp(x[NC] + dx[NC], kMinSigmaPx, max_sigma * 2);
    if (sigma_to != x[NC] + dx[NC]) {
      const double fixed = sigma_to - x[NC];
      Vec rhs = Jtr - A.col(NC) * fixed;
      A.row(NC).setZero();
      A.col(NC).setZero();
      A(NC, NC) = 1;
      rhs[NC] = fixed;
      dx = A.ldlt().solve(rhs);
      if (!dx.allFinite()) break;
    }
    if (curve_movement(dx) < tolerance_px && std::abs(dx[NC]) < tolerance_px) {
      converged = true;  // x is a solution already (a start from a converged fit)
      break;
    }
    Vec trial = x + dx;
    trial[NC] = std::clamp(trial[NC], kMinSigmaPx, max_sigma * 2);
    const double trial_cost = responses(trial, at_trial);
    if (trial_cost < cost) {
      const Vec step = trial - x;  // sigma may have been clamped
      x = trial;
      cost = trial_cost;
      std::swap(at_x, at_trial);
      normal_current = false;
      improved = true;
      lambda = std::max(lambda / 3, 1e-9);
      if (curve_movement(step) < tolerance_px && std::abs(step[NC]) < tolerance_px) break;
      normal(x, at_x, JtJ, Jtr);
      normal_current = true;
    } else {
      lambda *= 2;
      if (lambda > 1e8) break;
    }
  }
  if (!normal_current) normal(x, at_x, JtJ, Jtr);
  x_io = x;
  ModelFit result;
  result.ok = improved || converged || cost == 0;
  result.normal = JtJ;
  result.cost = cost;
  result.iterations = iterations;
  const double dof = static_cast<double>(samples.size()) - P;
  const double var = JtJ.inverse()(NC - 1, NC - 1) * cost / std::max(1.0, dof);
  result.top_z = var > 0 ? std::abs(x[NC - 1]) / std::sqrt(var) : 0;
  return result;
}

// RMS residual of the fitted model.
template <int NC>
double model_rms(const std::vector<Sample>& samples, const Footprint& fp, const Eigen::VectorXd& x) {
  double sum_sq = 0;
  const double inv_sigma = 1 / x[NC];
  for (const Sample& smp : samples) {
    const double r = smp.value - model_value<NC>(x, inv_sigma, smp, fp);
    sum_sq += r * r;
  }
  return std::sqrt(sum_sq / static_cast<double>(samples.size()));
}

double model_rms(const std::vector<Sample>& samples, const Footprint& fp, int degree, const Eigen::VectorXd& x) {
  switch (degree) {
    case 1: return model_rms<2>(samples, fp, x);
    case 2: return model_rms<3>(samples, fp, x);
    default: return model_rms<4>(samples, fp, x);
  }
}

ModelFit fit_edge_model(const std::vector<Sample>& samples, const Footprint& fp, int degree, int max_iterations,
                        double max_sigma, double tolerance_px, Eigen::VectorXd& x) {
  switch (degree) {
    case 1: return fit_edge_model<2>(samples, fp, max_iterations, max_sigma, tolerance_px, x);
    case 2: return fit_edge_model<3>(samples, fp, max_iterations, max_sigma, tolerance_px, x);
    default: return fit_edge_model<4>(samples, fp, max_iterations, max_sigma, tolerance_px, x);
  }
}

// Lowers the degree of a converged fit without fitting again. With H = J^T J at the solution x^,
// the Gauss-Newton model of the cost, cost^ + (x - x^)^T H (x - x^), is least under c_D = 0 at
//   x_r = x^_r + H_rr^-1 H_rD c_D  (r: the other parameters),  cost = cost^ + c_D^2 / [H^-1]_DD,
// and H_rr is the lower-degree problem's H: exact for a model linear in x, a close start for this
// one. Drops c_D while it is below `significance` standard errors (ModelFit::top_z, with
// s^2 = cost / (n - P)); returns the new degree, x shortened to match.
int drop_insignificant_degrees(Eigen::VectorXd& x, int degree, Eigen::MatrixXd H, double cost, double n,
                               double significance) {
  while (degree > 1) {
    const Eigen::MatrixXd H_inv = H.inverse();
    const double var = H_inv(degree, degree) * cost / std::max(1.0, n - static_cast<double>(x.size()));
    if (!(var > 0) || std::abs(x[degree]) / std::sqrt(var) >= significance) break;
    std::vector<int> rest;
    for (int k = 0; k < static_cast<int>(x.size()); ++k) {
      if (k != degree) rest.push_back(k);
    }
    const Eigen::MatrixXd H_rr = H(rest, rest);
    const Eigen::VectorXd shift = H_rr.ldlt().solve(H(rest, degree) * x[degree]);
    cost += x[degree] * x[degree] / H_inv(degree, degree);
    const Eigen::VectorXd lower = x(rest) + shift;
    x = lower;
    H = H_rr;
    --degree;
  }
  return degree;
}

// The band's half-width w for an edge whose border is `cell_px` wide across it, blurred by sigma
// (the last round's; the start's in the first). Without the code: half a cell, in the black border.
// With it, a small or blurred marker's band is widened to hold the blurred transition (reach
// 3 sigma + 3/4 px, the blur and the pixel's half diagonal) and `band_plateau_px` of level ground
// beyond it on each side, but at most to the whole border (one cell), whose inner edge the model's
// inner term explains. Within [min_window_px, max_window_px] either way.
double band_half_width(double cell_px, double sigma, bool code, const EdgeFitOptions& o) {
  double w = o.window_cells * cell_px;
  if (code) w = std::max(w, std::min(cell_px, 3 * sigma + 0.75 + o.band_plateau_px));
  return std::clamp(w, o.min_window_px, o.max_window_px);
}

struct EdgeFitResult {
  std::optional<EdgeCurve> curve;
  std::string failure;
  int iterations = 0;  // of every fit made for this edge
};

// Parameters for a fit of `degree` in `frame` that start where `fitted` (another frame's fit of the
// same edge) ended: the curve is sampled at 17 points of the new frame's line, each moved along n
// onto the fitted curve (Newton on g), and fitted by least squares with a polynomial of `degree`;
// sigma is kept, and the shading planes, affine in (tau, s), are re-expressed exactly:
//   tau_f = (d_f . (p - o_f)) / L_f - 1/2,  s_f = n_f . (p - o_f),  p = o + (tau + 1/2) L d + s n.
// Empty where the fitted curve does not reach the new line (then the fit starts from scratch).
std::optional<Eigen::VectorXd> start_from(const EdgeCurve& fitted, const EdgeFrame& frame, int degree) {
  constexpr int kPoints = 17;
  Eigen::MatrixXd A(kPoints, degree + 1);
  Eigen::VectorXd rhs(kPoints);
  for (int k = 0; k < kPoints; ++k) {
    const double tau = -0.5 + static_cast<double>(k) / (kPoints - 1);
    const Eigen::Vector2d on_line = frame.origin + (tau + 0.5) * frame.length * frame.d;
    double s = 0;
    for (int it = 0; it < 10; ++it) {
      const Eigen::Vector2d p = on_line + s * frame.n;
      const double slope = fitted.grad(p).dot(frame.n);
      if (!(std::abs(slope) > 0.1)) return std::nullopt;
      const double step = fitted.g(p) / slope;
      s -= step;
      if (std::abs(step) < 1e-9) break;
    }
    if (!(std::abs(s) < 3)) return std::nullopt;
    double tj = 1;
    for (int j = 0; j <= degree; ++j, tj *= tau) A(k, j) = tj;
    rhs[k] = s;
  }
  Eigen::VectorXd x(degree + 8);
  x.head(degree + 1) = A.colPivHouseholderQr().solve(rhs);
  const EdgeFrame& f = fitted.frame;
  // tau_f = t0 + tt tau + ts s, s_f = s0 + st tau + ss s.
  const Eigen::Vector2d o = frame.origin - f.origin;
  const double t0 = (f.d.dot(o + 0.5 * frame.length * frame.d)) / f.length - 0.5;
  const double tt = frame.length * f.d.dot(frame.d) / f.length, ts = f.d.dot(frame.n) / f.length;
  const double s0 = f.n.dot(o + 0.5 * frame.length * frame.d);
  const double st = frame.length * f.n.dot(frame.d), ss = f.n.dot(frame.n);
  x[degree + 1] = fitted.sigma;
  for (int plane = 0; plane < 2; ++plane) {
    const double c0 = fitted.shading[3 * plane], c_tau = fitted.shading[3 * plane + 1], c_s = fitted.shading[3 * plane + 2];
    x[degree + 2 + 3 * plane] = c0 + c_tau * t0 + c_s * s0;
    x[degree + 3 + 3 * plane] = c_tau * tt + c_s * st;
    x[degree + 4 + 3 * plane] = c_tau * ts + c_s * ss;
  }
  if (!x.allFinite()) return std::nullopt;
  return x;
}

// Fits one edge over t in [lo, hi] with band half-width w, and refuses a fit that fails the
// contrast, blur and residual limits: a first fit on a band around the straight edge between the
// given corners, then (rounds = 2) one on a band that follows the fitted curve. The neighbouring
// edges are kept out by delta = 3 sigma + 3/4 (the blur and the pixel's half diagonal) plus `corner_error_px`, the uncertainty of the corners the neighbours
// are drawn through. The polynomial degree is at most L / options.min_px_per_degree for a stretch
// of L px: a cubic fitted to a few pixels extrapolates badly. `final_pass`: the last round runs to
// options.tolerance_px; otherwise (a coarse pass that only places the next one's frames) every
// round stops at 10x the tolerance. Either way the last round lowers the degree while its top
// coefficient is not significant.
// `start` (a whole-edge fit of the pass before, in its own frame): for a marker whose cells are at
// least options.quick_start_min_cell_px wide, the last round's band follows that curve, re-expressed
// in this frame (start_from), and its fit starts from its parameters: the rounds before are skipped.
// Such a marker's cold first round runs its first iterations on every third sample. Smaller markers
// always take every round from the straight band: their corners depend on where the fit starts
// (docs/measurements/detect.md).
EdgeFitResult fit_edge(const cv::Mat& grey, const Levels& levels, const EdgeFrame& frame, double lo, double hi,
                       const std::array<NeighbourEdge, 2>& neighbours, double cell_px, int rounds, double corner_error_px,
                       bool final_pass, const InnerCode* code, const EdgeCurve* start, const EdgeFitOptions& o) {
  EdgeCurve curve;
  curve.frame = frame;
  const Footprint footprint = Footprint::across(frame.n);
  int degree = o.degree;
  Eigen::VectorXd x;
  const EdgeCurve* band_curve = nullptr;
  double sigma = o.initial_blur_px;
  int iterations = 0;
  // The margin delta kept from the neighbours for a blur sigma; the transition is clear of them
  // from delta / sin(alpha) on, so the stretch fitted is [t0, t1].
  struct Stretch {
    double delta, t0, t1;
  };
  auto stretch = [&](double blur) {
    const double delta = 3 * blur + 0.75 + corner_error_px;
    return Stretch{delta, std::max(lo, delta / neighbours[0].sin_a),
                   std::min(hi, frame.length - delta / neighbours[1].sin_a)};
  };
  // The first round's degree: at most L / min_px_per_degree for its stretch of L px.
  auto first_degree = [&](const Stretch& st) {
    return std::clamp(static_cast<int>((st.t1 - st.t0) / o.min_px_per_degree), 1, o.degree);
  };
  constexpr const char* kTooShort = "edge too short to fit clear of the corners";
  const bool quick = cell_px >= o.quick_start_min_cell_px;
  int first_round = 0;
  if (start && quick && rounds > 1) {
    // The degree the first round would take (its margins, from the initial blur).
    const Stretch st = stretch(sigma);
    if (st.t1 - st.t0 < o.min_fit_length_px) return {std::nullopt, kTooShort};
    degree = first_degree(st);
    if (auto warm = start_from(*start, frame, degree)) {
      x = *warm;
      curve.c = x.head(degree + 1);
      sigma = curve.sigma = x[degree + 1];
      band_curve = &curve;
      first_round = rounds - 1;
    }
  }
  for (int round = first_round; round < rounds; ++round) {
    const Stretch st = stretch(sigma);
    const double delta = st.delta;
    if (st.t1 - st.t0 < o.min_fit_length_px) return {std::nullopt, kTooShort};
    if (round == 0) {
      degree = first_degree(st);
      x = Eigen::VectorXd::Zero(degree + 8);
    }
    const double w = band_half_width(cell_px, sigma, code != nullptr, o);
    // The inner term only where the band comes within the blur's reach of the border's inner edge
    // (10 sigma + 1 px): big markers are fitted as before, at no extra cost.
    const InnerCode* round_code = code && cell_px - w < 10 * sigma + 1 ? code : nullptr;
    curve.band_px = w;
    const auto samples = band_samples(grey, levels, frame, std::max(lo, 0.0), std::min(hi, frame.length), w, band_curve,
                                      neighbours, delta, round_code, sigma);
    if (static_cast<int>(samples.size()) < std::max(o.min_pixels_per_edge, degree + 8)) {
      return {std::nullopt, "too few pixels along an edge (" + std::to_string(samples.size()) + ")"};
    }
    if (round == 0) {
      // Start: the initial line, a sharp edge, black and white levels from the band's extremes.
      std::vector<double> values;
      for (const Sample& s : samples) values.push_back(s.value);
      const auto lo_it = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 10);
      const auto hi_it = values.begin() + static_cast<std::ptrdiff_t>(values.size() * 9 / 10);
      std::nth_element(values.begin(), lo_it, values.end());
      const double dark = *lo_it;
      std::nth_element(values.begin(), hi_it, values.end());
      x[degree + 1] = o.initial_blur_px;
      x[degree + 2] = dark;
      x[degree + 5] = *hi_it - dark;
    }
    // From a cold start the first iterations only bring the curve near the edge: on a quick marker
    // they run on every third sample to 0.1 px, and the fit below goes on from there with all.
    const Eigen::VectorXd cold = x;
    bool warmed = false;
    if (quick && round == 0 && static_cast<int>(samples.size()) >= 3 * std::max(o.min_pixels_per_edge, degree + 8)) {
      std::vector<Sample> thinned;
      thinned.reserve(samples.size() / 3 + 1);
      for (std::size_t i = 0; i < samples.size(); i += 3) thinned.push_back(samples[i]);
      Eigen::VectorXd x_thinned = x;
      const ModelFit near = fit_edge_model(thinned, footprint, degree, o.max_iterations, o.max_blur_px,
                                           100 * o.tolerance_px, x_thinned);
      iterations += near.iterations;
      if (near.ok && x_thinned.allFinite()) {
        x = x_thinned;
        warmed = true;
      }
    }
    const bool last = final_pass && round == rounds - 1;
    // The rounds before the last only place the band (or the next pass): a coarse tolerance will do.
    const double tolerance = last ? o.tolerance_px : 10 * o.tolerance_px;
    ModelFit fitted = fit_edge_model(samples, footprint, degree, o.max_iterations, o.max_blur_px, tolerance, x);
    iterations += fitted.iterations;
    if ((!fitted.ok || !x.allFinite()) && warmed) {
      // No step improved on the warmed-up start (a perfectly sharp render's cost has a kink
      // there): the fit from the cold start decides, as without the warm-up.
      x = cold;
      fitted = fit_edge_model(samples, footprint, degree, o.max_iterations, o.max_blur_px, tolerance, x);
      iterations += fitted.iterations;
    }
    if (!fitted.ok || !x.allFinite()) return {std::nullopt, "edge fit did not converge"};
    // The fit's RMS residual (its cost is the sum of squares at x).
    curve.rms = std::sqrt(fitted.cost / static_cast<double>(samples.size()));
    // Occam's razor on each pass's last band: drop the highest curve coefficient while it is not
    // significant, so straight edges are not fitted with wiggles that extrapolate badly. The
    // degrees are dropped at once on the linearised solution (drop_insignificant_degrees); the
    // final pass then fits the lower degree again from there (one or two iterations), the coarse
    // pass keeps it.
    if (round == rounds - 1 && degree > 1 && fitted.top_z < o.degree_significance) {
      const int lowered = drop_insignificant_degrees(x, degree, fitted.normal, fitted.cost,
                                                     static_cast<double>(samples.size()), o.degree_significance);
      if (lowered < degree) {
        degree = lowered;
        // The linearised shift may take sigma out of the range a fit keeps it in.
        x[degree + 1] = std::clamp(x[degree + 1], kMinSigmaPx, 2 * o.max_blur_px);
        if (last) {
          const ModelFit again = fit_edge_model(samples, footprint, degree, o.max_iterations, o.max_blur_px, tolerance, x);
          iterations += again.iterations;
          if (!again.ok || !x.allFinite()) return {std::nullopt, "edge fit did not converge"};
          curve.rms = std::sqrt(again.cost / static_cast<double>(samples.size()));
        } else {
          curve.rms = model_rms(samples, footprint, degree, x);
        }
      }
    }
    curve.c = x.head(degree + 1);
    sigma = curve.sigma = x[degree + 1];
    for (int k = 0; k < 6; ++k) curve.shading[static_cast<std::size_t>(k)] = x[degree + 2 + k];
    curve.contrast = x[degree + 5];
    band_curve = &curve;
  }
  if (!(curve.contrast > 0)) return {std::nullopt, "edge contrast inverted (the fit found dark outside the marker)"};
  if (!(curve.contrast >= o.min_contrast)) {
    return {std::nullopt, "edge contrast " + std::to_string(static_cast<int>(std::lround(curve.contrast))) +
                              " grey levels is below " + std::to_string(static_cast<int>(o.min_contrast))};
  }
  if (curve.sigma > o.max_blur_px) return {std::nullopt, "edge blur sigma " + std::to_string(curve.sigma) + " px too large"};
  if (curve.rms > o.max_residual * curve.contrast) return {std::nullopt, "edge does not look like a step (fit residual too large)"};
  return {curve, "", iterations};
}

// Corner where two edge curves meet: Newton's method on (g_a, g_b)(p) = 0 from p.
std::optional<Eigen::Vector2d> intersect(const EdgeCurve& a, const EdgeCurve& b, Eigen::Vector2d p) {
  for (int it = 0; it < 30; ++it) {
    Eigen::Matrix2d J;
    J.row(0) = a.grad(p).transpose();
    J.row(1) = b.grad(p).transpose();
    if (std::abs(J.determinant()) < 1e-6) return std::nullopt;
    const Eigen::Vector2d dp = -J.inverse() * Eigen::Vector2d(a.g(p), b.g(p));
    p += dp;
    if (!p.allFinite()) return std::nullopt;
    if (dp.norm() < 1e-10) return p;
  }
  return p;
}

double interior_angle(const std::array<Eigen::Vector2d, 4>& q, int k) {
  const Eigen::Vector2d u = (q[(k + 1) % 4] - q[k]).normalized(), v = (q[(k + 3) % 4] - q[k]).normalized();
  return std::acos(std::clamp(u.dot(v), -1.0, 1.0));
}

}  // namespace

// ---------------------------------------------------------------------------------------------

MarkerDictionary MarkerDictionary::predefined(const std::string& name) {
  MarkerDictionary d;
  d.dictionary_ = cv::aruco::getPredefinedDictionary(aruco_dictionary_id(name));
  d.name_ = name;
  return d;
}

MarkerDictionary MarkerDictionary::from_file(const std::string& path) {
  if (!std::ifstream(path)) throw InputError(path, 0, "cannot open dictionary file");
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception&) {
    throw InputError(path, 0, "not an OpenCV YAML/XML dictionary file (cv::FileStorage cannot parse it)");
  }
  if (!fs.isOpened()) throw InputError(path, 0, "not an OpenCV YAML/XML dictionary file");
  const cv::FileNode root = fs.root();
  auto int_key = [&](const std::string& key, bool required, int fallback, int lo, int hi) {
    const cv::FileNode n = root[key];
    if (n.empty()) {
      if (required) throw InputError(path, 0, "missing key '" + key + "'");
      return fallback;
    }
    if (!n.isInt()) throw InputError(path, 0, "'" + key + "' must be an integer");
    const int v = static_cast<int>(n);
    if (v < lo || v > hi) {
      throw InputError(path, 0, "'" + key + "' must be in " + std::to_string(lo) + ".." + std::to_string(hi));
    }
    return v;
  };
  const int count = int_key("nmarkers", true, 0, 1, 100000);
  const int size = int_key("markersize", true, 0, 2, 16);
  const int correction = int_key("maxCorrectionBits", false, 0, 0, size * size);
  cv::Mat bytes;
  cv::Mat bits(size, size, CV_8UC1);
  for (int i = 0; i < count; ++i) {
    const std::string key = "marker_" + std::to_string(i);
    const cv::FileNode n = root[key];
    if (n.empty()) throw InputError(path, 0, "missing key '" + key + "' (nmarkers is " + std::to_string(count) + ")");
    if (!n.isString()) throw InputError(path, 0, "'" + key + "' must be a string of bits");
    const std::string s = static_cast<std::string>(n);
    if (static_cast<int>(s.size()) != size * size || s.find_first_not_of("01") != std::string::npos) {
      throw InputError(path, 0, "'" + key + "' must be " + std::to_string(size * size) + " characters '0' or '1'");
    }
    for (int j = 0; j < size * size; ++j) bits.at<std::uint8_t>(j / size, j % size) = s[static_cast<std::size_t>(j)] == '1';
    bytes.push_back(cv::aruco::Dictionary::getByteListFromBits(bits));
  }
  MarkerDictionary d;
  d.dictionary_ = cv::makePtr<cv::aruco::Dictionary>(bytes, size, correction);
  d.name_ = path;
  return d;
}

int MarkerDictionary::marker_count() const { return dictionary_->bytesList.rows; }
int MarkerDictionary::bits_per_side() const { return dictionary_->markerSize; }
int MarkerDictionary::max_correction_bits() const { return dictionary_->maxCorrectionBits; }
cv::Mat MarkerDictionary::code(int id) const {
  if (id < 0 || id >= marker_count()) throw UsageError("marker id " + std::to_string(id) + " is not in the dictionary");
  return cv::aruco::Dictionary::getBitsFromByteList(dictionary_->bytesList.rowRange(id, id + 1), dictionary_->markerSize);
}

const std::vector<std::string>& corner_refinement_names() {
  static const std::vector<std::string> names{"edges", "subpix", "contour", "none"};
  return names;
}

CornerRefinement corner_refinement_from_name(const std::string& name) {
  const auto& names = corner_refinement_names();
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw UsageError("unknown corner refinement '" + name + "'");
  return static_cast<CornerRefinement>(it - names.begin());
}

std::vector<Observation> MarkerDetection::observations() const {
  std::vector<Observation> out;
  for (std::size_t k = 0; k < marker_ids.size(); ++k) {
    for (int c = 0; c < 4; ++c) {
      out.push_back({image, static_cast<PointId>(marker_ids[k]) * 4 + c, corners[k][c].x(), corners[k][c].y()});
    }
  }
  std::sort(out.begin(), out.end(), [](const Observation& a, const Observation& b) { return a.point_id < b.point_id; });
  return out;
}

namespace {

// One pass of the refinement from corners q: frames, bands and neighbours drawn through q, whose
// corners are uncertain by `corner_error_px`; corners = intersections of the fitted edges.
// `final_pass` as fit_edge takes it.
// The homography taking marker cells (u, v) (corners (0, 0), (cells, 0), (cells, cells),
// (0, cells)) to q: the 8 x 8 linear system of the four point pairs, h33 = 1 (Hartley &
// Zisserman, "Multiple View Geometry", 2nd ed., sec. 4.1). Not cv::getPerspectiveTransform: it
// takes float points, which would round corners of a 2000 px photo by ~1e-4 px.
std::optional<Eigen::Matrix3d> image_from_marker(const std::array<Eigen::Vector2d, 4>& q, int cells) {
  const double c = cells;
  const std::array<Eigen::Vector2d, 4> m{Eigen::Vector2d(0, 0), {c, 0}, {c, c}, {0, c}};
  Eigen::Matrix<double, 8, 8> A;
  Eigen::Matrix<double, 8, 1> b;
  for (int k = 0; k < 4; ++k) {
    const double u = m[k].x(), v = m[k].y(), x = q[k].x(), y = q[k].y();
    A.row(2 * k) << u, v, 1, 0, 0, 0, -u * x, -v * x;
    A.row(2 * k + 1) << 0, 0, 0, u, v, 1, -u * y, -v * y;
    b[2 * k] = x;
    b[2 * k + 1] = y;
  }
  const Eigen::Matrix<double, 8, 1> h = A.fullPivLu().solve(b);
  if (!h.allFinite()) return std::nullopt;
  Eigen::Matrix3d H;
  H << h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1;
  if (!(std::abs(H.determinant()) > 1e-12)) return std::nullopt;
  return H;
}

// The code cells next to edge e's border (markers.hpp's corner and edge order: edge e runs from
// corner e to e + 1, TL TR BR BL), for a code of n x n cells (1 = white) inside a border of one cell.
std::array<InnerCode, 4> inner_codes(const Eigen::Matrix3d& H, const cv::Mat& code, int cells,
                                     const std::array<double, 4>& edge_length_px) {
  const int n = code.rows;
  const double c = cells;
  std::array<InnerCode, 4> out;
  for (int e = 0; e < 4; ++e) {
    // marker_from_edge: (a, d) -> (u, v) for edge e.
    Eigen::Matrix3d M;
    switch (e) {
      case 0: M << 1, 0, 0, 0, 1, 0, 0, 0, 1; break;       // u = a,     v = d
      case 1: M << 0, -1, c, 1, 0, 0, 0, 0, 1; break;      // u = c - d, v = a
      case 2: M << -1, 0, c, 0, -1, c, 0, 0, 1; break;     // u = c - a, v = c - d
      default: M << 0, 1, 0, -1, 0, c, 0, 0, 1; break;     // u = d,     v = c - a
    }
    InnerCode& ic = out[static_cast<std::size_t>(e)];
    ic.image_from_edge = H * M;
    ic.edge_from_image = ic.image_from_edge.inverse();
    ic.cell_px = edge_length_px[static_cast<std::size_t>(e)] / c;
    for (int j = 0; j < n; ++j) {
      int row = 0, col = 0;
      switch (e) {
        case 0: row = 0, col = j; break;
        case 1: row = j, col = n - 1; break;
        case 2: row = n - 1, col = n - 1 - j; break;
        default: row = n - 1 - j, col = 0; break;
      }
      ic.white.push_back(code.at<std::uint8_t>(row, col) ? 1.0 : 0.0);
    }
  }
  return out;
}

// Whole-edge fits (span 1) of a pass, by edge, for the next pass's start.
using EdgeCurves = std::array<std::optional<EdgeCurve>, 4>;

EdgeFit refine_pass(const cv::Mat& grey, const Levels& levels, const std::array<Eigen::Vector2d, 4>& q, int cells,
                    int rounds, double corner_error_px, bool final_pass, const cv::Mat& code, const EdgeFitOptions& o,
                    const EdgeCurves* start = nullptr, EdgeCurves* fitted = nullptr) {
  EdgeFit result;
  result.corners = q;
  const Eigen::Vector2d centre = 0.25 * (q[0] + q[1] + q[2] + q[3]);
  std::array<EdgeFrame, 4> frames;
  std::array<double, 4> cell_px{};
  std::array<double, 4> sin_angle{};
  for (int e = 0; e < 4; ++e) {
    EdgeFrame& f = frames[e];
    f.origin = q[e];
    const Eigen::Vector2d v = q[(e + 1) % 4] - q[e];
    f.length = v.norm();
    if (!(f.length > 1)) {
      result.failure = "degenerate quadrilateral";
      return result;
    }
    f.d = v / f.length;
    f.n = Eigen::Vector2d(-f.d.y(), f.d.x());
    if (f.n.dot(centre - q[e]) > 0) f.n = -f.n;  // outwards, towards the white quiet zone
    const double angle = interior_angle(q, e);
    sin_angle[e] = std::sin(angle);
    if (sin_angle[e] < 0.2) {
      result.failure = "corner angle too acute";
      return result;
    }
  }
  std::array<InnerCode, 4> codes;
  if (!code.empty()) {
    const auto H = image_from_marker(q, cells);
    if (!H) {
      result.failure = "degenerate quadrilateral";
      return result;
    }
    codes = inner_codes(*H, code, cells, {frames[0].length, frames[1].length, frames[2].length, frames[3].length});
  }
  for (int e = 0; e < 4; ++e) {
    // Across edge e, the marker extends as far as its neighbouring edges reach across it: their
    // length times the sine of the angle they make with it (a skewed marker is thinner across an
    // edge than its sides are long).
    const double across = std::min(frames[(e + 3) % 4].length * sin_angle[e],
                                   frames[(e + 1) % 4].length * sin_angle[(e + 1) % 4]) / cells;
    cell_px[e] = across;
  }
  // fits[k][0]: the edge ending at corner k (edge k-1); fits[k][1]: the edge starting there (edge k).
  std::array<std::array<std::optional<EdgeCurve>, 2>, 4> fits;
  double blur = 0, band = 0;
  result.contrast = 1e300;
  auto take = [&](const EdgeFitResult& r) -> std::optional<EdgeCurve> {
    if (!r.curve) {
      if (result.failure.empty()) result.failure = r.failure;
      return std::nullopt;
    }
    result.iterations += r.iterations;
    blur += r.curve->sigma;
    band += r.curve->band_px;
    result.contrast = std::min(result.contrast, r.curve->contrast);
    result.residual = std::max(result.residual, r.curve->rms / r.curve->contrast);
    return r.curve;
  };
  int n_fits = 0;
  for (int e = 0; e < 4; ++e) {
    const double L = frames[e].length;
    // Edge e runs from corner e to corner e+1; its neighbours there are edges e-1 and e+1.
    auto inward = [&](int from, int to) {
      const Eigen::Vector2d v = (q[to] - q[from]).normalized();
      Eigen::Vector2d m(-v.y(), v.x());
      return m.dot(centre - q[from]) < 0 ? Eigen::Vector2d(-m) : m;
    };
    const std::array<NeighbourEdge, 2> nb{NeighbourEdge{q[e], inward(e, (e + 3) % 4), sin_angle[e]},
                                          NeighbourEdge{q[(e + 1) % 4], inward((e + 1) % 4, (e + 2) % 4),
                                                        sin_angle[(e + 1) % 4]}};
    auto fit = [&](double lo, double hi, const EdgeCurve* from) {
      const InnerCode* inner = code.empty() ? nullptr : &codes[static_cast<std::size_t>(e)];
      EdgeFitResult r = fit_edge(grey, levels, frames[e], lo, hi, nb, cell_px[e], rounds, corner_error_px, final_pass,
                                 inner, from, o);
      // A quick start that fails (e.g. a perfectly sharp render, whose start sits on a kink of
      // the cost that no step improves) is not the edge's verdict: the full fit decides.
      if (!r.curve && from) {
        r = fit_edge(grey, levels, frames[e], lo, hi, nb, cell_px[e], rounds, corner_error_px, final_pass, inner, nullptr, o);
      }
      return take(r);
    };
    if (o.span >= 1) {
      const std::optional<EdgeCurve>* from = start ? &(*start)[static_cast<std::size_t>(e)] : nullptr;
      const auto curve = fit(0, L, from && *from ? &**from : nullptr);
      ++n_fits;
      if (!curve) return result;
      if (fitted) (*fitted)[static_cast<std::size_t>(e)] = curve;
      fits[e][1] = curve;
      fits[(e + 1) % 4][0] = curve;
    } else {
      const auto first = fit(0, o.span * L, nullptr);
      const auto second = fit((1 - o.span) * L, L, nullptr);
      n_fits += 2;
      if (!first || !second) return result;
      fits[e][1] = first;
      fits[(e + 1) % 4][0] = second;
    }
  }
  result.blur_px = blur / n_fits;
  result.band_px = band / n_fits;
  for (int k = 0; k < 4; ++k) {
    const auto p = intersect(*fits[k][0], *fits[k][1], q[k]);
    if (!p) {
      result.failure = "edges of corner " + std::to_string(k) + " do not intersect";
      return result;
    }
    result.corners[k] = *p;
  }
  result.ok = true;
  return result;
}

}  // namespace

EdgeFit refine_marker_corners(const cv::Mat& grey, const std::array<Eigen::Vector2d, 4>& q, int cells,
                              const EdgeFitOptions& o, const cv::Mat& code) {
  CV_Assert(grey.type() == CV_8UC1);
  if (!code.empty() && (code.type() != CV_8UC1 || code.rows != cells - 2 || code.cols != cells - 2)) {
    throw UsageError("a marker code must be (cells - 2) x (cells - 2) CV_8UC1");
  }
  if (o.degree < 1 || o.degree > 3 || !(o.span > 0 && o.span <= 1) || !(o.gamma > 0) || !(o.initial_corner_error_px >= 0)) {
    throw UsageError("bad edge-fit options");
  }
  Levels levels;
  for (int v = 0; v < 256; ++v) levels[static_cast<std::size_t>(v)] = 255 * std::pow(v / 255.0, o.gamma);
  // A coarse pass from OpenCV's polygon (its corners off by up to ~1 px; one round, at 10x the
  // tolerance), then the fine pass with frames, bands and neighbours drawn through the coarse
  // corners. If the coarse pass fails (a small marker leaves too little edge clear of its
  // uncertain corners), the fine pass starts from OpenCV's corners with their uncertainty.
  EdgeCurves coarse_curves;
  const EdgeFit coarse = refine_pass(grey, levels, q, cells, 1, o.initial_corner_error_px, false, code, o, nullptr,
                                     &coarse_curves);
  EdgeFit fine = coarse.ok ? refine_pass(grey, levels, coarse.corners, cells, 2, 0, true, code, o, &coarse_curves)
                           : refine_pass(grey, levels, q, cells, 2, o.initial_corner_error_px, true, code, o);
  fine.iterations += coarse.iterations;
  if (!fine.ok) return fine;
  double mean_side = 0;
  for (int k = 0; k < 4; ++k) mean_side += 0.25 * (q[(k + 1) % 4] - q[k]).norm();
  const double max_shift = std::max(o.min_max_shift_px, o.max_shift_cells * mean_side / cells);
  for (int k = 0; k < 4; ++k) {
    // An error e across each edge moves an acute corner by e / sin(alpha / 2) along its bisector:
    // OpenCV's polygon corners are that much worse there, so the allowance grows the same way.
    const double allowed = max_shift * std::max(1.0, std::sin(M_PI / 4) / std::sin(interior_angle(q, k) / 2));
    const double moved = (fine.corners[k] - q[k]).norm();
    if (moved > allowed) {
      fine.ok = false;
      fine.failure = "corner " + std::to_string(k) + " moved " + std::to_string(moved) + " px from OpenCV's (more than " +
                     std::to_string(allowed) + ")";
      return fine;
    }
  }
  return fine;
}

MarkerDetection detect_markers(const cv::Mat& grey, const std::string& image_name, const MarkerDictionary& dictionary,
                               const MarkerDetectOptions& options) {
  CV_Assert(grey.type() == CV_8UC1);
  MarkerDetection out;
  out.image = image_name;
  out.width_px = grey.cols;
  out.height_px = grey.rows;
  auto params = cv::aruco::DetectorParameters::create();
  params->errorCorrectionRate = options.error_correction_rate;
  // The candidates' adaptive thresholds: windows from the smallest (OpenCV's 3 px by default) to
  // OpenCV's largest, 23, in steps of 10 (MarkerDetectOptions::threshold_window_min_px).
  params->adaptiveThreshWinSizeMin = options.threshold_window_min_px;
  switch (options.refinement) {
    case CornerRefinement::Subpix:
      // Tighter than OpenCV's defaults (0.1 px, 30 iterations), so the comparison is fair to it.
      params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
      params->cornerRefinementMinAccuracy = 0.001;
      params->cornerRefinementMaxIterations = 100;
      break;
    case CornerRefinement::Contour: params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_CONTOUR; break;
    case CornerRefinement::Edges:
    case CornerRefinement::None: params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE; break;
  }
  std::vector<std::vector<cv::Point2f>> corners, unidentified;
  std::vector<int> ids;
  cv::aruco::detectMarkers(grey, cv::Ptr<cv::aruco::Dictionary>(dictionary.opencv()), corners, ids, params,
                           unidentified);
  for (const auto& c : unidentified) {
    if (c.size() != 4) continue;
    out.candidates.push_back({Eigen::Vector2d(c[0].x, c[0].y), Eigen::Vector2d(c[1].x, c[1].y),
                              Eigen::Vector2d(c[2].x, c[2].y), Eigen::Vector2d(c[3].x, c[3].y)});
  }
  std::map<int, int> seen;
  for (int id : ids) ++seen[id];
  const int cells = dictionary.bits_per_side() + 2;
  std::vector<std::size_t> order(ids.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ids[a] < ids[b]; });
  for (std::size_t k : order) {
    const int id = ids[k];
    std::array<Eigen::Vector2d, 4> q;
    for (int c = 0; c < 4; ++c) q[c] = {corners[k][c].x, corners[k][c].y};
    if (seen[id] > 1) {
      out.rejected.push_back({id, "id found " + std::to_string(seen[id]) + " times in this image", q});
      continue;
    }
    if (options.refinement == CornerRefinement::Edges) {
      const EdgeFit fit = refine_marker_corners(grey, q, cells, options.edges,
                                                options.edges.model_code ? dictionary.code(id) : cv::Mat());
      if (!fit.ok) {
        out.rejected.push_back({id, fit.failure, q});
        continue;
      }
      q = fit.corners;
    }
    out.marker_ids.push_back(id);
    out.corners.push_back(q);
  }
  return out;
}

std::vector<ScaleBar> marker_scale_bars(const std::vector<int>& ids, double side_mm) {
  std::vector<int> sorted = ids;
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  std::vector<ScaleBar> bars;
  for (int id : sorted) {
    for (int c = 0; c < 4; ++c) {
      bars.push_back({static_cast<PointId>(id) * 4 + c, static_cast<PointId>(id) * 4 + (c + 1) % 4, side_mm, {}});
    }
  }
  return bars;
}

}  // namespace photomill::detect
