// Axes, scale bars and colour bars for photomill's pictures (see plot.hpp).
#include "formats/plot.hpp"

#include <algorithm>
#include <cmath>
#include <locale>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace photomill::plot {
namespace {

const int kFont = cv::FONT_HERSHEY_SIMPLEX;

double decade(double x) { return std::pow(10.0, std::floor(std::log10(x))); }

}  // namespace

double nice_ceil(double x) {
  if (!(x > 0) || !std::isfinite(x)) return 1;
  const double p = decade(x);
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (m * p >= x * (1 - 1e-12)) return m * p;
  }
  return 10 * p;
}

double nice_floor(double x) {
  if (!(x > 0) || !std::isfinite(x)) return 1;
  const double p = decade(x);
  for (double m : {10.0, 5.0, 2.5, 2.0, 1.0}) {
    if (m * p <= x * (1 + 1e-12)) return m * p;
  }
  return p;
}

std::string number(double value, int digits) {
  if (value == 0) value = 0;  // no "-0"
  std::ostringstream s;
  s.imbue(std::locale::classic());
  s.precision(std::max(1, digits));
  s << value;
  return s.str();
}

std::vector<double> ticks(double lo, double hi, int target) {
  std::vector<double> out;
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo)) {
    if (std::isfinite(lo)) out.push_back(lo);
    return out;
  }
  // Steps of 1, 2 or 5 x 10^k (2.5 would give ticks like 7.5 that read worse).
  double step = nice_ceil((hi - lo) / std::max(1, target));
  if (std::abs(step / decade(step) - 2.5) < 1e-9) step *= 2;
  const double first = std::ceil(lo / step - 1e-9), last = std::floor(hi / step + 1e-9);
  for (double k = first; k <= last && out.size() < 100; k += 1) {
    const double v = k * step;
    out.push_back(std::abs(v) < step * 1e-9 ? 0.0 : v);
  }
  return out;
}

void text(cv::Mat& img, const std::string& s, cv::Point org, double size, const cv::Scalar& colour) {
  cv::putText(img, s, org, kFont, size, colour, 1, cv::LINE_AA);
}

cv::Size text_size(const std::string& s, double size) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, size, 1, &baseline);
}

cv::Point2d Axes::px(double x, double y) const {
  const double fx = (x - x0) / (x1 - x0), fy = (y - y0) / (y1 - y0);
  return {plot.x + fx * plot.width, y_up ? plot.y + plot.height - fy * plot.height : plot.y + fy * plot.height};
}

void draw_axes(cv::Mat& img, const Axes& a, bool grid) {
  const int left = a.plot.x, right = a.plot.x + a.plot.width, top = a.plot.y, bottom = a.plot.y + a.plot.height;
  const double size = 0.42;
  for (double v : ticks(std::min(a.x0, a.x1), std::max(a.x0, a.x1), std::max(2, a.plot.width / 110))) {
    const int x = cvRound(a.px(v, a.y0).x);
    if (grid) cv::line(img, {x, top}, {x, bottom}, kGrid, 1);
    cv::line(img, {x, bottom}, {x, bottom + 5}, kInk, 1);
    const std::string s = number(v);
    text(img, s, {x - text_size(s, size).width / 2, bottom + 19}, size);
  }
  for (double v : ticks(std::min(a.y0, a.y1), std::max(a.y0, a.y1), std::max(2, a.plot.height / 70))) {
    const int y = cvRound(a.px(a.x0, v).y);
    if (grid) cv::line(img, {left, y}, {right, y}, kGrid, 1);
    cv::line(img, {left - 5, y}, {left, y}, kInk, 1);
    const std::string s = number(v);
    text(img, s, {left - 8 - text_size(s, size).width, y + 5}, size);
  }
  cv::rectangle(img, cv::Point(left, top), cv::Point(right, bottom), kInk, 1);
  if (!a.x_label.empty()) text(img, a.x_label, {right - text_size(a.x_label, 0.45).width, bottom + 36}, 0.45);
  if (!a.y_label.empty()) text(img, a.y_label, {std::max(2, left - kAxisLeftPx + 4), top - 8}, 0.45);
}

void draw_scale_bar(cv::Mat& img, cv::Point right_end, double px_per_unit, int max_px, const std::string& unit) {
  if (!(px_per_unit > 0) || max_px < 2) return;
  const double length = nice_floor(max_px / px_per_unit);
  const int bar = std::max(1, cvRound(length * px_per_unit));
  const cv::Point b0 = right_end - cv::Point(bar, 0);
  cv::line(img, b0, right_end, kInk, 2);
  cv::line(img, b0 - cv::Point(0, 5), b0 + cv::Point(0, 5), kInk, 1);
  cv::line(img, right_end - cv::Point(0, 5), right_end + cv::Point(0, 5), kInk, 1);
  text(img, number(length) + " " + unit, {b0.x, b0.y - 9}, 0.45);
}

cv::Scalar viridis(double t) {
  // Viridis at 9 stops (matplotlib's table, every 32nd entry and the last), RGB, interpolated.
  static const double stops[9][3] = {{68, 1, 84},    {71, 44, 122},  {59, 81, 139},   {44, 113, 142}, {33, 144, 141},
                                     {39, 173, 129}, {92, 200, 99},  {170, 220, 50},  {253, 231, 37}};
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
  const double f = t * 8;
  const int i = std::min(7, static_cast<int>(f));
  const double w = f - i;
  double rgb[3];
  for (int c = 0; c < 3; ++c) rgb[c] = (1 - w) * stops[i][c] + w * stops[i + 1][c];
  return {rgb[2], rgb[1], rgb[0]};
}

void draw_colour_bar(cv::Mat& img, const ColourBar& b) {
  const double span = b.hi > b.lo ? b.hi - b.lo : 1.0;
  const auto colour = [&](double v) { return b.colour ? b.colour(v) : viridis((v - b.lo) / span); };
  const int top = b.bar.y, bottom = b.bar.y + b.bar.height;
  for (int y = top; y <= bottom; ++y) {
    const double v = b.lo + span * (bottom - y) / std::max(1, bottom - top);
    cv::line(img, {b.bar.x, y}, {b.bar.x + b.bar.width, y}, colour(v), 1);
  }
  cv::rectangle(img, cv::Point(b.bar.x, top), cv::Point(b.bar.x + b.bar.width, bottom), kInk, 1);
  const auto label = [&](double v, const std::string& prefix) {
    const int y = cvRound(bottom - (v - b.lo) / span * (bottom - top));
    cv::line(img, {b.bar.x + b.bar.width, y}, {b.bar.x + b.bar.width + 5, y}, kInk, 1);
    text(img, prefix + number(v), {b.bar.x + b.bar.width + 8, y + 5}, 0.42);
  };
  // The ends, and the round values between them that keep clear of the ends' numbers.
  label(b.lo, b.below ? "<=" : "");
  label(b.hi, b.above ? ">=" : "");
  const double clear = 16.0 / std::max(1, bottom - top) * span;
  for (double v : ticks(b.lo, b.hi, std::max(2, b.bar.height / 60))) {
    if (v - b.lo > clear && b.hi - v > clear) label(v, "");
  }
  text(img, b.title, {b.bar.x - 4, top - 26}, 0.45);
  text(img, b.unit, {b.bar.x - 4, top - 8}, 0.45);
}

}  // namespace photomill::plot
