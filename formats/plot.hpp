// What every picture photomill draws shares (issue 27: calib.png, cloud.png, surface.png,
// path.png): axes with round ticks and their unit, a scale bar, a colour bar with its range and
// unit, and the one font, drawn with OpenCV on a BGR canvas. Numbers in labels are written in the
// C locale whatever the user's locale. Library code: nothing printed, nothing read back.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace photomill::plot {

inline const cv::Scalar kInk(40, 40, 40);   // text, frames, ticks (BGR)
inline const cv::Scalar kGrid(225, 225, 225);

// The smallest of 1, 2, 2.5 or 5 x 10^k at or above x (x > 0); 1 for x <= 0 or not finite.
double nice_ceil(double x);
// The largest of 1, 2, 2.5 or 5 x 10^k at or below x (x > 0); 1 for x <= 0 or not finite.
double nice_floor(double x);

// A label number: at most `digits` significant digits, C locale, no trailing zeros ("0.05",
// "-120", "1.5e+04"); -0 written 0.
std::string number(double value, int digits = 4);

// The multiples of a 1-2-5 step in [lo, hi], about `target` of them (at least 2 when hi > lo).
std::vector<double> ticks(double lo, double hi, int target = 6);

// Text in the pictures' font (OpenCV's Hershey simplex), `org` its baseline's left end.
void text(cv::Mat& img, const std::string& s, cv::Point org, double size = 0.45, const cv::Scalar& colour = kInk);
// Its width and height (above the baseline) in pixels.
cv::Size text_size(const std::string& s, double size = 0.45);

// A linear map from data units to the pixels of a plot rectangle: x grows to the right, y up
// (y_up) or down (image rows, y_up = false).
struct Axes {
  cv::Rect plot;                    // the plot area, image pixels
  double x0 = 0, x1 = 1;            // data at the plot's left and right edges
  double y0 = 0, y1 = 1;            // data at the plot's bottom and top (y_up), or top and bottom
  bool y_up = true;
  std::string x_label, y_label;     // the quantity and its unit: "x mm", "u px"
  cv::Point2d px(double x, double y) const;  // sub-pixel image coordinates of a data point
};

// The room draw_axes needs outside the plot rectangle for its tick numbers and labels.
inline constexpr int kAxisLeftPx = 64, kAxisBottomPx = 40, kAxisTopPx = 22;

// A frame around axes.plot, ticks with their numbers on the left and bottom edges (a light grid
// across the plot with `grid`), the x label under the right end of the x axis, the y label above
// the top of the y axis.
void draw_axes(cv::Mat& img, const Axes& axes, bool grid = false);

// A bar of a round length (nice_floor) at most max_px long, its right end at `right_end`,
// end ticks, labelled above with its length and unit ("50 mm").
void draw_scale_bar(cv::Mat& img, cv::Point right_end, double px_per_unit, int max_px, const std::string& unit);

// Viridis (perceptually uniform, readable in grey), t in [0, 1] clamped; BGR.
cv::Scalar viridis(double t);

// A vertical colour bar: `lo` at the bottom, `hi` at the top, ticks with numbers on its right,
// the title and unit above it; ">=" / "<=" on the end numbers when values lie beyond them.
struct ColourBar {
  cv::Rect bar;                                   // the bar itself, image pixels
  double lo = 0, hi = 1;
  std::string title, unit;                        // "tip z", "mm"
  std::function<cv::Scalar(double)> colour;       // value -> BGR; viridis over [lo, hi] when empty
  bool above = false, below = false;              // some values lie beyond hi / below lo
};
// The width a colour bar with its numbers needs: bar + ticks + the widest number.
inline constexpr int kColourBarAreaPx = 120;
void draw_colour_bar(cv::Mat& img, const ColourBar& bar);

}  // namespace photomill::plot
