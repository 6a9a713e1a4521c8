// Part selection: box, half-space, RANSAC dominant-plane removal (see select.hpp).
#include "fitsurf/select.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "fitsurf/numbers.hpp"
#include "formats/error.hpp"
#include "geometry/random.hpp"

namespace photomill::fitsurf {
namespace {

// Least-squares plane of the points: through their centroid, normal = eigenvector of the
// smallest eigenvalue of their covariance.
Plane fit_plane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& idx) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t k : idx) c += points[k];
  c /= static_cast<double>(idx.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t k : idx) {
    const Eigen::Vector3d d = points[k] - c;
    cov.noalias() += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Plane pl;
  pl.normal = eig.eigenvectors().col(0).normalized();
  pl.offset_mm = -pl.normal.dot(c);
  return pl;
}

std::string percent(double fraction) { return fixed(100.0 * fraction, 1) + " %"; }
std::string percent(std::size_t a, std::size_t b) {
  return percent(static_cast<double>(a) / static_cast<double>(std::max<std::size_t>(b, 1)));
}

}  // namespace

Plane dominant_plane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& indices,
                     const SelectOptions& o) {
  const std::size_t n = indices.size();
  if (n < 3) throw GeometryError("too few points (" + std::to_string(n) + ") to look for a plane");
  geometry::Rng rng(o.seed);
  std::vector<std::size_t> subset;
  if (n > o.ransac_sample_size) {
    subset.reserve(o.ransac_sample_size);
    for (std::size_t k = 0; k < o.ransac_sample_size; ++k) subset.push_back(indices[rng.index(n)]);
  } else {
    subset = indices;
  }
  const std::size_t m = subset.size();
  std::size_t best_count = 0;
  Plane best;
  long needed = o.ransac_max_iterations;
  for (long it = 0; it < needed && it < o.ransac_max_iterations; ++it) {
    const Eigen::Vector3d& a = points[subset[rng.index(m)]];
    const Eigen::Vector3d& b = points[subset[rng.index(m)]];
    const Eigen::Vector3d& c = points[subset[rng.index(m)]];
    const Eigen::Vector3d nrm = (b - a).cross(c - a);
    const double len = nrm.norm();
    if (!(len > 1e-12 * std::max(1.0, (b - a).squaredNorm()))) continue;  // collinear sample
    Plane pl{nrm / len, -nrm.dot(a) / len};
    std::size_t count = 0;
    for (std::size_t k : subset) count += std::abs(pl.distance_mm(points[k])) <= o.plane_threshold_mm;
    if (count > best_count) {
      best_count = count;
      best = pl;
      const double e = static_cast<double>(count) / static_cast<double>(m);
      const double miss = 1.0 - e * e * e;
      if (miss <= 0) break;
      needed = static_cast<long>(std::ceil(std::log(1.0 - o.ransac_confidence) / std::log(miss)));
    }
  }
  if (best_count < 3) throw GeometryError("no plane found among the points");
  // Refine on all inliers (twice: the refined plane may gather a few more).
  std::vector<std::size_t> inliers;
  for (int round = 0; round < 2; ++round) {
    inliers.clear();
    for (std::size_t k : indices) {
      if (std::abs(best.distance_mm(points[k])) <= o.plane_threshold_mm) inliers.push_back(k);
    }
    if (inliers.size() < 3) break;
    best = fit_plane(points, inliers);
  }
  if (static_cast<double>(inliers.size()) < o.min_plane_fraction * static_cast<double>(n)) {
    throw GeometryError("no dominant plane: the best plane holds " + percent(inliers.size(), n) +
                        " of the points (less than " + percent(o.min_plane_fraction) +
                        ") within " + sig(o.plane_threshold_mm) + " mm");
  }
  return best;
}

namespace {

// The box, the plane above, the dominant plane.
Selection select_by_box_and_planes(const std::vector<Eigen::Vector3d>& points, const SelectOptions& o) {
  Selection sel;
  sel.kept.reserve(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    if (o.keep_box_mm) {
      const auto& b = *o.keep_box_mm;
      const Eigen::Vector3d& x = points[k];
      const bool inside = x.x() >= b[0] && x.y() >= b[1] && x.z() >= b[2] && x.x() <= b[3] && x.y() <= b[4] && x.z() <= b[5];
      if (!inside) {
        ++sel.dropped_box;
        continue;
      }
    }
    if (o.keep_above && !(o.keep_above->distance_mm(points[k]) > 0)) {
      ++sel.dropped_below;
      continue;
    }
    sel.kept.push_back(k);
  }
  if (sel.kept.empty() && !points.empty()) {
    throw GeometryError("no point is left after " + std::string(sel.dropped_box ? "--keep-box" : "--keep-above") +
                        " (" + std::to_string(points.size()) + " points given)");
  }
  if (!o.drop_plane) return sel;

  Plane pl = dominant_plane(points, sel.kept, o);
  std::size_t above = 0, below = 0;
  for (std::size_t k : sel.kept) {
    const double d = pl.distance_mm(points[k]);
    if (d > o.plane_threshold_mm) ++above;
    else if (d < -o.plane_threshold_mm) ++below;
  }
  if (below > above) {
    pl.normal = -pl.normal;
    pl.offset_mm = -pl.offset_mm;
    std::swap(above, below);
  }
  const std::size_t before = sel.kept.size();
  std::vector<std::size_t> kept;
  kept.reserve(above);
  for (std::size_t k : sel.kept) {
    const double d = pl.distance_mm(points[k]);
    if (d > o.plane_threshold_mm) kept.push_back(k);
    else if (d >= -o.plane_threshold_mm) ++sel.dropped_plane;
    else ++sel.dropped_beyond_plane;
  }
  sel.kept = std::move(kept);
  sel.plane = pl;
  if (sel.kept.size() < 3) {
    throw GeometryError("the cloud is flat: the dominant plane holds " + percent(sel.dropped_plane, before) +
                        " of the points within " + sig(o.plane_threshold_mm) + " mm and only " +
                        std::to_string(sel.kept.size()) +
                        " lie above it; nothing stands on the plate (drop --drop-plane to fit the plane itself)");
  }
  return sel;
}

}  // namespace

Selection select_part(const std::vector<Eigen::Vector3d>& points, const SelectOptions& o,
                      const std::vector<Eigen::Vector3d>& normals) {
  Selection sel = select_by_box_and_planes(points, o);
  sel.walls = split_walls(points, sel.kept, o.walls, normals);
  if (sel.walls && sel.kept.size() < 3) {
    throw GeometryError("only walls and the floor at their foot are left (" + std::to_string(sel.walls->wall_points) +
                        " points on faces steeper than " + sig(o.walls.slope_deg) +
                        " degrees): no top to fit; --walls off fits them all as one height field");
  }
  return sel;
}

}  // namespace photomill::fitsurf
