// PCA parameter plane and the degenerate-cloud checks (coincident, collinear points).
#include "fitsurf/frame.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "formats/error.hpp"
#include "fitsurf/numbers.hpp"

namespace photomill::fitsurf {
namespace {

std::string mm(double v) { return sig(v, 4) + " mm"; }

// Normal oriented to the first world axis (z, then y, then x) it is not perpendicular to.
Eigen::Vector3d oriented_normal(Eigen::Vector3d n) {
  for (int axis : {2, 1, 0}) {
    if (std::abs(n[axis]) > 1e-12) return n[axis] < 0 ? Eigen::Vector3d(-n) : n;
  }
  return n;
}

}  // namespace

PlaneFrame parameter_frame(const std::vector<Eigen::Vector3d>& points, PlaneChoice choice,
                           const FrameOptions& options) {
  if (points.empty()) throw GeometryError("no points to fit");
  if (choice == PlaneChoice::Auto) throw UsageError("parameter_frame: choose the plane first (choose_plane)");
  // Two passes (centroid, then the covariance about it) keep the covariance accurate for clouds
  // far from the origin.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector3d d = p - centroid;
    cov.noalias() += d * d.transpose();
  }
  cov /= static_cast<double>(points.size());

  PlaneFrame f;
  f.origin_mm = centroid;
  if (choice == PlaneChoice::Pca) {
    // Eigenvalues in increasing order: e3 belongs to the smallest, e1 to the largest.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Eigen::Vector3d e1 = eig.eigenvectors().col(2);
    const Eigen::Vector3d e3 = oriented_normal(eig.eigenvectors().col(0));
    // e1 along +x (or +y) when possible, so u grows with world x as a user expects.
    if (e1.x() < -1e-12 || (std::abs(e1.x()) <= 1e-12 && e1.y() < 0)) e1 = -e1;
    const Eigen::Vector3d e2 = e3.cross(e1);
    f.axes.col(0) = e1;
    f.axes.col(1) = e2;
    f.axes.col(2) = e3;
  } else {
    // In-plane axes x, y; the larger spread decides nothing here: u is x, v is y.
    f.axes.setIdentity();
  }
  const Eigen::Matrix3d local_cov = f.axes.transpose() * cov * f.axes;
  for (int k = 0; k < 3; ++k) f.spread_mm[k] = std::sqrt(std::max(0.0, local_cov(k, k)));

  const double along = std::max(f.spread_mm[0], f.spread_mm[1]);
  const double across = std::min(f.spread_mm[0], f.spread_mm[1]);
  if (along < options.min_spread_mm) {
    throw GeometryError("all " + std::to_string(points.size()) +
                        " points coincide (spread " + mm(along) + "): no surface to fit");
  }
  if (across < options.min_width_ratio * along) {
    throw GeometryError("the points lie on a line (width " + mm(across) + " across a length of " +
                        mm(along) + (choice == PlaneChoice::Xy ? " in the xy plane" : "") +
                        "): a surface needs points spread in two directions");
  }
  return f;
}

bool is_flat(const PlaneFrame& frame, const FrameOptions& options) {
  return frame.spread_mm[2] < options.flat_ratio * std::min(frame.spread_mm[0], frame.spread_mm[1]);
}

ParameterBox parameter_box(const std::vector<Eigen::Vector3d>& local) {
  ParameterBox b;
  b.t1_min = b.t2_min = std::numeric_limits<double>::infinity();
  b.t1_max = b.t2_max = -std::numeric_limits<double>::infinity();
  for (const auto& p : local) {
    b.t1_min = std::min(b.t1_min, p.x());
    b.t1_max = std::max(b.t1_max, p.x());
    b.t2_min = std::min(b.t2_min, p.y());
    b.t2_max = std::max(b.t2_max, p.y());
  }
  if (!(b.t1_max > b.t1_min) || !(b.t2_max > b.t2_min)) {
    throw GeometryError("the points span no area in the parameter plane");
  }
  return b;
}

}  // namespace photomill::fitsurf
