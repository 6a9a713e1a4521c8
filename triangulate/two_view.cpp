// Two-view points against their neighbours (see two_view.hpp).
#include "triangulate/two_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include "geometry/parallel.hpp"

namespace photomill::triangulate {
namespace {

// Distances (squared) from q to its k nearest points among refs[idx] (brute force), ascending;
// `skip` is left out (the query itself).
double kth_distance_brute(const std::vector<Eigen::Vector3d>& refs, const Eigen::Vector3d& q, std::size_t k,
                          std::size_t skip) {
  std::vector<double> best;
  best.reserve(k + 1);
  for (std::size_t i = 0; i < refs.size(); ++i) {
    if (i == skip) continue;
    const double d2 = (refs[i] - q).squaredNorm();
    if (best.size() < k) {
      best.push_back(d2);
      std::push_heap(best.begin(), best.end());
    } else if (d2 < best.front()) {
      std::pop_heap(best.begin(), best.end());
      best.back() = d2;
      std::push_heap(best.begin(), best.end());
    }
  }
  return best.size() < k ? std::numeric_limits<double>::infinity() : std::sqrt(best.front());
}

// A uniform grid of cells `cell` mm wide over the reference points (hashed: a surface fills few
// cells of its bounding box).
class Grid {
public:
  Grid(const std::vector<Eigen::Vector3d>& pts, double cell) : pts_(pts), cell_(cell) {
    for (std::size_t i = 0; i < pts.size(); ++i) cells_[key(index(pts[i]))].push_back(i);
  }

  // The k nearest points within `radius` of q (indices, nearest first); fewer when fewer are
  // within it.
  std::vector<std::size_t> nearest(const Eigen::Vector3d& q, std::size_t k, double radius) const {
    const Eigen::Vector3i c = index(q);
    const int span = static_cast<int>(std::ceil(radius / cell_));
    std::vector<std::pair<double, std::size_t>> found;
    const double r2 = radius * radius;
    for (int x = c.x() - span; x <= c.x() + span; ++x) {
      for (int y = c.y() - span; y <= c.y() + span; ++y) {
        for (int z = c.z() - span; z <= c.z() + span; ++z) {
          const auto it = cells_.find(key({x, y, z}));
          if (it == cells_.end()) continue;
          for (std::size_t i : it->second) {
            const double d2 = (pts_[i] - q).squaredNorm();
            if (d2 <= r2) found.emplace_back(d2, i);
          }
        }
      }
    }
    const std::size_t n = std::min(k, found.size());
    std::partial_sort(found.begin(), found.begin() + static_cast<std::ptrdiff_t>(n), found.end());
    std::vector<std::size_t> out(n);
    for (std::size_t j = 0; j < n; ++j) out[j] = found[j].second;
    return out;
  }

private:
  Eigen::Vector3i index(const Eigen::Vector3d& p) const {
    return {static_cast<int>(std::floor(p.x() / cell_)), static_cast<int>(std::floor(p.y() / cell_)),
            static_cast<int>(std::floor(p.z() / cell_))};
  }
  static std::uint64_t key(const Eigen::Vector3i& c) {
    // 21 bits per axis (cells +-10^6 around the origin); wrapping only merges far cells' lists,
    // which the distance test sorts out.
    const auto u = [](int v) { return static_cast<std::uint64_t>(static_cast<std::uint32_t>(v) & 0x1FFFFFu); };
    return u(c.x()) | (u(c.y()) << 21) | (u(c.z()) << 42);
  }

  const std::vector<Eigen::Vector3d>& pts_;
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells_;
};

// Fewer neighbours than this are judged by their plane, more by their quadric.
constexpr std::size_t kQuadricMinNeighbours = 10;

double median_of(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

TwoViewCheck check_two_view_points(const std::vector<CheckedPoint>& points, const TwoViewOptions& o) {
  TwoViewCheck out;
  out.verdict.assign(points.size(), TwoViewVerdict::NotChecked);
  out.distance_mm.assign(points.size(), std::numeric_limits<double>::quiet_NaN());
  out.allowed_mm.assign(points.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<Eigen::Vector3d> refs;
  std::vector<std::size_t> candidates;
  std::size_t seen_thrice = 0;  // references that are not control points
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].xyz_mm.allFinite()) continue;
    if (points[i].views >= o.min_views || points[i].control) {
      refs.push_back(points[i].xyz_mm);
      seen_thrice += points[i].control ? 0 : 1;
    } else if (points[i].views >= 2) {
      candidates.push_back(i);
    }
  }
  out.reference_points = refs.size();
  const std::size_t k = std::max<std::size_t>(3, o.neighbours);
  // Control points alone (a plate) say nothing about the part: the check needs points of the
  // scene seen in a third view.
  if (!o.enabled || candidates.empty() || seen_thrice < k + 1) {
    for (std::size_t i : candidates) out.verdict[i] = TwoViewVerdict::Kept;
    return out;
  }
  out.ran = true;

  // D: the median k-th neighbour distance over (a deterministic sample of at most 1000 of) the
  // reference points.
  const std::size_t samples = std::min<std::size_t>(1000, refs.size());
  std::vector<double> kth(samples);
  geometry::parallel_blocks(samples, o.threads, 64, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t s = b; s < e; ++s) {
      const std::size_t i = s * refs.size() / samples;
      kth[s] = kth_distance_brute(refs, refs[i], k, i);
    }
  });
  out.spacing_mm = median_of(kth);
  const double radius = o.reach * out.spacing_mm;
  if (!(radius > 0) || !std::isfinite(radius)) {
    // Every reference point on one spot: no plane to judge by.
    for (std::size_t i : candidates) out.verdict[i] = TwoViewVerdict::Kept;
    out.ran = false;
    return out;
  }
  const Grid grid(refs, radius / 2);
  geometry::parallel_blocks(candidates.size(), o.threads, 64, [&](std::size_t b, std::size_t e, int) {
    for (std::size_t c = b; c < e; ++c) {
      const std::size_t i = candidates[c];
      const CheckedPoint& p = points[i];
      const std::vector<std::size_t> near = grid.nearest(p.xyz_mm, k, radius);
      if (near.size() < k) {
        out.verdict[i] = TwoViewVerdict::Unsupported;
        continue;
      }
      Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
      for (std::size_t j : near) centroid += refs[j];
      centroid /= static_cast<double>(near.size());
      Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
      for (std::size_t j : near) scatter += (refs[j] - centroid) * (refs[j] - centroid).transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
      const Eigen::Vector3d n = eig.eigenvectors().col(0);  // smallest eigenvalue first
      const Eigen::Vector3d e1 = eig.eigenvectors().col(2), e2 = eig.eigenvectors().col(1);
      // Heights w over the plane, fitted by the quadric w = a + b u + c v + d u^2 + e uv + f v^2
      // (the local jet of the surface: Cazals & Pouget 2005) when there are enough neighbours,
      // else by the plane (w = 0): a curved surface's sagitta over the neighbourhood is not taken
      // for an offset.
      const auto kk = static_cast<Eigen::Index>(near.size());
      const bool quadric = near.size() >= kQuadricMinNeighbours;
      const Eigen::Index terms = quadric ? 6 : 1;
      Eigen::MatrixXd A(kk, terms);
      Eigen::VectorXd w(kk);
      const auto row = [&](const Eigen::Vector3d& x, Eigen::Index r, Eigen::MatrixXd& M) {
        const Eigen::Vector3d q = x - centroid;
        const double u = e1.dot(q), v = e2.dot(q);
        M(r, 0) = 1;
        if (quadric) M.block(r, 1, 1, 5) << u, v, u * u, u * v, v * v;
      };
      for (Eigen::Index j = 0; j < kk; ++j) {
        row(refs[near[static_cast<std::size_t>(j)]], j, A);
        w[j] = n.dot(refs[near[static_cast<std::size_t>(j)]] - centroid);
      }
      const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
      Eigen::VectorXd coef = Eigen::VectorXd::Zero(terms);
      if (qr.rank() == terms) coef = qr.solve(w);  // else the plane (neighbours on a line)
      std::vector<double> r(near.size());
      for (Eigen::Index j = 0; j < kk; ++j) r[static_cast<std::size_t>(j)] = w[j] - A.row(j).dot(coef);
      const double m = median_of(r);
      for (double& x : r) x = std::abs(x - m);
      // Robust standard deviation of the residuals, corrected for the terms fitted, and the
      // prediction's own variance at P taken as the mean leverage terms / k of it.
      const double dof = static_cast<double>(kk) / static_cast<double>(kk - terms);
      const double s = 1.4826 * median_of(r) * std::sqrt(dof);
      const double s_pred2 = s * s * (1 + static_cast<double>(terms) / static_cast<double>(kk));
      Eigen::MatrixXd at(1, terms);
      row(p.xyz_mm, 0, at);
      const double along = std::max(0.0, n.dot(p.covariance_mm2 * n));
      const double d = std::abs(n.dot(p.xyz_mm - centroid) - at.row(0).dot(coef));
      const double allowed = std::max(o.tolerance_mm, o.sigmas * std::sqrt(s_pred2 + along));
      out.distance_mm[i] = d;
      out.allowed_mm[i] = allowed;
      out.verdict[i] = d <= allowed ? TwoViewVerdict::Kept : TwoViewVerdict::OffNeighbours;
    }
  });
  for (std::size_t i : candidates) {
    ++out.checked;
    out.unsupported += out.verdict[i] == TwoViewVerdict::Unsupported ? 1 : 0;
    out.off_neighbours += out.verdict[i] == TwoViewVerdict::OffNeighbours ? 1 : 0;
  }
  return out;
}

}  // namespace photomill::triangulate
