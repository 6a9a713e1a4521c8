// The synthetic part: a smooth height field z = h(x, y) over a rectangle, evaluated exactly
// (height, gradient, normal) together with rigorous bounds on its slope and curvature that the
// ray caster needs to step safely. World frame: mm, plate top at z = 0, z up.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill::synth {

// One additive term of the shape function f(x, y). With u = (x - x0)/s1, v = (y - y0)/s2:
//   Gauss:  a * exp(-(u^2 + v^2) / 2)                      s1, s2 = standard deviations, mm
//   Wave:   a * cos(2 pi (x - x0)/s1) * cos(2 pi (y - y0)/s2)  s1, s2 = wavelengths, mm;
//           a wavelength of 0 makes the term constant along that axis
//   Saddle: a * tanh(u) * tanh(v)                          s1, s2 = length scales, mm
struct ShapeTerm {
  enum class Kind { Gauss, Wave, Saddle };
  Kind kind = Kind::Gauss;
  double amplitude_mm = 0;  // a
  double x0_mm = 0;
  double y0_mm = 0;
  double s1_mm = 1;  // > 0 (Wave: >= 0)
  double s2_mm = 1;  // > 0 (Wave: >= 0)
  bool operator==(const ShapeTerm&) const = default;
};

std::string to_string(ShapeTerm::Kind kind);
// "gauss", "wave", "saddle"; throws std::invalid_argument otherwise.
ShapeTerm::Kind shape_term_kind(const std::string& name);

// h(x, y) = w(x, y) * f(x, y) inside the rectangle, 0 outside, where
//   f = base + sum of terms,
//   w = S(dx / b) * S(dy / b), dx, dy = distance to the nearest x and y edge, b = edge blend,
//   S(t) = 6t^5 - 15t^4 + 10t^3 for 0 <= t <= 1 (1 beyond): C2, so h is C2 on the whole plane
// and meets the plate (z = 0) tangentially along the rectangle's edge.
// b = 0 makes a walled part: h = f on the closed rectangle, 0 outside, so the part ends in
// vertical walls from the plate up to f along the rectangle's edge (f must be positive there).
struct HeightField {
  double x_min_mm = -75;
  double x_max_mm = 75;
  double y_min_mm = -50;
  double y_max_mm = 50;
  double edge_blend_mm = 20;  // b, 0 (walls) or > 0 and <= half the smaller side
  double base_mm = 0;         // constant term of f
  std::vector<ShapeTerm> terms;
  bool operator==(const HeightField&) const = default;

  bool contains(double x, double y) const {
    return x > x_min_mm && x < x_max_mm && y > y_min_mm && y < y_max_mm;
  }
  // Vertical walls along the rectangle's edge (b = 0).
  bool walled() const { return edge_blend_mm == 0; }
  // f at the point of the closed rectangle nearest (x, y): the height of the top at a wall.
  double wall_top_mm(double x, double y) const;
  double height_mm(double x, double y) const;
  // dh/dx, dh/dy (dimensionless).
  Eigen::Vector2d gradient(double x, double y) const;
  // Height and gradient in one pass (what the ray caster uses).
  double evaluate(double x, double y, Eigen::Vector2d& gradient) const;
  // Upward unit normal (-h_x, -h_y, 1) / norm.
  Eigen::Vector3d normal(double x, double y) const;

  // Upper bound of |grad h| over the plane, from the terms' closed-form maxima.
  double slope_bound() const;
  // Upper bound of the spectral norm of the Hessian of h over the plane.
  double curvature_bound() const;
  // Upper bound of |h| (|base| + sum |a|).
  double height_bound() const;
};

// Throws std::invalid_argument with a readable message if the field is not usable (non-finite
// numbers, empty rectangle, blend negative or too wide, non-positive scales).
void validate(const HeightField& field);

// Named shapes over a rectangle of the given size centred at the origin, scaled so that the
// highest point is `height_mm` (20-40 mm in the issue; anything positive works). With
// edge_blend_mm = 0 the part is walled; make_shape throws if its top is not above the plate
// everywhere (a wall of zero height).
//   bumps:  four Gaussian bumps of different sizes on a low base
//   saddle: a tanh saddle on a base, with a gentle bump
//   wave:   a diagonal cosine wave on a base
//   dome:   one wide anisotropic Gaussian with a ripple
std::vector<std::string> shape_names();
HeightField make_shape(const std::string& name, double length_x_mm, double length_y_mm,
                       double height_mm, double edge_blend_mm);

}  // namespace photomill::synth
