// PNG preview of a reconstruction (see preview.hpp).
#include "triangulate/preview.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <sstream>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "formats/plot.hpp"
#include "triangulate/reconstruct.hpp"

namespace photomill::triangulate {

namespace {

constexpr int kShift = 4;  // fixed-point bits of drawing coordinates (1/16 px)
constexpr double kOne = 1 << kShift;
constexpr double kPi = 3.14159265358979323846;
const int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kGreyPoint(150, 150, 150);  // points without a value
const cv::Scalar kCameraInk(30, 30, 30);
const cv::Scalar kImageTop(0, 120, 230);       // top edge of each frustum (orange)

// An orthographic view: screen right r, screen up u, towards the viewer e (right-handed).
struct View {
  Eigen::Vector3d r, u, e;
  std::string title;
};

View oblique_view(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kPi / 180, el = elevation_deg * kPi / 180;
  View v;
  v.e = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  v.r = Eigen::Vector3d(-std::sin(az), std::cos(az), 0);  // z x e, normalised (horizontal)
  v.u = v.e.cross(v.r);
  std::ostringstream t;
  t << "oblique view (azimuth " << azimuth_deg << " deg, elevation " << elevation_deg << " deg)";
  v.title = t.str();
  return v;
}

View top_view() {
  return {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(), "top view of the points (x right, y up)"};
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

std::string format_value(double v) { return plot::number(v, 3); }

// Viridis (perceptually uniform, readable in grey) as 256 BGR colours.
std::vector<cv::Vec3b> viridis() {
  cv::Mat ramp(256, 1, CV_8UC1), colours;
  for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(i) = static_cast<std::uint8_t>(i);
  cv::applyColorMap(ramp, colours, cv::COLORMAP_VIRIDIS);
  std::vector<cv::Vec3b> lut(256);
  for (int i = 0; i < 256; ++i) lut[static_cast<std::size_t>(i)] = colours.at<cv::Vec3b>(i);
  return lut;
}

void text(cv::Mat& img, const std::string& s, cv::Point org, double size, const cv::Scalar& colour = kInk) {
  cv::putText(img, s, org, kFont, size, colour, 1, cv::LINE_AA);
}

struct Frustum {
  std::string name;
  Eigen::Vector3d apex;
  std::array<Eigen::Vector3d, 4> corners;  // image corners (0,0) (w,0) (w,h) (0,h) at the frustum depth
};

// A panel: a view and the mapping of world points onto its pixels (panel-relative). The points
// are drawn in `area`, the panel less its title and the room of its axes.
struct Panel {
  View view;
  cv::Size size;
  cv::Rect area;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // screen coordinates (r, u) at the area's centre
  double scale = 1;                                  // px per mm (per unit)
  std::string unit = "mm";                           // of the axes and the scale bar

  cv::Point2d px(const Eigen::Vector3d& p) const {
    return {area.x + area.width / 2.0 + (p.dot(view.r) - centre.x()) * scale,
            area.y + area.height / 2.0 - (p.dot(view.u) - centre.y()) * scale};
  }
  // Fixed-point drawing coordinates; false outside the area (nothing drawn there: a frustum or a
  // point beyond it would spill over the axes or the next panel).
  bool fixed(const Eigen::Vector3d& p, cv::Point& out) const {
    const cv::Point2d q = px(p);
    // (2 px of slack: what frames the area lies on its edge, give or take a rounding.)
    if (!(q.x >= area.x - 2 && q.x <= area.x + area.width + 2 && q.y >= area.y - 2 && q.y <= area.y + area.height + 2)) return false;
    out = cv::Point(cvRound(q.x * kOne), cvRound(q.y * kOne));
    return true;
  }
  // The axes of a view along z (x right, y up), in mm.
  plot::Axes axes() const {
    plot::Axes a;
    a.plot = area;
    a.x0 = centre.x() - area.width / 2.0 / scale, a.x1 = centre.x() + area.width / 2.0 / scale;
    a.y0 = centre.y() - area.height / 2.0 / scale, a.y1 = centre.y() + area.height / 2.0 / scale;
    a.x_label = "x " + unit, a.y_label = "y " + unit;
    return a;
  }
};

// `with_axes`: room for ticked axes (the top view); else a plain margin.
Panel frame_panel(const View& view, cv::Size size, const std::vector<Eigen::Vector3d>& framing, bool with_axes) {
  Panel p;
  p.view = view;
  p.size = size;
  const int title = 28;
  p.area = with_axes ? cv::Rect(plot::kAxisLeftPx + 6, title + plot::kAxisTopPx + 6, size.width - plot::kAxisLeftPx - 26,
                                size.height - title - plot::kAxisTopPx - plot::kAxisBottomPx - 16)
                     : cv::Rect(30, title + 20, size.width - 60, size.height - title - 50);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
  for (const auto& x : framing) {
    const Eigen::Vector2d s(x.dot(view.r), x.dot(view.u));
    lo = lo.cwiseMin(s), hi = hi.cwiseMax(s);
  }
  p.centre = 0.5 * (lo + hi);
  const Eigen::Vector2d ext = (hi - lo).cwiseMax(1e-9);
  p.scale = std::min(p.area.width / ext.x(), p.area.height / ext.y());
  return p;
}

// Returns the number of frusta not drawn (not wholly inside the panel's area).
std::size_t draw_panel(cv::Mat& img, const Panel& p, const std::vector<Eigen::Vector3d>& points,
                const std::vector<cv::Scalar>& colours, const std::vector<char>& control, double radius,
                const std::vector<Frustum>& frusta, bool with_axes) {
  img.setTo(cv::Scalar(250, 250, 250));
  cv::rectangle(img, cv::Rect(0, 0, img.cols, img.rows), cv::Scalar(200, 200, 200), 1);
  // Points far to near (painter's algorithm), then the control squares on top.
  std::vector<std::size_t> order(points.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::vector<double> depth(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) depth[i] = points[i].dot(p.view.e);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return depth[a] < depth[b]; });
  const int r16 = cvRound(radius * kOne);
  for (std::size_t i : order) {
    cv::Point q;
    if (p.fixed(points[i], q)) cv::circle(img, q, r16, colours[i], cv::FILLED, cv::LINE_AA, kShift);
  }
  const int half16 = cvRound((radius + 3) * kOne);
  for (std::size_t i = 0; i < points.size(); ++i) {
    cv::Point q;
    if (!control[i] || !p.fixed(points[i], q)) continue;
    cv::rectangle(img, q - cv::Point(half16, half16), q + cv::Point(half16, half16), cv::Scalar(0, 0, 0), 1, cv::LINE_AA,
                  kShift);
  }
  // Cameras.
  std::size_t outside = 0;
  for (const Frustum& f : frusta) {
    cv::Point a, c[4];
    bool ok = p.fixed(f.apex, a);
    for (int k = 0; k < 4; ++k) ok = ok && p.fixed(f.corners[static_cast<std::size_t>(k)], c[k]);
    if (!ok) {
      ++outside;
      continue;
    }
    for (int k = 0; k < 4; ++k) {
      cv::line(img, a, c[k], kCameraInk, 1, cv::LINE_AA, kShift);
      cv::line(img, c[k], c[(k + 1) % 4], k == 0 ? kImageTop : kCameraInk, k == 0 ? 2 : 1, cv::LINE_AA, kShift);
    }
    cv::circle(img, a, cvRound(2.5 * kOne), kCameraInk, cv::FILLED, cv::LINE_AA, kShift);
    if (frusta.size() <= 40) {
      const cv::Point2d at = p.px(f.apex);
      const int w = plot::text_size(f.name, 0.35).width;
      const int x = at.x + 5 + w < img.cols - 2 ? cvRound(at.x) + 5 : cvRound(at.x) - 5 - w;  // kept in the panel
      text(img, f.name, cv::Point(x, std::max(12, cvRound(at.y) - 5)), 0.35, kCameraInk);
    }
  }
  // Title; ticked axes in mm (a view along z), else the axis directions and a scale bar.
  text(img, p.view.title, cv::Point(10, 20), 0.5);
  if (with_axes) {
    plot::draw_axes(img, p.axes());
    return outside;
  }
  const cv::Point origin(45, img.rows - 40);
  const std::pair<Eigen::Vector3d, std::pair<const char*, cv::Scalar>> axes[3] = {
      {Eigen::Vector3d::UnitX(), {"x", cv::Scalar(0, 0, 210)}},
      {Eigen::Vector3d::UnitY(), {"y", cv::Scalar(0, 150, 0)}},
      {Eigen::Vector3d::UnitZ(), {"z", cv::Scalar(210, 0, 0)}}};
  for (const auto& [axis, style] : axes) {
    const cv::Point2d d(axis.dot(p.view.r) * 28, -axis.dot(p.view.u) * 28);
    const cv::Point tip = origin + cv::Point(cvRound(d.x), cvRound(d.y));
    if (std::hypot(d.x, d.y) > 4) {
      cv::arrowedLine(img, origin, tip, style.second, 2, cv::LINE_AA, 0, 0.25);
    } else {
      cv::circle(img, origin, 4, style.second, 2, cv::LINE_AA);  // pointing at the viewer
    }
    const cv::Point2d n = std::hypot(d.x, d.y) > 4 ? d * (1 / std::hypot(d.x, d.y)) : cv::Point2d(0.7, 0.7);
    text(img, style.first, tip + cv::Point(cvRound(n.x * 10) - 4, cvRound(n.y * 10) + 4), 0.45, style.second);
  }
  plot::draw_scale_bar(img, cv::Point(img.cols - 20, img.rows - 22), p.scale, img.cols / 5, p.unit);
  return outside;
}

}  // namespace

void validate(const PreviewOptions& o) {
  if (o.width_px < 400 || o.width_px > 8000) throw UsageError("--preview-width-px must be in 400..8000");
  if (o.colour_by != "rms" && o.colour_by != "sigma") throw UsageError("--preview-colour must be rms or sigma");
  if (!(o.elevation_deg >= 0 && o.elevation_deg <= 90)) throw UsageError("preview elevation must be in 0..90 degrees");
  if (!(o.frame_percentile >= 0 && o.frame_percentile < 0.5)) throw UsageError("preview frame percentile must be in [0, 0.5)");
  if (!(o.camera_frame_factor >= 0)) throw UsageError("preview camera frame factor must not be negative");
}

std::vector<std::uint8_t> render_preview_png(const PointCloud& cloud, const std::vector<Pose>& poses,
                                             const std::vector<Camera>& cameras, const PreviewOptions& o) {
  validate(o);
  if (cameras.empty() || (cameras.size() != 1 && cameras.size() != poses.size())) {
    throw UsageError("preview: " + std::to_string(cameras.size()) + " cameras for " + std::to_string(poses.size()) +
                     " poses (one per pose, or one for all)");
  }
  std::vector<Eigen::Vector3d> points;
  std::vector<std::size_t> index;  // into the cloud
  for (std::size_t i = 0; i < cloud.points_mm.size(); ++i) {
    if (cloud.points_mm[i].allFinite()) points.push_back(cloud.points_mm[i]), index.push_back(i);
  }
  if (points.empty()) throw GeometryError("nothing to preview: the point cloud is empty");
  const std::size_t n = points.size();
  const std::string unit = cloud.units == "mm" ? "mm" : "units";

  // Robust box of the points: per axis from the percentile to its complement.
  Eigen::Vector3d lo, hi;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> c(n);
    for (std::size_t i = 0; i < n; ++i) c[i] = points[i][a];
    lo[a] = quantile(c, o.frame_percentile);
    hi[a] = quantile(c, 1 - o.frame_percentile);
  }
  const Eigen::Vector3d pad = 0.05 * (hi - lo);  // the points beyond the percentiles near the edge
  lo -= pad, hi += pad;
  const Eigen::Vector3d mid = 0.5 * (lo + hi);
  const double diag = std::max((hi - lo).norm(), 1e-6);
  std::vector<Eigen::Vector3d> framing;
  for (int k = 0; k < 8; ++k) framing.emplace_back(k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z());
  const std::vector<Eigen::Vector3d> points_box = framing;

  // Frusta of the cameras near the scene, as deep as an eighth of the box diagonal, each by its
  // own camera's image size and K.
  const double depth = diag / 8;
  std::vector<Frustum> frusta;
  std::size_t far_cameras = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose& pose = poses[i];
    const Camera& camera = cameras[cameras.size() == 1 ? 0 : i];
    const double w = camera.image_width_px > 0 ? camera.image_width_px : 2 * camera.cx();
    const double h = camera.image_height_px > 0 ? camera.image_height_px : 2 * camera.cy();
    const Eigen::Matrix3d k_inv = camera.camera_matrix.inverse();
    const Eigen::Matrix3d world_from_cam = pose.rotation().transpose();
    Frustum f;
    f.name = pose.image.substr(0, pose.image.find_last_of('.'));
    f.name = f.name.substr(f.name.find_last_of('/') + 1);
    f.apex = pose.centre_mm();
    const Eigen::Vector2d uv[4] = {{0, 0}, {w, 0}, {w, h}, {0, h}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d ray = k_inv * Eigen::Vector3d(uv[k].x(), uv[k].y(), 1);  // z = 1
      f.corners[static_cast<std::size_t>(k)] = f.apex + world_from_cam * (ray * depth);
    }
    if (!f.apex.allFinite() || (f.apex - mid).norm() > o.camera_frame_factor * diag) {
      ++far_cameras;
      continue;
    }
    framing.push_back(f.apex);
    for (const auto& c : f.corners) framing.push_back(c);
    frusta.push_back(f);
  }

  // Colours from the quality property; its scale 0 .. a round number at the 95th percentile.
  const bool by_rms = o.colour_by == "rms";
  const PointProperty* quality = cloud.find(by_rms ? "reproj_rms_px" : "sigma_mm");
  const PointProperty* control_prop = cloud.find("control");
  std::vector<double> values;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = quality ? quality->values[index[i]] : std::nan("");
    if (std::isfinite(v)) values.push_back(v);
  }
  const double top = values.empty() ? 1 : quantile(values, 0.95);
  const double vmax = top > 0 ? plot::nice_ceil(top) : 1;
  const auto lut = viridis();
  std::vector<cv::Scalar> colours(n);
  std::vector<char> control(n, 0);
  std::size_t above = 0, missing = 0, controls = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = quality ? quality->values[index[i]] : std::nan("");
    if (!std::isfinite(v)) {
      colours[i] = kGreyPoint;
      ++missing;
    } else {
      above += v > vmax ? 1 : 0;
      const auto c = lut[static_cast<std::size_t>(std::lround(255 * std::clamp(v / vmax, 0.0, 1.0)))];
      colours[i] = cv::Scalar(c[0], c[1], c[2]);
    }
    control[i] = control_prop && control_prop->values[index[i]] != 0 ? 1 : 0;
    controls += static_cast<std::size_t>(control[i]);
  }

  // Layout: two panels, the colour bar at the right, two lines of text at the bottom.
  const int width = o.width_px, height = o.width_px / 2;
  const int bar_w = 120, legend_h = 48;
  const int panel_w = (width - bar_w) / 2, panel_h = height - legend_h;
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const double radius = std::clamp(0.22 * std::sqrt(static_cast<double>(panel_w) * panel_h / static_cast<double>(n)), 1.2, 4.0);
  const View views[2] = {oblique_view(o.azimuth_deg, o.elevation_deg), top_view()};
  std::size_t cut_cameras = 0;
  for (int k = 0; k < 2; ++k) {
    cv::Mat roi = img(cv::Rect(k * panel_w, 0, panel_w, panel_h));
    // The oblique view shows the whole scene, the top view the points in detail.
    // (The cameras are drawn in the oblique view only: the top view is framed on the points.)
    Panel panel = frame_panel(views[k], roi.size(), k == 0 ? framing : points_box, k == 1);
    panel.unit = unit;
    cut_cameras += draw_panel(roi, panel, points, colours, control, radius, k == 0 ? frusta : std::vector<Frustum>{}, k == 1);
  }

  // Colour bar.
  const int bx = 2 * panel_w + 20, by0 = 60, by1 = panel_h - 50, bw = 22;
  text(img, by_rms ? "reproj. RMS" : "sigma", cv::Point(bx - 8, 24), 0.45);
  text(img, by_rms ? "px" : unit, cv::Point(bx - 8, 44), 0.45);
  for (int y = by0; y <= by1; ++y) {
    const double t = static_cast<double>(by1 - y) / (by1 - by0);
    const auto c = lut[static_cast<std::size_t>(std::lround(255 * t))];
    cv::line(img, cv::Point(bx, y), cv::Point(bx + bw, y), cv::Scalar(c[0], c[1], c[2]), 1);
  }
  cv::rectangle(img, cv::Point(bx, by0), cv::Point(bx + bw, by1), kInk, 1);
  for (int k = 0; k <= 4; ++k) {
    const int y = by1 - (by1 - by0) * k / 4;
    cv::line(img, cv::Point(bx + bw, y), cv::Point(bx + bw + 5, y), kInk, 1);
    text(img, (k == 4 && above ? ">=" : "") + format_value(vmax * k / 4), cv::Point(bx + bw + 8, y + 5), 0.42);
  }
  if (missing) {
    cv::rectangle(img, cv::Point(bx, by1 + 18), cv::Point(bx + bw, by1 + 30), kGreyPoint, cv::FILLED);
    text(img, "none", cv::Point(bx + bw + 8, by1 + 30), 0.42);
  }

  // Two lines of text.
  std::ostringstream l1, l2;
  l1 << n << " points, " << controls << " control points (squares), " << frusta.size()
     << " cameras (frusta in the oblique view: apex at the centre, thick orange edge = top of the image)";
  if (far_cameras) l1 << "; " << far_cameras << " cameras far from the scene not drawn";
  if (cut_cameras) l1 << "; " << cut_cameras << " cameras across the view's edge not drawn";
  if (unit != "mm") l1 << "; ARBITRARY SCALE: no control points, scale bars or known poses, unit = first baseline";
  l2 << "colour: " << (by_rms ? "reprojection RMS per point, px" : "uncertainty sigma per point, " + unit) << ", scale 0 .. "
     << format_value(vmax) << " (95th percentile " << format_value(top) << "); " << above
     << " points above it at the top colour";
  if (missing) l2 << ", " << missing << " without a value in grey";
  text(img, l1.str(), cv::Point(10, height - legend_h + 18), 0.45);
  text(img, l2.str(), cv::Point(10, height - legend_h + 38), 0.45);

  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw GeometryError("PNG encoding failed");
  return png;
}

void write_preview(std::ostream& out, const Reconstruction& result, const PreviewOptions& options) {
  // Each registered image's own camera (in the order registered_poses gives them).
  std::vector<Camera> cameras;
  for (const SceneImage& im : result.scene.images) {
    if (im.registered) cameras.push_back(result.cameras.empty() ? result.camera : result.cameras.at(im.camera));
  }
  if (cameras.empty()) cameras.push_back(result.camera);
  const auto png = render_preview_png(make_point_cloud(result), registered_poses(result), cameras, options);
  out.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
}

}  // namespace photomill::triangulate
