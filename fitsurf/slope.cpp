// The data's slope per cell over a parameter plane, and the choice of plane by it (slope.hpp).
#include "fitsurf/slope.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>

#include "formats/error.hpp"

namespace photomill::fitsurf {

CellGrid::CellGrid(const ParameterBox& box, std::size_t n, double spacings)
    : t1_min(box.t1_min), t2_min(box.t2_min) {
  const double lu = box.length_u_mm(), lv = box.length_v_mm();
  cell_mm = spacings * std::sqrt(lu * lv / static_cast<double>(std::max<std::size_t>(n, 1)));
  nx = std::max(1, static_cast<int>(std::ceil(lu / cell_mm)));
  ny = std::max(1, static_cast<int>(std::ceil(lv / cell_mm)));
}

std::size_t CellGrid::cell_of(const Eigen::Vector3d& x) const {
  const int ix = std::clamp(static_cast<int>((x.x() - t1_min) / cell_mm), 0, nx - 1);
  const int iy = std::clamp(static_cast<int>((x.y() - t2_min) / cell_mm), 0, ny - 1);
  return static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(ix);
}

double DataSlope::near(double t1, double t2, double radius_mm) const {
  const int nx = grid.nx, ny = grid.ny;
  if (nx <= 0 || ny <= 0) return -1;
  const int ix = static_cast<int>(std::floor((t1 - grid.t1_min) / grid.cell_mm));
  const int iy = static_cast<int>(std::floor((t2 - grid.t2_min) / grid.cell_mm));
  const int k = std::clamp(static_cast<int>(std::ceil(radius_mm / grid.cell_mm)), 1, std::max(nx, ny));
  double s = -1;
  for (int y = std::max(0, iy - k); y <= std::min(ny - 1, iy + k); ++y) {
    for (int x = std::max(0, ix - k); x <= std::min(nx - 1, ix + k); ++x) {
      s = std::max(s, static_cast<double>(slope_deg[static_cast<std::size_t>(y) * nx + x]));
    }
  }
  return s;
}

DataSlope data_slope(const std::vector<Eigen::Vector3d>& local, const ParameterBox& box, const SlopeOptions& o) {
  DataSlope r;
  if (local.empty()) return r;
  r.grid = CellGrid(box, local.size(), o.cell_spacings);
  const std::size_t ncell = r.grid.size();
  auto cell_of = [&](const Eigen::Vector3d& x) { return r.grid.cell_of(x); };
  // Per cell: count, sum and sum of outer products (about the first point of the cell, so the
  // covariance keeps its precision far from the origin).
  std::vector<std::size_t> count(ncell, 0);
  std::vector<Eigen::Vector3d> first(ncell), sum(ncell, Eigen::Vector3d::Zero());
  std::vector<Eigen::Matrix3d> outer(ncell, Eigen::Matrix3d::Zero());
  for (const auto& x : local) {
    const std::size_t c = cell_of(x);
    if (count[c]++ == 0) first[c] = x;
    const Eigen::Vector3d d = x - first[c];
    sum[c] += d;
    outer[c].noalias() += d * d.transpose();
  }
  r.slope_deg.assign(ncell, -1.0f);
  std::vector<double> slopes;
  for (std::size_t c = 0; c < ncell; ++c) {
    if (count[c] < o.min_points) continue;
    const double n = static_cast<double>(count[c]);
    const Eigen::Vector3d mean = sum[c] / n;
    const Eigen::Matrix3d cov = outer[c] / n - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    const Eigen::Vector3d ev = eig.eigenvalues();  // increasing
    if (!(ev[2] > 0) || ev[1] < o.min_width_ratio * o.min_width_ratio * ev[2]) continue;
    const double slope = std::acos(std::min(1.0, std::abs(eig.eigenvectors().col(0).z()))) * 180 / std::numbers::pi;
    r.slope_deg[c] = static_cast<float>(slope);
    slopes.push_back(slope);
    if (slope > r.max_deg) {
      r.max_deg = slope;
      r.max_at = first[c] + mean;
    }
  }
  r.cells = slopes.size();
  if (!slopes.empty()) {
    const auto k = static_cast<std::ptrdiff_t>(std::floor(o.score_quantile * static_cast<double>(slopes.size() - 1)));
    std::nth_element(slopes.begin(), slopes.begin() + k, slopes.end());
    r.score_deg = slopes[static_cast<std::size_t>(k)];
  }
  return r;
}

PlaneChoice choose_plane(const std::vector<Eigen::Vector3d>& points, const FrameOptions& frame_options,
                         const SlopeOptions& options, double prefer_pca_deg, double* pca_score_deg,
                         double* xy_score_deg) {
  auto score = [&](PlaneChoice c) {
    const PlaneFrame f = parameter_frame(points, c, frame_options);
    std::vector<Eigen::Vector3d> local(points.size());
    for (std::size_t k = 0; k < points.size(); ++k) local[k] = f.to_local(points[k]);
    return data_slope(local, parameter_box(local), options).score_deg;
  };
  const double pca = score(PlaneChoice::Pca);
  double xy = 90;
  try {
    xy = score(PlaneChoice::Xy);
  } catch (const GeometryError&) {  // e.g. a part standing on edge: a line in xy
  }
  if (pca_score_deg) *pca_score_deg = pca;
  if (xy_score_deg) *xy_score_deg = xy;
  return xy < pca - prefer_pca_deg ? PlaneChoice::Xy : PlaneChoice::Pca;
}

}  // namespace photomill::fitsurf
