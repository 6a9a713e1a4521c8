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

namespace photomill::fitsurf {
namespace {

constexpr int kMargin = 20, kBarArea = 110, kLegend = 28;

std::string mm(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", x);
  return b;
}

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
  const double scale = (width - 2.0 * kMargin - kBarArea) / extent_u_mm;
  const int plot = std::clamp(static_cast<int>(std::ceil(extent_v_mm * scale)), 100, 8000);
  return {width, plot + 2 * kMargin + kLegend};
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
  const double scale = (width - 2.0 * kMargin - kBarArea) / lu;
  const int plot_bottom = height - kLegend - kMargin;
  // Local (x, y) mm -> pixel, 16x sub-pixel (4 fractional bits), y up.
  const auto px = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround(((x - fit.box.t1_min) * scale + kMargin) * 16)),
                     static_cast<int>(std::lround((plot_bottom - (y - fit.box.t2_min) * scale) * 16)));
  };
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));

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
  const double plot_area = (width - 2.0 * kMargin - kBarArea) * (plot_bottom - kMargin);
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
  const int bx = width - kBarArea + 10, bw = 18, by0 = kMargin + 20, by1 = plot_bottom - 10;
  for (int y = by0; y <= by1; ++y) {
    const double t = 1.0 - 2.0 * (y - by0) / std::max(1, by1 - by0);
    cv::line(img, cv::Point(bx, y), cv::Point(bx + bw, y), residual_colour(t), 1, cv::LINE_8);
  }
  cv::rectangle(img, cv::Point(bx, by0), cv::Point(bx + bw, by1), cv::Scalar(0, 0, 0), 1);
  const auto label = [&](int y, const std::string& text) {
    cv::line(img, cv::Point(bx + bw, y), cv::Point(bx + bw + 4, y), cv::Scalar(0, 0, 0), 1);
    cv::putText(img, text, cv::Point(bx + bw + 7, y + 5), cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  };
  // (Appended rather than "+" + mm(...): GCC 12 warns falsely (-Wrestrict) on that operator+.)
  std::string top = "+", bottom = "-";
  top += mm(range);
  bottom += mm(range);
  label(by0, top);
  label((by0 + by1) / 2, "0");
  label(by1, bottom);
  cv::putText(img, "residual mm", cv::Point(bx - 8, by0 - 8), cv::FONT_HERSHEY_SIMPLEX, 0.42, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);

  const ResidualStats& st = result.stats;
  std::string text = std::to_string(d.size()) + " points, " + std::to_string(s.num_poles_u) + "x" +
                     std::to_string(s.num_poles_v) + " net; residual RMS " + mm(st.rms_mm) + " mm, max " +
                     mm(st.max_abs_mm) + " mm; dots: signed residual (red above, blue below)";
  if (outliers) text += "; x: " + std::to_string(outliers) + " outliers";
  const double font = std::clamp(0.42 * width / 1100.0, 0.3, 0.6);  // the line fits the width
  cv::putText(img, text, cv::Point(kMargin, height - 10), cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw GeometryError("PNG encoding failed");
  return png;
}

}  // namespace photomill::fitsurf
