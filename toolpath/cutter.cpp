#include "toolpath/cutter.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "formats/bspline.hpp"
#include "formats/error.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kNegInf = -std::numeric_limits<double>::infinity();

// Value, gradient and Hessian in (u, v) of g(u, v) = S_z + w, w = sqrt(r^2 - |S_xy - c|^2), the
// centre height of a ball at c touching the surface point S(u, v). With D = S_xy - c and
// a_u = D . S_u,xy:
//   g_u  = S_u,z - a_u / w
//   g_uu = S_uu,z - (S_u,xy . S_u,xy + D . S_uu,xy) / w - a_u^2 / w^3
//   g_uv = S_uv,z - (S_u,xy . S_v,xy + D . S_uv,xy) / w - a_u a_v / w^3   (and alike for v).
struct BallHeight {
  bool inside = false;  // the point is under the ball (|D| < r)
  double g = kNegInf;
  Eigen::Vector2d grad = Eigen::Vector2d::Zero();
  Eigen::Matrix2d hess = Eigen::Matrix2d::Zero();
  Eigen::Vector3d p, su, sv;
};

BallHeight ball_height(const BSplineSurface& s, const Eigen::Vector2d& uv, const Eigen::Vector2d& c, double r) {
  const SurfaceDerivatives d = surface_derivatives(s, uv.x(), uv.y());
  BallHeight b;
  b.p = d.p, b.su = d.su, b.sv = d.sv;
  const Eigen::Vector2d D = d.p.head<2>() - c;
  const double w2 = r * r - D.squaredNorm();
  if (!(w2 > 0)) return b;
  const double w = std::sqrt(w2), w3 = w2 * w;
  const Eigen::Vector2d Su = d.su.head<2>(), Sv = d.sv.head<2>();
  const double au = D.dot(Su), av = D.dot(Sv);
  b.inside = true;
  b.g = d.p.z() + w;
  b.grad = {d.su.z() - au / w, d.sv.z() - av / w};
  b.hess(0, 0) = d.suu.z() - (Su.dot(Su) + D.dot(d.suu.head<2>())) / w - au * au / w3;
  b.hess(0, 1) = d.suv.z() - (Su.dot(Sv) + D.dot(d.suv.head<2>())) / w - au * av / w3;
  b.hess(1, 0) = b.hess(0, 1);
  b.hess(1, 1) = d.svv.z() - (Sv.dot(Sv) + D.dot(d.svv.head<2>())) / w - av * av / w3;
  return b;
}

}  // namespace

Eigen::Vector3d ball_centre(const Eigen::Vector3d& cc, const Eigen::Vector3d& normal, double R, double a) {
  return cc + (R + a) * normal;
}

DropCutter::DropCutter(const BSplineSurface& surface, double ball_radius_mm, double sample_mm)
    : surface_(&surface), r_(ball_radius_mm) {
  if (!(ball_radius_mm > 0) || !(sample_mm > 0)) throw UsageError("drop cutter: ball radius and sample spacing must be > 0");
  const auto [u0, u1] = domain_u(surface);
  const auto [v0, v1] = domain_v(surface);
  // Sample counts: the longest piece of a 32 x 32 coarse grid, divided to `sample_mm`.
  constexpr int kCoarse = 32;
  double longest_u = 0, longest_v = 0;
  std::vector<Eigen::Vector3d> coarse((kCoarse + 1) * (kCoarse + 1));
  for (int i = 0; i <= kCoarse; ++i) {
    for (int j = 0; j <= kCoarse; ++j) {
      coarse[static_cast<std::size_t>(i * (kCoarse + 1) + j)] =
          surface_point(surface, u0 + (u1 - u0) * i / kCoarse, v0 + (v1 - v0) * j / kCoarse);
    }
  }
  for (int i = 0; i <= kCoarse; ++i) {
    for (int j = 0; j <= kCoarse; ++j) {
      const auto& p = coarse[static_cast<std::size_t>(i * (kCoarse + 1) + j)];
      if (i < kCoarse) longest_u = std::max(longest_u, (coarse[static_cast<std::size_t>((i + 1) * (kCoarse + 1) + j)] - p).norm());
      if (j < kCoarse) longest_v = std::max(longest_v, (coarse[static_cast<std::size_t>(i * (kCoarse + 1) + j + 1)] - p).norm());
    }
  }
  constexpr double kMaxSamples = 4e7;
  ni_ = kCoarse * std::max(1, static_cast<int>(std::ceil(longest_u / sample_mm))) + 1;
  nj_ = kCoarse * std::max(1, static_cast<int>(std::ceil(longest_v / sample_mm))) + 1;
  if (static_cast<double>(ni_) * nj_ > kMaxSamples) {
    throw GeometryError("the surface is too large for a drop-cutter sample spacing of " + std::to_string(sample_mm) +
                        " mm (" + std::to_string(ni_) + " x " + std::to_string(nj_) + " samples)");
  }
  spacing_ = std::max(longest_u * kCoarse / (ni_ - 1), longest_v * kCoarse / (nj_ - 1));
  pts_.resize(static_cast<std::size_t>(ni_) * nj_);
  uvs_.resize(pts_.size());
  min_xy_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  max_xy_ = -min_xy_;
  top_z_ = kNegInf;
  bottom_z_ = -kNegInf;
  for (int i = 0; i < ni_; ++i) {
    const double u = i == ni_ - 1 ? u1 : u0 + (u1 - u0) * i / (ni_ - 1);
    for (int j = 0; j < nj_; ++j) {
      const double v = j == nj_ - 1 ? v1 : v0 + (v1 - v0) * j / (nj_ - 1);
      const std::size_t k = static_cast<std::size_t>(i) * nj_ + j;
      uvs_[k] = {u, v};
      pts_[k] = surface_point(surface, u, v);
      min_xy_ = min_xy_.cwiseMin(pts_[k].head<2>());
      max_xy_ = max_xy_.cwiseMax(pts_[k].head<2>());
      top_z_ = std::max(top_z_, pts_[k].z());
      bottom_z_ = std::min(bottom_z_, pts_[k].z());
    }
  }
  if (!std::isfinite(top_z_) || !min_xy_.allFinite() || !max_xy_.allFinite()) {
    throw GeometryError("the surface evaluates to non-finite points");
  }
  bx_ = std::max(1, static_cast<int>(std::ceil((max_xy_.x() - min_xy_.x()) / r_)));
  by_ = std::max(1, static_cast<int>(std::ceil((max_xy_.y() - min_xy_.y()) / r_)));
  if (static_cast<double>(bx_) * by_ > kMaxSamples) throw GeometryError("the surface is too large for the tool radius");
  const auto bucket_of = [&](const Eigen::Vector3d& p) {
    const int bx = std::clamp(static_cast<int>((p.x() - min_xy_.x()) / r_), 0, bx_ - 1);
    const int by = std::clamp(static_cast<int>((p.y() - min_xy_.y()) / r_), 0, by_ - 1);
    return static_cast<std::size_t>(by) * bx_ + bx;
  };
  bucket_start_.assign(static_cast<std::size_t>(bx_) * by_ + 1, 0);
  for (const auto& p : pts_) ++bucket_start_[bucket_of(p) + 1];
  for (std::size_t b = 1; b < bucket_start_.size(); ++b) bucket_start_[b] += bucket_start_[b - 1];
  bucket_items_.resize(pts_.size());
  std::vector<int> fill(bucket_start_.begin(), bucket_start_.end() - 1);
  for (std::size_t k = 0; k < pts_.size(); ++k) bucket_items_[static_cast<std::size_t>(fill[bucket_of(pts_[k])]++)] = static_cast<int>(k);
}

double DropCutter::g_at(int i, int j, const Eigen::Vector2d& xy) const {
  if (i < 0 || j < 0 || i >= ni_ || j >= nj_) return kNegInf;
  const Eigen::Vector3d& p = pts_[static_cast<std::size_t>(i) * nj_ + j];
  const double d2 = (p.head<2>() - xy).squaredNorm();
  const double w2 = r_ * r_ - d2;
  return w2 > 0 ? p.z() + std::sqrt(w2) : kNegInf;
}

DropCutter::Contact DropCutter::refine(const Eigen::Vector2d& xy, const Eigen::Vector2d& uv0) const {
  // Damped Newton ascent on g(u, v) (see BallHeight), kept inside the parameter domain; steps
  // longer than one sample spacing on the surface are shortened (a trust region).
  // Plain variables, not structured bindings: lambdas capture them in clang 14 too.
  const std::pair<double, double> du = domain_u(*surface_), dv = domain_v(*surface_);
  const double u0 = du.first, u1 = du.second, v0 = dv.first, v1 = dv.second;
  const auto clamp_uv = [&](Eigen::Vector2d uv) {
    return Eigen::Vector2d(std::clamp(uv.x(), u0, u1), std::clamp(uv.y(), v0, v1));
  };
  Eigen::Vector2d uv = clamp_uv(uv0);
  BallHeight b = ball_height(*surface_, uv, xy, r_);
  Contact best;
  if (!b.inside) return best;
  constexpr int kMaxIterations = 40;
  for (int it = 0; it < kMaxIterations; ++it) {
    Eigen::Vector2d step;
    const Eigen::Matrix2d& H = b.hess;
    const bool concave_down = H(0, 0) < 0 && H.determinant() > 0;
    if (concave_down) {
      step = -H.inverse() * b.grad;
    } else {
      const double speed = std::max({b.su.norm(), b.sv.norm(), 1e-300});
      const double gn = b.grad.norm();
      if (gn == 0) break;
      step = b.grad / gn * (0.5 * spacing_ / speed);
    }
    // Coordinates held at a bound by the step are frozen (projected ascent).
    for (int c = 0; c < 2; ++c) {
      const double lo = c == 0 ? u0 : v0, hi = c == 0 ? u1 : v1;
      if ((uv[c] <= lo && step[c] < 0) || (uv[c] >= hi && step[c] > 0)) {
        step[c] = 0;
        const int o = 1 - c;
        step[o] = H(o, o) < 0 ? -b.grad[o] / H(o, o) : step[o];
      }
    }
    const double phys = (step.x() * b.su + step.y() * b.sv).norm();
    if (phys > spacing_) step *= spacing_ / phys;
    bool accepted = false;
    double t = 1.0;
    for (int k = 0; k < 20; ++k, t *= 0.5) {
      const Eigen::Vector2d cand = clamp_uv(uv + t * step);
      BallHeight nb = ball_height(*surface_, cand, xy, r_);
      if (nb.inside && nb.g >= b.g) {
        const double moved = ((cand - uv).x() * b.su + (cand - uv).y() * b.sv).norm();
        uv = cand;
        b = nb;
        accepted = true;
        if (moved < 1e-10) it = kMaxIterations;
        break;
      }
    }
    if (!accepted) break;
  }
  best.centre_z = b.g;
  best.uv = uv;
  best.point = b.p;
  best.hit = true;
  return best;
}

DropCutter::Contact DropCutter::drop(const Eigen::Vector2d& xy, const Contact* known,
                                     const std::vector<Eigen::Vector2d>& hints) const {
  struct Hit {
    int k;
    double g;
  };
  thread_local std::vector<Hit> hits;
  hits.clear();
  const double r2 = r_ * r_;
  const int bx0 = std::max(0, static_cast<int>(std::floor((xy.x() - r_ - min_xy_.x()) / r_)));
  const int bx1 = std::min(bx_ - 1, static_cast<int>(std::floor((xy.x() + r_ - min_xy_.x()) / r_)));
  const int by0 = std::max(0, static_cast<int>(std::floor((xy.y() - r_ - min_xy_.y()) / r_)));
  const int by1 = std::min(by_ - 1, static_cast<int>(std::floor((xy.y() + r_ - min_xy_.y()) / r_)));
  double best_g = kNegInf;
  int best_k = -1;
  for (int by = by0; by <= by1; ++by) {
    for (int bx = bx0; bx <= bx1; ++bx) {
      const std::size_t b = static_cast<std::size_t>(by) * bx_ + bx;
      for (int idx = bucket_start_[b]; idx < bucket_start_[b + 1]; ++idx) {
        const int k = bucket_items_[static_cast<std::size_t>(idx)];
        const Eigen::Vector3d& p = pts_[static_cast<std::size_t>(k)];
        const double d2 = (p.x() - xy.x()) * (p.x() - xy.x()) + (p.y() - xy.y()) * (p.y() - xy.y());
        if (d2 >= r2) continue;
        const double g = p.z() + std::sqrt(r2 - d2);
        hits.push_back({k, g});
        if (g > best_g) best_g = g, best_k = k;
      }
    }
  }
  Contact result;
  if (known && known->hit) result = *known;
  if (best_k < 0) return result;
  // Contacts already found: the known one and those refined from the hints.
  std::array<Eigen::Vector3d, 16> basins{};
  std::size_t nbasins = 0;
  if (result.hit) basins[nbasins++] = result.point;
  for (const Eigen::Vector2d& uv : hints) {
    const Contact c = refine(xy, uv);
    if (!c.hit) continue;
    if (nbasins < basins.size()) basins[nbasins++] = c.point;
    if (!result.hit || c.centre_z > result.centre_z) result = c;
  }
  const double reference = result.hit ? result.centre_z : best_g;
  const double margin = spacing_ * spacing_ / r_;
  const double basin2 = 4 * spacing_ * spacing_;  // samples this close to a found contact share its basin
  // Candidates: local maxima of the samples (8-neighbourhood in (i, j)) within the margin.
  std::array<Hit, 8> cands{};
  std::size_t ncand = 0;
  for (const Hit& h : hits) {
    if (h.g < reference - margin) continue;
    if (h.g <= reference &&
        std::any_of(basins.begin(), basins.begin() + static_cast<long>(nbasins), [&](const Eigen::Vector3d& b) {
          return (pts_[static_cast<std::size_t>(h.k)] - b).squaredNorm() < basin2;
        })) {
      continue;
    }
    const int i = h.k / nj_, j = h.k % nj_;
    bool local_max = true;
    for (int di = -1; di <= 1 && local_max; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        if ((di != 0 || dj != 0) && g_at(i + di, j + dj, xy) > h.g) {
          local_max = false;
          break;
        }
      }
    }
    if (!local_max) continue;
    if (ncand < cands.size()) {
      cands[ncand++] = h;
    } else {
      auto low = std::min_element(cands.begin(), cands.end(), [](const Hit& a, const Hit& b) { return a.g < b.g; });
      if (h.g > low->g) *low = h;
    }
  }
  // Best first; a candidate in the basin of a contact already refined, and not above it, is the
  // same maximum seen from another sample (ridges sampled on a slant have many).
  for (std::size_t i = 1; i < ncand; ++i) {  // insertion sort of at most 8
    for (std::size_t j = i; j > 0 && cands[j].g > cands[j - 1].g; --j) std::swap(cands[j], cands[j - 1]);
  }
  for (std::size_t c = 0; c < ncand; ++c) {
    const Eigen::Vector3d& p = pts_[static_cast<std::size_t>(cands[c].k)];
    if (result.hit && cands[c].g <= result.centre_z &&
        std::any_of(basins.begin(), basins.begin() + static_cast<long>(nbasins),
                    [&](const Eigen::Vector3d& b) { return (p - b).squaredNorm() < basin2; })) {
      continue;
    }
    const Contact refined = refine(xy, uvs_[static_cast<std::size_t>(cands[c].k)]);
    // Never below the sample itself (Newton only climbs); keep the sample if refinement failed.
    Contact cand = refined;
    if (!cand.hit || cand.centre_z < cands[c].g) {
      cand.hit = true;
      cand.centre_z = cands[c].g;
      cand.uv = uvs_[static_cast<std::size_t>(cands[c].k)];
      cand.point = pts_[static_cast<std::size_t>(cands[c].k)];
    }
    if (nbasins < basins.size()) basins[nbasins++] = cand.point;
    if (!result.hit || cand.centre_z > result.centre_z) result = cand;
  }
  if (!result.hit) {
    result.hit = true;
    result.centre_z = best_g;
    result.uv = uvs_[static_cast<std::size_t>(best_k)];
    result.point = pts_[static_cast<std::size_t>(best_k)];
  }
  return result;
}

CutterLocation cc_to_cl(const PassFrame& f, const DropCutter& drop, const CutterOptions& o) {
  CutterLocation cl;
  cl.uv = f.uv;
  cl.cc = f.p;
  cl.normal = f.normal;
  const Eigen::Vector3d tangent_centre = ball_centre(f.p, f.normal, o.tool_radius_mm, o.stock_mm);
  // The tangent ball touches the surface at cc with centre height exactly g(cc) = cc_z + r n_z.
  DropCutter::Contact known;
  known.hit = true;
  known.centre_z = tangent_centre.z();
  known.uv = f.uv;
  known.point = f.p;
  const DropCutter::Contact top = drop.drop(tangent_centre.head<2>(), &known);
  cl.gouge_depth_mm = std::max(0.0, top.centre_z - tangent_centre.z());
  cl.contact = top.point;
  cl.contact_uv = top.uv;
  const double k = max_concave_curvature(f);
  if (k > 0) cl.concave_radius_mm = 1.0 / k;
  cl.gouge = cl.gouge_depth_mm > o.gouge_tol_mm || cl.concave_radius_mm < o.tool_radius_mm + o.stock_mm;
  cl.centre = tangent_centre;
  // Lifts far below the tolerance are rounding or a ball resting a hair above its tangent spot;
  // the tool is raised by them all the same, but the point is marked lifted only beyond a tenth
  // of the tolerance (the forward step treats lifted points more strictly).
  if (o.lift && cl.gouge_depth_mm > 0) cl.centre.z() += cl.gouge_depth_mm;
  if (o.lift && cl.gouge_depth_mm > 0.1 * o.gouge_tol_mm) {
    cl.lifted = true;
  }
  cl.tip = tip_from_centre(cl.centre, o.tool_radius_mm);
  return cl;
}

}  // namespace photomill::toolpath
