// Least-squares B-spline surface fitting of scattered points (the paper, section 4; Piegl &
// Tiller, The NURBS Book, 2nd ed.: 9.4.1 for the least-squares fit, eqs. 9.68-9.69 for knot
// placement, 6.1 for the foot points), with thin-plate smoothing, parameter correction and robust
// reweighting:
//
//   1. parameter frame: best-fit plane (PCA) or the xy plane; first parameters (u_k, v_k) by
//      orthogonal projection onto it, scaled to the data's rectangle [0,1]^2;
//   2. knots: clamped uniform, or averaged (NURBS Book eq. 9.69 on the sorted parameters, so every
//      span holds about as many points), or adaptive (adaptive_knots: placed by the shape of a
//      first fit with uniform knots, denser where it bends sharply);
//   3. round r: solve the normal equations (normal_equations.hpp) for the poles with weights
//      w_k; project every point onto the new surface (Newton foot point) - the parameter
//      correction of Hoschek (1988, "Intrinsic parametrization for approximation") - and take
//      the RMS of the signed orthogonal distances d_k;
//   4. robust weights (IRLS, Holland & Welsch 1977) judged locally: for each point, the median m_k
//      and scale s_k = 1.4826 MAD of its neighbours' residuals, its deviation e_k = d_k - m_k, and
//      the cutoff c_k = threshold * max(s_k, sigma), sigma = 1.4826 MAD(e) over all points.
//      The error a coarse net makes is smooth and shared by neighbours: it moves m_k and widens
//      s_k instead of being taken for outliers; an isolated outlier keeps its residual.
//      "reject" (iterative k-sigma rejection, as in geodetic data snooping) w = 1 for
//      |e_k| <= c_k else 0; Huber w = min(1, c_k/|e_k|); Tukey biweight w = (1 - (e_k/c_k)^2)^2
//      for |e_k| < c_k, else 0. "reject" by default: on clean noisy data it gives the same surface
//      as no reweighting, and it removes 1-5 % gross outliers (docs/measurements/fitsurf.md);
//      reweighting starts after the first parameter correction, and the first weighting restarts
//      from the plane parameters (an unweighted fit curled by outliers scrambles the foot points
//      of the points near it);
//   (before round 1, with reweighting on: gross outliers screened by their height against a
//      coarse first fit at the plane parameters, judged locally like step 4 with gross_threshold;)
//   5. repeat 3-4 until a round lowers the weighted RMS by less than min_rms_gain (relative, with
//      the weights held fixed, under which it can only decrease) and no weight changes by more
//      than weight_tolerance, or max_rounds; the last round is the result.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/frame.hpp"
#include "fitsurf/project.hpp"
#include "fitsurf/slope.hpp"
#include "formats/error.hpp"
#include "formats/surface.hpp"

namespace photomill::fitsurf {

enum class KnotPlacement { Uniform, Averaged, Adaptive };
enum class LinearSolver { Ldlt, Cg };
enum class RobustLoss { None, Reject, Huber, Tukey };

// Detection of clouds that are not a height field over the parameter plane (a part folding over
// it: overhangs, more than a half cylinder).
struct FoldOptions {
  // Before fitting: the plane is cut into square cells of cell_spacings mean point spacings; a
  // cell whose points split, along the plane normal, into two groups of >= 2 points separated
  // by more than gap_cells cell sizes holds two layers. Folding is declared when at least
  // min_cells cells and min_fraction of the occupied cells do. Skipped below min_points points.
  double cell_spacings = 4;
  double gap_cells = 3;
  std::size_t min_cells = 3;
  double min_fraction = 0.01;
  std::size_t min_points = 500;
  // After fitting: the angle between the surface normal and the plane normal must stay below
  // this inside the outline. A sparse folded cloud is interpolated by a height field that turns
  // (nearly) vertical between its layers; a part with vertical walls is not a height field either.
  double max_slope_deg = 84;
  // ... except where the data themselves are steep (their cell slopes, slope.hpp, within one knot
  // span of the surface point, as far as its poles reach): there the surface may be as steep as they are plus
  // data_margin_deg, never steeper than steepest_deg (beyond 90 it folds over the plane). A range
  // scan's flank at 84 degrees has to be followed by a surface at 84-87.
  double data_margin_deg = 3;
  double steepest_deg = 89;
  int check_samples = 64;  // per direction
};

struct FitOptions {
  int degree_u = 3;                   // p
  int degree_v = 3;                   // q
  int poles_u = 30;                   // control net size along u (n + 1)
  int poles_v = 30;                   // along v (m + 1)
  KnotPlacement knots = KnotPlacement::Uniform;
  // Adaptive knots (adaptive_knots below): the density of knots is kept within this factor of
  // its mean, so a flat stretch still gets knots and a sharp one does not take them all.
  double adaptive_knot_ratio = 4;
  // ... and every span's |D^(p+1) f| h^(p+1) (its error scale) counts at least this much, so
  // that a plane, or a shape flat to a tenth of a micrometre, keeps uniform knots.
  double adaptive_knot_floor_mm = 1e-4;
  // Auto: the best-fit plane, or world xy where its steepest data slope is lower by more than
  // prefer_pca_deg (choose_plane): a scan whose flank turns past 89 degrees against its best-fit
  // plane may be at 84 against the scanner's xy.
  PlaneChoice plane = PlaneChoice::Auto;
  double prefer_pca_deg = 1;
  SlopeOptions slope;
  double smoothing_mm4 = 1e-2;        // lambda of the smoothing term (normal_equations.hpp); mm^6 for order 3
  // m of the smoothing energy E_m (normal_equations.hpp): 2 = thin plate (second derivatives;
  // planes are free), 3 = third derivatives (quadrics are free, so a gap on a curved part is
  // bridged along its curvature instead of being flattened; docs/measurements/fitsurf.md).
  int smoothing_order = 2;
  // > 0: choose lambda instead so that the residual RMS of the first fit equals this noise level
  // (Reinsch's criterion; for sparse noisy points such as markers, whose noise is known).
  double noise_mm = 0;
  LinearSolver solver = LinearSolver::Ldlt;
  double cg_tolerance = 1e-12;        // CG: relative residual |M x - B| / |B|
  int cg_max_iterations = 20000;
  bool parameter_correction = true;   // project the points onto the surface between rounds
  // Fits at most (the first one included). Parameter correction converges linearly: on a range
  // scan the RMS still falls by several percent a round after 8 (docs/measurements/fitsurf.md).
  int max_rounds = 20;
  // Work limit on the unknowns (--max-net-poles): a net of more poles is refused before any
  // work. The normal equations' factor grows faster than the net: 200 x 200 poles on the demo's
  // 7 700 points took 26 s and 250 MB; the Makefile's net is 75 x 50, --tolerance stops at
  // 200 x 200. The default, 500 x 500, is 6 times that; the old fixed cap was 4 million poles
  // (a 2000 x 2000 net), far beyond the memory of the machine.
  long long max_net_poles = 250'000;
  // A round whose surface is steeper than the fold check allows (check_no_fold, at the foot points'
  // cells) is undone and the correction stops there, with a warning: the points slide along a steep
  // flank round after round until the surface curls over.
  bool stop_before_fold = true;
  double min_rms_gain = 0.001;        // stop when a round improves the RMS by less than this fraction
  // Without parameter correction: still project every point onto the final surface so residuals
  // are orthogonal distances (false: residuals |Q - S(u,v)| at the plane parameters, faster).
  bool final_projection = true;
  RobustLoss robust = RobustLoss::Reject;
  double robust_threshold = 0;        // c / sigma; 0 = the loss's usual constant (reject 5, Huber 1.345, Tukey 4.685)
  // Floor of sigma: residuals below threshold x this are never outliers, so that exact or nearly
  // exact data do not lose the points where the net cannot follow the shape (reject: 0.1 mm).
  double robust_min_scale_mm = 0.02;
  double robust_min_redundancy = 3;   // reweight only with at least this many points per pole
  // When the net has fewer points per pole than that, the robust weights come from a coarser net
  // that has them (same aspect, the most poles allowed): with ~2 points per pole the fine fit
  // follows an outlier nearly onto itself, so its residual does not show it, while on the coarser
  // net it stands out from its neighbours. The fine net is then fitted with those weights fixed.
  // false: no reweighting on such a net (the gross screening only).
  bool robust_on_coarser_net = true;
  double weight_tolerance = 0.01;     // rounds go on while a robust weight changes by more than this
  // Gross outliers are screened before the first round (with reweighting on): a point whose
  // height above the parameter plane, against a coarse first fit (about gross_points_per_pole
  // points per pole) at the plane parameters, deviates from its neighbours' by more than
  // gross_threshold times the robust scale (local, at least the global one) starts with weight 0.
  // Parameter correction would hide it: a point tens of mm off pulls a spike up to itself in the
  // fine fit, and its orthogonal distance to the spike's flank is small (docs/measurements/fitsurf.md).
  double gross_threshold = 20;
  double gross_points_per_pole = 25;
  double min_pivot_ratio = 1e-13;     // LDLT pivots below this times the largest: singular system
  ProjectionOptions projection;
  FrameOptions frame;
  FoldOptions fold;
  int threads = 0;                    // 0: all hardware threads
};

// Throws UsageError for option values that cannot work (degrees, net sizes, negative values).
void validate(const FitOptions& options);

struct FitResult {
  BSplineSurface surface;        // world frame, knots on [0, 1]; boundary_uv left empty
  BSplineSurface local_surface;  // the same surface with poles in the parameter frame
  PlaneFrame frame;
  ParameterBox box;
  std::vector<Eigen::Vector2d> uv;    // foot-point parameters of each point on `surface`
  std::vector<double> residual_mm;    // signed orthogonal distance, positive on the normal's side
  std::vector<double> weight;         // final robust weight (all 1 without reweighting)
  std::vector<double> round_rms_mm;   // weighted RMS distance after each round's fit (the last is returned)
  DataSlope data_slope;               // the data's own slope over the parameter plane (slope.hpp)
  double pca_slope_deg = -1;          // with PlaneChoice::Auto: both planes' scores (else -1)
  double xy_slope_deg = -1;
  PlaneChoice plane = PlaneChoice::Pca;  // the plane used
  int stopped_at_round = 0;           // > 0: round stopped_at_round + 1 was steeper than allowed, undone
  double smoothing_mm4 = 0;           // lambda used (options.smoothing_mm4, or chosen for noise_mm)
  bool robust_applied = false;
  double robust_scale_mm = 0;         // global sigma of the last weighting
  double robust_cutoff_mm = 0;        // threshold * sigma: the smallest cutoff c_k of any point
  std::size_t outliers = 0;           // points whose local deviation |e_k| exceeds c_k
  std::size_t gross_outliers = 0;     // left out before the first round (FitOptions::gross_threshold)
  std::vector<std::uint8_t> outlier;  // per point: 1 if an outlier (empty without reweighting)
  int robust_poles_u = 0;             // net the robust weights were judged on (0: none; the fit's own,
  int robust_poles_v = 0;             // or a coarser one: FitOptions::robust_on_coarser_net)
};

// The options with PlaneChoice::Auto replaced by the plane choose_plane picks for the points
// (logged when it is xy); pca_deg and xy_deg receive both planes' scores (-1 when not Auto).
FitOptions with_plane_chosen(const std::vector<Eigen::Vector3d>& points, const FitOptions& options, double& pca_deg,
                             double& xy_deg);

// Fits the points (world mm). Throws GeometryError for degenerate input: too few points for the
// degrees, coincident or collinear points, a cloud folding over the parameter plane, a singular
// system (empty net cells with smoothing 0), a surface that turns over inside the data.
// point_weights: one positive weight per point (e.g. 1 / sigma^2 of the point), multiplied into
// the robust weights; empty = all 1.
FitResult fit_surface(const std::vector<Eigen::Vector3d>& points, const FitOptions& options,
                      const std::vector<double>& point_weights = {});

// The median of v (the upper one of an even count; 0 for none): the robust statistics' centre.
double median(std::vector<double> v);

// At least (p + 1)(q + 1) points for degrees p x q, else GeometryError saying so.
void require_points(std::size_t n, const FitOptions& options);

// check_no_fold's refusal where the surface is steeper than the data under it allow (it curls
// beyond them between or at the edge of the points), which a stiffer surface may not do; where the
// data themselves are too steep for a height field it throws a plain GeometryError.
class CurlError : public GeometryError {
 public:
  using GeometryError::GeometryError;
};

// The surface folds over the parameter plane inside `boundary_uv` (or the whole domain when it
// is empty)? Throws CurlError or GeometryError naming the place. Part of fit_point_cloud, after the outline.
void check_no_fold(const FitResult& fit, const std::vector<Eigen::Vector2d>& boundary_uv, const FoldOptions& options);

// Knot vector "averaged" over the parameters (NURBS Book eq. 9.69 with d = (m+1)/(n-p+1)),
// with interior knots kept at least 5% of a uniform span apart. Falls back to uniform knots
// when there are fewer parameters than spans.
std::vector<double> averaged_knots(std::vector<double> params, int num_poles, int degree);

// Knots placed by the shape of a first fit (de Boor 1978/2001, "A Practical Guide to Splines",
// ch. XII, NEWNOT): the error of a degree-p spline on a span of width h is about
// C h^(p+1) |D^(p+1) f|, so knots that make h |D^(p+1) f|^(1/(p+1)) equal on every span
// equidistribute it. |D^(p+1) f| near each interior knot of `first` along `direction` (0: u,
// 1: v) is the jump of its p-th derivative there over the mean width of the two spans (the p-th
// derivative's control points, The NURBS Book eq. 3.8, one per span, of every row of poles;
// RMS over the rows); each span takes the mean of its two ends plus floor_mm / h^(p+1) (h its
// width); the density |D^(p+1) f|^(1/(p+1)) is clamped to [mean / ratio, mean * ratio]; the new
// knots split its integral into num_poles - p equal parts. Clamped on [0, 1].
std::vector<double> adaptive_knots(const BSplineSurface& first, int direction, int num_poles, double ratio,
                                   double floor_mm);

}  // namespace photomill::fitsurf
