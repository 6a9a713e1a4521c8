// Steps 1, 5 and 6 of the paper's tool path generation (section 5): iso-parametric curves, the
// side step g from the scallop height h, and its conversion to a parameter step between passes.
// Input: a B-spline surface (formats/surface.hpp); output: the fixed parameter of every pass and
// the parameter intervals of that pass inside the boundary polygon.
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Core>

#include "formats/bspline.hpp"
#include "formats/surface.hpp"

namespace photomill::toolpath {

// Which parameter a pass runs along. U: passes are curves v = const, u varies, side steps in v.
enum class PassDirection { U, V };

// A parameter interval [t0, t1] along a pass (t is u for PassDirection::U, v for V).
struct Interval {
  double t0 = 0;
  double t1 = 0;
  bool operator==(const Interval&) const = default;
};

// Position and derivatives of the surface at one point, renamed for a pass: t along the pass,
// w across it (the fixed parameter). For PassDirection::U, t = u and w = v.
struct PassFrame {
  Eigen::Vector2d uv;        // (u, v) of the point
  Eigen::Vector3d p;         // S, world mm
  Eigen::Vector3d st, sw;    // dS/dt, dS/dw, mm per parameter unit
  Eigen::Vector3d stt, stw, sww;
  // Unit normal S_u x S_v / |S_u x S_v| (S_t x S_w for V passes is its negative; the normal is
  // always that of (u, v)). It points up wherever the surface does not overhang, once the
  // surface is upward_oriented(); where it points down (n_z < 0, an undercut) a 3-axis ball
  // cannot touch the surface and the drop cutter lifts it.
  Eigen::Vector3d normal;
};

// Step 1: the iso-parametric curve w = const of `surface`, as a function of t. Holding t fixed
// too gives a point; w at either end of the domain gives a boundary curve (paper, step 1).
class IsoCurve {
public:
  IsoCurve(const BSplineSurface& surface, PassDirection direction, double w)
      : surface_(&surface), direction_(direction), w_(w) {}
  Eigen::Vector2d uv(double t) const {
    return direction_ == PassDirection::U ? Eigen::Vector2d(t, w_) : Eigen::Vector2d(w_, t);
  }
  Eigen::Vector3d point(double t) const;
  PassFrame frame(double t) const;
  double w() const { return w_; }
  PassDirection direction() const { return direction_; }
  const BSplineSurface& surface() const { return *surface_; }

private:
  const BSplineSurface* surface_;
  PassDirection direction_;
  double w_;
};

// Derivatives at (u, v) in pass notation; the normal is su x sv, never flipped point by point
// (at a vertical tangent plane rounding would flip it to either side: into the part). Where
// su x sv vanishes (a collapsed edge) the normal is taken a little inside the domain; throws
// GeometryError if it is undefined there too.
PassFrame pass_frame(const BSplineSurface& surface, PassDirection direction, double u, double v);

// Which way a surface faces: its area inside the boundary polygon and the areas of its
// projection onto the xy plane where S_u x S_v points up and where it points down (mm^2,
// integrated on a 48 x 48 grid of the domain). A vertical wall has up + down ~ 0.
struct SurfaceFacing {
  double area_mm2 = 0;
  double up_mm2 = 0;
  double down_mm2 = 0;
};
SurfaceFacing surface_facing(const BSplineSurface& surface);
// The same surface parameterized u' = u0 + u1 - u (knots, pole rows and boundary polygon
// reflected): its normal S_u x S_v is reversed everywhere.
BSplineSurface mirrored_u(const BSplineSurface& surface);
// `surface` itself if its up area is at least its down area (surface_facing), else mirrored_u(surface): afterwards S_u x S_v points
// up where the surface faces up (the whole surface, not point by point). generate_toolpath
// orients its input so.
BSplineSurface upward_oriented(const BSplineSurface& surface);
// Even-odd point-in-polygon test in (u, v).
bool inside_uv_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p);

// Parameter ranges along (t) and across (w) the passes.
std::pair<double, double> along_domain(const BSplineSurface& surface, PassDirection direction);
std::pair<double, double> across_domain(const BSplineSurface& surface, PassDirection direction);

// Normal curvature (1/mm) of the surface at `f` in the tangent direction a*st + b*sw:
//   kappa_n = II(d, d) / I(d, d) = (a^2 L + 2ab M + b^2 N) / (a^2 E + 2ab F + b^2 G),
// with E = st.st, F = st.sw, G = sw.sw, L = stt.n, M = stw.n, N = sww.n (do Carmo, 3-3).
// Sign: with n pointing up, kappa_n > 0 where the surface bends towards the tool (concave, a
// bowl) and kappa_n < 0 where it bends away (convex, a hill).
double normal_curvature(const PassFrame& f, double a, double b);
// Along the pass: direction st. Across the pass: the tangent direction perpendicular to st,
// (a, b) = (-F, E).
double along_curvature(const PassFrame& f);
double across_curvature(const PassFrame& f);
// Largest principal curvature (1/mm, concave positive), the root of
// (EG - F^2) k^2 - (EN + GL - 2FM) k + (LN - M^2) = 0.
double max_concave_curvature(const PassFrame& f);

// Step 5: the side step g (mm, arc length on the surface across the pass) that leaves cusps of
// height `cusp_mm` for a ball of radius R = `ball_radius_mm` running at `stock_mm` above the
// surface, where the surface's normal curvature across the pass is `kappa_across` (sign as
// above). Two neighbouring ball centres lie on a circle of radius A about the centre of
// curvature, the cusp tip at radius B, so by the law of cosines (Suresh & Yang 1994, eq. 3;
// Lin & Koren 1996, eq. 4), with rho = 1/|kappa|:
//   convex:  A = rho + a + R,  B = rho + a + h;   concave: A = rho - a - R,  B = rho - a - h;
//   R^2 = (A - B)^2 + 4 A B sin^2(theta / 4)   =>   theta = 4 asin(sqrt((R^2 - (R-h)^2) / (4AB)))
//   g = rho * theta.
// On a flat surface (kappa -> 0) this is g = 2 sqrt(h (2R - h)). A concave radius below
// 2 (R + a) is taken as 2 (R + a) (the formula's benefit is capped where the ball barely fits;
// tighter bowls are gouge regions that the cutter model handles).
double side_step_mm(double ball_radius_mm, double cusp_mm, double stock_mm, double kappa_across);

// Step 6: the parameter step across the pass that moves the next pass g mm away at `f`: the
// across-pass speed is the part of sw perpendicular to st, |sw_perp| = sqrt(G - F^2 / E), so
// dw = g / |sw_perp|. Returns +infinity where the surface does not move across the pass.
double across_param_step(const PassFrame& f, double side_step_mm);

// Parts of the line w = const inside the surface's boundary polygon (even-odd rule), clipped to
// the domain; the whole domain when the surface has no polygon. Sorted by t.
std::vector<Interval> clip_to_boundary(const BSplineSurface& surface, PassDirection direction, double w);

struct PassPlanOptions {
  PassDirection direction = PassDirection::U;
  double tool_radius_mm = 3;     // R
  double scallop_mm = 0.01;      // h: highest material left, cusps plus forward-step excess
  double chord_tol_mm = 0.005;   // e: chord tolerance of the forward step (see cusp_budget_mm)
  double stock_mm = 0;           // a: allowance left on the surface
  double max_step_mm = 2;        // longest forward step (bounds the chords' sag on gentle curves)
  // Spacing of the samples along a pass at which the side step is evaluated (at least two per
  // knot span are taken too: a B-spline's curvature changes within a span).
  double sample_mm = 1;
  int threads = 0;               // for evaluating the samples; 0 = all cores
};

// The share of h left for the cusps at a point: the forward step's chords leave up to
// delta = s (rho - R - a) / rho of extra material where the pass is concave along its length
// (radius rho: a chord of sagitta s on the surface has sagitta s (rho - R - a) / rho on the
// ball-centre curve), with s = min(e, L^2 / (8 rho)) the largest sagitta a chord can have there
// (L = the longest forward step), and none where it is convex or straight. cusp = h - delta.
double cusp_budget_mm(const PassFrame& f, const PassPlanOptions& options);

// One pass: the fixed parameter and the parts of the line to machine.
struct PassLine {
  double w = 0;
  std::vector<Interval> intervals;
  double side_step_mm = 0;   // smallest side step g on this line (0 on the last line)
  double across_step = 0;    // parameter step to the next line (0 on the last line)
};

// Steps 5 and 6 for one line: the parameter step from line w to the next, conservative over
// the whole line: the minimum of dw over samples of the line, of the line halfway to the next
// and of the next line (so h holds over the whole strip between the two).
// `g_min_mm` receives the smallest side step found.
double conservative_across_step(const BSplineSurface& surface, const PassPlanOptions& options, double w,
                                double* g_min_mm = nullptr);

// All passes from one end of the domain (or of the boundary polygon) to the other, the first and
// last on the boundary. With a polygon, each pass covers the polygon over its strip (halfway to
// the neighbouring passes): the union of the intervals of its own line and of the two midlines. Throws GeometryError if the passes would be absurdly many (a degenerate
// surface) or a step cannot be computed.
std::vector<PassLine> plan_passes(const BSplineSurface& surface, const PassPlanOptions& options);

}  // namespace photomill::toolpath
