#include "fitsurf/preview.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "fitsurf/evaluate.hpp"
#include "fitsurf/outline.hpp"
#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "formats/plot.hpp"

namespace photomill::fitsurf {
namespace {

// Room around the plot: the axes' numbers and labels (left, top, bottom), the colour bar, the
// legend line.
constexpr int kLeft = plot::kAxisLeftPx, kTop = plot::kAxisTopPx + 30, kBarArea = plot::kColourBarAreaPx + 10;
constexpr int kBottom = plot::kAxisBottomPx, kLegend = 28;

std::string mm(double x) { return plot::number(x, 3); }

// Diverging blue - white - red (the end colours of ColorBrewer's RdBu), t in [-1, 1]; BGR.
cv::Scalar residual_colour(double t) {
  t = std::clamp(t, -1.0, 1.0);
  const double white[3] = {247, 247, 247}, blue[3] = {33, 102, 172}, red[3] = {178, 24, 43};
  const double* end = t < 0 ? blue : red;
  const double a = std::abs(t);
  double rgb[3];
  for (int c = 0; c < 3; ++c) rgb[c] = (1 - a) * white[c] + a * end[c];
  return cv::Scalar(rgb[2], rgb[1], rgb[0]);
}

}  // namespace

Eigen::Vector2i preview_size_px(double extent_u_mm, double extent_v_mm, const PreviewOptions& o) {
  const int width = std::clamp(o.width_px, 400, 8000);
  const double scale = static_cast<double>(width - kLeft - kBarArea) / extent_u_mm;
  const int plot = std::clamp(static_cast<int>(std::ceil(extent_v_mm * scale)), 100, 8000);
  return {width, plot + kTop + kBottom + kLegend};
}

std::vector<std::uint8_t> render_preview_png(const Result& result, const std::vector<Eigen::Vector3d>& points,
                                             const PreviewOptions& o) {
  const FitResult& fit = result.fit;
  const BSplineSurface& s = fit.local_surface;  // poles in the parameter frame: x, y in the plane, z up
  const double lu = fit.box.length_u_mm(), lv = fit.box.length_v_mm();
  if (!(lu > 0) || !(lv > 0) || !std::isfinite(lu) || !std::isfinite(lv)) {
    throw GeometryError("nothing to preview: the fit has no extent in its parameter plane");
  }
  if (points.size() != fit.residual_mm.size()) {
    throw GeometryError("preview: " + std::to_string(points.size()) + " points for " +
                        std::to_string(fit.residual_mm.size()) + " residuals");
  }
  const Eigen::Vector2i size = preview_size_px(lu, lv, o);
  const int width = size.x(), height = size.y();
  const double scale = static_cast<double>(width - kLeft - kBarArea) / lu;
  const int plot_h = height - kTop - kBottom - kLegend;
  const int plot_bottom = kTop + plot_h;
  // Axes in the parameter plane's mm, equal scales: the v range is what the plot's height holds.
  plot::Axes axes;
  axes.plot = cv::Rect(kLeft, kTop, width - kLeft - kBarArea, plot_h);
  axes.x0 = fit.box.t1_min, axes.x1 = fit.box.t1_min + lu;
  axes.y0 = fit.box.t2_min, axes.y1 = fit.box.t2_min + plot_h / scale;
  // A cloud without a datum is in its own unit, not mm: the labels say "units" (Result::units).
  const std::string unit = result.units == "mm" ? "mm" : "units";
  axes.x_label = "u " + unit, axes.y_label = "v " + unit;
  // Local (x, y) mm -> pixel, 16x sub-pixel (4 fractional bits), y up.
  const auto px = [&](double x, double y) {
    const cv::Point2d q = axes.px(x, y);
    return cv::Point(static_cast<int>(std::lround(q.x * 16)), static_cast<int>(std::lround(q.y * 16)));
  };
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  plot::text(img, "fitted surface seen along the fit plane's normal (u, v: " + unit + " in that plane)", {kLeft, 22}, 0.55);

  // The surface: grid cells inside the outline, grey by Lambert shading of the cell's normal,
  // light from the upper left and above. Seen along z: cells drawn lowest first.
  const int n = std::clamp(o.surface_cells, 2, 1000);
  std::vector<Eigen::Vector3d> grid(static_cast<std::size_t>((n + 1) * (n + 1)));
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) grid[static_cast<std::size_t>(i * (n + 1) + j)] = surface_point(s, double(i) / n, double(j) / n);
  }
  const auto at = [&](int i, int j) { return grid[static_cast<std::size_t>(i * (n + 1) + j)]; };
  const Eigen::Vector3d light = Eigen::Vector3d(-1, 1, 2).normalized();
  struct Cell {
    double z;
    int i, j;
  };
  std::vector<Cell> cells;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d uv((i + 0.5) / n, (j + 0.5) / n);
      if (!s.boundary_uv.empty() && !point_in_polygon(s.boundary_uv, uv)) continue;
      cells.push_back({0.25 * (at(i, j).z() + at(i + 1, j).z() + at(i, j + 1).z() + at(i + 1, j + 1).z()), i, j});
    }
  }
  std::sort(cells.begin(), cells.end(), [](const Cell& a, const Cell& b) { return a.z < b.z; });
  for (const Cell& c : cells) {
    const Eigen::Vector3d a = at(c.i, c.j), b = at(c.i + 1, c.j), d = at(c.i + 1, c.j + 1), e = at(c.i, c.j + 1);
    Eigen::Vector3d nrm = (d - a).cross(e - b);
    if (nrm.z() < 0) nrm = -nrm;
    const double lit = nrm.norm() > 0 ? std::max(0.0, nrm.normalized().dot(light)) : 1.0;
    const double g = 95 + 140 * lit;
    const cv::Point quad[4] = {px(a.x(), a.y()), px(b.x(), b.y()), px(d.x(), d.y()), px(e.x(), e.y())};
    cv::fillConvexPoly(img, quad, 4, cv::Scalar(g, g, g), cv::LINE_8, 4);
  }
  if (!s.boundary_uv.empty()) {
    std::vector<cv::Point> poly;
    for (const auto& uv : s.boundary_uv) {
      const Eigen::Vector3d p = surface_point(s, uv.x(), uv.y());
      poly.push_back(px(p.x(), p.y()));
    }
    cv::polylines(img, poly, true, cv::Scalar(40, 140, 40), 2, cv::LINE_AA, 4);
  }

  // The points, coloured by residual on a symmetric scale of +-R, R = p99 of |d| of the inliers.
  const auto& d = fit.residual_mm;
  const auto outlier = [&](std::size_t k) { return !fit.outlier.empty() && fit.outlier[k]; };
  std::vector<double> a;
  for (std::size_t k = 0; k < d.size(); ++k) {
    if (!outlier(k)) a.push_back(std::abs(d[k]));
  }
  double range = 0;
  if (!a.empty()) {
    const std::size_t rank = std::min(a.size() - 1, static_cast<std::size_t>(std::ceil(0.99 * a.size())) - 1);
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(rank), a.end());
    range = a[rank];
  }
  if (!(range > 0)) range = 1e-3;  // exact data: a scale of 1 micrometre
  std::vector<std::size_t> order;
  const std::size_t stride = std::max<std::size_t>(1, (d.size() + o.max_dots - 1) / std::max<std::size_t>(1, o.max_dots));
  for (std::size_t k = 0; k < d.size(); ++k) {
    if (k % stride == 0 || std::abs(d[k]) > range || outlier(k)) order.push_back(k);
  }
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return std::abs(d[x]) < std::abs(d[y]); });
  // Dots cover at most about a quarter of the plot, so the shading stays visible: radius 1..4 px.
  const double plot_area = static_cast<double>(axes.plot.width) * axes.plot.height;
  const int radius = std::clamp(
      static_cast<int>(std::sqrt(0.25 * plot_area / (3.14159 * static_cast<double>(std::max<std::size_t>(1, order.size()))))), 1, 4);
  std::size_t outliers = 0;
  for (std::size_t k : order) {
    const Eigen::Vector3d q = fit.frame.to_local(points[k]);
    const cv::Point c = px(q.x(), q.y());
    if (outlier(k)) {
      ++outliers;
      const int r = (radius + 2) * 16;
      cv::line(img, c + cv::Point(-r, -r), c + cv::Point(r, r), cv::Scalar(0, 0, 0), 1, cv::LINE_AA, 4);
      cv::line(img, c + cv::Point(-r, r), c + cv::Point(r, -r), cv::Scalar(0, 0, 0), 1, cv::LINE_AA, 4);
      continue;
    }
    cv::circle(img, c, radius * 16, residual_colour(d[k] / range), cv::FILLED, cv::LINE_AA, 4);
    if (radius >= 4) cv::circle(img, c, radius * 16, cv::Scalar(60, 60, 60), 1, cv::LINE_AA, 4);
  }

  // Colour bar: +R at the top, 0, -R at the bottom, in mm.
  plot::draw_axes(img, axes);
  plot::ColourBar bar;
  bar.bar = cv::Rect(width - kBarArea + 24, kTop + 10, 18, std::max(40, plot_bottom - kTop - 20));
  bar.lo = -range, bar.hi = range, bar.title = "residual", bar.unit = unit;
  bar.colour = [range](double v) { return residual_colour(v / range); };
  plot::draw_colour_bar(img, bar);

  const ResidualStats& st = result.stats;
  std::string text = std::to_string(d.size()) + " points, " + std::to_string(s.num_poles_u) + "x" +
                     std::to_string(s.num_poles_v) + " net; residual RMS " + mm(st.rms_mm) + " " + unit + ", max " +
                     mm(st.max_abs_mm) + " " + unit + "; dots: signed residual (red above, blue below)";
  if (outliers) text += "; x: " + std::to_string(outliers) + " outliers";
  const double font = std::clamp(0.42 * width / 1100.0, 0.3, 0.6);  // the line fits the width
  cv::putText(img, text, cv::Point(kLeft, height - 10), cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw GeometryError("PNG encoding failed");
  return png;
}

}  // namespace photomill::fitsurf
