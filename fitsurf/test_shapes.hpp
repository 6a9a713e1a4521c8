// Ground truth for fitsurf's tests and benchmark: analytic height fields z = f(x, y) over
// 150 x 100 mm ([-75, 75] x [-50, 50]), mostly 20-40 mm high - sums of Gaussian bumps, a tanh
// saddle, a wave, a dome (the kinds of tools/synth's shapes, without synth's blend down to the
// plate), a narrow bump (the most curved), a cylindrical ridge (the steepest) and the demo part
// (synth's bumps written out, so that these tests need not link synth; synth's own parts:
// synth_shapes.hpp) - plus samplers with Gaussian noise and the deviation of a fitted surface
// from the truth. Header-only; deterministic (SplitMix64 + Box-Muller).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "fitsurf/outline.hpp"
#include "geometry/random.hpp"
#include "formats/bspline.hpp"
#include "formats/point_cloud.hpp"

namespace photomill::fitsurf::test {

struct Shape {
  std::string name;
  std::function<double(double, double)> f;  // z in mm at (x, y) mm
};

inline double gauss(double x, double y, double x0, double y0, double sx, double sy) {
  const double a = (x - x0) / sx, b = (y - y0) / sy;
  return std::exp(-0.5 * (a * a + b * b));
}

// The shapes over the rectangle.
inline std::vector<Shape> shapes() {
  return {
      {"bumps",
       [](double x, double y) {
         return 20 + 12 * gauss(x, y, -35, 10, 22, 18) + 9 * gauss(x, y, 30, -15, 18, 20) +
                6 * gauss(x, y, 45, 28, 12, 12) + 5 * gauss(x, y, -10, -30, 25, 12);
       }},
      {"saddle", [](double x, double y) { return 30 + 8 * std::tanh(x / 40) * std::tanh(y / 30) + 2 * gauss(x, y, 0, 0, 30, 30); }},
      {"wave",
       [](double x, double y) {
         return 30 + 6 * std::sin(2 * std::numbers::pi * (x + 10) / 80) * std::cos(2 * std::numbers::pi * (y - 5) / 70);
       }},
      {"dome", [](double x, double y) { return 20 + 18 * gauss(x, y, 5, -5, 45, 32) + 2 * gauss(x, y, -40, 20, 20, 20); }},
      // The most curved: a narrow bump, 10 mm radius of curvature at the top, slopes to 41 degrees.
      {"steep", [](double x, double y) { return 20 + 20 * gauss(x, y, 0, 0, 14, 14); }},
      // The steepest: a cylindrical ridge of radius 52 mm along x, 14-52 mm high, its sides 74
      // degrees steep at y = +-50 (where projection onto a plane compresses the data most).
      {"ridge", [](double, double y) { return std::sqrt(52.0 * 52.0 - y * y); }},
      // The demo part (data/demo: synth --shape bumps, 30 mm high, scene.txt's terms verbatim):
      // h = w f, f = base + four Gaussians (one a dip), w = S(dx/20) S(dy/20), S(t) = 6t^5 - 15t^4
      // + 10t^3 (1 beyond t = 1), dx, dy the distances to the nearest x and y edge
      // (tools/synth/height_field.hpp): it meets the plate tangentially, with 50-70 degree flanks.
      {"demo",
       [](double x, double y) {
         const auto S = [](double t) { return t >= 1 ? 1.0 : t <= 0 ? 0.0 : t * t * t * (10 + t * (-15 + 6 * t)); };
         const double w = S((75 - std::abs(x)) / 20) * S((50 - std::abs(y)) / 20);
         return w * (13.4994200692133 + 16.499291195705148 * gauss(x, y, -27, 10, 21, 20) +
                     10.499548942721455 * gauss(x, y, 33, -12, 15, 15) + 7.499677816229611 * gauss(x, y, 7.5, -28, 12, 10) -
                     4.499806689737767 * gauss(x, y, 30, 22, 10.5, 9));
       }},
  };
}

inline Shape shape(const std::string& name) {
  for (auto& s : shapes()) {
    if (s.name == name) return s;
  }
  return shapes().front();
}

using geometry::Rng;

constexpr double kXMin = -75, kXMax = 75, kYMin = -50, kYMax = 50;

// n points uniform in (x, y) over the rectangle, on the shape, plus isotropic Gaussian noise of
// standard deviation sigma_mm on each coordinate.
inline std::vector<Eigen::Vector3d> sample(const Shape& s, std::size_t n, double sigma_mm, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Eigen::Vector3d> pts(n);
  for (auto& p : pts) {
    const double x = rng.uniform(kXMin, kXMax), y = rng.uniform(kYMin, kYMax);
    p = Eigen::Vector3d(x, y, s.f(x, y));
    if (sigma_mm > 0) p += sigma_mm * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
  }
  return pts;
}

// Marker-like sparse points: a jittered nx x ny grid over [x_min, x_max] x [y_min, y_max], each
// cell's centre moved by up to jitter_mm in x and y, plus Gaussian noise as sample().
inline std::vector<Eigen::Vector3d> sample_grid_over(const Shape& s, double x_min, double x_max, double y_min, double y_max,
                                                     int nx, int ny, double jitter_mm, double sigma_mm, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Eigen::Vector3d> pts;
  const double hx = (x_max - x_min) / nx, hy = (y_max - y_min) / ny;
  for (int i = 0; i < nx; ++i) {
    for (int j = 0; j < ny; ++j) {
      const double x = x_min + (i + 0.5) * hx + rng.uniform(-jitter_mm, jitter_mm);
      const double y = y_min + (j + 0.5) * hy + rng.uniform(-jitter_mm, jitter_mm);
      Eigen::Vector3d p(x, y, s.f(x, y));
      if (sigma_mm > 0) p += sigma_mm * Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal());
      pts.push_back(p);
    }
  }
  return pts;
}

// The same over the whole rectangle (margin kept: half a cell).
inline std::vector<Eigen::Vector3d> sample_grid(const Shape& s, int nx, int ny, double jitter_mm, double sigma_mm,
                                                std::uint64_t seed) {
  return sample_grid_over(s, kXMin, kXMax, kYMin, kYMax, nx, ny, jitter_mm, sigma_mm, seed);
}

// Gradient and Hessian of f by central differences (step 1e-3 mm: truncation ~1e-7 relative,
// rounding ~1e-10 mm^-1 for these smooth shapes).
inline void derivatives(const Shape& s, double x, double y, Eigen::Vector2d& g, Eigen::Matrix2d& H) {
  constexpr double h = 1e-3;
  const double f0 = s.f(x, y);
  const double fxp = s.f(x + h, y), fxm = s.f(x - h, y), fyp = s.f(x, y + h), fym = s.f(x, y - h);
  g = Eigen::Vector2d((fxp - fxm) / (2 * h), (fyp - fym) / (2 * h));
  H(0, 0) = (fxp - 2 * f0 + fxm) / (h * h);
  H(1, 1) = (fyp - 2 * f0 + fym) / (h * h);
  H(0, 1) = H(1, 0) = (s.f(x + h, y + h) - s.f(x + h, y - h) - s.f(x - h, y + h) + s.f(x - h, y - h)) / (4 * h * h);
}

// Largest |principal curvature| of the height field at (x, y): the eigenvalues of the shape
// operator I^-1 II with I = 1 + g g^T, II = H / sqrt(1 + |g|^2).
inline double true_max_curvature(const Shape& s, double x, double y) {
  Eigen::Vector2d g;
  Eigen::Matrix2d H;
  derivatives(s, x, y, g, H);
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity() + g * g.transpose();
  const Eigen::Matrix2d W = I.inverse() * H / std::sqrt(1 + g.squaredNorm());
  return W.eigenvalues().cwiseAbs().maxCoeff();
}

// Largest |principal curvature| of a B-spline surface at (u, v) (same formula with I, II from
// S_u, S_v, S_uu, S_uv, S_vv).
inline double surface_max_curvature(const BSplineSurface& s, double u, double v) {
  const SurfaceDerivatives d = surface_derivatives(s, u, v);
  const Eigen::Vector3d n = d.normal();
  Eigen::Matrix2d I, II;
  I << d.su.dot(d.su), d.su.dot(d.sv), d.su.dot(d.sv), d.sv.dot(d.sv);
  II << d.suu.dot(n), d.suv.dot(n), d.suv.dot(n), d.svv.dot(n);
  const Eigen::Matrix2d W = I.inverse() * II;
  return W.eigenvalues().cwiseAbs().maxCoeff();
}

// Distance of a point to the height field, to first order: |z - f(x, y)| / sqrt(1 + |grad f|^2).
inline double distance_to_truth(const Shape& s, const Eigen::Vector3d& x) {
  Eigen::Vector2d g;
  Eigen::Matrix2d H;
  derivatives(s, x.x(), x.y(), g, H);
  return std::abs(x.z() - s.f(x.x(), x.y())) / std::sqrt(1 + g.squaredNorm());
}

// The thin-plate spline interpolant of scattered heights (Duchon 1977): z(x, y) = a0 + a1 x + a2 y
// + sum_i c_i phi(|(x, y) - (x_i, y_i)|), phi(r) = r^2 log r, with sum c_i = sum c_i x_i =
// sum c_i y_i = 0; among all surfaces through the points it has the least thin-plate energy
// (the quantity fitsurf's smoothing penalises). A yardstick for sparse fits: it shows how far a
// smooth, plausible surface through the same samples can lie from the truth. Dense (n + 3)^2 solve:
// for up to a few thousand points.
inline std::function<double(double, double)> thin_plate_interpolant(const std::vector<Eigen::Vector3d>& pts) {
  const int n = static_cast<int>(pts.size());
  const auto phi = [](double r2) { return r2 > 0 ? 0.5 * r2 * std::log(r2) : 0.0; };  // r^2 log r
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n + 3, n + 3);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n + 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) A(i, j) = phi((pts[i].head<2>() - pts[j].head<2>()).squaredNorm());
    A(i, n) = A(n, i) = 1;
    A(i, n + 1) = A(n + 1, i) = pts[i].x();
    A(i, n + 2) = A(n + 2, i) = pts[i].y();
    b(i) = pts[i].z();
  }
  const Eigen::VectorXd c = A.partialPivLu().solve(b);
  std::vector<Eigen::Vector2d> xy(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) xy[i] = pts[i].head<2>();
  return [c, xy, phi, n](double x, double y) {
    double z = c(n) + c(n + 1) * x + c(n + 2) * y;
    for (int i = 0; i < n; ++i) z += c(i) * phi((Eigen::Vector2d(x, y) - xy[static_cast<std::size_t>(i)]).squaredNorm());
    return z;
  };
}

struct TruthDeviation {
  double rms_mm = 0, max_mm = 0;
  double max_curvature = 0, true_max_curvature = 0;  // 1/mm over the same samples
  std::size_t samples = 0;
};

// Deviation of the surface from the truth over an n x n grid in (u, v), keeping the samples
// accepted by `inside` (e.g. inside the outline or the points' hull).
inline TruthDeviation compare_with_truth(const BSplineSurface& s, const Shape& shape, int n,
                                         const std::function<bool(const Eigen::Vector2d&)>& inside) {
  TruthDeviation t;
  double sum2 = 0;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      const Eigen::Vector2d uv((a + 0.5) / n, (b + 0.5) / n);
      if (!inside(uv)) continue;
      const Eigen::Vector3d x = surface_point(s, uv.x(), uv.y());
      const double d = distance_to_truth(shape, x);
      sum2 += d * d;
      t.max_mm = std::max(t.max_mm, d);
      t.max_curvature = std::max(t.max_curvature, surface_max_curvature(s, uv.x(), uv.y()));
      t.true_max_curvature = std::max(t.true_max_curvature, true_max_curvature(shape, x.x(), x.y()));
      ++t.samples;
    }
  }
  t.rms_mm = t.samples ? std::sqrt(sum2 / static_cast<double>(t.samples)) : 0.0;
  return t;
}

// The same inside the surface's outline (its boundary_uv; everywhere when it has none), over
// kTruthGrid x kTruthGrid samples unless told.
constexpr int kTruthGrid = 120;
inline TruthDeviation truth_inside_outline(const BSplineSurface& s, const Shape& shape, int n = kTruthGrid) {
  return compare_with_truth(s, shape, n, [&](const Eigen::Vector2d& uv) {
    return s.boundary_uv.empty() || point_in_polygon(s.boundary_uv, uv);
  });
}

inline PointCloud cloud_of(std::vector<Eigen::Vector3d> pts) {
  PointCloud c;
  c.points_mm = std::move(pts);
  return c;
}

}  // namespace photomill::fitsurf::test
