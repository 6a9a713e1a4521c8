#include "formats/camera.hpp"

#include <cmath>
#include <cctype>
#include <sstream>

#include <opencv2/core.hpp>

#include "formats/error.hpp"
#include "formats/text.hpp"

namespace photomill {
namespace {

// A camera file's matrices are 3x3 and at most 14x1. Checking the declared sizes in the text
// before cv::FileStorage parses it keeps a hostile "rows: 1000000" from allocating gigabytes.
constexpr long kMaxDeclaredDim = 64;

void check_declared_sizes(const std::string& text, const std::string& source) {
  // Every "rows:" or "cols:" followed by an integer, wherever it is (a hostile file need not be
  // well-formed YAML for FileStorage to start allocating).
  for (const char* key : {"rows", "cols"}) {
    for (std::size_t pos = text.find(key); pos != std::string::npos; pos = text.find(key, pos + 4)) {
      std::size_t i = pos + 4;
      while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
      if (i >= text.size() || text[i] != ':') continue;
      ++i;
      while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
      const std::size_t start = i;
      if (i < text.size() && text[i] == '-') ++i;
      while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
      const std::string digits = text.substr(start, i - start);
      if (digits.empty() || digits == "-") continue;
      const bool too_long = digits.size() > 9;
      const long value = too_long ? kMaxDeclaredDim + 1 : std::stol(digits);
      if (value < 0 || value > kMaxDeclaredDim) {
        throw InputError(source, 0, "matrix declares " + std::string(key) + ": " + digits + ", not a camera file");
      }
    }
  }
}

cv::Mat read_matrix(const cv::FileNode& node, const char* key, const std::string& source) {
  if (node.empty() || node.isNone()) throw InputError(source, 0, std::string("missing key '") + key + "'");
  cv::Mat m;
  node >> m;
  if (m.empty()) throw InputError(source, 0, std::string("'") + key + "' is not an OpenCV matrix");
  m.convertTo(m, CV_64F);
  return m;
}

int read_int(const cv::FileNode& node, const char* key, const std::string& source) {
  if (node.empty() || node.isNone()) throw InputError(source, 0, std::string("missing key '") + key + "'");
  if (!node.isInt()) throw InputError(source, 0, std::string("'") + key + "' is not an integer");
  return static_cast<int>(node);
}

}  // namespace

void validate_camera(const Camera& c, const std::string& source) {
  if (c.image_width_px <= 0 || c.image_height_px <= 0 || c.image_width_px > 1'000'000 ||
      c.image_height_px > 1'000'000) {
    throw InputError(source, 0, "image size " + std::to_string(c.image_width_px) + "x" +
                                    std::to_string(c.image_height_px) + " is not plausible");
  }
  if (!c.camera_matrix.allFinite()) throw InputError(source, 0, "camera_matrix has a non-finite value");
  if (!(c.fx() > 0) || !(c.fy() > 0)) throw InputError(source, 0, "focal lengths fx, fy must be positive");
  if (c.camera_matrix(1, 0) != 0 || c.camera_matrix(2, 0) != 0 || c.camera_matrix(2, 1) != 0 ||
      c.camera_matrix(2, 2) != 1) {
    throw InputError(source, 0, "camera_matrix must be [fx s cx; 0 fy cy; 0 0 1]");
  }
  const std::size_t n = c.distortion.size();
  if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    throw InputError(source, 0, "distortion_coefficients has " + std::to_string(n) +
                                    " values; OpenCV uses 4, 5, 8, 12 or 14");
  }
  for (double d : c.distortion) {
    if (!std::isfinite(d)) throw InputError(source, 0, "distortion_coefficients has a non-finite value");
  }
  if (c.avg_reprojection_error_px && !(std::isfinite(*c.avg_reprojection_error_px) && *c.avg_reprojection_error_px >= 0)) {
    throw InputError(source, 0, "avg_reprojection_error must be a non-negative number");
  }
}

Camera read_camera_yaml(std::istream& in, const std::string& source, CameraYamlLimits limits) {
  std::string text;
  {
    char buf[4096];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) {
      text.append(buf, static_cast<std::size_t>(in.gcount()));
      if (text.size() > limits.max_bytes) {
        throw InputError(source, 0, "larger than " + std::to_string(limits.max_bytes) + " bytes, not a camera file");
      }
      if (!in) break;
    }
  }
  if (trim(text).empty()) throw InputError(source, 0, "empty input: expected an OpenCV camera YAML file");
  if (text.find('\0') != std::string::npos) throw InputError(source, 0, "binary data, not a camera YAML file");
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
  // OpenCV's YAML parser insists on the "%YAML" directive; accept files without one.
  if (text.rfind("%YAML", 0) != 0) text = "%YAML:1.0\n---\n" + text;
  check_declared_sizes(text, source);

  Camera c;
  try {
    cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
    if (!fs.isOpened()) throw InputError(source, 0, "not a readable OpenCV YAML file");
    c.image_width_px = read_int(fs["image_width"], "image_width", source);
    c.image_height_px = read_int(fs["image_height"], "image_height", source);
    const cv::Mat k = read_matrix(fs["camera_matrix"], "camera_matrix", source);
    if (k.rows != 3 || k.cols != 3) throw InputError(source, 0, "camera_matrix must be 3x3");
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) c.camera_matrix(r, col) = k.at<double>(r, col);
    }
    const cv::FileNode dn = fs["distortion_coefficients"];
    if (!dn.empty() && !dn.isNone()) {
      const cv::Mat d = read_matrix(dn, "distortion_coefficients", source);
      if (d.rows != 1 && d.cols != 1) throw InputError(source, 0, "distortion_coefficients must be a vector");
      c.distortion.assign(d.begin<double>(), d.end<double>());
    }
    const cv::FileNode e = fs["avg_reprojection_error"];
    if (!e.empty() && !e.isNone()) {
      if (!e.isReal() && !e.isInt()) throw InputError(source, 0, "avg_reprojection_error is not a number");
      c.avg_reprojection_error_px = static_cast<double>(e);
    }
  } catch (const cv::Exception& e) {
    // OpenCV's message is multi-line with its own source location; keep the first useful part.
    std::string msg = e.err.empty() ? e.what() : e.err;
    if (const auto nl = msg.find('\n'); nl != std::string::npos) msg.resize(nl);
    throw InputError(source, 0, "not a valid OpenCV YAML camera file: " + msg);
  }
  validate_camera(c, source);
  return c;
}

void write_camera_yaml(std::ostream& out, const Camera& camera) {
  validate_camera(camera, "camera to write");
  // Written by hand rather than through cv::FileStorage so numbers round-trip exactly
  // (FileStorage prints 16 significant digits); the layout is FileStorage's, so OpenCV reads it.
  auto matrix = [](const std::string& key, int rows, int cols, const std::vector<double>& data) {
    std::string s = key + ": !!opencv-matrix\n   rows: " + std::to_string(rows) + "\n   cols: " +
                    std::to_string(cols) + "\n   dt: d\n   data: [ ";
    for (std::size_t i = 0; i < data.size(); ++i) {
      if (i) s += ", ";
      std::string v = format_double(data[i]);
      // YAML needs a '.' or exponent to read a real; "1" would be an int (OpenCV accepts both,
      // but keep the file unambiguous for other YAML readers).
      if (v.find_first_of(".eEn") == std::string::npos) v += ".";
      s += v;
    }
    return s + " ]\n";
  };
  std::vector<double> k(9);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) k[static_cast<std::size_t>(r * 3 + c)] = camera.camera_matrix(r, c);
  }
  std::string text = "%YAML:1.0\n---\n";
  text += "image_width: " + std::to_string(camera.image_width_px) + "\n";
  text += "image_height: " + std::to_string(camera.image_height_px) + "\n";
  text += matrix("camera_matrix", 3, 3, k);
  if (!camera.distortion.empty()) {
    text += matrix("distortion_coefficients", static_cast<int>(camera.distortion.size()), 1, camera.distortion);
  }
  if (camera.avg_reprojection_error_px) {
    std::string v = format_double(*camera.avg_reprojection_error_px);
    if (v.find_first_of(".eE") == std::string::npos) v += ".";
    text += "avg_reprojection_error: " + v + "\n";
  }
  out << text;
}

}  // namespace photomill
