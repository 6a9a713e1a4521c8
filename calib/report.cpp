// Text and JSON reports and the residual plot (see report.hpp).
#include "calib/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/run.hpp"
#include "formats/json.hpp"
#include "formats/plot.hpp"

namespace photomill::calib {
namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string pad(std::string s, std::size_t width) {
  if (s.size() < width) s.append(width - s.size(), ' ');
  return s;
}

std::string value_sigma(const std::string& name, double v, double sigma, const char* format) {
  std::string s = name + " = " + fmt(format, v);
  if (sigma > 0) s += std::isfinite(sigma) ? " +- " + fmt(format, sigma) : " +- (undetermined)";
  else s += " (fixed)";
  return s;
}

// 1, 2, 5, 10, 20, ... : the largest such step not above x.
double nice_floor(double x) {
  const double e = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {5.0, 2.0, 1.0}) {
    if (m * e <= x) return m * e;
  }
  return e;
}

// The view with the largest RMS in the first, all-view calibration.
const ViewReport* worst_view(const CalibResult& r) {
  const ViewReport* worst = nullptr;
  for (const auto& v : r.views) {
    if (!worst || v.first_rms_px > worst->first_rms_px) worst = &v;
  }
  return worst;
}

}  // namespace

std::vector<std::string> text_report(const CalibResult& r) {
  std::vector<std::string> lines;
  int rejected = 0;
  for (const auto& v : r.views) rejected += v.rejected ? 1 : 0;
  lines.push_back(std::to_string(r.views.size()) + " views (" + std::to_string(rejected) + " rejected), " +
                  std::to_string(r.points_used) + " points used; method " + to_string(r.method) + ", optimizer " +
                  r.stats.optimizer + ": " + fmt("%.3f", r.stats.seconds) + " s" +
                  (r.stats.iterations >= 0 ? ", " + std::to_string(r.stats.iterations) + " iterations" : "") +
                  (r.stats.evaluations >= 0 ? ", " + std::to_string(r.stats.evaluations) + " evaluations" : ""));
  std::size_t width = 4;
  for (const auto& v : r.views) width = std::max(width, v.image.size());
  lines.push_back("  " + pad("view", width) + "  points  rms_px  max_px  tilt_deg");
  for (const auto& v : r.views) {
    std::string line = "  " + pad(v.image, width) + "  " + fmt("%6.0f", v.points) + "  " + fmt("%6.3f", v.rms_px) +
                       "  " + fmt("%6.3f", v.max_px) + "  " +
                       (std::isfinite(v.tilt_deg) ? fmt("%8.1f", v.tilt_deg) : "       -");
    if (v.rejected) line += "  REJECTED: " + v.reason;
    lines.push_back(line);
  }
  for (const auto& s : r.skipped_views) lines.push_back("  skipped (too few points): " + s);
  if (r.unmatched_observations > 0) {
    lines.push_back(std::to_string(r.unmatched_observations) + " observations have no control point (ignored)");
  }
  if (const ViewReport* w = worst_view(r)) {
    lines.push_back("worst view: " + w->image + " (" + fmt("%.3f", w->first_rms_px) + " px in the first pass" +
                    (w->rejected ? ", rejected)" : ", kept)"));
  }
  lines.push_back("RMS " + fmt("%.5f", r.rms_px) + " px over the views kept; " + fmt("%.5f", r.rms_all_views_px) +
                  " px in the first pass with every view");
  const auto& u = r.uncertainty;
  const auto& c = r.camera;
  lines.push_back(value_sigma("fx", c.fx(), u.intrinsics_sigma[0], "%.4f") + " px   " +
                  value_sigma("fy", c.fy(), u.intrinsics_sigma[1], "%.4f") + " px");
  lines.push_back(value_sigma("cx", c.cx(), u.intrinsics_sigma[2], "%.4f") + " px   " +
                  value_sigma("cy", c.cy(), u.intrinsics_sigma[3], "%.4f") + " px");
  std::string d;
  for (std::size_t i = 0; i < c.distortion.size(); ++i) {
    d += (i ? "   " : "") + value_sigma(distortion_names()[i], c.distortion[i], u.distortion_sigma[i], "%.6g");
    if (i % 3 == 2 || i + 1 == c.distortion.size()) {
      lines.push_back(d);
      d.clear();
    }
  }
  lines.push_back("(+- one standard deviation; a-posteriori sigma of one coordinate " + fmt("%.4f", u.sigma_px) + " px)");
  lines.push_back("projection sigma " + fmt("%.3f", u.projection_sigma_centre_px) + " px at the centre, " +
                  fmt("%.3f", u.projection_sigma_edges_px) + " px at the edges, " +
                  fmt("%.3f", u.projection_sigma_corners_px) + " px at the corners");
  return lines;
}

void write_json_report(std::ostream& out, const CalibResult& r, const CalibOptions& o) {
  JsonWriter j(out);
  const auto& c = r.camera;
  const auto& u = r.uncertainty;
  j.begin_object();
  j.field("tool", "calib");
  j.field("run_id", run_id());
  j.field("method", to_string(r.method));
  j.field("optimizer", r.stats.optimizer);
  j.field("image_width_px", c.image_width_px);
  j.field("image_height_px", c.image_height_px);
  j.field("rms_px", r.rms_px);
  j.field("rms_all_views_px", r.rms_all_views_px);
  j.field("points_used", r.points_used);
  j.field("unmatched_observations", r.unmatched_observations);
  j.field("coverage", r.coverage);
  j.key("camera").begin_object();
  j.field("fx_px", c.fx()).field("fy_px", c.fy()).field("cx_px", c.cx()).field("cy_px", c.cy());
  j.key("distortion").begin_array();
  for (double v : c.distortion) j.value(v);
  j.end_array().end_object();
  const auto& a = r.camera_all_views;
  j.key("camera_all_views").begin_object();
  j.field("fx_px", a.fx()).field("fy_px", a.fy()).field("cx_px", a.cx()).field("cy_px", a.cy());
  j.key("distortion").begin_array();
  for (double v : a.distortion) j.value(v);
  j.end_array().end_object();
  j.key("std_dev").begin_object();
  for (int i = 0; i < kIntrinsics; ++i) j.field(intrinsic_names()[i] + "_px", u.intrinsics_sigma[i]);
  j.key("distortion").begin_array();
  for (std::size_t i = 0; i < c.distortion.size(); ++i) j.value(u.distortion_sigma[i]);
  j.end_array();
  j.field("sigma_px", u.sigma_px);
  j.field("degrees_of_freedom", u.degrees_of_freedom);
  j.end_object();
  j.key("projection_sigma_px").begin_object();
  j.field("centre", u.projection_sigma_centre_px);
  j.field("edges", u.projection_sigma_edges_px);
  j.field("corners", u.projection_sigma_corners_px);
  j.field("corner_parameter", u.corner_sigma_parameter);
  j.field("corner_parameter_px", u.corner_sigma_parameter_px);
  j.end_object();
  j.key("optimizer_stats").begin_object();
  j.field("iterations", static_cast<std::int64_t>(r.stats.iterations));
  j.field("evaluations", static_cast<std::int64_t>(r.stats.evaluations));
  j.field("restarts", r.stats.restarts);
  if (r.stats.optimizer == "simplex") {
    j.field("simplex_scaling", o.simplex.scaling == SimplexScaling::Jacobian ? "jacobian" : "diagonal");
  }
  j.field("seconds", r.stats.seconds);
  j.field("initial_rms_px", r.stats.initial_rms_px);
  j.field("converged", r.stats.converged);
  j.field("message", r.stats.message);
  j.end_object();
  j.key("model").begin_object();
  j.field("fix_aspect_ratio", o.model.fix_aspect_ratio);
  j.field("fix_principal_point", o.model.fix_principal_point);
  j.field("zero_tangent", o.model.zero_tangent);
  j.field("fix_k3", o.model.fix_k3);
  j.field("rational", o.model.rational);
  j.end_object();
  j.key("rejection").begin_object();
  j.field("factor", o.reject_factor).field("min_px", o.reject_min_px).field("min_views", o.min_views);
  j.end_object();
  j.key("views").begin_array();
  for (const auto& v : r.views) {
    const auto q = v.cam_from_world.cam_from_world_rotation;
    const auto& t = v.cam_from_world.cam_from_world_translation_mm;
    j.begin_object();
    j.field("image", v.image).field("points", v.points).field("rms_px", v.rms_px).field("max_px", v.max_px);
    j.field("first_rms_px", v.first_rms_px).field("tilt_deg", v.tilt_deg).field("rejected", v.rejected);
    if (v.rejected) j.field("reason", v.reason);
    j.key("cam_from_world").begin_object();
    j.field("qw", q.w()).field("qx", q.x()).field("qy", q.y()).field("qz", q.z());
    j.field("tx_mm", t.x()).field("ty_mm", t.y()).field("tz_mm", t.z());
    j.end_object();
    j.end_object();
  }
  j.end_array();
  if (const ViewReport* w = worst_view(r)) j.field("worst_view", w->image);
  j.key("skipped_views").begin_array();
  for (const auto& s : r.skipped_views) j.value(s);
  j.end_array();
  j.key("undetermined").begin_array();
  for (const auto& s : u.undetermined) j.value(s);
  j.end_array();
  j.key("warnings").begin_array();
  for (const auto& s : r.warnings) j.value(s);
  j.end_array();
  j.end_object();
  out << "\n";
}

ResidualPlot residual_plot(const CalibResult& r) {
  ResidualPlot out;
  const double w = r.camera.image_width_px;
  const double h = r.camera.image_height_px;
  const double canvas_scale = 1200.0 / std::max(w, h);  // the long side drawn 1200 px
  // Room for the title and the axes' numbers and labels (image pixels, u right, v down), the legend.
  const int left = plot::kAxisLeftPx, top = plot::kAxisTopPx + 30, right = 40, bottom = plot::kAxisBottomPx;
  const int legend = 50;
  const cv::Size frame(static_cast<int>(std::lround(w * canvas_scale)), static_cast<int>(std::lround(h * canvas_scale)));
  const cv::Size canvas(frame.width + left + right, frame.height + top + bottom + legend);
  cv::Mat img(canvas, CV_8UC3, cv::Scalar(255, 255, 255));
  // The frame spans the image's pixels from the top-left pixel's outer edge (-0.5) to the
  // bottom-right one's (w - 0.5): OpenCV's convention puts pixel centres on integers.
  plot::Axes axes;
  axes.plot = cv::Rect(left, top, frame.width, frame.height);
  axes.x0 = -0.5, axes.x1 = w - 0.5, axes.y0 = -0.5, axes.y1 = h - 0.5, axes.y_up = false;
  axes.x_label = "u px", axes.y_label = "v px";
  auto to_canvas = [&](const Eigen::Vector2d& p) { return axes.px(p.x(), p.y()); };
  plot::draw_axes(img, axes, true);
  // Magnification: the 95th percentile residual of the kept views drawn ~3 % of the diagonal.
  std::vector<double> lengths;
  for (const auto& p : r.residuals) {
    if (!p.rejected_view) lengths.push_back(p.residual_px.norm());
  }
  std::sort(lengths.begin(), lengths.end());
  const double p95 = lengths.empty() ? 1.0 : std::max(1e-6, lengths[lengths.size() * 95 / 100]);
  const double diag = std::hypot(frame.width, frame.height);
  out.magnification = nice_floor(0.03 * diag / (p95 * canvas_scale));
  out.bar_px = nice_floor(p95);
  const cv::Scalar kept(160, 60, 0);      // blue (BGR)
  const cv::Scalar outlier(0, 140, 255);  // orange
  for (const auto& p : r.residuals) {
    const cv::Point2d a = to_canvas(p.observed_px);
    const cv::Point2d b = a + cv::Point2d(p.residual_px.x(), p.residual_px.y()) * (out.magnification * canvas_scale);
    const cv::Scalar colour = p.rejected_view ? outlier : kept;
    cv::line(img, a, b, colour, 1, cv::LINE_AA);
    cv::circle(img, a, 2, colour, cv::FILLED, cv::LINE_AA);
  }
  plot::text(img, "calibration residuals over the image frame (model - observed, drawn x" +
                       plot::number(out.magnification) + ")", {left, 22}, 0.55);
  // Legend: a bar for bar_px of residual, the magnification and the RMS.
  const int y = canvas.height - legend / 2;
  const int bar = static_cast<int>(std::lround(out.bar_px * out.magnification * canvas_scale));
  cv::line(img, {left, y}, {left + bar, y}, kept, 3);
  const std::string text = "= " + plot::number(out.bar_px) + " px of residual   (residuals x" + plot::number(out.magnification) +
                           "; RMS " + plot::number(r.rms_px, 3) + " px; rejected views in orange)";
  plot::text(img, text, {left + bar + 10, y + 6}, 0.55, cv::Scalar(0, 0, 0));
  cv::imencode(".png", img, out.png);
  return out;
}

}  // namespace photomill::calib
