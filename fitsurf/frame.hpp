// The parameter plane of a fit: a right-handed orthonormal frame in which the points are (nearly)
// a height field, and the rectangle they cover in it. The first parameterisation of the data is
// the orthogonal projection onto this plane (the paper, section 4: "a given parameterisation";
// Piegl & Tiller 9.4.1 for scattered data).
#pragma once

#include <vector>

#include <Eigen/Core>

namespace photomill::fitsurf {

enum class PlaneChoice {
  Pca,  // best-fit plane of the points (principal component analysis)
  Xy,   // the world xy plane (parts measured standing on a horizontal plate)
  Auto, // whichever of the two holds the data better as a height field (choose_plane, slope.hpp)
};

struct PlaneFrame {
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();  // centroid of the points, world mm
  // Columns e1, e2, e3 (world). e1: the direction of largest spread; e3 = e1 x e2: the plane
  // normal, oriented towards world +z (or +y, +x if perpendicular) so that the fitted surface's
  // normal S_u x S_v points "up".
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d spread_mm = Eigen::Vector3d::Zero();  // standard deviation along e1, e2, e3

  // local = axes^T (world - origin): (t1, t2) in the plane, t3 the height above it.
  Eigen::Vector3d to_local(const Eigen::Vector3d& world) const { return axes.transpose() * (world - origin_mm); }
  Eigen::Vector3d to_world(const Eigen::Vector3d& local) const { return origin_mm + axes * local; }
};

struct FrameOptions {
  // All points within this distance (standard deviation, mm) of their centroid: they coincide.
  double min_spread_mm = 1e-6;
  // Spread across the main direction below this fraction of the spread along it: a line.
  double min_width_ratio = 1e-3;
  // Spread normal to the plane below this fraction of the in-plane spread: a flat cloud.
  double flat_ratio = 1e-4;
};

// The frame of `points`. Throws GeometryError when the points coincide or lie on a line (in the
// chosen plane): no surface is defined by them.
PlaneFrame parameter_frame(const std::vector<Eigen::Vector3d>& points, PlaneChoice choice,
                           const FrameOptions& options = {});

// True when the points are flat to within options.flat_ratio (a plane fits them exactly).
bool is_flat(const PlaneFrame& frame, const FrameOptions& options = {});

// The rectangle [t1_min, t1_max] x [t2_min, t2_max] (mm) the local points cover; the parameter
// domain [0,1]^2 maps onto it: u = (t1 - t1_min) / (t1_max - t1_min), v likewise.
struct ParameterBox {
  double t1_min = 0, t1_max = 1, t2_min = 0, t2_max = 1;
  double length_u_mm() const { return t1_max - t1_min; }
  double length_v_mm() const { return t2_max - t2_min; }
  Eigen::Vector2d to_uv(const Eigen::Vector3d& local) const {
    return {(local.x() - t1_min) / length_u_mm(), (local.y() - t2_min) / length_v_mm()};
  }
};
ParameterBox parameter_box(const std::vector<Eigen::Vector3d>& local_points);

}  // namespace photomill::fitsurf
