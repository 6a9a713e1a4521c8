// The fitting loop of fitsurf (method and sources in fit.hpp).
#include "fitsurf/fit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <string>

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>

#include "fitsurf/evaluate.hpp"
#include "fitsurf/normal_equations.hpp"
#include "fitsurf/numbers.hpp"
#include "fitsurf/outline.hpp"
#include "geometry/parallel.hpp"
#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::fitsurf {
namespace {

std::string at_mm(const Eigen::Vector3d& x) {
  std::string s(1, '(');  // appended piecewise: GCC 12 warns (-Wrestrict) on "(" + std::string&&
  s += fixed(x.x(), 1);
  s += ", ";
  s += fixed(x.y(), 1);
  s += ", ";
  s += fixed(x.z(), 1);
  s += ") mm";
  return s;
}

double weighted_rms(const std::vector<double>& d, const std::vector<double>& w) {
  double s = 0, sw = 0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    const double wk = w.empty() ? 1.0 : w[k];
    s += wk * d[k] * d[k];
    sw += wk;
  }
  return sw > 0 ? std::sqrt(s / sw) : 0.0;
}

struct Weighting {
  double scale_mm = 0, cutoff_mm = 0;
  std::size_t outliers = 0;
};

// Local statistics of the residuals: for each point k, the median m_k and the scale
// s_k = 1.4826 MAD of the residuals of the points around it (in the parameter plane, mm), and its
// deviation e_k = d_k - m_k. The error a coarse net makes is smooth and shared by neighbours: it
// moves m_k and widens s_k, so it is not taken for outliers; an isolated outlier keeps its whole
// residual and does not widen its neighbours' scale much. The neighbours are the points in the
// 3 x 3 block of grid cells around k's cell, cells 1.5 mean point spacings wide (about 20
// points); with fewer than 4 of them e_k = d_k and s_k = 0.
struct LocalResiduals {
  std::vector<double> deviation_mm, scale_mm;
};

LocalResiduals local_residuals(const std::vector<Eigen::Vector2d>& uv, const std::vector<double>& d, double lu,
                               double lv, int threads) {
  const std::size_t n = d.size();
  const double cell = 1.5 * std::sqrt(lu * lv / static_cast<double>(std::max<std::size_t>(n, 1)));
  const int nx = std::clamp(static_cast<int>(std::ceil(lu / cell)), 1, 4096);
  const int ny = std::clamp(static_cast<int>(std::ceil(lv / cell)), 1, 4096);
  auto cell_of = [&](const Eigen::Vector2d& p) {
    const int ix = std::clamp(static_cast<int>(p.x() * nx), 0, nx - 1);
    const int iy = std::clamp(static_cast<int>(p.y() * ny), 0, ny - 1);
    return static_cast<std::size_t>(iy) * nx + ix;
  };
  const std::size_t ncell = static_cast<std::size_t>(nx) * ny;
  std::vector<std::size_t> start(ncell + 1, 0), order(n);
  for (const auto& p : uv) ++start[cell_of(p) + 1];
  for (std::size_t c = 0; c < ncell; ++c) start[c + 1] += start[c];
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < n; ++k) order[fill[cell_of(uv[k])]++] = k;
  }
  LocalResiduals r;
  r.deviation_mm.resize(n);
  r.scale_mm.resize(n);
  geometry::parallel_blocks(n, threads, 4096, [&](std::size_t b, std::size_t end, int) {
    std::vector<double> near;
    for (std::size_t k = b; k < end; ++k) {
      const std::size_t c = cell_of(uv[k]);
      const int cx = static_cast<int>(c % static_cast<std::size_t>(nx));
      const int cy = static_cast<int>(c / static_cast<std::size_t>(nx));
      near.clear();
      for (int y = std::max(0, cy - 1); y <= std::min(ny - 1, cy + 1); ++y) {
        for (int x = std::max(0, cx - 1); x <= std::min(nx - 1, cx + 1); ++x) {
          const std::size_t cc = static_cast<std::size_t>(y) * nx + x;
          for (std::size_t i = start[cc]; i < start[cc + 1]; ++i) {
            if (order[i] != k) near.push_back(d[order[i]]);
          }
        }
      }
      if (near.size() < 4) {
        r.deviation_mm[k] = d[k];
        r.scale_mm[k] = 0;
        continue;
      }
      const auto mid = near.begin() + static_cast<std::ptrdiff_t>(near.size() / 2);
      std::nth_element(near.begin(), mid, near.end());
      const double m = *mid;
      for (double& x : near) x = std::abs(x - m);
      std::nth_element(near.begin(), mid, near.end());
      r.deviation_mm[k] = d[k] - m;
      r.scale_mm[k] = 1.4826 * *mid;
    }
  });
  return r;
}

// IRLS weights (fit.hpp, step 4) from the local residual statistics: point k's cutoff is
// c_k = threshold * max(s_k, sigma), sigma = max(1.4826 MAD(e), robust_min_scale_mm) the global
// scale (consistent for Gaussian residuals).
Weighting robust_weights(const LocalResiduals& lr, const FitOptions& o, std::vector<double>& w,
                         std::vector<std::uint8_t>* outlier = nullptr) {
  const std::vector<double>& e = lr.deviation_mm;
  const double k = o.robust_threshold > 0                ? o.robust_threshold
                   : o.robust == RobustLoss::Reject ? 5.0
                   : o.robust == RobustLoss::Huber  ? 1.345
                                                    : 4.685;
  const double med = median(e);
  std::vector<double> dev(e.size());
  for (std::size_t i = 0; i < e.size(); ++i) dev[i] = std::abs(e[i] - med);
  Weighting r;
  r.scale_mm = std::max(1.4826 * median(std::move(dev)), o.robust_min_scale_mm);
  r.cutoff_mm = k * r.scale_mm;
  w.resize(e.size());
  if (outlier) outlier->assign(e.size(), 0);
  for (std::size_t i = 0; i < e.size(); ++i) {
    const double a = std::abs(e[i]) / (k * std::max(lr.scale_mm[i], r.scale_mm));
    if (a > 1) {
      ++r.outliers;
      if (outlier) (*outlier)[i] = 1;
    }
    if (o.robust == RobustLoss::Reject) {
      w[i] = a <= 1 ? 1.0 : 0.0;
    } else if (o.robust == RobustLoss::Huber) {
      w[i] = a <= 1 ? 1.0 : 1.0 / a;
    } else {
      w[i] = a < 1 ? (1 - a * a) * (1 - a * a) : 0.0;
    }
  }
  return r;
}

BSplineSurface make_surface(const SplineSpace& s, const Eigen::MatrixXd& X) {
  BSplineSurface out;
  out.degree_u = s.p;
  out.degree_v = s.q;
  out.num_poles_u = s.nu;
  out.num_poles_v = s.nv;
  out.knots_u = s.U;
  out.knots_v = s.V;
  out.poles_mm.resize(static_cast<std::size_t>(s.num_poles()));
  for (int g = 0; g < s.num_poles(); ++g) out.poles_mm[static_cast<std::size_t>(g)] = X.row(g).transpose();
  return out;
}

// The linear solve of one round; keeps the symbolic factorisation (the pattern never changes)
// and the previous solution (the CG starting guess).
class NetSolver {
public:
  NetSolver(SplineSpace space, const FitOptions& o, double lu, double lv)
      : space_(std::move(space)), o_(o), K_(thin_plate_matrix(space_, lu, lv, o.smoothing_order)), lambda_(o.smoothing_mm4) {}

  void set_smoothing(double lambda_mm4) { lambda_ = lambda_mm4; }
  double smoothing() const { return lambda_; }

  Eigen::MatrixXd solve(const std::vector<Eigen::Vector2d>& uv, const std::vector<Eigen::Vector3d>& pts,
                        const std::vector<double>& w) {
    const DataNormalEquations ne = accumulate_normal_equations(space_, uv, pts, w, o_.threads);
    if (!(ne.weight_sum > 0)) throw GeometryError("no point carries weight in the fit");
    const double sd = 1.0 / ne.weight_sum;
    const Eigen::SparseMatrix<double> A = assemble_sparse(ne.matrix, sd, K_, lambda_);
    Eigen::MatrixXd B(space_.num_poles(), 3);
    for (int g = 0; g < space_.num_poles(); ++g) B.row(g) = sd * ne.rhs[static_cast<std::size_t>(g)].transpose();
    Eigen::MatrixXd X;
    if (o_.solver == LinearSolver::Ldlt) {
      if (!analyzed_) {
        ldlt_.analyzePattern(A);
        analyzed_ = true;
      }
      ldlt_.factorize(A);
      if (ldlt_.info() != Eigen::Success) singular(ne);
      const Eigen::VectorXd D = ldlt_.vectorD();
      if (!(D.minCoeff() > o_.min_pivot_ratio * D.maxCoeff())) singular(ne);
      X = ldlt_.solve(B);
    } else {
      Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper,
                               Eigen::IncompleteCholesky<double>>
          cg;
      cg.setTolerance(o_.cg_tolerance);
      cg.setMaxIterations(o_.cg_max_iterations);
      cg.compute(A);
      if (cg.info() != Eigen::Success) singular(ne);
      X = guess_.size() ? Eigen::MatrixXd(cg.solveWithGuess(B, guess_)) : Eigen::MatrixXd(cg.solve(B));
      if (cg.info() != Eigen::Success) {
        throw GeometryError("conjugate gradients did not converge (relative error " + sig(cg.error(), 3) +
                            " after " + std::to_string(cg.iterations()) +
                            " iterations): use --solver ldlt, or more --smoothing");
      }
      guess_ = X;
    }
    if (!X.allFinite()) singular(ne);
    return X;
  }

private:
  [[noreturn]] void singular(const DataNormalEquations& ne) const {
    int empty = 0;
    for (int g = 0; g < space_.num_poles(); ++g) empty += ne.matrix.at(g, 0, 0) == 0.0;
    throw GeometryError("the least-squares system is singular: " + std::to_string(empty) + " of the " +
                        std::to_string(space_.nu) + "x" + std::to_string(space_.nv) +
                        " poles have no point in their support" +
                        (lambda_ > 0 ? std::string() : std::string(" and --smoothing is 0")) +
                        "; use a smaller --net or a positive --smoothing");
  }

  SplineSpace space_;
  const FitOptions& o_;
  BandedSymmetric K_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
  bool analyzed_ = false;
  Eigen::MatrixXd guess_;
  double lambda_;
};

// |Q - S(u, v)| at fixed parameters (the residual the fit itself minimises when the parameters
// are not corrected), signed by the side of the parameter plane (local t3) Q lies on: the
// surface normal's side wherever the surface does not fold, which check_no_fold enforces.
void parameter_residuals(const BSplineSurface& s, const std::vector<Eigen::Vector3d>& pts,
                         const std::vector<Eigen::Vector2d>& uv, std::vector<double>& d, int threads) {
  d.resize(pts.size());
  geometry::parallel_blocks(pts.size(), threads, 512, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t k = b; k < e; ++k) {
      const BasisRow bu = basis_row(s.num_poles_u - 1, s.degree_u, uv[k].x(), s.knots_u);
      const BasisRow bv = basis_row(s.num_poles_v - 1, s.degree_v, uv[k].y(), s.knots_v);
      Eigen::Vector3d x = Eigen::Vector3d::Zero();
      for (int a = 0; a <= s.degree_u; ++a) {
        Eigen::Vector3d row = Eigen::Vector3d::Zero();
        for (int c = 0; c <= s.degree_v; ++c) row += bv.values[static_cast<std::size_t>(c)] * s.pole(bu.first + a, bv.first + c);
        x += bu.values[static_cast<std::size_t>(a)] * row;
      }
      const Eigen::Vector3d r = pts[k] - x;
      d[k] = r.z() < 0 ? -r.norm() : r.norm();
    }
  });
}

// Reinsch's criterion (Reinsch 1967, "Smoothing by spline functions"): the smoothest surface
// whose residuals match the noise. lambda is found by bisection on log10(lambda) in
// [-6, 6] such that the RMS of the first fit's residuals (plane parameters, unit weights) equals
// noise_mm; the RMS grows monotonically with lambda. Returns the lambda used.
double smoothing_for_noise(NetSolver& solver, const SplineSpace& space, const std::vector<Eigen::Vector2d>& uv,
                           const std::vector<Eigen::Vector3d>& local, const FitOptions& o) {
  std::vector<double> d;
  auto rms_at = [&](double log_lambda) {
    solver.set_smoothing(std::pow(10.0, log_lambda));
    parameter_residuals(make_surface(space, solver.solve(uv, local, {})), local, uv, d, o.threads);
    return weighted_rms(d, {});
  };
  double lo = -6, hi = 6;
  if (rms_at(lo) >= o.noise_mm) return std::pow(10.0, lo);  // even the least smoothing leaves that much
  if (rms_at(hi) <= o.noise_mm) return std::pow(10.0, hi);  // the data are smoother than the noise
  while (hi - lo > 0.02) {  // lambda to within 5 %
    const double mid = 0.5 * (lo + hi);
    (rms_at(mid) < o.noise_mm ? lo : hi) = mid;
  }
  return std::pow(10.0, 0.5 * (lo + hi));
}

// The two-layer test of FoldOptions on the local points (t3 = height above the plane).
void check_height_field(const std::vector<Eigen::Vector3d>& local, const ParameterBox& box,
                        const PlaneFrame& frame, const FoldOptions& o) {
  if (local.size() < o.min_points) return;
  const CellGrid grid(box, local.size(), o.cell_spacings);
  const double cell = grid.cell_mm;
  const std::size_t ncell = grid.size();
  // Counting sort of the points by cell.
  auto cell_of = [&](const Eigen::Vector3d& x) { return grid.cell_of(x); };
  std::vector<std::size_t> start(ncell + 1, 0);
  for (const auto& x : local) ++start[cell_of(x) + 1];
  for (std::size_t c = 0; c < ncell; ++c) start[c + 1] += start[c];
  std::vector<std::size_t> fill(start.begin(), start.end() - 1), order(local.size());
  for (std::size_t k = 0; k < local.size(); ++k) order[fill[cell_of(local[k])]++] = k;

  std::size_t occupied = 0, flagged = 0;
  double worst_gap = 0;
  Eigen::Vector3d worst_lo, worst_hi;
  std::vector<std::pair<double, std::size_t>> h;
  for (std::size_t c = 0; c < ncell; ++c) {
    const std::size_t n = start[c + 1] - start[c];
    if (n == 0) continue;
    ++occupied;
    if (n < 4) continue;
    h.clear();
    for (std::size_t i = start[c]; i < start[c + 1]; ++i) h.emplace_back(local[order[i]].z(), order[i]);
    std::sort(h.begin(), h.end());
    double gap = 0;
    std::size_t at = 0;
    for (std::size_t i = 2; i + 2 <= n; ++i) {  // >= 2 points on each side
      if (h[i].first - h[i - 1].first > gap) {
        gap = h[i].first - h[i - 1].first;
        at = i;
      }
    }
    if (gap > o.gap_cells * cell) {
      ++flagged;
      if (gap > worst_gap) {
        worst_gap = gap;
        worst_lo = frame.to_world(local[h[at - 1].second]);
        worst_hi = frame.to_world(local[h[at].second]);
      }
    }
  }
  if (flagged >= o.min_cells && static_cast<double>(flagged) >= o.min_fraction * static_cast<double>(occupied)) {
    throw GeometryError("the part folds over its projection plane: points such as " + at_mm(worst_lo) + " and " +
                        at_mm(worst_hi) + " project to the same place but lie " + fixed(worst_gap, 2) +
                        " mm apart along its normal (two layers in " + std::to_string(flagged) + " of " +
                        std::to_string(occupied) +
                        " cells); fitsurf fits a height field over one plane: select one side of the part "
                        "(--keep-above, --keep-box) or fit it in pieces");
  }
}

// The sample of a check_samples x check_samples grid in (u, v) where the surface's slope over its
// plane (the angle between S_u x S_v and the plane normal; beyond 90 degrees it folds) most exceeds
// what FoldOptions allows there: max_slope_deg, or as steep as the data near the surface point
// plus data_margin_deg, at most steepest_deg. Only samples `inside` are looked at.
struct SlopeExcess {
  double excess_deg = -std::numeric_limits<double>::infinity();  // slope - allowed (<= 0: none)
  double slope_deg = 0, allowed_deg = 0, data_deg = -1;
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
};
template <class Inside>
SlopeExcess steepest_excess(const BSplineSurface& local_surface, const DataSlope& data, const ParameterBox& box,
                            const FoldOptions& o, const Inside& inside) {
  const int n = std::max(2, o.check_samples);
  // The widest knot span, mm: the data within it shape the surface at a point.
  double span_mm = 0;
  for (int dir : {0, 1}) {
    const std::vector<double>& T = dir == 0 ? local_surface.knots_u : local_surface.knots_v;
    const double length = dir == 0 ? box.length_u_mm() : box.length_v_mm();
    for (std::size_t k = 0; k + 1 < T.size(); ++k) span_mm = std::max(span_mm, (T[k + 1] - T[k]) * length);
  }
  SlopeExcess worst;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      const Eigen::Vector2d uv((a + 0.5) / n, (b + 0.5) / n);
      if (!inside(uv)) continue;
      const SurfaceDerivatives d = evaluate(local_surface, uv.x(), uv.y(), 1);
      const Eigen::Vector3d nrm = d.su.cross(d.sv);
      const double len = nrm.norm();
      const double c = len > 0 ? nrm.z() / len : -1.0;
      const double slope = std::acos(std::clamp(c, -1.0, 1.0)) * 180 / std::numbers::pi;
      const double near = data.near(d.p.x(), d.p.y(), span_mm);
      const double allowed = std::max(o.max_slope_deg, std::min(near + o.data_margin_deg, o.steepest_deg));
      if (slope - allowed > worst.excess_deg) worst = {slope - allowed, slope, allowed, near, uv};
    }
  }
  return worst;
}

// Adaptive knots come from a first fit (fit_net); the coarse nets of the screening take uniform ones.
std::vector<double> knots_for(KnotPlacement placement, const std::vector<Eigen::Vector2d>& uv, int num_poles,
                              int degree, int coordinate) {
  if (placement != KnotPlacement::Averaged) return clamped_uniform_knots(num_poles, degree, 0.0, 1.0);
  std::vector<double> params(uv.size());
  for (std::size_t k = 0; k < uv.size(); ++k) params[k] = uv[k][coordinate];
  return averaged_knots(std::move(params), num_poles, degree);
}

}  // namespace

void validate(const FitOptions& o) {
  auto need = [](bool ok, const std::string& what) {
    if (!ok) throw UsageError(what);
  };
  need(o.degree_u >= 1 && o.degree_u <= kMaxBSplineDegree && o.degree_v >= 1 && o.degree_v <= kMaxBSplineDegree,
       "degrees must be 1.." + std::to_string(kMaxBSplineDegree));
  need(o.poles_u >= o.degree_u + 1 && o.poles_v >= o.degree_v + 1,
       "a degree " + std::to_string(o.degree_u) + "x" + std::to_string(o.degree_v) + " surface needs a net of at least " +
           std::to_string(o.degree_u + 1) + "x" + std::to_string(o.degree_v + 1) + " poles, got " +
           std::to_string(o.poles_u) + "x" + std::to_string(o.poles_v));
  need(o.max_net_poles >= 1, "--max-net-poles must be >= 1");
  need(static_cast<long long>(o.poles_u) * o.poles_v <= o.max_net_poles,
       "a " + std::to_string(o.poles_u) + "x" + std::to_string(o.poles_v) + " net has " +
           std::to_string(static_cast<long long>(o.poles_u) * o.poles_v) + " poles, more than the work limit --max-net-poles " +
           std::to_string(o.max_net_poles) + ": use a smaller --net, or raise --max-net-poles for a job this large");
  need(std::isfinite(o.smoothing_mm4) && o.smoothing_mm4 >= 0, "--smoothing must be >= 0");
  need(o.smoothing_order == 2 || o.smoothing_order == 3, "--smoothing-order must be 2 or 3");
  need(std::isfinite(o.noise_mm) && o.noise_mm >= 0, "--noise-mm must be >= 0");
  need(o.max_rounds >= 1, "--max-rounds must be >= 1");
  need(o.min_rms_gain >= 0 && o.min_rms_gain < 1, "--min-gain must be in [0, 1)");
  need(o.robust_threshold >= 0, "--robust-threshold must be >= 0");
  need(o.gross_threshold > 0 && o.gross_points_per_pole > 0, "the gross-outlier screening options must be positive");
  need(o.robust_min_scale_mm > 0, "--robust-floor-mm must be positive");
  need(o.adaptive_knot_ratio >= 1 && o.adaptive_knot_floor_mm > 0, "the adaptive knots' ratio must be >= 1 and floor > 0");
  need(o.cg_tolerance > 0, "--cg-tolerance must be positive");
  need(o.cg_max_iterations > 0, "the CG iterations must be positive");
  need(o.threads >= 0, "--threads must be >= 0");
  need(o.fold.data_margin_deg >= 0 && o.fold.steepest_deg > 0 && o.fold.steepest_deg <= 90,
       "the fold check's data margin must be >= 0 and its steepest slope in (0, 90] degrees");
  need(o.prefer_pca_deg >= 0 && o.slope.cell_spacings > 0 && o.slope.min_points >= 3 &&
           o.slope.score_quantile >= 0 && o.slope.score_quantile <= 1,
       "the plane choice's options are out of range");
}

std::vector<double> averaged_knots(std::vector<double> params, int num_poles, int p) {
  const int n = num_poles - 1;
  const int spans = n - p + 1;
  if (params.size() < static_cast<std::size_t>(spans) + 1) return clamped_uniform_knots(num_poles, p, 0.0, 1.0);
  std::sort(params.begin(), params.end());
  std::vector<double> U(static_cast<std::size_t>(num_poles + p + 1), 0.0);
  for (int k = num_poles; k <= num_poles + p; ++k) U[static_cast<std::size_t>(k)] = 1.0;
  // NURBS Book (9.68)-(9.69): d = (m+1)/(n-p+1); u_{p+j} = (1-alpha) ubar_{i-1} + alpha ubar_i,
  // i = int(j d), alpha = j d - i, j = 1..n-p.
  const double d = static_cast<double>(params.size()) / spans;
  for (int j = 1; j <= n - p; ++j) {
    const std::size_t i = static_cast<std::size_t>(j * d);
    const double alpha = j * d - static_cast<double>(i);
    U[static_cast<std::size_t>(p + j)] = (1 - alpha) * params[i - 1] + alpha * params[std::min(i, params.size() - 1)];
  }
  // Keep interior knots apart (ties in the data would give multiple knots, empty spans).
  const double gap = 0.05 / spans;
  for (int k = p + 1; k <= n; ++k) {
    U[static_cast<std::size_t>(k)] = std::max(U[static_cast<std::size_t>(k)], U[static_cast<std::size_t>(k - 1)] + gap);
  }
  for (int k = n; k >= p + 1; --k) {
    U[static_cast<std::size_t>(k)] = std::min(U[static_cast<std::size_t>(k)], U[static_cast<std::size_t>(k + 1)] - gap);
  }
  return U;
}

std::vector<double> adaptive_knots(const BSplineSurface& first, int direction, int num_poles, double ratio,
                                   double floor_mm) {
  const int p = direction == 0 ? first.degree_u : first.degree_v;
  const std::vector<double>& T = direction == 0 ? first.knots_u : first.knots_v;
  const int n = (direction == 0 ? first.num_poles_u : first.num_poles_v) - 1;
  const int rows = direction == 0 ? first.num_poles_v : first.num_poles_u;
  const int spans = n - p + 1;
  const int new_spans = num_poles - p;
  if (spans < 2 || new_spans < 1 || !(ratio >= 1)) return clamped_uniform_knots(num_poles, p, 0.0, 1.0);
  // Squared jumps of the p-th derivative at the interior knots T[p + b], b = 1..spans-1, summed over rows.
  std::vector<double> jump2(static_cast<std::size_t>(spans + 1), 0.0);
  std::vector<Eigen::Vector3d> Q(static_cast<std::size_t>(n + 1));
  for (int row = 0; row < rows; ++row) {
    for (int i = 0; i <= n; ++i) Q[static_cast<std::size_t>(i)] = direction == 0 ? first.pole(i, row) : first.pole(row, i);
    // The NURBS Book eq. 3.8: P^(k)_i = (p - k + 1) / (u_{i+p+1} - u_{i+k}) (P^(k-1)_{i+1} - P^(k-1)_i);
    // after k = p, Q[i] (i = 0..n-p) is the constant p-th derivative on the span [T[i+p], T[i+p+1]].
    for (int k = 1; k <= p; ++k) {
      for (int i = 0; i <= n - k; ++i) {
        const double du = T[static_cast<std::size_t>(i + p + 1)] - T[static_cast<std::size_t>(i + k)];
        Q[static_cast<std::size_t>(i)] = du > 0 ? Eigen::Vector3d((p - k + 1) / du * (Q[static_cast<std::size_t>(i + 1)] - Q[static_cast<std::size_t>(i)]))
                                                : Eigen::Vector3d::Zero();
      }
    }
    for (int b = 1; b < spans; ++b) {
      const double width = 0.5 * (T[static_cast<std::size_t>(p + b + 1)] - T[static_cast<std::size_t>(p + b - 1)]);
      const double j = width > 0 ? (Q[static_cast<std::size_t>(b)] - Q[static_cast<std::size_t>(b - 1)]).norm() / width : 0.0;
      jump2[static_cast<std::size_t>(b)] += j * j;
    }
  }
  // Density on each span: |D^(p+1) f|^(1/(p+1)), |D^(p+1) f| the mean of the RMS jumps at its ends.
  std::vector<double> g(static_cast<std::size_t>(spans));
  double mean = 0;
  for (int i = 0; i < spans; ++i) {
    double a = 0;
    int m = 0;
    for (int b : {i, i + 1}) {
      if (b >= 1 && b < spans) {
        a += std::sqrt(jump2[static_cast<std::size_t>(b)] / rows);
        ++m;
      }
    }
    const double h = T[static_cast<std::size_t>(i + p + 1)] - T[static_cast<std::size_t>(i + p)];
    g[static_cast<std::size_t>(i)] = h > 0 ? std::pow(a / m + floor_mm / std::pow(h, p + 1), 1.0 / (p + 1)) : 0.0;
    mean += g[static_cast<std::size_t>(i)] * h;
  }
  if (!(mean > 0) || !std::isfinite(mean)) return clamped_uniform_knots(num_poles, p, 0.0, 1.0);  // a plane: nothing to follow
  std::vector<double> G(static_cast<std::size_t>(spans + 1), 0.0);  // its integral up to T[p + i]
  for (int i = 0; i < spans; ++i) {
    double& gi = g[static_cast<std::size_t>(i)];
    gi = std::clamp(gi, mean / ratio, mean * ratio);
    G[static_cast<std::size_t>(i + 1)] = G[static_cast<std::size_t>(i)] + gi * (T[static_cast<std::size_t>(i + p + 1)] - T[static_cast<std::size_t>(i + p)]);
  }
  std::vector<double> U(static_cast<std::size_t>(num_poles + p + 1), 0.0);
  for (int k = num_poles; k <= num_poles + p; ++k) U[static_cast<std::size_t>(k)] = 1.0;
  int i = 0;
  for (int j = 1; j < new_spans; ++j) {
    const double t = G.back() * j / new_spans;
    while (i < spans - 1 && G[static_cast<std::size_t>(i + 1)] <= t) ++i;
    U[static_cast<std::size_t>(p + j)] = T[static_cast<std::size_t>(i + p)] + (t - G[static_cast<std::size_t>(i)]) / g[static_cast<std::size_t>(i)];
  }
  return U;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void require_points(std::size_t n, const FitOptions& o) {
  const int p = o.degree_u, q = o.degree_v;
  const std::size_t needed = static_cast<std::size_t>((p + 1) * (q + 1));
  if (n < needed) {
    throw GeometryError(std::to_string(n) + " points are too few for a degree " + std::to_string(p) + "x" +
                        std::to_string(q) + " surface: at least " + std::to_string(needed) + " are needed");
  }
}

namespace {

FitResult fit_net(const std::vector<Eigen::Vector3d>& points, const FitOptions& o,
                  const std::vector<double>& point_weights);

// The points in the frame of the parameter plane.
std::vector<Eigen::Vector3d> to_local(const std::vector<Eigen::Vector3d>& points, const PlaneFrame& frame, int threads) {
  std::vector<Eigen::Vector3d> local(points.size());
  geometry::parallel_blocks(points.size(), threads, 2048, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t k = b; k < e; ++k) local[k] = frame.to_local(points[k]);
  });
  return local;
}

// The net's degrees, pole counts and knots (o.knots; adaptive ones from a first fit).
SplineSpace net_space(const std::vector<Eigen::Vector3d>& points, const FitOptions& o,
                      const std::vector<double>& point_weights, const std::vector<Eigen::Vector2d>& uv) {
  SplineSpace space;
  space.p = o.degree_u;
  space.q = o.degree_v;
  space.nu = o.poles_u;
  space.nv = o.poles_v;
  if (o.knots == KnotPlacement::Adaptive) {
    // The first fit, with uniform knots and the same options, shows where the shape needs them.
    FitOptions first = o;
    first.knots = KnotPlacement::Uniform;
    const FitResult f = fit_net(points, first, point_weights);
    space.U = adaptive_knots(f.local_surface, 0, o.poles_u, o.adaptive_knot_ratio, o.adaptive_knot_floor_mm);
    space.V = adaptive_knots(f.local_surface, 1, o.poles_v, o.adaptive_knot_ratio, o.adaptive_knot_floor_mm);
  } else {
    space.U = knots_for(o.knots, uv, o.poles_u, space.p, 0);
    space.V = knots_for(o.knots, uv, o.poles_v, space.q, 1);
  }
  return space;
}

// The weights of the fit: the points' own (point_weights) times the robust ones.
std::vector<double> total_weights(const std::vector<double>& point_weights, const std::vector<double>& robust) {
  if (point_weights.empty()) return robust;
  std::vector<double> t(point_weights);
  if (!robust.empty()) {
    for (std::size_t k = 0; k < t.size(); ++k) t[k] *= robust[k];
  }
  return t;
}

// Gross outliers first (why and how: FitOptions::gross_threshold): rejected against a coarse
// first fit; when there are any, w becomes the screen's weights (0 for them, 1 for the rest).
// d gets the coarse fit's residuals.
void screen_gross_outliers(const SplineSpace& space, const std::vector<Eigen::Vector2d>& uv,
                           const std::vector<Eigen::Vector3d>& local, const std::vector<double>& point_weights,
                           const FitOptions& o, FitResult& r, std::vector<double>& w, std::vector<double>& d) {
  const int p = o.degree_u, q = o.degree_v;
  SplineSpace coarse = space;
  const double n = static_cast<double>(local.size()) / o.gross_points_per_pole;
  const double aspect = r.box.length_u_mm() / r.box.length_v_mm();
  coarse.nu = std::clamp(static_cast<int>(std::lround(std::sqrt(n * aspect))), p + 1, space.nu);
  coarse.nv = std::clamp(static_cast<int>(std::lround(std::sqrt(n / aspect))), q + 1, space.nv);
  coarse.U = knots_for(o.knots, uv, coarse.nu, p, 0);
  coarse.V = knots_for(o.knots, uv, coarse.nv, q, 1);
  NetSolver screen_solver(coarse, o, r.box.length_u_mm(), r.box.length_v_mm());
  screen_solver.set_smoothing(r.smoothing_mm4);
  bool screened = true;
  try {
    parameter_residuals(make_surface(coarse, screen_solver.solve(uv, local, total_weights(point_weights, w))), local, uv, d,
                        o.threads);
  } catch (const GeometryError& e) {  // e.g. no smoothing over a gap: the fit itself will say so
    log::debug(std::string("no gross-outlier screening: ") + e.what());
    screened = false;
  }
  FitOptions gross = o;
  gross.robust = RobustLoss::Reject;
  gross.robust_threshold = o.gross_threshold;
  std::vector<double> screen;
  const Weighting g = screened ? robust_weights(local_residuals(uv, d, r.box.length_u_mm(), r.box.length_v_mm(), o.threads),
                                                gross, screen)
                               : Weighting{};
  r.gross_outliers = g.outliers;
  if (g.outliers > 0) {
    log::debug(std::to_string(g.outliers) + " gross outliers (off their neighbours' height by more than " +
               sig(g.cutoff_mm, 3) + " mm against a " + std::to_string(coarse.nu) + "x" + std::to_string(coarse.nv) +
               " first fit) left out from the start");
    w = std::move(screen);
  }
}

// The slope check of check_no_fold on r.local_surface, on the grid cells that hold a foot point
// (r.uv); `occupied` is the cells' scratch space.
SlopeExcess slope_excess_at_points(const FitResult& r, const FitOptions& o, std::vector<std::uint8_t>& occupied) {
  const int grid = std::max(2, o.fold.check_samples);
  occupied.assign(static_cast<std::size_t>(grid) * grid, 0);
  for (const auto& x : r.uv) {
    const int a = std::clamp(static_cast<int>(x.x() * grid), 0, grid - 1);
    const int b = std::clamp(static_cast<int>(x.y() * grid), 0, grid - 1);
    occupied[static_cast<std::size_t>(a) * grid + b] = 1;
  }
  return steepest_excess(r.local_surface, r.data_slope, r.box, o.fold, [&](const Eigen::Vector2d& x) {
    return occupied[static_cast<std::size_t>(x.x() * grid) * grid + static_cast<std::size_t>(x.y() * grid)] != 0;
  });
}

// The rounds of the fit (fit.hpp, steps 2-4): fit, correct the parameters (or take the residuals
// at fixed ones), reweight, until the RMS stops improving and the weights have settled, or
// o.max_rounds. Leaves the surface, the parameters and the rounds' RMS in r, the last
// residuals in d, the robust weights in w; uv follows the corrected parameters.
void fit_rounds(NetSolver& solver, const SplineSpace& space, std::vector<Eigen::Vector2d>& uv,
                const std::vector<Eigen::Vector3d>& local, const std::vector<double>& point_weights, const FitOptions& o,
                bool reweight, std::vector<double>& w, std::vector<double>& d, FitResult& r) {
  const auto total = [&](const std::vector<double>& robust) { return total_weights(point_weights, robust); };
  // RMS of the previous round's residuals under the weights of this round's fit: with the weights
  // fixed, refitting and then projecting can only lower it, so the gain measures convergence.
  double previous = std::numeric_limits<double>::infinity();
  // The first weighting restarts from the plane parameters: outliers (near the edge of the data
  // most) can curl the unweighted first fit so far that projecting onto it scrambles the
  // parameters of the points there, which no reweighting repairs (docs/measurements/fitsurf.md).
  const std::vector<Eigen::Vector2d> plane_uv = reweight && o.parameter_correction ? uv : std::vector<Eigen::Vector2d>{};
  bool weighted = false;
  // The last round whose surface kept within the slopes FoldOptions allows (stop_before_fold).
  struct Kept {
    BSplineSurface surface;
    std::vector<Eigen::Vector2d> uv;
    std::vector<double> d;
  };
  std::optional<Kept> kept;
  std::vector<std::uint8_t> occupied;
  for (int round = 0; round < o.max_rounds; ++round) {
    r.local_surface = make_surface(space, solver.solve(uv, local, total(w)));
    r.uv = uv;
    if (o.parameter_correction) {
      project_points(r.local_surface, local, r.uv, d, o.projection, o.threads);
    } else {
      parameter_residuals(r.local_surface, local, uv, d, o.threads);
    }
    if (o.stop_before_fold && o.parameter_correction) {
      const SlopeExcess e = slope_excess_at_points(r, o, occupied);
      if (e.excess_deg > 0 && kept) {
        log::debug("round " + std::to_string(round + 1) + " undone: slope " + fixed(e.slope_deg, 1) +
                   " degrees at u " + fixed(e.uv.x(), 3) + ", v " + fixed(e.uv.y(), 3) + " (at most " +
                   fixed(e.allowed_deg, 1) + " allowed there)");
        r.local_surface = std::move(kept->surface);
        r.uv = std::move(kept->uv);
        d = std::move(kept->d);
        r.stopped_at_round = round;
        break;
      }
      if (e.excess_deg <= 0) kept = Kept{r.local_surface, r.uv, d};
    }
    const double rms = weighted_rms(d, total(w));
    r.round_rms_mm.push_back(rms);
    log::debug("round " + std::to_string(round + 1) + ": RMS " + sig(rms, 6) + " mm");
    if (!o.parameter_correction && !reweight) break;
    // Converged when the RMS has stopped improving and the weights have settled (else the last fit
    // would not be the one its own residuals call for).
    bool weights_changed = false;
    // Reweighting starts once the parameters have been corrected: the first fit's residuals, at
    // the plane parameters, overstate the error on steep parts.
    if (reweight && (round >= 1 || !o.parameter_correction)) {
      std::vector<double> next;
      robust_weights(local_residuals(r.uv, d, r.box.length_u_mm(), r.box.length_v_mm(), o.threads), o, next);
      for (std::size_t k = 0; k < next.size() && !weights_changed; ++k) {
        weights_changed = std::abs(next[k] - (w.empty() ? 1.0 : w[k])) > o.weight_tolerance;
      }
      w = std::move(next);
    }
    if (rms >= previous * (1 - o.min_rms_gain) && !weights_changed) break;
    previous = weighted_rms(d, total(w));
    if (o.parameter_correction) uv = r.uv;
    if (weights_changed && !weighted && !plane_uv.empty()) {
      weighted = true;
      uv = plane_uv;
      previous = std::numeric_limits<double>::infinity();
    }
  }
}

// The weights and outliers reported for the n points' final residuals (r.residual_mm): the
// robust weighting's, else the gross screening's (w), else all 1.
void report_weights(const FitOptions& o, bool reweight, const std::vector<double>& w, std::size_t n, FitResult& r) {
  if (reweight) {
    const Weighting wt = robust_weights(
        local_residuals(r.uv, r.residual_mm, r.box.length_u_mm(), r.box.length_v_mm(), o.threads), o, r.weight, &r.outlier);
    r.robust_applied = true;
    r.robust_scale_mm = wt.scale_mm;
    r.robust_cutoff_mm = wt.cutoff_mm;
    r.outliers = wt.outliers;
  } else if (!w.empty()) {  // only the gross outliers were left out
    r.weight = w;
    r.outlier.assign(n, 0);
    for (std::size_t k = 0; k < w.size(); ++k) {
      r.outlier[k] = w[k] == 0.0;
      r.outliers += r.outlier[k];
    }
  } else {
    r.weight.assign(n, 1.0);
  }
  if (r.robust_applied) {
    r.robust_poles_u = o.poles_u;
    r.robust_poles_v = o.poles_v;
  }
}

FitResult fit_net(const std::vector<Eigen::Vector3d>& points, const FitOptions& o,
                  const std::vector<double>& point_weights) {
  if (!point_weights.empty() && point_weights.size() != points.size()) {
    throw UsageError("fit_surface: " + std::to_string(point_weights.size()) + " point weights for " +
                     std::to_string(points.size()) + " points");
  }
  require_points(points.size(), o);
  const int p = o.degree_u, q = o.degree_v;
  FitResult r;
  r.plane = o.plane;
  r.frame = parameter_frame(points, o.plane, o.frame);
  if (is_flat(r.frame, o.frame)) log::info("the points are flat (a plane fits them): the surface will be a plane");
  const std::vector<Eigen::Vector3d> local = to_local(points, r.frame, o.threads);
  r.box = parameter_box(local);
  check_height_field(local, r.box, r.frame, o.fold);
  r.data_slope = data_slope(local, r.box, o.slope);
  std::vector<Eigen::Vector2d> uv(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) uv[k] = r.box.to_uv(local[k]);

  const SplineSpace space = net_space(points, o, point_weights, uv);
  NetSolver solver(space, o, r.box.length_u_mm(), r.box.length_v_mm());
  const bool reweight = o.robust != RobustLoss::None &&
                        static_cast<double>(points.size()) >= o.robust_min_redundancy * space.num_poles();
  if (o.robust != RobustLoss::None && !reweight) {
    log::debug("robust reweighting off: " + std::to_string(points.size()) + " points for " +
               std::to_string(space.num_poles()) + " poles (fewer than " + sig(o.robust_min_redundancy) + " per pole)");
  }

  if (o.noise_mm > 0) {
    r.smoothing_mm4 = smoothing_for_noise(solver, space, uv, local, o);
    solver.set_smoothing(r.smoothing_mm4);
    log::debug("smoothing " + sig(r.smoothing_mm4, 3) + " mm^4 for residuals of " + sig(o.noise_mm, 3) + " mm");
  } else {
    r.smoothing_mm4 = o.smoothing_mm4;
  }
  std::vector<double> w;  // robust weights; empty: all 1
  std::vector<double> d;
  // The screening's coarse fit has redundancy even where the fine net has too little for reweighting.
  const bool screen_gross = o.robust != RobustLoss::None &&
                            static_cast<double>(points.size()) >= o.gross_points_per_pole * static_cast<double>((p + 1) * (q + 1));
  if (screen_gross) screen_gross_outliers(space, uv, local, point_weights, o, r, w, d);
  fit_rounds(solver, space, uv, local, point_weights, o, reweight, w, d, r);
  r.residual_mm = std::move(d);
  if (!o.parameter_correction && o.final_projection) {
    // The reported residuals are orthogonal distances whatever the method.
    project_points(r.local_surface, local, r.uv, r.residual_mm, o.projection, o.threads);
  }
  report_weights(o, reweight, w, points.size(), r);
  r.surface = r.local_surface;
  for (auto& pole : r.surface.poles_mm) pole = r.frame.to_world(pole);
  return r;
}

}  // namespace

FitOptions with_plane_chosen(const std::vector<Eigen::Vector3d>& points, const FitOptions& options, double& pca_deg,
                             double& xy_deg) {
  pca_deg = xy_deg = -1;
  if (options.plane != PlaneChoice::Auto) return options;
  require_points(points.size(), options);
  FitOptions chosen = options;
  chosen.plane = choose_plane(points, options.frame, options.slope, options.prefer_pca_deg, &pca_deg, &xy_deg);
  if (chosen.plane == PlaneChoice::Xy) {
    log::info("parameter plane xy: the data's steepest slopes are " + fixed(xy_deg, 1) + " degrees over it, " +
              fixed(pca_deg, 1) + " over their best-fit plane");
  }
  return chosen;
}

FitResult fit_surface(const std::vector<Eigen::Vector3d>& points, const FitOptions& options,
                      const std::vector<double>& point_weights) {
  validate(options);
  if (options.plane == PlaneChoice::Auto) {
    double pca = 0, xy = 0;
    FitResult r = fit_surface(points, with_plane_chosen(points, options, pca, xy), point_weights);
    r.pca_slope_deg = pca;
    r.xy_slope_deg = xy;
    return r;
  }
  const FitOptions& o = options;
  const double n = static_cast<double>(points.size());
  const double poles = static_cast<double>(o.poles_u) * o.poles_v;
  if (o.robust == RobustLoss::None || !o.robust_on_coarser_net || n >= o.robust_min_redundancy * poles) {
    return fit_net(points, o, point_weights);
  }
  // The net lacks the redundancy to judge outliers (FitOptions::robust_on_coarser_net): both pole
  // counts scaled by sqrt(n / (redundancy * poles)) give the finest net of the same aspect that has it.
  const double f = std::sqrt(n / (o.robust_min_redundancy * poles));
  FitOptions coarse = o;
  coarse.poles_u = std::max(o.degree_u + 1, static_cast<int>(std::floor(f * o.poles_u)));
  coarse.poles_v = std::max(o.degree_v + 1, static_cast<int>(std::floor(f * o.poles_v)));
  if (static_cast<double>(coarse.poles_u) * coarse.poles_v * o.robust_min_redundancy > n) {
    return fit_net(points, o, point_weights);  // too few points for any net: no reweighting (fit_net says so)
  }
  log::debug("robust weights judged on a " + std::to_string(coarse.poles_u) + "x" + std::to_string(coarse.poles_v) +
             " net (" + sig(n / poles, 3) + " points per pole of the " + std::to_string(o.poles_u) + "x" +
             std::to_string(o.poles_v) + " net, fewer than " + sig(o.robust_min_redundancy) + ")");
  const FitResult judged = fit_net(points, coarse, point_weights);
  std::vector<double> w = judged.weight;
  if (!point_weights.empty()) {
    for (std::size_t k = 0; k < w.size(); ++k) w[k] *= point_weights[k];
  }
  FitOptions fixed = o;
  fixed.robust = RobustLoss::None;
  FitResult r = fit_net(points, fixed, w);
  r.weight = judged.weight;
  r.outlier = judged.outlier;
  r.robust_applied = judged.robust_applied;
  r.robust_scale_mm = judged.robust_scale_mm;
  r.robust_cutoff_mm = judged.robust_cutoff_mm;
  r.outliers = judged.outliers;
  r.gross_outliers = judged.gross_outliers;
  r.robust_poles_u = judged.robust_poles_u;
  r.robust_poles_v = judged.robust_poles_v;
  return r;
}

void check_no_fold(const FitResult& fit, const std::vector<Eigen::Vector2d>& boundary, const FoldOptions& o) {
  const SlopeExcess e = steepest_excess(fit.local_surface, fit.data_slope, fit.box, o, [&](const Eigen::Vector2d& uv) {
    return boundary.empty() || point_in_polygon(boundary, uv);
  });
  if (e.excess_deg <= 0) return;
  const Eigen::Vector3d x = surface_point(fit.surface, e.uv.x(), e.uv.y());
  std::string what = e.slope_deg >= 90 ? "the fitted surface folds over its projection plane near " + at_mm(x) +
                                             " (slope " + fixed(e.slope_deg, 1) + " degrees"
                                       : "the fitted surface is steeper than allowed near " + at_mm(x) + " (" +
                                             fixed(e.slope_deg, 1) + " degrees over the " + std::string(fit.plane == PlaneChoice::Xy ? "xy" : "pca") +
                                             " plane against at most " + fixed(e.allowed_deg, 1);
  what += ", u " + fixed(e.uv.x(), 3) + ", v " + fixed(e.uv.y(), 3) + "; the data there ";
  what += e.data_deg >= 0 ? "are at most " + fixed(e.data_deg, 1) + " degrees steep)" : "are too sparse for a slope)";
  std::string advice;
  const bool data_too_steep = e.data_deg >= o.steepest_deg - o.data_margin_deg;
  if (data_too_steep) {
    advice = "the data are not a height field over that plane (overhangs, vertical walls): select the part's top "
             "(--keep-above, --keep-box)";
  } else {
    advice = "the surface curls beyond the data between or at the edge of the points: a larger --smoothing keeps it "
             "flatter, --no-correction keeps the points where they project";
  }
  if (fit.pca_slope_deg >= 0) {
    advice += "; the data's steepest slopes are " + fixed(fit.pca_slope_deg, 1) + " degrees over the pca plane and " +
              fixed(fit.xy_slope_deg, 1) + " over xy (--plane)";
  } else {
    advice += "; --plane auto chooses the plane that holds the data best";
  }
  advice += "; --max-slope-deg " + sig(o.max_slope_deg, 3) + " is the limit where the data are not steep";
  if (!data_too_steep) throw CurlError(what + ": " + advice);
  throw GeometryError(what + ": " + advice);
}

}  // namespace photomill::fitsurf
