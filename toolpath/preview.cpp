#include "toolpath/preview.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "formats/plot.hpp"

namespace photomill::toolpath {
namespace {

// Room around the plot: the axes' numbers and labels, the colour bar, the legend line.
constexpr int kLeft = plot::kAxisLeftPx, kTop = plot::kAxisTopPx + 30, kRight = plot::kColourBarAreaPx + 10;
constexpr int kBottom = plot::kAxisBottomPx, kLegend = 28;

cv::Scalar bgr(const Eigen::Vector3i& c) { return cv::Scalar(c[0], c[1], c[2]); }

// A labelled mark: a filled disc (start) or square (end) with a white rim, its name beside it.
void mark(cv::Mat& img, const cv::Rect& plot, cv::Point2d at, bool disc, const cv::Scalar& colour, const std::string& name) {
  const cv::Point p(cvRound(at.x), cvRound(at.y));
  if (disc) {
    cv::circle(img, p, 8, cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA);
    cv::circle(img, p, 6, colour, cv::FILLED, cv::LINE_AA);
  } else {
    cv::rectangle(img, p - cv::Point(8, 8), p + cv::Point(8, 8), cv::Scalar(255, 255, 255), cv::FILLED);
    cv::rectangle(img, p - cv::Point(6, 6), p + cv::Point(6, 6), colour, cv::FILLED);
  }
  const cv::Size t = plot::text_size(name, 0.5);
  // Beside the mark, inside the plot.
  cv::Point org = p.x + 12 + t.width < plot.x + plot.width ? p + cv::Point(12, 5) : p + cv::Point(-12 - t.width, 5);
  org.y = std::clamp(org.y, plot.y + t.height + 4, plot.y + plot.height - 6);
  cv::rectangle(img, org + cv::Point(-2, 4), org + cv::Point(t.width + 2, -t.height - 3), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(img, name, org, cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv::LINE_AA);
}

}  // namespace

Eigen::Vector2i preview_size_px(double extent_x_mm, double extent_y_mm, const PreviewOptions& o) {
  const int width = std::clamp(o.width_px, 400, 8000);
  const double scale = (width - kLeft - kRight) / extent_x_mm;
  const int plot = std::clamp(static_cast<int>(std::ceil(extent_y_mm * scale)), 100, 8000);
  return {width, plot + kTop + kBottom + kLegend};
}

std::vector<std::uint8_t> render_preview_png(const BSplineSurface& surface, const ToolpathResult& path,
                                             const PreviewOptions& o) {
  const int n = std::clamp(o.surface_cells, 2, 2000);
  const auto [u0, u1] = domain_u(surface);
  const auto [v0, v1] = domain_v(surface);
  std::vector<Eigen::Vector3d> grid(static_cast<std::size_t>((n + 1) * (n + 1)));
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const Eigen::Vector3d p = surface_point(surface, u0 + (u1 - u0) * i / n, v0 + (v1 - v0) * j / n);
      grid[static_cast<std::size_t>(i * (n + 1) + j)] = p;
      lo = lo.cwiseMin(p.head<2>()), hi = hi.cwiseMax(p.head<2>());
    }
  }
  const auto& moves = path.cl.moves;
  for (const ClMove& m : moves) lo = lo.cwiseMin(m.tip_mm.head<2>()), hi = hi.cwiseMax(m.tip_mm.head<2>());
  const Eigen::Vector2d ext = hi - lo;
  if (!(ext.x() > 0) || !(ext.y() > 0) || !ext.allFinite()) throw GeometryError("nothing to preview: the part has no horizontal extent");
  const Eigen::Vector2i size = preview_size_px(ext.x(), ext.y(), o);
  const int width = size.x(), height = size.y();
  const double scale = static_cast<double>(width - kLeft - kRight) / ext.x();
  const int plot_h = height - kTop - kBottom - kLegend;
  plot::Axes axes;
  axes.plot = cv::Rect(kLeft, kTop, width - kLeft - kRight, plot_h);
  // Equal scales on x and y: the y range is what the plot's height holds at the x scale.
  const double mid_y = 0.5 * (lo.y() + hi.y()), half_y = 0.5 * plot_h / scale;
  axes.x0 = lo.x(), axes.x1 = hi.x(), axes.y0 = mid_y - half_y, axes.y1 = mid_y + half_y;
  axes.x_label = "x mm", axes.y_label = "y mm";
  const auto px = [&](const Eigen::Vector3d& p) {
    const cv::Point2d q = axes.px(p.x(), p.y());
    return cv::Point(cvRound(q.x * 16), cvRound(q.y * 16));
  };
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  plot::text(img, "tool path seen from above", {kLeft, 22}, 0.55);

  // The surface's extent in light grey, its boundary polygon in green.
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const auto at = [&](int a, int b) { return grid[static_cast<std::size_t>(a * (n + 1) + b)]; };
      const cv::Point quad[4] = {px(at(i, j)), px(at(i + 1, j)), px(at(i + 1, j + 1)), px(at(i, j + 1))};
      cv::fillConvexPoly(img, quad, 4, cv::Scalar(236, 236, 236), cv::LINE_8, 4);
    }
  }
  if (!surface.boundary_uv.empty()) {
    std::vector<cv::Point> poly;
    for (const auto& uv : surface.boundary_uv) poly.push_back(px(surface_point(surface, uv.x(), uv.y())));
    cv::polylines(img, poly, true, cv::Scalar(40, 140, 40), 2, cv::LINE_AA, 4);
  }

  // Feed moves coloured by the tip's height: the scale spans the cutting moves (a feed after a
  // feed; a plunge starts at the clearance height), plunges and lifts take its end colours.
  double zlo = 1e300, zhi = -1e300;
  for (std::size_t k = 1; k < moves.size(); ++k) {
    if (moves[k].kind == ClMove::Kind::Feed && moves[k - 1].kind == ClMove::Kind::Feed) {
      zlo = std::min(zlo, moves[k].tip_mm.z()), zhi = std::max(zhi, moves[k].tip_mm.z());
    }
  }
  if (!(zhi >= zlo)) zlo = 0, zhi = 1;
  if (!(zhi > zlo)) zlo -= 0.5, zhi += 0.5;
  for (std::size_t k = 1; k < moves.size(); ++k) {
    if (moves[k].kind != ClMove::Kind::Feed) continue;
    const double z = 0.5 * (moves[k - 1].tip_mm.z() + moves[k].tip_mm.z());
    // (Not antialiased: a pass keeps its height's colour exactly, not blended into the ground.)
    cv::line(img, px(moves[k - 1].tip_mm), px(moves[k].tip_mm), plot::viridis((z - zlo) / (zhi - zlo)), 1, cv::LINE_8, 4);
  }
  // Rapids dashed on top, thin, so the passes under them show between the dashes.
  for (std::size_t k = 1; k < moves.size(); ++k) {
    if (moves[k].kind != ClMove::Kind::Rapid) continue;
    const cv::Point2d a = px(moves[k - 1].tip_mm), b = px(moves[k].tip_mm);
    const double len = cv::norm(b - a) / 16;  // pixels
    const int dashes = std::max(1, static_cast<int>(len / 5));
    for (int d = 0; d < dashes; d += 2) {
      const cv::Point2d p = a + (b - a) * (static_cast<double>(d) / dashes);
      const cv::Point2d q = a + (b - a) * (static_cast<double>(d + 1) / dashes);
      cv::line(img, cv::Point(cvRound(p.x), cvRound(p.y)), cv::Point(cvRound(q.x), cvRound(q.y)), bgr(kRapidBgr), 1, cv::LINE_8, 4);
    }
  }
  for (const PassSegment& seg : path.segments) {
    for (const CutterLocation& p : seg.points) {
      if (p.gouge) cv::circle(img, px(p.tip), 4 * 16, bgr(kGougeBgr), 1, cv::LINE_AA, 4);
    }
  }
  // Uncertainty-aware stock: orange over the path where k sigma exceeds the threshold, in three
  // shades (above the threshold, above half the 95th percentile of k sigma, above that percentile),
  // blended so the passes show through.
  double stock_max_mm = 0, stock_ref_mm = 0;
  if (o.stock != nullptr && o.stock_k > 0 && !o.stock->sigma_mm.empty()) {
    const UncertaintyGrid& g = *o.stock;
    std::vector<double> extra;
    for (double sg : g.sigma_mm) extra.push_back(o.stock_k * sg), stock_max_mm = std::max(stock_max_mm, extra.back());
    std::vector<double> sorted = extra;
    const auto at95 = sorted.begin() + static_cast<long>(0.95 * static_cast<double>(sorted.size() - 1));
    std::nth_element(sorted.begin(), at95, sorted.end());
    stock_ref_mm = std::max(*at95, o.stock_threshold_mm);
    const double hs = 0.5 * g.step_mm;
    const double level_mm[3] = {o.stock_threshold_mm, std::max(o.stock_threshold_mm, 0.5 * stock_ref_mm), stock_ref_mm};
    for (int level = 0; level < 3; ++level) {
      cv::Mat overlay = img.clone();
      for (std::size_t j = 0; j < g.ny; ++j) {
        for (std::size_t i = 0; i < g.nx; ++i) {
          if (!(extra[j * g.nx + i] > level_mm[level])) continue;
          const double x = g.x0_mm + static_cast<double>(i) * g.step_mm, y = g.y0_mm + static_cast<double>(j) * g.step_mm;
          const cv::Point quad[4] = {px(Eigen::Vector3d(x - hs, y - hs, 0)), px(Eigen::Vector3d(x + hs, y - hs, 0)),
                                     px(Eigen::Vector3d(x + hs, y + hs, 0)), px(Eigen::Vector3d(x - hs, y + hs, 0))};
          cv::fillConvexPoly(overlay, quad, 4, bgr(kStockBgr), cv::LINE_8, 4);
        }
      }
      cv::addWeighted(img, 0.75, overlay, 0.25, 0, img);
    }
  }

  // Start and end of the cut: the first and last feed moves.
  const auto first = std::find_if(moves.begin(), moves.end(), [](const ClMove& m) { return m.kind == ClMove::Kind::Feed; });
  const auto last = std::find_if(moves.rbegin(), moves.rend(), [](const ClMove& m) { return m.kind == ClMove::Kind::Feed; });
  if (first != moves.end()) {
    mark(img, axes.plot, axes.px(last->tip_mm.x(), last->tip_mm.y()), false, bgr(kEndBgr), "end");
    mark(img, axes.plot, axes.px(first->tip_mm.x(), first->tip_mm.y()), true, bgr(kStartBgr), "start");
  }
  plot::draw_axes(img, axes);
  plot::ColourBar bar;
  bar.bar = cv::Rect(width - kRight + 24, kTop + 10, 18, std::max(40, plot_h - 20));
  bar.lo = zlo, bar.hi = zhi, bar.title = "tip z", bar.unit = "mm";
  plot::draw_colour_bar(img, bar);

  const std::string text = std::to_string(path.stats.passes) + " passes, " + std::to_string(path.stats.cl_points) +
                           " CL points, " + plot::number(std::round(path.stats.feed_length_mm), 12) +
                           " mm feed. Colour: tool tip height; red dashes: rapids; magenta rings: gouges (" +
                           std::to_string(path.stats.gouge_points) + ")" +
                           (o.stock != nullptr ? "; orange: stock " + plot::number(o.stock_k, 3) +
                                                           " sigma > " + plot::number(o.stock_threshold_mm, 3) +
                                                           ", > " + plot::number(0.5 * stock_ref_mm, 3) + ", > " +
                                                           plot::number(stock_ref_mm, 3) + " (p95), max " +
                                                           plot::number(stock_max_mm, 3) + " mm"
                                                     : std::string());
  const double font = std::clamp(0.45 * width / 1100.0, 0.3, 0.6);
  cv::putText(img, text, cv::Point(kLeft, height - 10), cv::FONT_HERSHEY_SIMPLEX, font, plot::kInk, 1, cv::LINE_AA);
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw GeometryError("PNG encoding failed");
  return png;
}

}  // namespace photomill::toolpath
