// Scattered-data interpolation of a height field z = f(x, y) by a radial kernel whose shape and
// length are chosen by leave-one-out cross-validation: fitsurf's prefit for sparse clouds (a few
// hundred markers), where the B-spline's smoothing term, not the data, would decide the shape
// between the points (docs/fitsurf.md, Method; figures in docs/measurements/fitsurf.md).
//
//   f(x) = sum_k c_k phi(|x - x_k|) + sum_j d_j p_j(x),   [Phi + D   P] [c]   [z]
//                                                         [P^T      0] [d] = [0]
//
// with one of the kernels (Rasmussen & Williams 2006, "Gaussian Processes for Machine Learning",
// eqs. 4.9, 4.16 and 4.17; Duchon 1977 for the polyharmonic splines; Wendland 2005, "Scattered
// Data Approximation", 8.3):
//   Gaussian       phi = exp(-r^2 / (2 l^2));
//   Matern 3/2     phi = (1 + a) exp(-a),                          a = sqrt(3) r / l;
//   Matern 5/2     phi = (1 + a + a^2 / 3) exp(-a),                a = sqrt(5) r / l;
//   Matern 7/2     phi = (1 + a + 2 a^2 / 5 + a^3 / 15) exp(-a),   a = sqrt(7) r / l;
//     each with a trend p of degree 1 or 2 (universal kriging);
//   polyharmonic m phi = r^(2m-2) log r (m = 3, 4, 5),  p: the polynomials of degree m - 1.
// (The thin-plate spline is m = 2; the B-spline's own smoothing of order 2 and 3 corresponds to
// m = 2 and 3.) It interpolates: D holds only a ridge of KernelOptions::ridge (times phi(0) = 1) keeps the
// Gaussian's nearly singular matrices solvable (the polyharmonic systems need none).
//
// Leave-one-out residuals need no refits: e_k = z_k - f^(-k)(x_k) = c_k / (A^-1)_kk (Rippa 1999,
// "An algorithm for selecting a good value for the parameter c in radial basis function
// interpolation", Adv. Comput. Math. 11, eq. 2.5; with the polynomial block, A the whole matrix).
// The candidate with the smallest RMS of e_k wins: every kernel and trend, the lengths l from
// min_length_spacings to max_length_spacings mean point spacings in steps of coarse_ratio, then
// around each kernel's best in steps of fine_ratio; then the best families anisotropic
// (KernelModel::aspect, KernelOptions::max_aspect), taken only by a margin (anisotropy_gain).
// (A nugget for noisy points - kriging with measurement error, its scale by the discrepancy
// principle - was tried and gained nothing on 150 markers with 0.005-0.1 mm noise,
// docs/measurements/fitsurf.md; fitsurf keeps the spline's --noise-mm for them.)
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill::fitsurf {

enum class KernelShape { Gaussian, Matern32, Matern52, Matern72, Polyharmonic3, Polyharmonic4, Polyharmonic5 };
std::string to_string(KernelShape k);
bool is_polyharmonic(KernelShape k);

struct KernelModel {
  KernelShape shape = KernelShape::Gaussian;
  int trend_degree = 1;  // degree of the polynomial part (the polyharmonic kernels: m - 1, fixed)
  double length_mm = 0;  // l; 0 for the polyharmonic kernels (scale-free)
  // Anisotropy: distances are measured with the long axis, at angle_deg from the u axis, shrunk by
  // aspect, r^2 = (d.e / aspect)^2 + (d.e_perp)^2, so l is the length across that axis and
  // aspect * l the length along it (Rasmussen & Williams 2006, eq. 5.2, M = R diag(l_i^-2) R^T;
  // any affine map of the plane keeps the polyharmonic kernels' polynomial reproduction). A ridge or
  // a fold, flat along one direction, is predicted from markers far along it. aspect 1: isotropic.
  double aspect = 1;
  double angle_deg = 0;  // [0, 180)
};
std::string to_string(const KernelModel& m);  // "matern52, length 29.3 mm, linear trend[, 4x along 45 deg]"

struct KernelOptions {
  double min_length_spacings = 0.5;  // shortest length l tried, in mean point spacings
  double max_length_spacings = 40;   // longest
  double coarse_ratio = 1.25;        // geometric step between the lengths tried first
  double fine_ratio = 1.05;          // then around each kernel's best
  double ridge = 1e-8;               // added to Phi's diagonal (phi(0) = 1) for the positive definite kernels
  // Anisotropic candidates: the best isotropic kernel/trend families (anisotropic_families) again
  // with aspects aspect_step, aspect_step^2, ... up to max_aspect, long axes `directions` evenly
  // spread over 180 degrees, lengths across from 1 / anisotropic_length_span to
  // anisotropic_length_span^(1/2) times the family's isotropic best (coarse_ratio steps, then
  // fine). One is chosen only when its leave-one-out RMS is anisotropy_gain times smaller than the
  // isotropic best's: on 150 markers of parts without a preferred direction the extra freedom
  // otherwise wins by a few per cent and extrapolates worse. Measured on 150 markers, 24 layouts
  // each (docs/measurements/fitsurf.md): smooth parts without a preferred direction up to 1.49x (one wave
  // layout's 1.47x, a fluke of the length grid, took an anisotropic kernel 0.154 mm off the
  // truth where the isotropic one is 0.102 mm), the ridge 2.3x and more. max_aspect 1: none.
  double max_aspect = 8;
  double aspect_step = 2;
  int directions = 4;
  int anisotropic_families = 2;
  double anisotropic_length_span = 4;
  double anisotropy_gain = 2;
  int threads = 0;                   // 0: all hardware threads
};

struct KernelCandidate {
  KernelModel model;
  double loo_rms_mm = 0;  // RMS leave-one-out residual; infinity when the system was singular
};

class KernelInterpolant {
public:
  const KernelModel& model() const { return model_; }
  double loo_rms_mm() const { return loo_rms_mm_; }
  // z_k - f^(-k)(x_k) of each point: the error predicting it from all the others.
  const std::vector<double>& loo_residual_mm() const { return loo_; }
  // The same divided by its prediction's standard deviation up to a common factor, e_k
  // sqrt(|(A^-1)_kk|) (the kriging variance of predicting x_k from the others is proportional to
  // 1 / |(A^-1)_kk|): comparable between a point amid others and one on the hull's edge.
  const std::vector<double>& loo_standardised() const { return loo_standardised_; }
  // Every candidate tried, in the order tried (for the report and the tests).
  const std::vector<KernelCandidate>& candidates() const { return candidates_; }
  double operator()(const Eigen::Vector2d& xy_mm) const;

private:
  friend KernelInterpolant fit_kernel(const std::vector<Eigen::Vector2d>&, const std::vector<double>&,
                                      const KernelOptions&);
  friend KernelInterpolant fit_kernel_model(const std::vector<Eigen::Vector2d>&, const std::vector<double>&,
                                            const KernelModel&, const KernelOptions&);
  KernelModel model_;
  double loo_rms_mm_ = 0;
  std::vector<double> loo_, loo_standardised_;
  std::vector<KernelCandidate> candidates_;
  Eigen::Vector2d centre_mm_ = Eigen::Vector2d::Zero();
  double scale_mm_ = 1;  // coordinates are (x - centre) / scale inside
  std::vector<Eigen::Vector2d> nodes_;
  Eigen::VectorXd coef_;  // c (n), then d (the polynomial terms)
};

// Chooses the kernel, trend and length by leave-one-out cross-validation and returns the
// interpolant. Throws GeometryError when there are fewer than 4 points, they coincide, or no
// candidate system can be solved.
KernelInterpolant fit_kernel(const std::vector<Eigen::Vector2d>& xy_mm, const std::vector<double>& z_mm,
                             const KernelOptions& options = {});

// One given model (no search); candidates() holds it alone.
KernelInterpolant fit_kernel_model(const std::vector<Eigen::Vector2d>& xy_mm, const std::vector<double>& z_mm,
                                   const KernelModel& model, const KernelOptions& options = {});

}  // namespace photomill::fitsurf
