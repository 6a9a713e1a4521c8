#include "formats/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <functional>
#include <map>
#include <set>
#include <optional>
#include <string_view>

#include <Eigen/LU>  // determinant()

#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"

namespace photomill {
namespace {

// The camera file is read by a strict parser of the YAML subset that OpenCV's FileStorage writes
// (and its sample calibration files use), not by cv::FileStorage itself: OpenCV 4.6's YAML
// parser loops forever on some 20-byte inputs (" L:0\n%m--\ni", "[i{:&,|]]{\n->", found by
// fuzzing) and allocates whatever rows x cols a matrix declares before looking at its data (a
// non-numeric "cols" reads as INT_MAX: 48 GB). The subset:
//   [%YAML:1.x]  [---]                   directive and document start, both optional
//   key: scalar                          top-level entries at column 0, each key once
//   key: !!opencv-matrix                 followed by indented "rows: R", "cols: C", "dt: d"
//      rows: 3 ...                       and "data: [ v, v, ... ]" (the list may continue on
//      data: [ 1., 0.,                   further indented lines)
//          0. ]
//   # comments, blank lines; "..." ends the document
// Entries this reader does not use (nframes, flags, per_view_reprojection_errors...) are skipped
// with their indented lines, unparsed. Everything else is refused with its line number.

// A camera file's matrices are 3x3 and at most 14x1.
constexpr int kMaxMatrixDim = 64;

struct Line {
  std::size_t number;     // 1-based
  std::string_view text;  // without the line end
};

std::vector<Line> lines_of(const std::string& text) {
  std::vector<Line> lines;
  std::size_t number = 1;
  for (std::size_t pos = 0; pos < text.size(); ++number) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line = std::string_view(text).substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);  // CRLF line ends
    lines.push_back({number, line});
    pos = end + 1;
  }
  return lines;
}

bool blank_or_comment(std::string_view line) {
  const std::string_view t = trim(line);
  return t.empty() || t.front() == '#';
}

bool indented(std::string_view line) { return !line.empty() && (line.front() == ' ' || line.front() == '\t'); }

// A value less a trailing " # comment" (a '#' inside double quotes is kept).
std::string_view strip_comment(std::string_view v) {
  bool quoted = false;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] == '"') quoted = !quoted;
    if (v[i] == '#' && !quoted && (i == 0 || v[i - 1] == ' ' || v[i - 1] == '\t')) return trim(v.substr(0, i));
  }
  return trim(v);
}

bool is_key(std::string_view k) {
  if (k.empty() || k.size() > 256) return false;
  for (char ch : k) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' || ch == '-';
    if (!ok) return false;
  }
  return true;
}

struct KeyValue {
  std::string_view key;
  std::string_view value;  // trimmed, comment removed
};

// "key: value" or "key:" (after any indentation), else nullopt.
std::optional<KeyValue> key_value(std::string_view line) {
  const std::string_view t = trim(line);
  const auto colon = t.find(':');
  if (colon == std::string_view::npos) return std::nullopt;
  const std::string_view key = t.substr(0, colon);
  if (!is_key(key)) return std::nullopt;
  const std::string_view rest = t.substr(colon + 1);
  if (!rest.empty() && rest.front() != ' ' && rest.front() != '\t') return std::nullopt;
  return KeyValue{key, strip_comment(rest)};
}

struct Entry {
  std::size_t line = 0;
  std::string_view value;
  std::vector<Line> block;  // the indented lines that follow
};

// YAML's spellings of the non-finite reals, which OpenCV writes.
std::optional<double> yaml_special(std::string_view v) {
  if (v == ".nan" || v == ".NaN" || v == ".NAN") return std::numeric_limits<double>::quiet_NaN();
  if (v == ".inf" || v == ".Inf" || v == ".INF" || v == "+.inf") return std::numeric_limits<double>::infinity();
  if (v == "-.inf" || v == "-.Inf" || v == "-.INF") return -std::numeric_limits<double>::infinity();
  return std::nullopt;
}

class CameraYaml {
public:
  // `kind` names the file in errors ("camera", "rig").
  CameraYaml(const std::string&& text, const std::string& source, std::string kind = "camera") = delete;
  CameraYaml(const std::string& text, const std::string& source, std::string kind = "camera")
      : source_(source), kind_(std::move(kind)) {
    parse(lines_of(text));
  }

  const Entry* find(const std::string& key) const {
    const auto it = entries_.find(key);
    return it == entries_.end() ? nullptr : &it->second;
  }

  const Entry& require(const std::string& key) const {
    const Entry* e = find(key);
    if (e == nullptr) throw InputError(source_, 0, "missing key '" + key + "'");
    return *e;
  }

  int integer(const std::string& key) const {
    const Entry& e = require(key);
    scalar_only(e, key);
    const auto v = parse_int(e.value);
    if (!v || *v < std::numeric_limits<int>::min() || *v > std::numeric_limits<int>::max()) {
      throw InputError(source_, e.line, "'" + key + "' is not an integer: '" + std::string(e.value) + "'");
    }
    return static_cast<int>(*v);
  }

  double real(const Entry& e, const std::string& key) const {
    scalar_only(e, key);
    if (const auto special = yaml_special(e.value)) return *special;
    const auto v = parse_double(e.value);
    if (!v) throw InputError(source_, e.line, "'" + key + "' is not a number: '" + std::string(e.value) + "'");
    return *v;
  }

  // A string scalar: "double" or 'single' quoted (without quotes, backslashes inside) or plain.
  std::string text(const std::string& key) const {
    const Entry& e = require(key);
    scalar_only(e, key);
    std::string_view v = e.value;
    if (!v.empty() && (v.front() == '"' || v.front() == '\'')) {
      if (v.size() < 2 || v.back() != v.front() ||
          v.substr(1, v.size() - 2).find_first_of("\\\"'") != std::string_view::npos) {
        throw InputError(source_, e.line, "'" + key + "' is not a plain quoted string: " + std::string(v));
      }
      v = v.substr(1, v.size() - 2);
    }
    return std::string(v);
  }

  // Every top-level key with its line.
  std::vector<std::pair<std::string, std::size_t>> keys() const {
    std::vector<std::pair<std::string, std::size_t>> out;
    for (const auto& [k, e] : entries_) out.emplace_back(k, e.line);
    return out;
  }

  struct Matrix {
    int rows = 0;
    int cols = 0;
    std::vector<double> data;  // row-major
  };

  // An !!opencv-matrix entry. The declared sizes are checked against the limits and against the
  // number of values actually listed before anything is sized by them.
  Matrix matrix(const std::string& key) const {
    const Entry& e = require(key);
    const std::string name = "'" + key + "'";
    if (e.value != "!!opencv-matrix") {
      throw InputError(source_, e.line, name + " is not an !!opencv-matrix (rows, cols, dt, data)");
    }
    std::map<std::string_view, std::size_t> seen;  // field -> line
    std::optional<int> rows, cols;
    std::optional<std::size_t> data_line;
    std::vector<double> data;
    for (std::size_t i = 0; i < e.block.size(); ++i) {
      const Line& l = e.block[i];
      if (blank_or_comment(l.text)) continue;
      const auto kv = key_value(l.text);
      if (!kv) throw InputError(source_, l.number, name + ": expected 'rows:', 'cols:', 'dt:' or 'data:'");
      if (!seen.emplace(kv->key, l.number).second) {
        throw InputError(source_, l.number, name + " has '" + std::string(kv->key) + "' twice");
      }
      if (kv->key == "rows" || kv->key == "cols") {
        const auto v = parse_int(kv->value);
        if (!v) {
          throw InputError(source_, l.number, name + " " + std::string(kv->key) + ": '" + std::string(kv->value) +
                                                  "' is not an integer");
        }
        if (*v < 1 || *v > kMaxMatrixDim) {
          throw InputError(source_, l.number, name + " matrix declares " + std::string(kv->key) + ": " +
                                                  std::string(kv->value) + "; a camera file's matrices have 1 to " +
                                                  std::to_string(kMaxMatrixDim));
        }
        (kv->key == "rows" ? rows : cols) = static_cast<int>(*v);
      } else if (kv->key == "dt") {
        std::string_view dt = kv->value;
        if (dt.size() >= 2 && dt.front() == '"' && dt.back() == '"') dt = dt.substr(1, dt.size() - 2);
        // One channel of a number type (OpenCV's format letters); "3d" would be three channels.
        if (dt.size() != 1 || std::string_view("ucwsifd").find(dt.front()) == std::string_view::npos) {
          throw InputError(source_, l.number, name + " dt: '" + std::string(dt) +
                                                  "' is not a one-channel OpenCV number type (d, f, i...)");
        }
      } else if (kv->key == "data") {
        data_line = l.number;
        // The list, possibly continued on the following block lines, up to its ']'.
        std::string list(kv->value);
        for (bool closed = list.find(']') != std::string::npos; !closed && i + 1 < e.block.size();) {
          const std::string_view more = strip_comment(e.block[++i].text);
          closed = more.find(']') != std::string_view::npos;
          list += ' ';
          list += more;
        }
        const std::string_view t = trim(list);
        if (t.size() < 2 || t.front() != '[' || t.back() != ']' || t.find(']') != t.size() - 1 ||
            t.find('[', 1) != std::string_view::npos) {
          throw InputError(source_, l.number, name + " data is not a list [ v, v, ... ]");
        }
        const std::string_view inner = trim(t.substr(1, t.size() - 2));
        constexpr std::size_t kMaxValues = static_cast<std::size_t>(kMaxMatrixDim) * kMaxMatrixDim;
        if (static_cast<std::size_t>(std::count(inner.begin(), inner.end(), ',')) >= kMaxValues) {
          throw InputError(source_, l.number, name + " data has more than " + std::to_string(kMaxValues) + " values");
        }
        if (!inner.empty()) {
          for (std::string_view field : split_fields(inner, ',')) {
            if (const auto special = yaml_special(field)) {
              data.push_back(*special);
              continue;
            }
            const auto v = parse_double(field);
            if (!v) {
              throw InputError(source_, l.number, name + " data has a value that is not a number: '" +
                                                      std::string(field) + "'");
            }
            data.push_back(*v);
          }
        }
      } else {
        throw InputError(source_, l.number, name + " has an unknown field '" + std::string(kv->key) + "'");
      }
    }
    for (const char* field : {"rows", "cols", "dt", "data"}) {
      if (!seen.count(field)) throw InputError(source_, e.line, name + " has no '" + field + "'");
    }
    const std::size_t expected = static_cast<std::size_t>(*rows) * static_cast<std::size_t>(*cols);
    if (data.size() != expected) {
      throw InputError(source_, *data_line, name + " data has " + std::to_string(data.size()) +
                                                " values; rows x cols = " + std::to_string(*rows) + " x " +
                                                std::to_string(*cols) + " needs " + std::to_string(expected));
    }
    return {*rows, *cols, std::move(data)};
  }

private:
  void scalar_only(const Entry& e, const std::string& key) const {
    for (const Line& l : e.block) {
      if (!blank_or_comment(l.text)) throw InputError(source_, l.number, "'" + key + "' must be a single value");
    }
  }

  void parse(const std::vector<Line>& lines) {
    std::size_t i = 0;
    const auto skip_blank = [&] {
      while (i < lines.size() && blank_or_comment(lines[i].text)) ++i;
    };
    skip_blank();
    if (i < lines.size() && lines[i].text.rfind("%", 0) == 0) {
      const std::string_view d = trim(lines[i].text);
      if (d.rfind("%YAML:1.", 0) != 0 && d.rfind("%YAML 1.", 0) != 0) {
        throw InputError(source_, lines[i].number, "not an OpenCV " + kind_ + " YAML file: unsupported directive '" +
                                                       std::string(d.substr(0, 40)) + "'");
      }
      ++i;
      skip_blank();
    }
    if (i < lines.size() && trim(lines[i].text) == "---") ++i;
    for (; i < lines.size();) {
      const Line& l = lines[i];
      if (blank_or_comment(l.text)) {
        ++i;
        continue;
      }
      if (trim(l.text) == "...") break;  // end of the document
      const auto kv = indented(l.text) ? std::nullopt : key_value(l.text);
      if (!kv) {
        throw InputError(source_, l.number, "not an OpenCV " + kind_ + " YAML file: expected 'key: value' at the start of the line");
      }
      Entry e{l.number, kv->value, {}};
      for (++i; i < lines.size() && (indented(lines[i].text) || blank_or_comment(lines[i].text)); ++i) {
        e.block.push_back(lines[i]);
      }
      if (!entries_.emplace(std::string(kv->key), std::move(e)).second) {
        throw InputError(source_, l.number, "duplicate key '" + std::string(kv->key) + "'");
      }
    }
    if (entries_.empty()) throw InputError(source_, 0, "not an OpenCV " + kind_ + " YAML file: no 'key: value' entries");
  }

  std::string source_;
  std::string kind_;
  std::map<std::string, Entry> entries_;
};

}  // namespace

void validate_camera(const Camera& c, const std::string& source) {
  if (c.image_width_px <= 0 || c.image_height_px <= 0 || c.image_width_px > 1'000'000 ||
      c.image_height_px > 1'000'000) {
    throw InputError(source, 0, "image size " + std::to_string(c.image_width_px) + "x" +
                                    std::to_string(c.image_height_px) + " is not plausible");
  }
  if (!c.camera_matrix.allFinite()) throw InputError(source, 0, "camera_matrix has a non-finite value");
  if (!(c.fx() > 0) || !(c.fy() > 0)) throw InputError(source, 0, "focal lengths fx, fy must be positive");
  // A pinhole's field of view across a side of n px is 2 atan(n / (2 f)): between
  // kMinFieldOfViewDeg and kMaxFieldOfViewDeg the focal length lies in [n / (2 tan(max / 2)),
  // n / (2 tan(min / 2))] (issue #25: fx = 1e308 was accepted and triangulate blamed the tracks).
  const auto plausible_focal = [&](double f, int side_px, const char* name) {
    const double deg = std::acos(-1.0) / 180;
    const double most = side_px / (2 * std::tan(kMinFieldOfViewDeg / 2 * deg));
    const double least = side_px / (2 * std::tan(kMaxFieldOfViewDeg / 2 * deg));
    if (f < least || f > most) {
      throw InputError(source, 0, std::string(name) + " = " + format_double(f) + " px is not plausible for a side of " +
                                      std::to_string(side_px) + " px (a field of view outside " +
                                      format_double(kMinFieldOfViewDeg) + "-" + format_double(kMaxFieldOfViewDeg) +
                                      " degrees)");
    }
  };
  plausible_focal(c.fx(), c.image_width_px, "fx");
  plausible_focal(c.fy(), c.image_height_px, "fy");
  const double cx = c.camera_matrix(0, 2), cy = c.camera_matrix(1, 2);
  if (cx < -c.image_width_px || cx > 2.0 * c.image_width_px || cy < -c.image_height_px || cy > 2.0 * c.image_height_px) {
    throw InputError(source, 0, "principal point (" + format_double(cx) + ", " + format_double(cy) +
                                    ") px lies more than an image size outside the " + std::to_string(c.image_width_px) +
                                    "x" + std::to_string(c.image_height_px) + " image");
  }
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

namespace {

// The whole input, refused before parsing if it is larger than a camera file can be, empty or binary.
std::string read_small_text(std::istream& in, const std::string& source, const CameraYamlLimits& limits,
                            const std::string& kind) {
  std::string text;
  char buf[4096];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, static_cast<std::size_t>(in.gcount()));
    if (text.size() > limits.max_bytes) {
      throw InputError(source, 0, "larger than " + std::to_string(limits.max_bytes) + " bytes, not a " + kind + " file");
    }
    if (!in) break;
  }
  if (trim(text).empty()) throw InputError(source, 0, "empty input: expected an OpenCV " + kind + " YAML file");
  if (text.find('\0') != std::string::npos) throw InputError(source, 0, "binary data, not a " + kind + " YAML file");
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
  return text;
}

// The camera whose keys are `prefix` + OpenCV's names (image_width, camera_matrix, ...).
Camera camera_from(const CameraYaml& yaml, const std::string& source, const std::string& prefix) {
  Camera c;
  c.image_width_px = yaml.integer(prefix + "image_width");
  c.image_height_px = yaml.integer(prefix + "image_height");
  const std::string km = prefix + "camera_matrix";
  const CameraYaml::Matrix k = yaml.matrix(km);
  if (k.rows != 3 || k.cols != 3) throw InputError(source, yaml.require(km).line, km + " must be 3x3");
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) c.camera_matrix(r, col) = k.data[static_cast<std::size_t>(r * 3 + col)];
  }
  const std::string kd = prefix + "distortion_coefficients";
  if (yaml.find(kd) != nullptr) {
    const CameraYaml::Matrix d = yaml.matrix(kd);
    if (d.rows != 1 && d.cols != 1) throw InputError(source, yaml.require(kd).line, kd + " must be a vector");
    c.distortion = d.data;
  }
  const std::string ke = prefix + "avg_reprojection_error";
  if (const Entry* e = yaml.find(ke)) c.avg_reprojection_error_px = yaml.real(*e, ke);
  validate_camera(c, prefix.empty() ? source : source + " (" + prefix.substr(0, prefix.size() - 1) + ")");
  return c;
}

// A real as YAML reads a real: with a '.' or an exponent ("1" would be an int).
std::string yaml_real(double value) {
  std::string v = format_double(value);
  if (v.find_first_of(".eEn") == std::string::npos) v += ".";
  return v;
}

// Written by hand rather than through cv::FileStorage so numbers round-trip exactly
// (FileStorage prints 16 significant digits); the layout is FileStorage's, so OpenCV reads it.
std::string matrix_entry(const std::string& key, int rows, int cols, const std::vector<double>& data) {
  std::string s = key + ": !!opencv-matrix\n   rows: " + std::to_string(rows) + "\n   cols: " + std::to_string(cols) +
                  "\n   dt: d\n   data: [ ";
  for (std::size_t i = 0; i < data.size(); ++i) s += (i ? ", " : "") + yaml_real(data[i]);
  return s + " ]\n";
}

std::string camera_entries(const Camera& camera, const std::string& prefix) {
  std::vector<double> k(9);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) k[static_cast<std::size_t>(r * 3 + c)] = camera.camera_matrix(r, c);
  }
  std::string text = prefix + "image_width: " + std::to_string(camera.image_width_px) + "\n";
  text += prefix + "image_height: " + std::to_string(camera.image_height_px) + "\n";
  text += matrix_entry(prefix + "camera_matrix", 3, 3, k);
  if (!camera.distortion.empty()) {
    text += matrix_entry(prefix + "distortion_coefficients", static_cast<int>(camera.distortion.size()), 1,
                         camera.distortion);
  }
  if (camera.avg_reprojection_error_px) {
    text += prefix + "avg_reprojection_error: " + yaml_real(*camera.avg_reprojection_error_px) + "\n";
  }
  return text;
}

}  // namespace

Camera read_camera_yaml(std::istream& in, const std::string& source, CameraYamlLimits limits) {
  const std::string text = read_small_text(in, source, limits, "camera");  // the parser's views point into it
  const CameraYaml yaml(text, source);
  return camera_from(yaml, source, "");
}

void write_camera_yaml(std::ostream& out, const Camera& camera) {
  validate_camera(camera, "camera to write");
  out << "%YAML:1.0\n---\n" + stamp_line(std::nullopt) + camera_entries(camera, "");
}

// ---------------------------------------------------------------------------------------------
// Rig files: the cameras' entries under "camera_K_", K = 0..rig_cameras-1, each with its image
// name prefix and its pose in the rig's frame (docs/formats.md, rig.yaml).

namespace {

constexpr int kMaxRigCameras = 64;
// A rotation matrix written with 17 digits is orthonormal to ~1e-16; one typed by hand from
// six-digit values to ~1e-6.
constexpr double kRotationTolerance = 1e-5;

std::string rig_key(std::size_t k) { return "camera_" + std::to_string(k) + "_"; }

// The line of camera k's key `suffix` ("prefix", "cam_from_rig_rotation", ...), 0 if unknown.
using RigLine = std::function<std::size_t(std::size_t k, const std::string& suffix)>;

// A translation or sigma beyond this (mm: 1000 km) is junk, not a rig.
constexpr double kMaxRigValue = 1e9;

void validate_rig(const Rig& rig, const std::string& source, const RigLine& line) {
  if (rig.cameras.empty() || rig.cameras.size() > static_cast<std::size_t>(kMaxRigCameras)) {
    throw InputError(source, 0, "a rig has 1 to " + std::to_string(kMaxRigCameras) + " cameras, not " +
                                    std::to_string(rig.cameras.size()));
  }
  std::map<std::string, std::size_t> prefixes;
  for (std::size_t k = 0; k < rig.cameras.size(); ++k) {
    const RigCamera& c = rig.cameras[k];
    const std::string who = "camera " + std::to_string(k);
    if (c.prefix.empty()) throw InputError(source, line(k, "prefix"), who + " has an empty image name prefix");
    const bool control = std::any_of(c.prefix.begin(), c.prefix.end(), [](char ch) {
      return static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f || ch == '"' || ch == '\\' || ch == '\'';
    });
    if (control || c.prefix.front() == ' ' || c.prefix.back() == ' ') {
      throw InputError(source, line(k, "prefix"), who + "'s prefix holds a quote, a backslash, a control character "
                                                        "or a leading or trailing space");
    }
    const auto [it, fresh] = prefixes.emplace(c.prefix, k);
    if (!fresh) {
      throw InputError(source, line(k, "prefix"), "cameras " + std::to_string(it->second) + " and " +
                                                      std::to_string(k) + " have the same image name prefix '" +
                                                      c.prefix + "'");
    }
    validate_camera(c.camera, source + " (camera_" + std::to_string(k) + ")");
    const Eigen::Matrix3d& r = c.cam_from_rig_rotation;
    if (!r.allFinite() || !c.cam_from_rig_translation_mm.allFinite() ||
        c.cam_from_rig_translation_mm.cwiseAbs().maxCoeff() > kMaxRigValue) {
      throw InputError(source, line(k, "cam_from_rig_translation_mm"),
                       who + "'s pose in the rig has a non-finite or implausible value");
    }
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kRotationTolerance ||
        !(r.determinant() > 0)) {
      throw InputError(source, line(k, "cam_from_rig_rotation"),
                       who + "'s cam_from_rig_rotation is not a rotation matrix (orthonormal, det +1)");
    }
    if (c.cam_from_rig_sigma && !(c.cam_from_rig_sigma->allFinite() && c.cam_from_rig_sigma->minCoeff() >= 0 &&
                                  c.cam_from_rig_sigma->maxCoeff() <= kMaxRigValue)) {
      throw InputError(source, line(k, "cam_from_rig_sigma"),
                       who + "'s cam_from_rig_sigma must be 6 non-negative numbers");
    }
  }
  if (rig.avg_reprojection_error_px && !(std::isfinite(*rig.avg_reprojection_error_px) && *rig.avg_reprojection_error_px >= 0)) {
    throw InputError(source, line(0, "rig_avg_reprojection_error"), "rig_avg_reprojection_error must be a non-negative number");
  }
}

// The keys a rig file may hold after "camera_K_" (K = 0 ... rig_cameras - 1, written plainly).
const std::set<std::string>& rig_camera_suffixes() {
  static const std::set<std::string> s{"prefix", "image_width", "image_height", "camera_matrix",
                                       "distortion_coefficients", "avg_reprojection_error", "cam_from_rig_rotation",
                                       "cam_from_rig_translation_mm", "cam_from_rig_sigma"};
  return s;
}

}  // namespace

Rig read_rig_yaml(std::istream& in, const std::string& source, CameraYamlLimits limits) {
  const std::string text = read_small_text(in, source, limits, "rig");  // the parser's views point into it
  const CameraYaml yaml(text, source, "rig");
  const int count = yaml.integer("rig_cameras");
  if (count < 1 || count > kMaxRigCameras) {
    throw InputError(source, yaml.require("rig_cameras").line,
                     "rig_cameras: " + std::to_string(count) + "; a rig has 1 to " + std::to_string(kMaxRigCameras));
  }
  // Every key "camera_..." must name one of the rig's cameras and one of its fields, and every
  // "rig_..." key one of the rig's: a misspelt key would otherwise drop what it holds unseen.
  for (const auto& [key, line] : yaml.keys()) {
    if (key.rfind("rig_", 0) == 0) {
      if (key != "rig_cameras" && key != "rig_avg_reprojection_error") {
        throw InputError(source, line, "unknown key '" + key + "' (a rig file has rig_cameras, rig_avg_reprojection_error "
                                       "and camera_K_... keys)");
      }
      continue;
    }
    if (key.rfind("camera_", 0) != 0) continue;
    const std::size_t digits_end = key.find('_', 7);
    const std::string number = key.substr(7, digits_end == std::string::npos ? std::string::npos : digits_end - 7);
    const bool canonical = !number.empty() && number.size() <= 3 &&
                           number.find_first_not_of("0123456789") == std::string::npos &&
                           (number == "0" || number.front() != '0');
    if (!canonical || digits_end == std::string::npos) {
      throw InputError(source, line, "unknown key '" + key + "' (expected camera_K_FIELD, K = 0 ... " +
                                         std::to_string(count - 1) + ")");
    }
    if (std::stoi(number) >= count) {
      throw InputError(source, line, "'" + key + "' is for camera " + number + " but rig_cameras is " +
                                         std::to_string(count));
    }
    if (!rig_camera_suffixes().count(key.substr(digits_end + 1))) {
      throw InputError(source, line, "unknown key '" + key + "'");
    }
  }
  Rig rig;
  for (std::size_t k = 0; k < static_cast<std::size_t>(count); ++k) {
    const std::string p = rig_key(k);
    RigCamera c;
    c.prefix = yaml.text(p + "prefix");
    c.camera = camera_from(yaml, source, p);
    const CameraYaml::Matrix r = yaml.matrix(p + "cam_from_rig_rotation");
    if (r.rows != 3 || r.cols != 3) {
      throw InputError(source, yaml.require(p + "cam_from_rig_rotation").line, p + "cam_from_rig_rotation must be 3x3");
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) c.cam_from_rig_rotation(i, j) = r.data[static_cast<std::size_t>(i * 3 + j)];
    }
    const CameraYaml::Matrix t = yaml.matrix(p + "cam_from_rig_translation_mm");
    if (t.rows * t.cols != 3 || (t.rows != 1 && t.cols != 1)) {
      throw InputError(source, yaml.require(p + "cam_from_rig_translation_mm").line,
                       p + "cam_from_rig_translation_mm must be a 3-vector");
    }
    c.cam_from_rig_translation_mm = Eigen::Vector3d(t.data[0], t.data[1], t.data[2]);
    if (yaml.find(p + "cam_from_rig_sigma") != nullptr) {
      const CameraYaml::Matrix s = yaml.matrix(p + "cam_from_rig_sigma");
      if (s.rows * s.cols != 6 || (s.rows != 1 && s.cols != 1)) {
        throw InputError(source, yaml.require(p + "cam_from_rig_sigma").line, p + "cam_from_rig_sigma must be a 6-vector");
      }
      c.cam_from_rig_sigma = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(s.data.data());
    }
    rig.cameras.push_back(std::move(c));
  }
  if (const Entry* e = yaml.find("rig_avg_reprojection_error")) {
    rig.avg_reprojection_error_px = yaml.real(*e, "rig_avg_reprojection_error");
  }
  validate_rig(rig, source, [&](std::size_t k, const std::string& suffix) -> std::size_t {
    const Entry* e = yaml.find(suffix.rfind("rig_", 0) == 0 ? suffix : rig_key(k) + suffix);
    return e ? e->line : 0;
  });
  return rig;
}

void write_rig_yaml(std::ostream& out, const Rig& rig) {
  validate_rig(rig, "rig to write", [](std::size_t, const std::string&) -> std::size_t { return 0; });
  std::string text = "%YAML:1.0\n---\n" + stamp_line(std::nullopt);
  text += "rig_cameras: " + std::to_string(rig.cameras.size()) + "\n";
  for (std::size_t k = 0; k < rig.cameras.size(); ++k) {
    const RigCamera& c = rig.cameras[k];
    const std::string p = rig_key(k);
    text += p + "prefix: \"" + c.prefix + "\"\n";
    text += camera_entries(c.camera, p);
    std::vector<double> r(9);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) r[static_cast<std::size_t>(i * 3 + j)] = c.cam_from_rig_rotation(i, j);
    }
    text += matrix_entry(p + "cam_from_rig_rotation", 3, 3, r);
    const Eigen::Vector3d& t = c.cam_from_rig_translation_mm;
    text += matrix_entry(p + "cam_from_rig_translation_mm", 3, 1, {t.x(), t.y(), t.z()});
    if (c.cam_from_rig_sigma) {
      const auto& s = *c.cam_from_rig_sigma;
      text += matrix_entry(p + "cam_from_rig_sigma", 6, 1, {s[0], s[1], s[2], s[3], s[4], s[5]});
    }
  }
  if (rig.avg_reprojection_error_px) text += "rig_avg_reprojection_error: " + yaml_real(*rig.avg_reprojection_error_px) + "\n";
  out << text;
}

std::optional<RigMatch> match_rig_prefix(const std::vector<std::string>& prefixes, const std::string& image) {
  const std::size_t slash = image.find_last_of('/');
  const std::size_t base = slash == std::string::npos ? 0 : slash + 1;
  std::optional<RigMatch> best;
  std::size_t best_length = 0;
  for (std::size_t k = 0; k < prefixes.size(); ++k) {
    const std::string& p = prefixes[k];
    if (p.empty() || p.size() <= best_length) continue;
    if (p.find('/') != std::string::npos) {
      // A prefix with a directory starts the whole name.
      if (image.compare(0, p.size(), p) != 0) continue;
      best = RigMatch{k, image.substr(p.size())};
    } else {
      // Any other starts the file name, whatever directories lead to it.
      if (image.compare(base, p.size(), p) != 0) continue;
      best = RigMatch{k, image.substr(0, base) + image.substr(base + p.size())};
    }
    best_length = p.size();
  }
  return best;
}

}  // namespace photomill
