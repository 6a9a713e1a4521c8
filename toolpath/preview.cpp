#include "toolpath/preview.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/bspline.hpp"
#include "formats/error.hpp"

namespace photomill::toolpath {

std::vector<std::uint8_t> render_preview_png(const BSplineSurface& surface, const ToolpathResult& path,
                                             const PreviewOptions& o) {
  const int n = std::clamp(o.surface_cells, 2, 2000);
  const auto [u0, u1] = domain_u(surface);
  const auto [v0, v1] = domain_v(surface);
  std::vector<Eigen::Vector3d> grid(static_cast<std::size_t>((n + 1) * (n + 1)));
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
  double zlo = 1e300, zhi = -1e300;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const Eigen::Vector3d p = surface_point(surface, u0 + (u1 - u0) * i / n, v0 + (v1 - v0) * j / n);
      grid[static_cast<std::size_t>(i * (n + 1) + j)] = p;
      lo = lo.cwiseMin(p.head<2>()), hi = hi.cwiseMax(p.head<2>());
      zlo = std::min(zlo, p.z()), zhi = std::max(zhi, p.z());
    }
  }
  for (const ClMove& m : path.cl.moves) lo = lo.cwiseMin(m.tip_mm.head<2>()), hi = hi.cwiseMax(m.tip_mm.head<2>());
  const Eigen::Vector2d ext = hi - lo;
  if (!(ext.x() > 0) || !(ext.y() > 0) || !ext.allFinite()) throw GeometryError("nothing to preview: the part has no horizontal extent");
  const int margin = 20, legend = 28;
  const int width = std::clamp(o.width_px, 200, 8000);
  const double scale = (width - 2.0 * margin) / ext.x();
  const int height = std::clamp(static_cast<int>(std::ceil(ext.y() * scale)) + 2 * margin + legend, 100, 8000);
  const auto px = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(std::lround((p.x() - lo.x()) * scale * 16 + margin * 16)),
                     static_cast<int>(std::lround((height - legend - margin) * 16 - (p.y() - lo.y()) * scale * 16)));
  };
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));

  // Surface cells, lowest first so that higher parts cover lower ones.
  std::vector<int> order(static_cast<std::size_t>(n * n));
  std::vector<double> cell_z(order.size());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const auto at = [&](int a, int b) { return grid[static_cast<std::size_t>(a * (n + 1) + b)]; };
      cell_z[static_cast<std::size_t>(i * n + j)] = 0.25 * (at(i, j).z() + at(i + 1, j).z() + at(i, j + 1).z() + at(i + 1, j + 1).z());
    }
  }
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return cell_z[static_cast<std::size_t>(a)] < cell_z[static_cast<std::size_t>(b)]; });
  const double zr = zhi > zlo ? zhi - zlo : 1.0;
  for (int c : order) {
    const int i = c / n, j = c % n;
    const auto at = [&](int a, int b) { return grid[static_cast<std::size_t>(a * (n + 1) + b)]; };
    const cv::Point quad[4] = {px(at(i, j)), px(at(i + 1, j)), px(at(i + 1, j + 1)), px(at(i, j + 1))};
    const double s = (cell_z[static_cast<std::size_t>(c)] - zlo) / zr;  // 0 low .. 1 high
    const cv::Scalar colour(150 + 90 * s, 110 + 120 * s, 70 + 150 * s);  // BGR: dark slate to pale sand
    cv::fillConvexPoly(img, quad, 4, colour, cv::LINE_8, 4);
  }
  if (!surface.boundary_uv.empty()) {
    std::vector<cv::Point> poly;
    for (const auto& uv : surface.boundary_uv) poly.push_back(px(surface_point(surface, uv.x(), uv.y())));
    cv::polylines(img, poly, true, cv::Scalar(40, 140, 40), 2, cv::LINE_AA, 4);
  }
  // Feed moves solid, then rapids dashed on top (in a top view they run over the passes).
  const auto& moves = path.cl.moves;
  for (std::size_t k = 1; k < moves.size(); ++k) {
    if (moves[k].kind == ClMove::Kind::Feed) cv::line(img, px(moves[k - 1].tip_mm), px(moves[k].tip_mm), cv::Scalar(120, 40, 0), 1, cv::LINE_AA, 4);
  }
  for (std::size_t k = 1; k < moves.size(); ++k) {
    if (moves[k].kind != ClMove::Kind::Rapid) continue;
    const cv::Point2d a = px(moves[k - 1].tip_mm), b = px(moves[k].tip_mm);
    const double len = cv::norm(b - a) / 16;  // pixels
    const int dashes = std::max(1, static_cast<int>(len / 6));
    for (int d = 0; d < dashes; d += 2) {
      const cv::Point2d p = a + (b - a) * (static_cast<double>(d) / dashes);
      const cv::Point2d q = a + (b - a) * (static_cast<double>(d + 1) / dashes);
      cv::line(img, cv::Point(cvRound(p.x), cvRound(p.y)), cv::Point(cvRound(q.x), cvRound(q.y)), cv::Scalar(40, 40, 220), 2,
               cv::LINE_8, 4);
    }
  }
  for (const PassSegment& seg : path.segments) {
    for (const CutterLocation& p : seg.points) {
      if (p.gouge) cv::circle(img, px(p.tip), 4 * 16, cv::Scalar(220, 0, 220), 1, cv::LINE_AA, 4);
    }
  }
  const std::string text = std::to_string(path.stats.passes) + " passes, " + std::to_string(path.stats.cl_points) +
                           " CL points, " + std::to_string(static_cast<long>(std::lround(path.stats.feed_length_mm))) +
                           " mm feed. blue: feed, red dashes: rapid, magenta: gouge";
  cv::putText(img, text, cv::Point(margin, height - 10), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw GeometryError("PNG encoding failed");
  return png;
}

}  // namespace photomill::toolpath
