// The pictures' shared marks (formats/plot): round ticks inside the range, C-locale numbers, axes
// drawn outside the plot area and not inside it, a colour bar that runs from its low to its high
// colour.
#include "formats/plot.hpp"

#include <algorithm>
#include <clocale>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace photomill::plot {
namespace {

TEST(Plot, TicksAreRoundAndInsideTheRange) {
  for (const auto& [lo, hi] : {std::pair{-85.3, 84.9}, std::pair{0.0, 1.0}, std::pair{1999.5, 2000.5}, std::pair{-0.062, 0.062},
                               std::pair{-0.5, 1999.5}}) {
    const auto t = ticks(lo, hi, 6);
    ASSERT_GE(t.size(), 2u) << lo << " " << hi;
    EXPECT_LE(t.size(), 13u) << lo << " " << hi;
    const double step = t[1] - t[0];
    const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
    EXPECT_TRUE(std::abs(mantissa - 1) < 1e-6 || std::abs(mantissa - 2) < 1e-6 || std::abs(mantissa - 5) < 1e-6) << step;
    for (double v : t) {
      EXPECT_GE(v, lo - 1e-9);
      EXPECT_LE(v, hi + 1e-9);
      EXPECT_NEAR(std::remainder(v, step), 0, 1e-9 * std::max(step, std::abs(v))) << v << " is not a multiple of " << step;
    }
  }
  EXPECT_EQ(ticks(3, 3).size(), 1u) << "an empty range gets its one value";
}

TEST(Plot, NumbersInTheCLocale) {
  EXPECT_EQ(number(0.05), "0.05");
  EXPECT_EQ(number(-120), "-120");
  EXPECT_EQ(number(-0.0), "0");
  EXPECT_EQ(number(0.0622473, 3), "0.0622");
  if (std::setlocale(LC_ALL, "de_DE.UTF-8")) {  // a decimal comma, where the system has it
    std::locale::global(std::locale("de_DE.UTF-8"));
    EXPECT_EQ(number(2.5), "2.5");
    std::locale::global(std::locale::classic());
    std::setlocale(LC_ALL, "C");
  }
  EXPECT_EQ(nice_floor(37), 25);
  EXPECT_EQ(nice_ceil(37), 50);
  EXPECT_EQ(nice_floor(-1), 1) << "no nonsense for a bad input";
}

int dark(const cv::Mat& img, cv::Rect r) {
  cv::Mat grey;
  cv::cvtColor(img(r), grey, cv::COLOR_BGR2GRAY);
  return cv::countNonZero(grey < 128);
}

TEST(Plot, AxesAreDrawnAroundThePlotNotInIt) {
  cv::Mat img(400, 600, CV_8UC3, cv::Scalar(255, 255, 255));
  Axes a;
  a.plot = cv::Rect(kAxisLeftPx, kAxisTopPx, 600 - kAxisLeftPx - 20, 400 - kAxisTopPx - kAxisBottomPx);
  a.x0 = -85, a.x1 = 85, a.y0 = -60, a.y1 = 60, a.x_label = "x mm", a.y_label = "y mm";
  draw_axes(img, a);
  EXPECT_GT(dark(img, cv::Rect(0, a.plot.y + 2, kAxisLeftPx - 6, a.plot.height - 4)), 100) << "y tick numbers";
  EXPECT_GT(dark(img, cv::Rect(a.plot.x + 2, a.plot.y + a.plot.height + 6, a.plot.width - 4, kAxisBottomPx - 6)), 100)
      << "x tick numbers and label";
  EXPECT_EQ(dark(img, cv::Rect(a.plot.x + 2, a.plot.y + 2, a.plot.width - 4, a.plot.height - 4)), 0) << "the plot stays clear";
  // The data map: corners of the ranges on the plot's corners, y up.
  EXPECT_NEAR(a.px(-85, -60).x, a.plot.x, 1e-9);
  EXPECT_NEAR(a.px(-85, -60).y, a.plot.y + a.plot.height, 1e-9);
  EXPECT_NEAR(a.px(85, 60).y, a.plot.y, 1e-9);
}

TEST(Plot, ColourBarRunsFromLowToHigh) {
  cv::Mat img(300, 200, CV_8UC3, cv::Scalar(255, 255, 255));
  const ColourBar b{.bar = cv::Rect(40, 60, 20, 200), .lo = 1.5, .hi = 9.5, .title = "tip z", .unit = "mm",
                    .colour = nullptr, .above = false, .below = false};
  draw_colour_bar(img, b);
  const auto at = [&](int y) { return img.at<cv::Vec3b>(y, 50); };
  const cv::Scalar low = viridis(0), high = viridis(1);
  EXPECT_NEAR(at(258)[0], low[0], 12);
  EXPECT_NEAR(at(258)[2], low[2], 12);
  EXPECT_NEAR(at(62)[1], high[1], 12);
  EXPECT_NEAR(at(62)[2], high[2], 12);
  EXPECT_GT(dark(img, cv::Rect(62, 50, 130, 220)), 100) << "the numbers beside the bar";
  EXPECT_GT(dark(img, cv::Rect(30, 0, 160, 56)), 50) << "the title and unit above it";
}

}  // namespace
}  // namespace photomill::plot
