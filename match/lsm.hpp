// Least-squares matching (LSM): refines the position of a feature in one image so that its
// neighbourhood matches a reference image's neighbourhood of the same point to a few hundredths of
// a pixel. SIFT places a keypoint at a scale-space extremum, which lies on the same surface point
// in two photos only to a fraction of the feature's size (and less so on a surface seen at
// different angles); LSM aligns the grey values themselves.
//
// Model (Gruen 1985, "Adaptive least squares correlation", with an affine geometric and a linear
// radiometric transformation): for window offsets d around the reference point p_ref,
//   f(p_ref + d) = r0 + r1 * g(A d + t) + e,
// f the reference image, g the search image, A (2x2) and t (the search point) the affine
// geometric transformation, r0 and r1 brightness and contrast; the 8 parameters are found by
// Gauss-Newton on sum e^2, with the gradients of g from the cubic-convolution samples.
// With `quadratic`, the geometric model gains second-order terms, A d + t + C (dx^2, dx dy, dy^2)
// with C 2x3 (14 parameters; LSM with higher-order geometric models: Bethmann & Luhmann 2010,
// "Least-squares matching with advanced geometric transformation models", ISPRS Archives
// XXXVIII-5). The map between two photos of a curved surface has such terms; fitted by A d + t
// alone, t moves off the true match of the reference point by about C E[m], the quadratic part's
// mean over the window (all of one sign on a shoulder), which is what put the demo's points
// 0.046 mm inside its convex shoulders (docs/measurements/match.md).
#pragma once

#include <optional>
#include <span>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace photomill::match {

struct LsmOptions {
  // Window half-width: this many times the reference feature's size, clamped to the range below.
  double window_per_size = 1.0;
  int min_half_window_px = 5;
  int max_half_window_px = 15;
  // Adds second-order terms to the geometric model (x = t + A d + q(d), q quadratic in d): on a
  // curved surface the map between two photos is not affine, and the best affine fit over the
  // window moves t off the reference point's true match by about the quadratic part's mean over
  // the window (see lsm_align).
  bool quadratic = false;
  int max_iterations = 30;
  // Converged when the point moves by less than this in an iteration (and the window's corners too).
  double converged_px = 0.01;
  // Refused if the point moved farther than this from where it started (a different texture
  // was found), if the window's zoom sqrt|det A| left [1/max_zoom, max_zoom] relative to the
  // start, or if the aligned windows correlate below min_correlation.
  double max_shift_px = 3;
  double max_zoom = 2;
  double min_correlation = 0.9;
};

struct LsmResult {
  Eigen::Vector2d point_px;   // refined search point (OpenCV pixel convention)
  Eigen::Matrix2d affine;     // A: window offsets in the reference -> in the search image
  double correlation = 0;     // normalised cross-correlation of the aligned windows
  int iterations = 0;
};

// Why an alignment was refused (for the summary).
enum class LsmFailure { None, Border, Singular, NotConverged, Shift, Zoom, Correlation };
const char* to_string(LsmFailure f);

// Aligns the search image `g` to the reference image `f` around `ref_px`, starting from the
// affine map A0 and search point t0. Both images single-channel CV_32F. Returns nullopt (and
// sets *why) when refused. `half_window_px` as chosen by half_window_for().
std::optional<LsmResult> lsm_align(const cv::Mat& f, const Eigen::Vector2d& ref_px, int half_window_px,
                                   const cv::Mat& g, const Eigen::Matrix2d& A0, const Eigen::Vector2d& t0,
                                   const LsmOptions& o, LsmFailure* why = nullptr);

int half_window_for(double ref_size_px, const LsmOptions& o);

// Cubic-convolution sample of a single-channel CV_32F image at (x, y), OpenCV convention (pixel
// centres at integers), with its gradient (Keys' kernel, a = -0.5, and its derivative: bilinear
// samples would lock matches towards whole pixels); false if the 4x4 neighbourhood leaves the image.
inline bool sample_cubic(const cv::Mat& im, double x, double y, double& v, double& gx, double& gy);

// Pearson correlation of two equally long sample vectors,
//   r = sum (a_k - mean a)(b_k - mean b) / sqrt(sum (a_k - mean a)^2 * sum (b_k - mean b)^2),
// 0 if either is flat (no variance).
double correlation_of(std::span<const double> a, std::span<const double> b);

// Normalised cross-correlation of the reference window and the search window mapped by (A, t);
// nullopt where a sample falls outside an image. Used to pick the start among candidates, on
// every `stride`-th pixel of the window (2: a quarter of the work, enough to rank them).
std::optional<double> window_correlation(const cv::Mat& f, const Eigen::Vector2d& ref_px, int half_window_px,
                                         const cv::Mat& g, const Eigen::Matrix2d& A, const Eigen::Vector2d& t,
                                         int stride = 1);

// Keys' cubic convolution kernel (a = -0.5; Keys 1981, eq. 15) and its derivative at the four
// taps -1, 0, 1, 2 from floor(x), t = x - floor(x) in [0, 1): the distances 1 + t and 2 - t lie in
// [1, 2], where the kernel is a x^3 - 5a x^2 + 8a x - 4a, and t and 1 - t in [0, 1], where it is
// (a + 2) x^3 - (a + 3) x^2 + 1 (at 1 both pieces give 0 and slope a). Bilinear interpolation
// would bias the match towards whole pixels ("pixel locking", up to ~0.06 px on a speckle texture
// in lsm_test); the cubic kernel reproduces quadratics and leaves a few thousandths. Inline, as
// least-squares matching samples hundreds of millions of times.
namespace detail {
inline void keys_weights(double t, double w[4], double dw[4]) {
  constexpr double a = -0.5;
  auto outer = [](double x, double& wk, double& dwk) {  // 1 <= x <= 2
    wk = ((a * x - 5 * a) * x + 8 * a) * x - 4 * a;
    dwk = (3 * a * x - 10 * a) * x + 8 * a;
  };
  auto inner = [](double x, double& wk, double& dwk) {  // 0 <= x <= 1
    wk = ((a + 2) * x - (a + 3)) * x * x + 1;
    dwk = (3 * (a + 2) * x - 2 * (a + 3)) * x;
  };
  // d/dt of the distance is +1 for the two taps left of x, -1 for the two right of it.
  outer(1 + t, w[0], dw[0]);
  inner(t, w[1], dw[1]);
  inner(1 - t, w[2], dw[2]);
  dw[2] = -dw[2];
  outer(2 - t, w[3], dw[3]);
  dw[3] = -dw[3];
}
}  // namespace detail

inline bool sample_cubic(const cv::Mat& im, double x, double y, double& v, double& gx, double& gy) {
  if (!(x >= 1 && y >= 1 && x < im.cols - 2 && y < im.rows - 2)) return false;
  const int x0 = static_cast<int>(x);  // floor, x and y being positive
  const int y0 = static_cast<int>(y);
  double wx[4], dwx[4], wy[4], dwy[4];
  detail::keys_weights(x - x0, wx, dwx);
  detail::keys_weights(y - y0, wy, dwy);
  v = gx = gy = 0;
  for (int j = 0; j < 4; ++j) {
    const float* row = im.ptr<float>(y0 - 1 + j) + (x0 - 1);
    double r = 0, dr = 0;
    for (int i = 0; i < 4; ++i) {
      r += wx[i] * row[i];
      dr += dwx[i] * row[i];
    }
    v += wy[j] * r;
    gx += wy[j] * dr;
    gy += dwy[j] * r;
  }
  return true;
}

}  // namespace photomill::match
