// SIFT's scale space built once (contract and conventions in sift_scale_space.hpp).
#include "detect/sift_scale_space.hpp"

#include <algorithm>
#include <array>
#include <cfloat>
#include <climits>
#include <cmath>

#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace photomill::detect {
namespace {

constexpr int kBorder = 5;              // no extremum this near an octave's edge
constexpr int kMaxMoves = 5;            // moves of the quadratic refinement
constexpr int kOrientationBins = 36;
constexpr float kOrientationSigma = 1.5f;  // the orientation window's sigma, in the keypoint's sigma
constexpr float kOrientationRadius = 3 * kOrientationSigma;
constexpr float kOrientationPeak = 0.8f;
constexpr int kCells = 4;               // descriptor cells per side
constexpr int kCellBins = 8;            // orientations per cell
constexpr float kCellWidth = 3;         // a cell's width in the keypoint's sigma
constexpr float kClip = 0.2f;           // each entry clipped at this share of the norm
constexpr float kByteScale = 512;

// Per-sample buffers of a window, reused from one keypoint to the next: the gradient (dx, dy),
// the Gaussian weight's exponent w, the descriptor's cell coordinates (rbins, cbins).
struct Scratch {
  std::vector<float> dx, dy, w, angle, mag, rbins, cbins;
  void resize(int len) {
    for (auto* v : {&dx, &dy, &w, &angle, &mag, &rbins, &cbins}) {
      if (v->size() < static_cast<std::size_t>(len)) v->resize(static_cast<std::size_t>(len));
    }
  }
  // For the first k samples: the gradient's angle (degrees, OpenCV's fast atan2) and magnitude,
  // and the weight exp(w).
  void polar(int k) {
    cv::hal::exp32f(w.data(), w.data(), k);
    cv::hal::fastAtan2(dy.data(), dx.data(), angle.data(), k, true);
    cv::hal::magnitude32f(dx.data(), dy.data(), mag.data(), k);
  }
};

// The orientation histogram of the gradients around `pt` in `img` (Lowe section 5): the
// gradients (central differences) within `radius`, weighted by their magnitude and a Gaussian of
// `sigma`, in kOrientationBins bins, then smoothed circularly by (1 4 6 4 1) / 16. Returns the
// highest bin.
float orientation_histogram(const cv::Mat& img, cv::Point pt, int radius, float sigma,
                            std::array<float, kOrientationBins>& hist, Scratch& s) {
  constexpr int bins = kOrientationBins;
  const int len = (2 * radius + 1) * (2 * radius + 1);
  const float weight_scale = -1.f / (2.f * sigma * sigma);
  s.resize(len);
  int k = 0;
  for (int i = -radius; i <= radius; ++i) {
    const int y = pt.y + i;
    if (y <= 0 || y >= img.rows - 1) continue;
    const float* row = img.ptr<float>(y);
    const float* up = img.ptr<float>(y - 1);
    const float* down = img.ptr<float>(y + 1);
    for (int j = -radius; j <= radius; ++j) {
      const int x = pt.x + j;
      if (x <= 0 || x >= img.cols - 1) continue;
      s.dx[k] = row[x + 1] - row[x - 1];
      s.dy[k] = up[x] - down[x];
      s.w[k] = static_cast<float>(i * i + j * j) * weight_scale;
      ++k;
    }
  }
  s.polar(k);
  std::array<float, kOrientationBins + 4> raw{};
  float* h = raw.data() + 2;
  for (int q = 0; q < k; ++q) {
    int bin = cvRound((static_cast<float>(bins) / 360.f) * s.angle[q]);
    if (bin >= bins) bin -= bins;
    if (bin < 0) bin += bins;
    h[bin] += s.w[q] * s.mag[q];
  }
  h[-1] = h[bins - 1];
  h[-2] = h[bins - 2];
  h[bins] = h[0];
  h[bins + 1] = h[1];
  for (int i = 0; i < bins; ++i) {
    hist[i] = (h[i - 2] + h[i + 2]) * (1.f / 16.f) + (h[i - 1] + h[i + 1]) * (4.f / 16.f) + h[i] * (6.f / 16.f);
  }
  return *std::max_element(hist.begin(), hist.end());
}

// Layer i of an octave's difference of Gaussians, G_(i+1) - G_i, evaluated where it is read (the
// same float difference cv::subtract would store): the DoG pyramid, as large as the Gaussian
// one, is never built, which halves what a photo's scale space moves through memory.
struct DogLayer {
  const cv::Mat& lower;
  const cv::Mat& upper;
  float at(int r, int c) const { return upper.at<float>(r, c) - lower.at<float>(r, c); }
  int rows() const { return lower.rows; }
  int cols() const { return lower.cols; }
};

DogLayer dog_layer(const std::vector<cv::Mat>& gauss, int layers, int octave, int layer) {
  const std::size_t i = static_cast<std::size_t>(octave * (layers + 3) + layer);
  return {gauss[i], gauss[i + 1]};
}

// Refines an extremum of the DoG at (r, c) of `layer` in octave `octave` (Lowe section 4,
// Brown & Lowe 2002): the offset x = -H^-1 grad D of the quadratic through the 3 x 3 x 3
// neighbourhood, moving to the neighbouring sample while an offset exceeds 0.5; then the contrast
// test on D(x) = D + grad D . x / 2 and the edge test on the 2 x 2 Hessian (section 4.1).
// Derivatives on grey values scaled to [0, 1], as OpenCV's.
// The DoG's value at (r, c) of `layer` and its first and second derivatives by central
// differences (x along columns, y along rows, s across layers), on grey values scaled to [0, 1].
struct Derivatives {
  float value;
  cv::Vec3f gradient;  // d/dx, d/dy, d/ds
  float dxx, dyy, dss, dxy, dxs, dys;
};

Derivatives derivatives(const std::vector<cv::Mat>& gauss, int layers, int octave, int layer, int r, int c) {
  constexpr float img_scale = 1.f / 255.f;
  constexpr float deriv_scale = img_scale * 0.5f;
  constexpr float second_deriv_scale = img_scale;
  constexpr float cross_deriv_scale = img_scale * 0.25f;
  const DogLayer img = dog_layer(gauss, layers, octave, layer);
  const DogLayer prev = dog_layer(gauss, layers, octave, layer - 1);
  const DogLayer next = dog_layer(gauss, layers, octave, layer + 1);
  Derivatives d;
  d.value = img.at(r, c);
  d.gradient = cv::Vec3f((img.at(r, c + 1) - img.at(r, c - 1)) * deriv_scale,
                         (img.at(r + 1, c) - img.at(r - 1, c)) * deriv_scale,
                         (next.at(r, c) - prev.at(r, c)) * deriv_scale);
  const float v2 = d.value * 2;
  d.dxx = (img.at(r, c + 1) + img.at(r, c - 1) - v2) * second_deriv_scale;
  d.dyy = (img.at(r + 1, c) + img.at(r - 1, c) - v2) * second_deriv_scale;
  d.dss = (next.at(r, c) + prev.at(r, c) - v2) * second_deriv_scale;
  d.dxy = (img.at(r + 1, c + 1) - img.at(r + 1, c - 1) - img.at(r - 1, c + 1) + img.at(r - 1, c - 1)) *
          cross_deriv_scale;
  d.dxs = (next.at(r, c + 1) - next.at(r, c - 1) - prev.at(r, c + 1) + prev.at(r, c - 1)) * cross_deriv_scale;
  d.dys = (next.at(r + 1, c) - next.at(r - 1, c) - prev.at(r + 1, c) + prev.at(r - 1, c)) * cross_deriv_scale;
  return d;
}

bool refine_extremum(const std::vector<cv::Mat>& gauss, int octave, int& layer, int& r, int& c, int layers,
                     float contrast_threshold, float edge_threshold, float sigma, cv::KeyPoint& kpt) {
  const cv::Mat& octave_base = gauss[static_cast<std::size_t>(octave * (layers + 3))];
  float xi = 0, xr = 0, xc = 0;
  int move = 0;
  for (; move < kMaxMoves; ++move) {
    const Derivatives d = derivatives(gauss, layers, octave, layer, r, c);
    const cv::Matx33f H(d.dxx, d.dxy, d.dxs, d.dxy, d.dyy, d.dys, d.dxs, d.dys, d.dss);
    const cv::Vec3f X = H.solve(d.gradient, cv::DECOMP_LU);
    xi = -X[2];
    xr = -X[1];
    xc = -X[0];
    if (std::abs(xi) < 0.5f && std::abs(xr) < 0.5f && std::abs(xc) < 0.5f) break;
    constexpr float far = static_cast<float>(INT_MAX / 3);
    if (std::abs(xi) > far || std::abs(xr) > far || std::abs(xc) > far) return false;
    c += cvRound(xc);
    r += cvRound(xr);
    layer += cvRound(xi);
    if (layer < 1 || layer > layers || c < kBorder || c >= octave_base.cols - kBorder || r < kBorder ||
        r >= octave_base.rows - kBorder) {
      return false;
    }
  }
  if (move >= kMaxMoves) return false;
  const Derivatives d = derivatives(gauss, layers, octave, layer, r, c);
  const float t = cv::Matx31f(d.gradient).dot(cv::Matx31f(xc, xr, xi));
  const float contrast = d.value * (1.f / 255.f) + t * 0.5f;
  if (std::abs(contrast) * static_cast<float>(layers) < contrast_threshold) return false;
  const float tr = d.dxx + d.dyy;
  const float det = d.dxx * d.dyy - d.dxy * d.dxy;
  if (det <= 0 || tr * tr * edge_threshold >= (edge_threshold + 1) * (edge_threshold + 1) * det) return false;
  kpt.pt.x = (static_cast<float>(c) + xc) * static_cast<float>(1 << octave);
  kpt.pt.y = (static_cast<float>(r) + xr) * static_cast<float>(1 << octave);
  kpt.octave = octave + (layer << 8) + (cvRound((xi + 0.5) * 255) << 16);
  kpt.size = sigma * std::pow(2.f, (static_cast<float>(layer) + xi) / static_cast<float>(layers)) *
             static_cast<float>(1 << octave) * 2;
  kpt.response = std::abs(contrast);
  return true;
}

// Whether v at column c of the DoG row `curr[1]` is >= (v > 0) or <= (v < 0) all its 26
// neighbours: in the rows above, at and below it (k = 0, 1, 2) of its own layer (`curr`, the
// differences already taken) and of the layers below and above it (upper[k] - lower[k] of their
// Gaussian rows).
bool is_extremum(float v, int c, const float* const* curr, const float* const* prev_lower, const float* const* prev_upper,
                 const float* const* next_lower, const float* const* next_upper) {
  const bool high = v > 0;
  auto beyond = [&](float n) { return high ? !(v >= n) : !(v <= n); };
  for (int k = 0; k < 3; ++k) {
    if (beyond(curr[k][c - 1]) || beyond(curr[k][c]) || beyond(curr[k][c + 1])) return false;
  }
  for (const auto& [lower, upper] : {std::pair{prev_lower, prev_upper}, std::pair{next_lower, next_upper}}) {
    for (int k = 0; k < 3; ++k) {
      for (int x = c - 1; x <= c + 1; ++x) {
        if (beyond(upper[k][x] - lower[k][x])) return false;
      }
    }
  }
  return true;
}

// Lowe's descriptor (section 6) of a keypoint at `ptf` (the octave's pixels) with orientation
// `ori` (degrees, OpenCV's sense) and sigma `scl` in the Gaussian layer `img`, into 128 floats,
// then clipped, renormalised and scaled to bytes in `out`.
void describe(const cv::Mat& img, cv::Point2f ptf, float ori, float scl, std::uint8_t* out, Scratch& s) {
  constexpr int d = kCells, n = kCellBins;
  const cv::Point pt(cvRound(ptf.x), cvRound(ptf.y));
  float cos_t = std::cos(ori * static_cast<float>(CV_PI / 180));
  float sin_t = std::sin(ori * static_cast<float>(CV_PI / 180));
  const float bins_per_rad = static_cast<float>(n) / 360.f;
  const float exp_scale = -1.f / (d * d * 0.5f);
  const float hist_width = kCellWidth * scl;
  int radius = cvRound(hist_width * 1.4142135623730951f * (d + 1) * 0.5f);
  radius = std::min(radius, static_cast<int>(std::sqrt(static_cast<double>(img.cols) * img.cols +
                                                       static_cast<double>(img.rows) * img.rows)));
  cos_t /= hist_width;
  sin_t /= hist_width;
  const int len = (2 * radius + 1) * (2 * radius + 1);
  s.resize(len);
  std::array<float, (d + 2) * (d + 2) * (n + 2)> hist{};
  // A sample counts if its cell coordinates fall in (-1, d) (it votes into a cell of the
  // descriptor): |rotated offset| < (d + 1) / 2 on both axes. Each is linear in j along a row,
  // so the columns to test are narrowed to that band first (one column wider on each side; the
  // test itself decides).
  const float half = (d + 1) * 0.5f;
  auto narrow = [half](float slope, float offset, int& lo, int& hi) {  // slope * j + offset in (-half, half)
    if (std::abs(slope) < 1e-6f) {
      if (!(std::abs(offset) < half + 1e-3f)) hi = lo - 1;
      return;
    }
    float a = (-half - offset) / slope, b = (half - offset) / slope;
    if (a > b) std::swap(a, b);
    lo = std::max(lo, static_cast<int>(std::floor(a)) - 1);
    hi = std::min(hi, static_cast<int>(std::ceil(b)) + 1);
  };
  int k = 0;
  for (int i = std::max(-radius, 1 - pt.y); i <= std::min(radius, img.rows - 2 - pt.y); ++i) {
    int lo = std::max(-radius, 1 - pt.x), hi = std::min(radius, img.cols - 2 - pt.x);
    narrow(sin_t, static_cast<float>(i) * cos_t, lo, hi);
    narrow(cos_t, -static_cast<float>(i) * sin_t, lo, hi);
    const int r = pt.y + i;
    const float* row = img.ptr<float>(r);
    const float* up = img.ptr<float>(r - 1);
    const float* down = img.ptr<float>(r + 1);
    for (int j = lo; j <= hi; ++j) {
      // The sample's cell coordinates, rotated to the keypoint's orientation; the 0.5 puts a
      // sample at a cell's centre wholly into that cell.
      const float c_rot = static_cast<float>(j) * cos_t - static_cast<float>(i) * sin_t;
      const float r_rot = static_cast<float>(j) * sin_t + static_cast<float>(i) * cos_t;
      const float rbin = r_rot + d / 2 - 0.5f;
      const float cbin = c_rot + d / 2 - 0.5f;
      const int c = pt.x + j;
      if (rbin > -1 && rbin < d && cbin > -1 && cbin < d) {
        s.dx[k] = row[c + 1] - row[c - 1];
        s.dy[k] = up[c] - down[c];
        s.rbins[k] = rbin;
        s.cbins[k] = cbin;
        s.w[k] = (c_rot * c_rot + r_rot * r_rot) * exp_scale;
        ++k;
      }
    }
  }
  s.polar(k);
  for (int q = 0; q < k; ++q) {
    float rbin = s.rbins[q], cbin = s.cbins[q];
    float obin = (s.angle[q] - ori) * bins_per_rad;
    const float m = s.mag[q] * s.w[q];
    const int r0 = cvFloor(rbin);
    const int c0 = cvFloor(cbin);
    int o0 = cvFloor(obin);
    rbin -= static_cast<float>(r0);
    cbin -= static_cast<float>(c0);
    obin -= static_cast<float>(o0);
    if (o0 < 0) o0 += n;
    if (o0 >= n) o0 -= n;
    // Trilinear votes into the two rows, columns and orientations about the sample.
    const float v_r1 = m * rbin, v_r0 = m - v_r1;
    const float v_rc11 = v_r1 * cbin, v_rc10 = v_r1 - v_rc11;
    const float v_rc01 = v_r0 * cbin, v_rc00 = v_r0 - v_rc01;
    const float v_rco111 = v_rc11 * obin, v_rco110 = v_rc11 - v_rco111;
    const float v_rco101 = v_rc10 * obin, v_rco100 = v_rc10 - v_rco101;
    const float v_rco011 = v_rc01 * obin, v_rco010 = v_rc01 - v_rco011;
    const float v_rco001 = v_rc00 * obin, v_rco000 = v_rc00 - v_rco001;
    const int idx = ((r0 + 1) * (d + 2) + c0 + 1) * (n + 2) + o0;
    hist[idx] += v_rco000;
    hist[idx + 1] += v_rco001;
    hist[idx + (n + 2)] += v_rco010;
    hist[idx + (n + 3)] += v_rco011;
    hist[idx + (d + 2) * (n + 2)] += v_rco100;
    hist[idx + (d + 2) * (n + 2) + 1] += v_rco101;
    hist[idx + (d + 3) * (n + 2)] += v_rco110;
    hist[idx + (d + 3) * (n + 2) + 1] += v_rco111;
  }
  std::array<float, d * d * n> raw{};
  for (int i = 0; i < d; ++i) {
    for (int j = 0; j < d; ++j) {
      const int idx = ((i + 1) * (d + 2) + (j + 1)) * (n + 2);
      hist[idx] += hist[idx + n];  // the orientation bins are circular
      hist[idx + 1] += hist[idx + n + 1];
      for (int q = 0; q < n; ++q) raw[(i * d + j) * n + q] = hist[idx + q];
    }
  }
  float norm2 = 0;
  for (float v : raw) norm2 += v * v;
  const float threshold = std::sqrt(norm2) * kClip;
  norm2 = 0;
  for (float& v : raw) {
    v = std::min(v, threshold);
    norm2 += v * v;
  }
  const float scale = kByteScale / std::max(std::sqrt(norm2), FLT_EPSILON);
  for (int q = 0; q < d * d * n; ++q) out[q] = cv::saturate_cast<std::uint8_t>(raw[q] * scale);
}

}  // namespace

SiftScaleSpace::SiftScaleSpace(const cv::Mat& grey, int octave_layers, double sigma)
    : layers_(octave_layers), sigma_(sigma) {
  CV_Assert(grey.type() == CV_8UC1 && !grey.empty());
  // The first octave: the photo doubled (bilinear), its blur taken from 2 x 0.5 px to sigma.
  cv::Mat grey_f, doubled, base;
  grey.convertTo(grey_f, CV_32F);
  cv::resize(grey_f, doubled, cv::Size(grey.cols * 2, grey.rows * 2), 0, 0, cv::INTER_LINEAR);
  grey_f.release();
  const float sigma_f = static_cast<float>(sigma);
  const float base_sigma = std::sqrt(std::max(sigma_f * sigma_f - 0.5f * 0.5f * 4, 0.01f));
  cv::GaussianBlur(doubled, base, cv::Size(), base_sigma, base_sigma);
  doubled.release();
  octaves_ = cvRound(std::log(static_cast<double>(std::min(base.cols, base.rows))) / std::log(2.) - 2) + 1;
  // Layer i of an octave has blur sigma k^i (k = 2^(1/s)); each is blurred from the one before
  // by the difference, sqrt((k^i sigma)^2 - (k^(i-1) sigma)^2).
  const int per = layers_ + 3;
  std::vector<double> blur(static_cast<std::size_t>(per));
  blur[0] = sigma;
  const double k = std::pow(2., 1. / layers_);
  for (int i = 1; i < per; ++i) {
    const double before = std::pow(k, static_cast<double>(i - 1)) * sigma;
    const double total = before * k;
    blur[static_cast<std::size_t>(i)] = std::sqrt(total * total - before * before);
  }
  gauss_.resize(static_cast<std::size_t>(octaves_ * per));
  for (int o = 0; o < octaves_; ++o) {
    for (int i = 0; i < per; ++i) {
      cv::Mat& dst = gauss_[static_cast<std::size_t>(o * per + i)];
      if (o == 0 && i == 0) {
        dst = base;
      } else if (i == 0) {
        // An octave starts from the previous one's layer s (blur 2 sigma) at every other pixel.
        const cv::Mat& src = gauss_[static_cast<std::size_t>((o - 1) * per + layers_)];
        cv::resize(src, dst, cv::Size(src.cols / 2, src.rows / 2), 0, 0, cv::INTER_NEAREST);
      } else {
        const double b = blur[static_cast<std::size_t>(i)];
        cv::GaussianBlur(gauss_[static_cast<std::size_t>(o * per + i - 1)], dst, cv::Size(), b, b);
      }
    }
  }
}

std::vector<cv::KeyPoint> SiftScaleSpace::keypoints(double contrast_threshold, double edge_threshold,
                                                    const cv::Mat& mask) const {
  const int per = layers_ + 3;
  // The first test of a sample, OpenCV's: |D| above half the contrast threshold in grey levels
  // (0 with the default 0.01 and 3 layers: the refined contrast test decides).
  const float threshold = static_cast<float>(cvFloor(0.5 * contrast_threshold / layers_ * 255));
  // The samples of each layer's band of rows, one task per band (kBandRows rows; on all cores
  // with OpenCV's parallel_for_), each task's keypoints in its own list, joined in task order.
  constexpr int kBandRows = 128;
  struct Band {
    int octave, layer, first_row, end_row;
  };
  std::vector<Band> bands;
  for (int o = 0; o < octaves_; ++o) {
    const int rows = gauss_[static_cast<std::size_t>(o * per)].rows;
    for (int i = 1; i <= layers_; ++i) {
      for (int r = kBorder; r < rows - kBorder; r += kBandRows) bands.push_back({o, i, r, std::min(r + kBandRows, rows - kBorder)});
    }
  }
  std::vector<std::vector<cv::KeyPoint>> found(bands.size());
  cv::parallel_for_(cv::Range(0, static_cast<int>(bands.size())), [&](const cv::Range& range) {
    std::array<float, kOrientationBins> hist;
    std::vector<std::uint8_t> candidate;
    Scratch scratch;
    for (int b = range.start; b < range.end; ++b) {
      const auto [o, i, r_begin, r_end] = bands[static_cast<std::size_t>(b)];
      std::vector<cv::KeyPoint>& out = found[static_cast<std::size_t>(b)];
      const cv::Mat* g[4];  // the Gaussian layers i - 1 .. i + 2 under DoG layers i - 1, i, i + 1
      for (int q = 0; q < 4; ++q) g[q] = &gauss_[static_cast<std::size_t>(o * per + i - 1 + q)];
      const int cols = g[0]->cols;
      // The DoG rows r - 1, r, r + 1 of layer i, rolled down the band.
      std::array<std::vector<float>, 3> buffer;
      auto difference_row = [&](int r, std::vector<float>& out) {
        out.resize(static_cast<std::size_t>(cols));
        const float* lo = g[1]->ptr<float>(r);
        const float* up = g[2]->ptr<float>(r);
        for (int c = 0; c < cols; ++c) out[static_cast<std::size_t>(c)] = up[c] - lo[c];
      };
      difference_row(r_begin - 1, buffer[0]);
      difference_row(r_begin, buffer[1]);
      candidate.assign(static_cast<std::size_t>(cols), 0);
      for (int r = r_begin; r < r_end; ++r) {
        difference_row(r + 1, buffer[static_cast<std::size_t>((r - r_begin + 2) % 3)]);
        const float* cr[3] = {buffer[static_cast<std::size_t>((r - r_begin) % 3)].data(),
                              buffer[static_cast<std::size_t>((r - r_begin + 1) % 3)].data(),
                              buffer[static_cast<std::size_t>((r - r_begin + 2) % 3)].data()};
        auto rows_of = [r](const cv::Mat* m) {
          return std::array<const float*, 3>{m->ptr<float>(r - 1), m->ptr<float>(r), m->ptr<float>(r + 1)};
        };
        const auto g0 = rows_of(g[0]), g1 = rows_of(g[1]), g2 = rows_of(g[2]), g3 = rows_of(g[3]);
        // A branch-free first pass over the row (the compiler vectorises it): above the threshold
        // and an extremum against the four neighbours in the layer; most samples stop here.
        const float* row = cr[1];
        const float* up = cr[0];
        const float* down = cr[2];
        for (int c = kBorder; c < cols - kBorder; ++c) {
          const float v = row[c];
          const bool high = (v > 0) & (v >= row[c - 1]) & (v >= row[c + 1]) & (v >= up[c]) & (v >= down[c]);
          const bool low = (v < 0) & (v <= row[c - 1]) & (v <= row[c + 1]) & (v <= up[c]) & (v <= down[c]);
          candidate[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>((std::abs(v) > threshold) & (high | low));
        }
        for (int c = kBorder; c < cols - kBorder; ++c) {
          if (!candidate[static_cast<std::size_t>(c)]) continue;
          const float v = row[c];
          if (!is_extremum(v, c, cr, g0.data(), g1.data(), g2.data(), g3.data())) continue;
          int r1 = r, c1 = c, layer = i;
          cv::KeyPoint kpt;
          if (!refine_extremum(gauss_, o, layer, r1, c1, layers_, static_cast<float>(contrast_threshold),
                               static_cast<float>(edge_threshold), static_cast<float>(sigma_), kpt)) {
            continue;
          }
          const float scl_octave = kpt.size * 0.5f / static_cast<float>(1 << o);
          const float highest = orientation_histogram(gauss_[static_cast<std::size_t>(o * per + layer)],
                                                      cv::Point(c1, r1), cvRound(kOrientationRadius * scl_octave),
                                                      kOrientationSigma * scl_octave, hist, scratch);
          const float peak = highest * kOrientationPeak;
          constexpr int n = kOrientationBins;
          for (int j = 0; j < n; ++j) {
            const int left = j > 0 ? j - 1 : n - 1;
            const int right = j < n - 1 ? j + 1 : 0;
            if (hist[j] > hist[left] && hist[j] > hist[right] && hist[j] >= peak) {
              // The parabola through the peak and its neighbours.
              float bin = static_cast<float>(j) + 0.5f * (hist[left] - hist[right]) / (hist[left] - 2 * hist[j] + hist[right]);
              bin = bin < 0 ? n + bin : bin >= n ? bin - n : bin;
              kpt.angle = 360.f - (360.f / n) * bin;
              if (std::abs(kpt.angle - 360.f) < FLT_EPSILON) kpt.angle = 0.f;
              out.push_back(kpt);
            }
          }
        }
      }
    }
  });
  std::vector<cv::KeyPoint> out;
  for (auto& f : found) out.insert(out.end(), f.begin(), f.end());
  cv::KeyPointsFilter::removeDuplicatedSorted(out);
  // From the doubled first octave's pixels to the photo's (octave -1 for the first).
  for (cv::KeyPoint& kpt : out) {
    kpt.octave = (kpt.octave & ~255) | ((kpt.octave - 1) & 255);
    kpt.pt *= 0.5f;
    kpt.size *= 0.5f;
  }
  if (!mask.empty()) cv::KeyPointsFilter::runByPixelsMask(out, mask);
  return out;
}

cv::Mat SiftScaleSpace::descriptors(const std::vector<cv::KeyPoint>& keypoints) const {
  cv::Mat out(static_cast<int>(keypoints.size()), kCells * kCells * kCellBins, CV_8U);
  const int per = layers_ + 3;
  // The keypoint's octave (-1: the doubled one) and layer, as keypoints() packed them.
  auto level = [&](const cv::KeyPoint& kpt) {
    int octave = kpt.octave & 255;
    const int layer = (kpt.octave >> 8) & 255;
    octave = octave < 128 ? octave : (-128 | octave);
    CV_Assert(octave >= -1 && octave + 1 < octaves_ && layer <= layers_ + 2);
    return std::pair{octave, layer};
  };
  // Described layer by layer, from the top of each down: a window's rows are then mostly still
  // in the cache from the keypoints above it (in random order every window's ~70 rows of a
  // 16 KB-wide layer came from memory, most of the time spent here).
  std::vector<std::size_t> order(keypoints.size());
  std::vector<int> key(keypoints.size());
  for (std::size_t q = 0; q < keypoints.size(); ++q) {
    const auto [octave, layer] = level(keypoints[q]);
    key[q] = (octave + 1) * per + layer;
    order[q] = q;
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return key[a] != key[b] ? key[a] < key[b] : keypoints[a].pt.y < keypoints[b].pt.y;
  });
  // In contiguous runs of that order on all cores (OpenCV's parallel_for_).
  constexpr int kRun = 512;
  const int runs = static_cast<int>((order.size() + kRun - 1) / kRun);
  cv::parallel_for_(cv::Range(0, runs), [&](const cv::Range& range) {
    Scratch scratch;
    for (std::size_t n = static_cast<std::size_t>(range.start) * kRun;
         n < std::min(order.size(), static_cast<std::size_t>(range.end) * kRun); ++n) {
      const std::size_t q = order[n];
      const cv::KeyPoint& kpt = keypoints[q];
      const int octave = level(kpt).first;
      const float scale = octave >= 0 ? 1.f / static_cast<float>(1 << octave) : static_cast<float>(1 << -octave);
      const cv::Mat& img = gauss_[static_cast<std::size_t>(key[q])];
      float angle = 360.f - kpt.angle;
      if (std::abs(angle - 360.f) < FLT_EPSILON) angle = 0.f;
      describe(img, cv::Point2f(kpt.pt.x * scale, kpt.pt.y * scale), angle, kpt.size * scale * 0.5f,
               out.ptr<std::uint8_t>(static_cast<int>(q)), scratch);
    }
  });
  return out;
}

}  // namespace photomill::detect
