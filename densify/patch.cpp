#include "densify/patch.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include "match/lsm.hpp"

namespace photomill::densify {

const char* to_string(PatchFailure f) {
  switch (f) {
    case PatchFailure::None: return "accepted";
    case PatchFailure::Behind: return "behind a camera";
    case PatchFailure::Border: return "window leaves the photos";
    case PatchFailure::Singular: return "no texture (singular normal equations)";
    case PatchFailure::NotConverged: return "not converged";
    case PatchFailure::Shift: return "moved too far from the start";
    case PatchFailure::Oblique: return "too oblique";
    case PatchFailure::Bent: return "bent across a crease";
    case PatchFailure::Correlation: return "correlation too low";
    case PatchFailure::Views: return "too few views";
    case PatchFailure::Reprojection: return "free matches off the projection";
    case PatchFailure::Count: break;
  }
  return "?";
}

namespace {

constexpr int kGridPoints = 9;
// The free match of the reprojection error (PatchMatcher::measure): Gauss-Newton iterations and
// the step below which it has converged.
constexpr int kFreeShiftIterations = 4;
constexpr double kFreeShiftConvergedPx = 0.005;

// Geometric parameters: n (3), then with `quadratic` the curvature terms c (3).
constexpr int kMaxGeo = 6;
using LocalMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGeo + 2, kMaxGeo + 2>;
using LocalVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxGeo + 2, 1>;

// The map of the window into one view for the current surface: pixel = C b(d), and its
// derivative with respect to geometric parameter i: D[i] b(d), b the quadratic basis.
struct ViewMap {
  Eigen::Matrix<double, 2, 6> C;
  std::array<Eigen::Matrix<double, 2, 6>, kMaxGeo> D;
  Eigen::Vector2d centre() const { return C.col(0); }  // b(0) = (1, 0, ...)
};

struct RelativePose {
  Eigen::Matrix3d R;  // view_from_ref
  Eigen::Vector3d t;
  Eigen::Vector3d centre_ref;  // the view's centre in the reference frame
};

// One view's part of the normal equations, sum J J^T and sum J e over the window's samples, and
// its sum of squares (PatchMatcher::measure, `evaluate`): J over the G geometric parameters and
// the view's a, b; e = f - a - b g(u(d)). The sums are kept in arrays of compile-time size (the
// lower triangle), as match's normal_equations keeps them: a rank update of a dynamic-size matrix
// per sample cost densify 13 % of its time. False if a sample leaves the photo.
template <int G>
bool accumulate_view(const cv::Mat& grey, const std::vector<std::array<double, 6>>& basis, const std::vector<double>& fv,
                     const ViewMap& m, double a, double b, LocalMatrix* H, LocalVector* g, double* ssr) {
  constexpr int n = G + 2;
  double N[n * (n + 1) / 2] = {};
  double r[n] = {};
  double ss = 0;
  for (std::size_t q = 0; q < basis.size(); ++q) {
    const Eigen::Map<const Eigen::Matrix<double, 6, 1>> bv(basis[q].data());
    double val, gx, gy;
    if (!match::sample_cubic(grey, m.C.row(0).dot(bv), m.C.row(1).dot(bv), val, gx, gy)) return false;
    double J[n];
    for (int i = 0; i < G; ++i) J[i] = -b * (gx * m.D[i].row(0).dot(bv) + gy * m.D[i].row(1).dot(bv));
    J[G] = -1;
    J[G + 1] = -val;
    const double e = fv[q] - a - b * val;
    int k = 0;
    for (int i = 0; i < n; ++i) {
      for (int l = 0; l <= i; ++l) N[k++] += J[i] * J[l];
      r[i] += J[i] * e;
    }
    ss += e * e;
  }
  H->resize(n, n);
  g->resize(n);
  int k = 0;
  for (int i = 0; i < n; ++i) {
    for (int l = 0; l <= i; ++l, ++k) (*H)(i, l) = (*H)(l, i) = N[k];
    (*g)(i) = r[i];
  }
  *ssr += ss;
  return true;
}

}  // namespace

PatchMatcher::PatchMatcher(const geometry::CameraModel& camera, const PatchOptions& options)
    : camera_(camera), shape_(geometry::shape_of(camera)), options_(options) {
  const int h = options_.half_window_px;
  // The window's samples: every window_stride_px-th pixel (the texture is band-limited by the
  // lens and the photo's resolution, so neighbouring pixels carry much the same information).
  const int st = options_.window_stride_px;
  for (int dy = -h; dy <= h; dy += st) {
    for (int dx = -h; dx <= h; dx += st) {
      offsets_.emplace_back(dx, dy);
      // Offsets scaled by h keep the basis well conditioned (the fit below uses the same scale).
      const double x = static_cast<double>(dx) / h, y = static_cast<double>(dy) / h;
      basis_.push_back({1.0, x, y, x * x, x * y, y * y});
    }
  }
  Eigen::Matrix<double, kGridPoints, 6> A;
  int s = 0;
  for (int gy = -1; gy <= 1; ++gy) {
    for (int gx = -1; gx <= 1; ++gx) {
      grid_[s] = Eigen::Vector2i(gx * h, gy * h);
      A.row(s) << 1.0, gx, gy, gx * gx, gx * gy, gy * gy;
      ++s;
    }
  }
  // coef = (A^T A)^-1 A^T values: the least-squares quadratic through the 9 grid values.
  fit_ = (A.transpose() * A).ldlt().solve(A.transpose());
  if (options_.quadratic && options_.max_bend_deg < 180 && options_.bend_check_half_window_px > 0 &&
      options_.bend_check_half_window_px < h) {
    PatchOptions small = options_;
    small.half_window_px = options_.bend_check_half_window_px;
    small.window_stride_px = 1;
    small.centre_half_window_px = std::min(options_.centre_half_window_px, small.half_window_px);
    small.max_bend_deg = 180;
    small_ = std::make_shared<const PatchMatcher>(camera, small);
  }
}

PatchFailure PatchMatcher::measure(const std::vector<PatchView>& views, int ref, const Eigen::Vector2i& centre,
                                   const Eigen::Vector3d& plane0, const std::vector<int>& candidates,
                                   PatchResult* out) const {
  const PatchOptions& o = options_;
  const cv::Mat& f = views[ref].grey;
  const int h = o.half_window_px;
  if (centre.x() - h < 0 || centre.y() - h < 0 || centre.x() + h >= f.cols || centre.y() + h >= f.rows) {
    return PatchFailure::Border;
  }
  // The reference window (integer pixels: no interpolation) and its spread.
  const std::size_t n_pix = offsets_.size();
  std::vector<double> fv(n_pix);
  double f_mean = 0;
  for (std::size_t k = 0; k < n_pix; ++k) {
    fv[k] = f.at<float>(centre.y() + offsets_[k].y(), centre.x() + offsets_[k].x());
    f_mean += fv[k];
  }
  f_mean /= static_cast<double>(n_pix);
  double f_var = 0;
  for (double v : fv) f_var += (v - f_mean) * (v - f_mean);
  if (!(f_var > 1e-6 * static_cast<double>(n_pix))) return PatchFailure::Singular;

  // The rays of the 3 x 3 grid (undistorted, z = 1).
  std::array<Eigen::Vector3d, kGridPoints> rays;
  for (int s = 0; s < kGridPoints; ++s) {
    const auto xy = geometry::undistort(camera_, (centre + grid_[s]).cast<double>());
    if (!xy) return PatchFailure::Border;
    rays[s] = Eigen::Vector3d(xy->x(), xy->y(), 1.0);
  }
  const Eigen::Vector3d& ray0 = rays[4];

  std::vector<RelativePose> rel(views.size());
  const Eigen::Matrix3d& Rr = views[ref].rotation;
  const Eigen::Vector3d& tr = views[ref].translation_mm;
  for (int j : candidates) {
    rel[j].R = views[j].rotation * Rr.transpose();
    rel[j].t = views[j].translation_mm - rel[j].R * tr;
    rel[j].centre_ref = -rel[j].R.transpose() * rel[j].t;
  }

  // The map of the window into view j for plane n (false: a grid point behind the plane's
  // horizon or behind the view).
  const double* k = camera_.params.data();
  const int G = o.quadratic ? 6 : 3;
  auto map_view = [&](const Eigen::Vector3d& n, const Eigen::Vector3d& c, int j, ViewMap* m) {
    Eigen::Matrix<double, 2, kGridPoints> pix;
    std::array<Eigen::Matrix<double, 2, kGridPoints>, kMaxGeo> dpix;
    for (int s = 0; s < kGridPoints; ++s) {
      const Eigen::Vector3d& r = rays[s];
      // Inverse depth along the ray: w(d) = n . r(d) + c . q(d), q = (x^2, x y, y^2) of the
      // offset in half-windows (0 at the centre, so the centre's point is r0 / (n . r0)).
      const double qx = grid_[s].x() / static_cast<double>(h), qy = grid_[s].y() / static_cast<double>(h);
      const Eigen::Vector3d q(qx * qx, qx * qy, qy * qy);
      const double denom = n.dot(r) + (G == 6 ? c.dot(q) : 0.0);
      if (!(denom > 0)) return false;
      const Eigen::Vector3d X = r / denom;
      const Eigen::Vector3d Xj = rel[j].R * X + rel[j].t;
      if (!(Xj.z() > 0)) return false;
      const double xn = Xj.x() / Xj.z(), yn = Xj.y() / Xj.z();
      double u, v;
      geometry::distort_to_pixel(shape_, k, xn, yn, &u, &v);
      pix(0, s) = u;
      pix(1, s) = v;
      // d pixel / d (xn, yn) by central differences (the distortion is smooth; 1e-6 in normalised
      // coordinates is ~0.002 px, and the error of the difference is of order eps^2).
      constexpr double eps = 1e-6;
      double u1, v1, u2, v2, u3, v3, u4, v4;
      geometry::distort_to_pixel(shape_, k, xn + eps, yn, &u1, &v1);
      geometry::distort_to_pixel(shape_, k, xn - eps, yn, &u2, &v2);
      geometry::distort_to_pixel(shape_, k, xn, yn + eps, &u3, &v3);
      geometry::distort_to_pixel(shape_, k, xn, yn - eps, &u4, &v4);
      Eigen::Matrix2d Jd;
      Jd << (u1 - u2) / (2 * eps), (u3 - u4) / (2 * eps), (v1 - v2) / (2 * eps), (v3 - v4) / (2 * eps);
      Eigen::Matrix<double, 2, 3> Jn;
      Jn << 1 / Xj.z(), 0, -Xj.x() / (Xj.z() * Xj.z()), 0, 1 / Xj.z(), -Xj.y() / (Xj.z() * Xj.z());
      // X = r / w: dX/dn = -r r^T / w^2, dX/dc = -r q^T / w^2.
      const Eigen::Vector2d dpdw = Jd * Jn * rel[j].R * (-r / (denom * denom));
      for (int i = 0; i < 3; ++i) dpix[i].col(s) = dpdw * r(i);
      if (G == 6) {
        for (int i = 0; i < 3; ++i) dpix[3 + i].col(s) = dpdw * q(i);
      }
    }
    m->C = pix * fit_.transpose();
    for (int i = 0; i < G; ++i) m->D[i] = dpix[i] * fit_.transpose();
    return true;
  };
  auto inside = [&](const Eigen::Vector2d& p) {
    const double margin = 1.5 * h + 3;
    return p.x() >= margin && p.y() >= margin && p.x() < f.cols - margin && p.y() < f.rows - margin;
  };

  Eigen::Vector3d n = plane0;
  Eigen::Vector3d curv = Eigen::Vector3d::Zero();
  if (!(n.dot(ray0) > 0)) return PatchFailure::Behind;
  // The views that see the plane's front with the whole window inside the photo.
  std::vector<int> active;
  std::vector<Eigen::Vector2d> start;
  std::vector<ViewMap> maps;
  for (int j : candidates) {
    if (!(n.dot(rel[j].centre_ref) < 1)) continue;  // the view is behind the plane
    ViewMap m;
    if (!map_view(n, curv, j, &m) || !inside(m.centre())) continue;
    active.push_back(j);
    start.push_back(m.centre());
    maps.push_back(m);
  }
  if (static_cast<int>(active.size()) < o.min_views - 1) return PatchFailure::Views;

  // Radiometric start: the view's window scaled to the reference's mean and spread.
  std::vector<double> a(active.size()), b(active.size());
  auto sample_window = [&](int j, const ViewMap& m, std::vector<double>* g) {
    g->resize(n_pix);
    for (std::size_t q = 0; q < n_pix; ++q) {
      const auto& bq = basis_[q];
      const Eigen::Map<const Eigen::Matrix<double, 6, 1>> bv(bq.data());
      const double u = m.C.row(0) * bv, v = m.C.row(1) * bv;
      double val, gx, gy;
      if (!match::sample_cubic(views[j].grey, u, v, val, gx, gy)) return false;
      (*g)[q] = val;
    }
    return true;
  };
  // The correlation over the window's centre alone (every pixel of the central
  // 2 centre_half_window_px + 1 square): where the centre pixel sees past a depth edge (a wall's
  // rim) while most of the window lies on the near face, the whole window still matches on the
  // near face's surface and would put the point in the air beyond the edge ("foreground
  // fattening"); the centre's own pixels do not match there.
  const int ch = std::min(o.centre_half_window_px, h);
  std::vector<double> fc;
  for (int dy = -ch; dy <= ch; ++dy) {
    for (int dx = -ch; dx <= ch; ++dx) fc.push_back(f.at<float>(centre.y() + dy, centre.x() + dx));
  }
  auto centre_correlation = [&](const cv::Mat& gimg, const ViewMap& m) -> std::optional<double> {
    std::vector<double> gc;
    gc.reserve(fc.size());
    for (int dy = -ch; dy <= ch; ++dy) {
      for (int dx = -ch; dx <= ch; ++dx) {
        const double x = static_cast<double>(dx) / h, y = static_cast<double>(dy) / h;
        const Eigen::Matrix<double, 6, 1> bv = (Eigen::Matrix<double, 6, 1>() << 1.0, x, y, x * x, x * y, y * y).finished();
        double val, gx, gy;
        if (!match::sample_cubic(gimg, m.C.row(0) * bv, m.C.row(1) * bv, val, gx, gy)) return std::nullopt;
        gc.push_back(val);
      }
    }
    return match::correlation_of(fc, gc);
  };
  {
    std::vector<double> g;
    for (std::size_t v = 0; v < active.size(); ++v) {
      if (!sample_window(active[v], maps[v], &g)) return PatchFailure::Border;
      double gm = 0, gvar = 0;
      for (double x : g) gm += x;
      gm /= static_cast<double>(n_pix);
      for (double x : g) gvar += (x - gm) * (x - gm);
      if (!(gvar > 0)) return PatchFailure::Singular;
      b[v] = std::sqrt(f_var / gvar);
      a[v] = f_mean - b[v] * gm;
    }
  }

  // Levenberg-Marquardt on (n, [c,] a_1, b_1, ..., a_m, b_m); e = f - a_j - b_j g_j(u_j(d; n, c)).
  // Gauss-Newton alone overshoots along the curvature terms and wanders for many iterations; a
  // step that raises the sum of squares is taken back and the damping raised (More 1978).
  Eigen::MatrixXd H;
  double ssr = 0;
  int iterations = 0;
  bool converged = false;
  bool refit = false;  // views were dropped after convergence: converge again with the rest
  // Sums of squares and normal equations at the current parameters; false if a window left a
  // photo or the surface turned behind a view.
  auto evaluate = [&](Eigen::MatrixXd* Hout, Eigen::VectorXd* gout, double* ssr_out) {
    const int P = G + 2 * static_cast<int>(active.size());
    *Hout = Eigen::MatrixXd::Zero(P, P);
    *gout = Eigen::VectorXd::Zero(P);
    *ssr_out = 0;
    for (std::size_t v = 0; v < active.size(); ++v) {
      const int j = active[v];
      ViewMap& m = maps[v];
      if (!map_view(n, curv, j, &m)) return false;
      LocalMatrix Hl(G + 2, G + 2);
      LocalVector gl(G + 2);
      const bool ok = G == 6 ? accumulate_view<6>(views[j].grey, basis_, fv, m, a[v], b[v], &Hl, &gl, ssr_out)
                             : accumulate_view<3>(views[j].grey, basis_, fv, m, a[v], b[v], &Hl, &gl, ssr_out);
      if (!ok) return false;
      const int c = G + 2 * static_cast<int>(v);
      Hout->topLeftCorner(G, G) += Hl.topLeftCorner(G, G);
      Hout->block(0, c, G, 2) += Hl.block(0, G, G, 2);
      Hout->block(c, 0, 2, G) += Hl.block(G, 0, 2, G);
      Hout->block<2, 2>(c, c) += Hl.block<2, 2>(G, G);
      gout->head(G) += gl.head(G);
      gout->segment<2>(c) += gl.segment<2>(G);
    }
    return true;
  };
  while (true) {
    converged = false;
    Eigen::VectorXd grad;
    if (!evaluate(&H, &grad, &ssr)) return PatchFailure::Border;
    // The accepted state.
    Eigen::Vector3d n_ok = n, curv_ok = curv;
    std::vector<double> a_ok = a, b_ok = b;
    double lambda = 1e-4;
    for (iterations = 1; iterations <= o.max_iterations; ++iterations) {
      // Solved with Jacobi scaling (the plane's terms are ~1/depth, the curvature's far smaller):
      // (S H S + lambda I) y = -S g, step = S y, S = diag(H)^-1/2; singular when a scaled pivot
      // of S H S vanishes.
      const Eigen::VectorXd scale = H.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
      const Eigen::MatrixXd A = scale.asDiagonal() * H * scale.asDiagonal();
      if (iterations == 1) {
        const Eigen::LDLT<Eigen::MatrixXd> plain(A);
        if (plain.info() != Eigen::Success || !(plain.vectorD().minCoeff() > 1e-10)) return PatchFailure::Singular;
      }
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(A + lambda * Eigen::MatrixXd::Identity(A.rows(), A.cols()));
      Eigen::VectorXd step = -scale.cwiseProduct(ldlt.solve(scale.cwiseProduct(grad)));
      if (!step.allFinite()) return PatchFailure::Singular;
      // The window centre's move in each view (linearised) decides convergence; a step moving it
      // more than 2 px is shortened to 2 px.
      double move = 0;
      for (const ViewMap& m : maps) {
        Eigen::Vector2d du = Eigen::Vector2d::Zero();
        for (int i = 0; i < G; ++i) du += m.D[i].col(0) * step(i);
        move = std::max(move, du.norm());
      }
      if (move > 2) {
        step *= 2 / move;
        move = 2;
      }
      n += step.head<3>();
      if (G == 6) curv += step.segment<3>(3);
      for (std::size_t v = 0; v < active.size(); ++v) {
        a[v] += step(G + 2 * static_cast<int>(v));
        b[v] += step(G + 1 + 2 * static_cast<int>(v));
      }
      if (move < o.converged_px) {
        converged = n.dot(ray0) > 0;
        break;
      }
      Eigen::MatrixXd H_new;
      Eigen::VectorXd g_new;
      double ssr_new = 0;
      if (n.dot(ray0) > 0 && evaluate(&H_new, &g_new, &ssr_new) && ssr_new <= ssr) {
        H = std::move(H_new);
        grad = std::move(g_new);
        ssr = ssr_new;
        n_ok = n;
        curv_ok = curv;
        a_ok = a;
        b_ok = b;
        lambda = std::max(lambda / 4, 1e-7);
      } else {
        n = n_ok;
        curv = curv_ok;
        a = a_ok;
        b = b_ok;
        lambda *= 8;
        for (std::size_t v = 0; v < active.size(); ++v) map_view(n, curv, active[v], &maps[v]);
      }
    }
    if (!converged) return PatchFailure::NotConverged;
    // Photo-consistency: each view's aligned window must correlate with the reference's.
    std::vector<int> kept;
    std::vector<Eigen::Vector2d> kept_start;
    std::vector<ViewMap> kept_maps;
    std::vector<double> ka, kb;
    double corr_sum = 0;
    std::vector<double> g;
    for (std::size_t v = 0; v < active.size(); ++v) {
      if (!map_view(n, curv, active[v], &maps[v]) || !sample_window(active[v], maps[v], &g)) return PatchFailure::Border;
      const double c = match::correlation_of(fv, g);
      if (c < o.min_correlation || !(b[v] > 0)) continue;
      const auto cc = centre_correlation(views[active[v]].grey, maps[v]);
      if (!cc) return PatchFailure::Border;
      if (*cc < o.min_centre_correlation) continue;
      kept.push_back(active[v]);
      kept_start.push_back(start[v]);
      kept_maps.push_back(maps[v]);
      ka.push_back(a[v]);
      kb.push_back(b[v]);
      corr_sum += c;
    }
    if (static_cast<int>(kept.size()) < o.min_views - 1) {
      return kept.empty() ? PatchFailure::Correlation : PatchFailure::Views;
    }
    if (kept.size() == active.size() || refit) {
      out->correlation = corr_sum / static_cast<double>(kept.size());
      active = kept;
      start = kept_start;
      maps = kept_maps;
      a = ka;  // (the kept views' brightness terms: the reprojection error's free match starts from them)
      b = kb;
      break;
    }
    active = kept;
    start = kept_start;
    maps = kept_maps;
    a = ka;
    b = kb;
    refit = true;
  }

  // Checks on the result.
  for (std::size_t v = 0; v < active.size(); ++v) {
    if ((maps[v].centre() - start[v]).norm() > o.max_shift_px) return PatchFailure::Shift;
  }
  const double cos_oblique = std::abs(n.dot(ray0)) / (n.norm() * ray0.norm());
  if (cos_oblique < std::cos(o.max_obliquity_deg * M_PI / 180)) return PatchFailure::Oblique;
  // Precision (Gauss-Markov): Cov = s0^2 H^-1, s0^2 = SSR / (N - P); the point moves along its
  // ray with depth z = 1 / (n . r0): dz/dn = -r0 z^2, so sigma_z^2 = z^4 r0^T Cov_n r0 and the
  // distance along the ray is z |r0|. Neighbouring pixels' noise is correlated (JPEG, the
  // interpolation), so this is a lower bound of the true spread.
  // (H is the last iteration's: its views are `active` before a last drop.)
  const auto P = static_cast<double>(H.rows());
  const double dof = static_cast<double>(n_pix) * (P - G) / 2 - P;
  const double s0 = dof > 0 ? ssr / dof : 0;
  const Eigen::MatrixXd H_inv = H.ldlt().solve(Eigen::MatrixXd::Identity(H.rows(), H.cols()));
  const Eigen::Matrix3d cov = s0 * H_inv.topLeftCorner<3, 3>();
  const double z = 1 / n.dot(ray0);
  const double var_z = z * z * z * z * ray0.dot(cov * ray0);

  // The bend across the window: the surface model at the 3 x 3 grid's rays, X_s = r_s / w_s, and
  // the normals of its four quadrants (the cross product of the two grid edges leaving each
  // quadrant's first corner); the largest angle between two of them. A window straddling a crease
  // (a wall's rim) is fitted by a tight bend through the corner's inside, which is no surface.
  out->bend_planes.clear();
  out->bend_deg = 0;
  if (G == 6) {
    std::array<Eigen::Vector3d, kGridPoints> X;
    bool turned = false;  // a grid ray meets the fitted surface behind the camera: it turned round
    for (int s = 0; s < kGridPoints && !turned; ++s) {
      const double qx = grid_[s].x() / static_cast<double>(h), qy = grid_[s].y() / static_cast<double>(h);
      const double w = n.dot(rays[s]) + curv.dot(Eigen::Vector3d(qx * qx, qx * qy, qy * qy));
      turned = !(w > 0);
      if (!turned) X[s] = rays[s] / w;
    }
    std::array<Eigen::Vector3d, 4> quad;
    const int first[4] = {0, 1, 3, 4};
    double bend = 180;
    if (!turned) {
      for (int k = 0; k < 4; ++k) {
        const int s = first[k];
        quad[k] = (X[s + 1] - X[s]).cross(X[s + 3] - X[s]).normalized();
      }
      double cos_min = 1;
      for (int a1 = 0; a1 < 4; ++a1) {
        for (int a2 = a1 + 1; a2 < 4; ++a2) cos_min = std::min(cos_min, quad[a1].dot(quad[a2]));
      }
      bend = std::acos(std::clamp(cos_min, -1.0, 1.0)) * 180 / M_PI;
    }
    if (o.max_bend_deg < 180 && !(bend <= o.max_bend_deg)) {
      // A crease, or a surface curved more tightly than the limit? The bend of a smooth surface
      // shrinks with the window (in proportion to its size), a crease's does not: the window of
      // bend_check_half_window_px measured from here gives the point if it bends by at most
      // bend_shrink_ratio of this one and within the limit itself (a crease near the small
      // window's edge bends it less than the large one, but still beyond the limit).
      if (small_) {
        PatchResult sr;
        if (small_->measure(views, ref, centre, n, active, &sr) == PatchFailure::None &&
            sr.bend_deg <= std::min(o.max_bend_deg, o.bend_shrink_ratio * bend)) {
          *out = std::move(sr);
          return PatchFailure::None;
        }
      }
      for (int k = 0; k < 4 && !turned; ++k) {
        const double d = quad[k].dot(X[first[k]]);
        if (std::abs(d) > 1e-12) out->bend_planes.push_back(quad[k] / d);
      }
      return PatchFailure::Bent;
    }
    out->bend_deg = bend;
  }

  // The reprojection error. The geometric constraint puts each view's window where the point
  // projects, so the fit itself leaves no residual in the image. The free match is the window's
  // own position in that view: a 2D shift s of the fitted map (its shape held; the brightness
  // terms a, b from the fit as start values) minimising sum (f - a - b g(u(d) + s))^2 by
  // Gauss-Newton on (s, a, b), as match's least-squares matching measures a track's observation.
  // |s| is that observation's distance from the point's projection; the reference's observation
  // is its pixel, on whose ray the point lies (0). The RMS over all of them is the point's
  // reprojection error as a track's is defined (a point triangulated from the same observations
  // by least squares would have a smaller one).
  double shift_ss = 0;
  for (std::size_t v = 0; v < active.size(); ++v) {
    const cv::Mat& g = views[active[v]].grey;
    Eigen::Vector2d shift = Eigen::Vector2d::Zero();
    double av = a[v], bv_ = b[v];
    for (int it = 0; it < kFreeShiftIterations; ++it) {
      Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
      Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
      bool ok = true;
      for (std::size_t q = 0; q < n_pix && ok; ++q) {
        const Eigen::Map<const Eigen::Matrix<double, 6, 1>> bq(basis_[q].data());
        double val, gx, gy;
        ok = match::sample_cubic(g, maps[v].C.row(0) * bq + shift.x(), maps[v].C.row(1) * bq + shift.y(), val, gx, gy);
        if (!ok) break;
        const Eigen::Vector4d J(bv_ * gx, bv_ * gy, 1, val);
        const double e = fv[q] - av - bv_ * val;
        N.noalias() += J * J.transpose();
        rhs.noalias() += J * e;
      }
      if (!ok) break;  // the shifted window left the photo: keep the last shift
      const Eigen::Vector4d step = N.ldlt().solve(rhs);
      if (!step.allFinite()) break;
      shift += step.head<2>();
      av += step(2);
      bv_ += step(3);
      if (step.head<2>().norm() < kFreeShiftConvergedPx) break;
    }
    shift_ss += shift.squaredNorm();
  }
  // RMS over all the point's observations, the reference's (0) included.
  out->reprojection_px = std::sqrt(shift_ss / static_cast<double>(active.size() + 1));
  if (o.max_reprojection_px > 0 && !(out->reprojection_px <= o.max_reprojection_px)) return PatchFailure::Reprojection;

  out->plane = n;
  out->point_ref = ray0 * z;
  out->sigma_along_ray = std::sqrt(std::max(0.0, var_z)) * ray0.norm();
  out->views = active;
  out->iterations = iterations;
  out->half_window_px = o.half_window_px;
  return PatchFailure::None;
}

}  // namespace photomill::densify
