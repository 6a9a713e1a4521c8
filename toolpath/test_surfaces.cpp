#include "toolpath/test_surfaces.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Dense>

#include "formats/bspline.hpp"

namespace photomill::toolpath::test {
namespace {

// Knots by averaging (eq. 9.8) on uniform parameters t_k = k / (n - 1), clamped.
std::vector<double> averaged_knots(int n, int p) {
  std::vector<double> U(static_cast<std::size_t>(n + p + 1), 0.0);
  for (int k = 0; k <= p; ++k) U[static_cast<std::size_t>(n + k)] = 1.0;
  for (int j = 1; j <= n - 1 - p; ++j) {
    double sum = 0;
    for (int i = j; i <= j + p - 1; ++i) sum += static_cast<double>(i) / (n - 1);
    U[static_cast<std::size_t>(j + p)] = sum / p;
  }
  return U;
}

// Collocation matrix A(k, i) = N_i,p(t_k).
Eigen::MatrixXd collocation(int n, int p, const std::vector<double>& U) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k) {
    const BasisRow row = basis_row(n - 1, p, static_cast<double>(k) / (n - 1), U);
    for (int i = 0; i <= p; ++i) A(k, row.first + i) = row.values[static_cast<std::size_t>(i)];
  }
  return A;
}

}  // namespace

BSplineSurface interpolate_height_field(const std::function<double(double, double)>& f, double x0, double x1, double y0,
                                        double y1, int nx, int ny, int p) {
  if (nx <= p || ny <= p) throw std::invalid_argument("interpolate_height_field: too few samples for the degree");
  BSplineSurface s;
  s.degree_u = s.degree_v = p;
  s.num_poles_u = nx;
  s.num_poles_v = ny;
  s.knots_u = averaged_knots(nx, p);
  s.knots_v = averaged_knots(ny, p);
  const Eigen::PartialPivLU<Eigen::MatrixXd> Au(collocation(nx, p, s.knots_u));
  const Eigen::PartialPivLU<Eigen::MatrixXd> Av(collocation(ny, p, s.knots_v));
  // Q(k, l) per coordinate; first solve along u for every column l, then along v for every row.
  std::array<Eigen::MatrixXd, 3> Q;
  for (auto& q : Q) q.resize(nx, ny);
  for (int k = 0; k < nx; ++k) {
    const double x = x0 + (x1 - x0) * k / (nx - 1);
    for (int l = 0; l < ny; ++l) {
      const double y = y0 + (y1 - y0) * l / (ny - 1);
      Q[0](k, l) = x, Q[1](k, l) = y, Q[2](k, l) = f(x, y);
    }
  }
  s.poles_mm.resize(static_cast<std::size_t>(nx) * ny);
  for (int c = 0; c < 3; ++c) {
    const Eigen::MatrixXd R = Au.solve(Q[static_cast<std::size_t>(c)]);           // nx x ny
    const Eigen::MatrixXd P = Av.solve(R.transpose()).transpose();               // nx x ny
    for (int i = 0; i < nx; ++i) {
      for (int j = 0; j < ny; ++j) s.pole(i, j)[c] = P(i, j);
    }
  }
  return s;
}

BSplineSurface bumps_surface() {
  const auto bump = [](double x, double y, double cx, double cy, double a, double sigma) {
    return a * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * sigma * sigma));
  };
  return interpolate_height_field(
      [&](double x, double y) {
        return 20 + bump(x, y, 45, 40, 16, 18) + bump(x, y, 105, 62, 12, 15) + bump(x, y, 125, 18, 8, 12);
      },
      0, 150, 0, 100, 76, 51);
}

BSplineSurface wave_surface() {
  constexpr double pi = std::numbers::pi;
  return interpolate_height_field(
      [](double x, double y) { return 30 + 6 * std::sin(2 * pi * x / 75) * std::cos(2 * pi * y / 50); }, 0, 150, 0, 100, 101,
      68);
}

BSplineSurface groove_surface() {
  return interpolate_height_field(
      [](double x, double y) {
        const double d = ((x - 75) - 0.3 * (y - 50)) / std::sqrt(1.09);
        return 25 + 0.08 * x - 3 * std::exp(-d * d / (2 * 1.2 * 1.2));
      },
      0, 150, 0, 100, 301, 101);
}

BSplineSurface cylinder_surface(double radius_mm, bool convex) {
  if (radius_mm <= 0) return interpolate_height_field([](double, double y) { return 20 + 0.3 * y; }, 0, 60, 0, 30, 7, 7);
  const double r = radius_mm;
  if (r < 15 / 0.9) throw std::invalid_argument("cylinder_surface: radius below 16.7 mm");
  return interpolate_height_field(
      [=](double, double y) {
        const double s = std::sqrt(r * r - (y - 15) * (y - 15));
        return convex ? 10 + s : 40 - s;
      },
      0, 60, 0, 30, 13, 121);
}

BSplineSurface rational_ridge_surface(double radius_mm) {
  const double r = radius_mm, c = std::sqrt(0.5);
  BSplineSurface s;
  s.degree_u = 1;
  s.degree_v = 2;
  s.num_poles_u = 2;
  s.num_poles_v = 3;
  s.knots_u = {0, 0, 1, 1};
  s.knots_v = {0, 0, 0, 1, 1, 1};
  for (double x : {0.0, 60.0}) {
    s.poles_mm.push_back({x, r * c, r * c});
    s.poles_mm.push_back({x, 0, r / c});  // the tangents at 45 and 135 degrees meet here
    s.poles_mm.push_back({x, -r * c, r * c});
    for (double w : {1.0, c, 1.0}) s.weights.push_back(w);
  }
  return s;
}

BSplineSurface tent_surface() {
  BSplineSurface s;
  s.degree_u = 1;
  s.degree_v = 2;
  s.num_poles_u = 2;
  s.num_poles_v = 3;
  s.knots_u = {0, 0, 1, 1};
  s.knots_v = {0, 0, 0, 1, 1, 1};
  s.poles_mm = {{0, 0, 30}, {0, 0, 30}, {0, 0, 30}, {40, -20, 10}, {40, 0, 20}, {40, 20, 10}};
  return s;
}

BSplineSurface trough_surface(double radius_mm) {
  const double r = radius_mm, a = r / std::sqrt(2.0);
  return interpolate_height_field(
      [=](double, double y) {
        const double d = std::abs(y - 15);
        return d <= a ? 20 - std::sqrt(r * r - d * d) : 20 - a + (d - a);
      },
      0, 60, 0, 30, 13, 241);
}

BSplineSurface named_surface(const std::string& name) {
  if (name == "bumps") return bumps_surface();
  if (name == "wave") return wave_surface();
  if (name == "groove") return groove_surface();
  throw std::invalid_argument("unknown test surface '" + name + "' (bumps, wave, groove)");
}

}  // namespace photomill::toolpath::test
