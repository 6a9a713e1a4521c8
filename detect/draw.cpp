// Drawings of what detect found (see draw.hpp).
#include "detect/draw.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "formats/plot.hpp"
#include "formats/tool.hpp"

namespace photomill::detect {

namespace fs = std::filesystem;

namespace {

constexpr int kShift = 4;  // fixed-point bits of drawing coordinates (1/16 px)
constexpr double kOne = 1 << kShift;
const int kFont = cv::FONT_HERSHEY_SIMPLEX;

// BGR colours.
const cv::Scalar kMarker(0, 220, 0);        // kept marker outline
const cv::Scalar kRejected(0, 140, 255);    // marker dropped by photomill (orange)
const cv::Scalar kCandidate(220, 80, 170);  // quadrilateral OpenCV could not identify (purple)
const cv::Scalar kFeature(255, 230, 0);     // SIFT keypoint (cyan)
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
// Corners 0..3 (TL, TR, BR, BL of the printed marker): red, yellow, blue, magenta.
const cv::Scalar kCorner[4] = {{40, 40, 255}, {0, 230, 255}, {255, 120, 0}, {255, 0, 255}};
// Board rows, cycled.
const cv::Scalar kRow[7] = {{40, 40, 255}, {0, 140, 255}, {0, 230, 255}, {0, 220, 0},
                            {255, 230, 0}, {255, 120, 0}, {255, 0, 255}};

// The dimmed grey photo at the output size, and the mapping of photo pixels onto it.
struct Canvas {
  cv::Mat img;
  double sx = 1, sy = 1;  // output px per photo px
  double unit = 1;        // size of marks and text: 1 on a 1600 px wide drawing

  // Photo pixel (OpenCV convention: pixel centres at integers) -> output pixel, same convention
  // (cv::resize maps output x' to photo (x' + 1/2) / s - 1/2).
  cv::Point2d map(const Eigen::Vector2d& p) const { return {(p.x() + 0.5) * sx - 0.5, (p.y() + 0.5) * sy - 0.5}; }
  static cv::Point fixed(const cv::Point2d& p) { return {cvRound(p.x * kOne), cvRound(p.y * kOne)}; }
  cv::Point at(const Eigen::Vector2d& p) const { return fixed(map(p)); }
  int thick(double w) const { return std::max(1, static_cast<int>(std::lround(w * unit))); }
};

Canvas make_canvas(const cv::Mat& grey, const DrawOptions& o) {
  CV_Assert(grey.type() == CV_8UC1 && !grey.empty());
  Canvas c;
  cv::Mat scaled = grey;
  if (o.max_width_px > 0 && grey.cols > o.max_width_px) {
    const int h = std::max(1, static_cast<int>(std::lround(grey.rows * static_cast<double>(o.max_width_px) / grey.cols)));
    cv::resize(grey, scaled, cv::Size(o.max_width_px, h), 0, 0, cv::INTER_AREA);
  }
  c.sx = static_cast<double>(scaled.cols) / grey.cols;
  c.sy = static_cast<double>(scaled.rows) / grey.rows;
  c.unit = std::max(0.75, scaled.cols / 1600.0);
  // Dimmed to 70..210 so that coloured marks stand out on black and on white.
  cv::Mat dim;
  scaled.convertTo(dim, CV_8U, 140.0 / 255.0, 70);
  cv::cvtColor(dim, c.img, cv::COLOR_GRAY2BGR);
  return c;
}

// Text centred on `centre` (output px), coloured, with a black outline so it reads on any ground.
void label(Canvas& c, const std::string& text, const cv::Point2d& centre, double size, const cv::Scalar& colour) {
  const double fs = size * c.unit;
  const int t = c.thick(1);
  int base = 0;
  const cv::Size sz = cv::getTextSize(text, kFont, fs, t, &base);
  const cv::Point org(cvRound(centre.x - sz.width / 2.0), cvRound(centre.y + sz.height / 2.0));
  cv::putText(c.img, text, org, kFont, fs, kBlack, t + 2, cv::LINE_AA);
  cv::putText(c.img, text, org, kFont, fs, colour, t, cv::LINE_AA);
}

void outline(Canvas& c, const std::array<Eigen::Vector2d, 4>& q, const cv::Scalar& colour, double width) {
  std::vector<cv::Point> poly;
  for (const auto& p : q) poly.push_back(c.at(p));
  cv::polylines(c.img, poly, true, colour, c.thick(width), cv::LINE_AA, kShift);
}

cv::Point2d centre_of(const Canvas& c, const std::array<Eigen::Vector2d, 4>& q) {
  return c.map(0.25 * (q[0] + q[1] + q[2] + q[3]));
}

// Lines of coloured text segments in a dark box at the top left.
using Segments = std::vector<std::pair<std::string, cv::Scalar>>;
void legend(Canvas& c, const std::vector<Segments>& lines) {
  const double fs = 0.5 * c.unit;
  const int t = c.thick(1);
  const int pad = c.thick(6);
  int base = 0;
  const int line_h = cv::getTextSize("Ag", kFont, fs, t, &base).height + base + c.thick(6);
  int width = 0;
  for (const auto& line : lines) {
    int w = 0;
    for (const auto& [text, colour] : line) w += cv::getTextSize(text, kFont, fs, t, &base).width;
    width = std::max(width, w);
  }
  const cv::Rect box = cv::Rect(0, 0, width + 2 * pad, static_cast<int>(lines.size()) * line_h + 2 * pad) &
                       cv::Rect(0, 0, c.img.cols, c.img.rows);
  cv::Mat roi = c.img(box);
  roi.convertTo(roi, -1, 0.25, 0);  // darken what lies under the box
  int y = pad + line_h - base - c.thick(3);
  for (const auto& line : lines) {
    int x = pad;
    for (const auto& [text, colour] : line) {
      cv::putText(c.img, text, cv::Point(x, y), kFont, fs, colour, t, cv::LINE_AA);
      x += cv::getTextSize(text, kFont, fs, t, &base).width;
    }
    y += line_h;
  }
}

std::string image_name(const std::string& image) { return fs::path(image).filename().string(); }

// "<lead><n><what>" built by appending: GCC 12's -Wrestrict misfires on `" " + std::string&&`
// (and CI builds with -Werror).
std::string count_text(const char* lead, std::size_t n, const char* what) {
  std::string s(lead);
  s += std::to_string(n);
  s += what;
  return s;
}

// Photo-pixel rulers (issue 27: a scale and its unit on every picture): ticks along the bottom
// (u px) and right (v px) edges at round steps, numbered, "u px" / "v px" at their ends.
void rulers(Canvas& c, int photo_w, int photo_h) {
  const int tick = c.thick(10), t = c.thick(1);
  const double fs = 0.4;
  const auto mark = [&](cv::Point a, cv::Point b) {
    cv::line(c.img, a, b, kBlack, t + 2, cv::LINE_AA);
    cv::line(c.img, a, b, kWhite, t, cv::LINE_AA);
  };
  const int bottom = c.img.rows - 1, right = c.img.cols - 1;
  for (double u : plot::ticks(0, photo_w - 1, std::max(2, c.img.cols / 200))) {
    const int x = cvRound(c.map({u, 0}).x);
    mark({x, bottom}, {x, bottom - tick});
    if (u > 0) label(c, plot::number(u), cv::Point2d(x, bottom - tick - 10 * c.unit), fs, kWhite);
  }
  for (double v : plot::ticks(0, photo_h - 1, std::max(2, c.img.rows / 150))) {
    const int y = cvRound(c.map({0, v}).y);
    mark({right, y}, {right - tick, y});
    if (v > 0) {
      const std::string n = plot::number(v);
      label(c, n, cv::Point2d(right - tick - (6 + 4.5 * static_cast<double>(n.size())) * c.unit, y), fs, kWhite);
    }
  }
  label(c, "u px", cv::Point2d(24 * c.unit, bottom - tick - 10 * c.unit), fs, kWhite);
  label(c, "v px", cv::Point2d(right - tick - 24 * c.unit, 12 * c.unit), fs, kWhite);
}

}  // namespace

void validate(const DrawOptions& o) {
  if (o.dir == "-") throw UsageError("--draw takes a folder for the pictures (they never go to stdout)");
  if (o.format != "jpg" && o.format != "png") throw UsageError("--draw-format must be jpg or png");
  if (o.max_width_px < 0) throw UsageError("--draw-max-width-px must be 0 (full size) or positive");
  if (o.max_width_px > 0 && o.max_width_px < 100) throw UsageError("--draw-max-width-px must be at least 100");
  if (o.jpeg_quality < 1 || o.jpeg_quality > 100) throw UsageError("JPEG quality must be in 1..100");
}

cv::Mat draw_photo(const cv::Mat& grey, const MarkerDetection* markers, const FeatureSet* features,
                   const DrawOptions& o) {
  Canvas c = make_canvas(grey, o);
  // Bottom to top: features, unidentified quadrilaterals, dropped markers, markers.
  if (features) {
    const double lo = 1.5 * c.unit, hi = 6 * c.unit;
    for (const Keypoint& k : features->keypoints) {
      const double r = std::clamp(0.5 * k.size_px * c.sx, lo, hi);
      cv::circle(c.img, c.at({k.x_px, k.y_px}), cvRound(r * kOne), kFeature, 1, cv::LINE_AA, kShift);
    }
  }
  if (markers) {
    for (const auto& q : markers->candidates) outline(c, q, kCandidate, 1);
    for (const RejectedMarker& r : markers->rejected) {
      outline(c, r.corners, kRejected, 2);
      const cv::Point2d m = centre_of(c, r.corners);
      label(c, std::to_string(r.marker_id) + " x", m, 0.6, kRejected);
      std::string why = r.reason.size() > 48 ? r.reason.substr(0, 45) + "..." : r.reason;
      label(c, why, m + cv::Point2d(0, 18 * c.unit), 0.4, kRejected);
    }
    for (std::size_t k = 0; k < markers->marker_ids.size(); ++k) {
      const auto& q = markers->corners[k];
      outline(c, q, kMarker, 2);
      const cv::Point2d m = centre_of(c, q);
      for (int i = 0; i < 4; ++i) {
        const cv::Point2d p = c.map(q[i]);
        cv::circle(c.img, Canvas::fixed(p), cvRound(3 * c.unit * kOne), kCorner[i], cv::FILLED, cv::LINE_AA, kShift);
        cv::Point2d out = p - m;
        const double n = std::hypot(out.x, out.y);
        out = n > 0 ? out * (1 / n) : cv::Point2d(0, -1);
        label(c, std::to_string(i), p + out * (11 * c.unit), 0.45, kCorner[i]);
      }
      label(c, std::to_string(markers->marker_ids[k]), m, 0.65, kWhite);
    }
  }
  const std::string name = image_name(markers ? markers->image : features ? features->image : "");
  std::vector<Segments> lines;
  Segments first{{name + ":", kWhite}};
  if (markers) {
    first.push_back({count_text(" ", markers->marker_ids.size(), " markers (id at centre)"), kMarker});
    first.push_back({count_text(", ", markers->rejected.size(), " dropped"), kRejected});
    first.push_back({count_text(", ", markers->candidates.size(), " unidentified"), kCandidate});
  }
  if (features) first.push_back({count_text(markers ? ", " : " ", features->keypoints.size(), " features"), kFeature});
  lines.push_back(first);
  if (markers) {
    lines.push_back({{"corners: ", kWhite}, {"0 ", kCorner[0]}, {"1 ", kCorner[1]}, {"2 ", kCorner[2]}, {"3", kCorner[3]},
                     {" (top-left, top-right, bottom-right, bottom-left of the printed marker)", kWhite}});
  }
  rulers(c, grey.cols, grey.rows);
  legend(c, lines);
  return c.img;
}

cv::Mat draw_board(const cv::Mat& grey, const ImageDetection& d, const BoardSpec& spec, const DrawOptions& o) {
  Canvas c = make_canvas(grey, o);
  const long row_len = std::max(1, spec.kind == BoardKind::Chessboard ? spec.cols : spec.cols - 1);
  std::map<PointId, Eigen::Vector2d> at;
  for (const Observation& ob : d.observations) at[ob.point_id] = {ob.u_px, ob.v_px};
  for (const auto& [id, uv] : at) {
    const auto next = at.find(id + 1);
    if (next != at.end() && (id + 1) % row_len != 0) {
      cv::line(c.img, c.at(uv), c.at(next->second), kRow[(id / row_len) % 7], c.thick(1.5), cv::LINE_AA, kShift);
    }
  }
  for (const auto& [id, uv] : at) {
    const cv::Scalar& colour = kRow[(id / row_len) % 7];
    const cv::Point2d p = c.map(uv);
    cv::circle(c.img, Canvas::fixed(p), cvRound(3.5 * c.unit * kOne), colour, cv::FILLED, cv::LINE_AA, kShift);
    label(c, std::to_string(id), p + cv::Point2d(0, -12 * c.unit), 0.4, colour);
  }
  const std::string kind = spec.kind == BoardKind::Chessboard ? "chessboard " : "ChArUco ";
  ImageDetection named = d;
  named.image = image_name(d.image);
  rulers(c, grey.cols, grey.rows);
  legend(c, {{{describe(named), d.found ? kWhite : kRejected}},
             {{kind + std::to_string(spec.cols) + "x" + std::to_string(spec.rows) +
                   ": corner ids row-major, one colour per row",
               kWhite}}});
  return c.img;
}

std::vector<std::uint8_t> encode_drawing(const cv::Mat& bgr, const DrawOptions& o) {
  std::vector<std::uint8_t> bytes;
  const bool ok = o.format == "png" ? cv::imencode(".png", bgr, bytes)
                                    : cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, o.jpeg_quality});
  if (!ok) throw GeometryError("cannot encode a drawing as " + o.format);
  return bytes;
}

DrawingFiles::DrawingFiles(const DrawOptions& options, const std::vector<std::string>& images) : options_(options) {
  validate(options_);
  std::map<std::string, std::string> by_name;
  for (const auto& image : images) {
    // The photo's stem and the drawing's own extension: part_05.jpg -> part_05.jpg (issue 27:
    // not part_05.jpg.jpg); two photos of one stem (a.jpg, a.png) are refused below.
    const std::string name = fs::path(image).stem().string() + "." + options_.format;
    const auto [it, fresh] = by_name.emplace(name, image);
    if (!fresh && it->second != image) {
      throw UsageError("--draw: images '" + it->second + "' and '" + image + "' would both write " + name);
    }
    paths_[image] = fs::path(options_.dir) / name;
  }
  std::error_code ec;
  fs::create_directories(options_.dir, ec);
  if (!fs::is_directory(options_.dir)) throw InputError(options_.dir, 0, "cannot create the drawings folder");
}

void DrawingFiles::write(const std::string& image, const cv::Mat& bgr) {
  const auto bytes = encode_drawing(bgr, options_);
  const fs::path& path = paths_.at(image);
  tool::OutputFile out(path.string());
  out.stream().write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  out.commit();
}

}  // namespace photomill::detect
