// Scene layout, validation and the synth-scene / synth-board text formats (see scene.hpp).
#include "tools/synth/scene.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include <opencv2/aruco.hpp>

#include "formats/error.hpp"
#include "formats/text.hpp"

namespace photomill::synth {
namespace {

struct DictionaryInfo {
  int id;
  int size;
  int bits;
};

const std::map<std::string, DictionaryInfo>& dictionaries() {
  static const std::map<std::string, DictionaryInfo> table = {
      {"DICT_4X4_50", {cv::aruco::DICT_4X4_50, 50, 4}},
      {"DICT_4X4_100", {cv::aruco::DICT_4X4_100, 100, 4}},
      {"DICT_4X4_250", {cv::aruco::DICT_4X4_250, 250, 4}},
      {"DICT_4X4_1000", {cv::aruco::DICT_4X4_1000, 1000, 4}},
      {"DICT_5X5_50", {cv::aruco::DICT_5X5_50, 50, 5}},
      {"DICT_5X5_100", {cv::aruco::DICT_5X5_100, 100, 5}},
      {"DICT_5X5_250", {cv::aruco::DICT_5X5_250, 250, 5}},
      {"DICT_5X5_1000", {cv::aruco::DICT_5X5_1000, 1000, 5}},
      {"DICT_6X6_50", {cv::aruco::DICT_6X6_50, 50, 6}},
      {"DICT_6X6_100", {cv::aruco::DICT_6X6_100, 100, 6}},
      {"DICT_6X6_250", {cv::aruco::DICT_6X6_250, 250, 6}},
      {"DICT_6X6_1000", {cv::aruco::DICT_6X6_1000, 1000, 6}},
      {"DICT_7X7_50", {cv::aruco::DICT_7X7_50, 50, 7}},
      {"DICT_7X7_100", {cv::aruco::DICT_7X7_100, 100, 7}},
      {"DICT_7X7_250", {cv::aruco::DICT_7X7_250, 250, 7}},
      {"DICT_7X7_1000", {cv::aruco::DICT_7X7_1000, 1000, 7}},
      {"DICT_ARUCO_ORIGINAL", {cv::aruco::DICT_ARUCO_ORIGINAL, 1024, 5}},
  };
  return table;
}

const DictionaryInfo& dictionary_info(const std::string& name) {
  const auto it = dictionaries().find(name);
  if (it == dictionaries().end()) {
    throw std::invalid_argument("unknown ArUco dictionary '" + name + "'");
  }
  return it->second;
}

struct Box {
  double x0, x1, y0, y1;
  bool overlaps(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
  bool inside(const Box& o) const { return x0 >= o.x0 && x1 <= o.x1 && y0 >= o.y0 && y1 <= o.y1; }
};

// The marker square grown by its quiet zone.
Box marker_box(const Marker& m, double quiet_cells, int bits) {
  const double q = quiet_cells * m.size_mm / (bits + 2);
  return {m.top_left_mm.x() - q, m.top_left_mm.x() + m.size_mm + q,
          m.top_left_mm.y() - m.size_mm - q, m.top_left_mm.y() + q};
}

std::string str(double v) { return format_double(v); }

}  // namespace

std::vector<std::string> dictionary_names() {
  std::vector<std::string> names;
  for (const auto& [name, info] : dictionaries()) names.push_back(name);
  return names;
}
int dictionary_id(const std::string& name) { return dictionary_info(name).id; }
int dictionary_size(const std::string& name) { return dictionary_info(name).size; }
int dictionary_bits(const std::string& name) { return dictionary_info(name).bits; }

Eigen::Vector2d PartScene::corner_xy(const Marker& m, int corner) {
  const double s = m.size_mm;
  switch (corner) {
    case 0: return m.top_left_mm;
    case 1: return m.top_left_mm + Eigen::Vector2d(s, 0);
    case 2: return m.top_left_mm + Eigen::Vector2d(s, -s);
    case 3: return m.top_left_mm + Eigen::Vector2d(0, -s);
    default: throw std::invalid_argument("marker corner must be 0..3");
  }
}

Eigen::Vector3d PartScene::corner_world(const Marker& m, int corner) const {
  const Eigen::Vector2d p = corner_xy(m, corner);
  return {p.x(), p.y(), m.on_part ? surface.height_mm(p.x(), p.y()) : 0.0};
}

void validate(const PartScene& s) {
  validate(s.surface);
  const DictionaryInfo& dict = dictionary_info(s.dictionary);
  const Box plate{s.plate_x_min_mm, s.plate_x_max_mm, s.plate_y_min_mm, s.plate_y_max_mm};
  const Box part{s.surface.x_min_mm, s.surface.x_max_mm, s.surface.y_min_mm, s.surface.y_max_mm};
  if (!std::isfinite(plate.x0) || !std::isfinite(plate.x1) || !std::isfinite(plate.y0) ||
      !std::isfinite(plate.y1) || !part.inside(plate) || part.x0 == plate.x0 ||
      part.x1 == plate.x1 || part.y0 == plate.y0 || part.y1 == plate.y1) {
    throw std::invalid_argument("the plate must contain the part rectangle with room around it");
  }
  if (!(s.quiet_zone_cells >= 0) || !std::isfinite(s.quiet_zone_cells)) {
    throw std::invalid_argument("quiet zone must be >= 0 cells");
  }
  if (!(s.speckle_mm > 0) || !std::isfinite(s.speckle_mm)) {
    throw std::invalid_argument("speckle grain must be positive");
  }
  std::set<int> ids;
  std::vector<Box> boxes;
  for (const Marker& m : s.markers) {
    const std::string name = "marker " + std::to_string(m.id);
    if (m.id < 0 || m.id >= dict.size) {
      throw std::invalid_argument(name + " is not in " + s.dictionary + " (ids 0.." +
                                  std::to_string(dict.size - 1) + ")");
    }
    if (!ids.insert(m.id).second) throw std::invalid_argument(name + " is used twice");
    if (!(m.size_mm > 0) || !std::isfinite(m.size_mm) || !m.top_left_mm.allFinite()) {
      throw std::invalid_argument(name + ": size must be positive");
    }
    const Box b = marker_box(m, s.quiet_zone_cells, dict.bits);
    if (m.on_part ? !b.inside(part) : (!b.inside(plate) || b.overlaps(part))) {
      throw std::invalid_argument(name + (m.on_part ? " is not inside the part rectangle"
                                                    : " is off the plate or overlaps the part"));
    }
    for (const Box& o : boxes) {
      if (b.overlaps(o)) throw std::invalid_argument(name + " overlaps another marker");
    }
    boxes.push_back(b);
  }
}

PartScene make_scene(const HeightField& surface, const std::string& dictionary,
                     const LayoutOptions& layout, std::uint64_t speckle_seed, double speckle_mm) {
  PartScene scene;
  scene.surface = surface;
  scene.dictionary = dictionary;
  scene.speckle_seed = speckle_seed;
  scene.speckle_mm = speckle_mm;
  const int bits = dictionary_info(dictionary).bits;
  const double cx = 0.5 * (surface.x_min_mm + surface.x_max_mm);
  const double cy = 0.5 * (surface.y_min_mm + surface.y_max_mm);
  const double s = layout.plate_marker_mm;
  const double quiet = scene.quiet_zone_cells * s / (bits + 2);
  // Ring of plate markers: centres on a rectangle around the part, clockwise from (-ax, +ay).
  const double ax = 0.5 * (surface.x_max_mm - surface.x_min_mm) + layout.marker_gap_mm + quiet + s / 2;
  const double ay = 0.5 * (surface.y_max_mm - surface.y_min_mm) + layout.marker_gap_mm + quiet + s / 2;
  // A marker at each corner of the ring, then as many as fit at the pitch along each side.
  const std::vector<Eigen::Vector2d> ring = {{-ax, ay}, {ax, ay}, {ax, -ay}, {-ax, -ay}, {-ax, ay}};
  int id = 0;
  for (int e = 0; e < 4; ++e) {
    const Eigen::Vector2d side = ring[e + 1] - ring[e];
    const int segments = std::max(1, static_cast<int>(std::floor(side.norm() / (layout.marker_pitch * s))));
    for (int k = 0; k < segments; ++k) {
      const Eigen::Vector2d c = ring[e] + side * (static_cast<double>(k) / segments);
      scene.markers.push_back({id++, {cx + c.x() - s / 2, cy + c.y() + s / 2}, s, false});
    }
  }
  const double margin = layout.plate_margin_mm + quiet + s / 2;
  scene.plate_x_min_mm = cx - ax - margin;
  scene.plate_x_max_mm = cx + ax + margin;
  scene.plate_y_min_mm = cy - ay - margin;
  scene.plate_y_max_mm = cy + ay + margin;
  // Part markers on a grid over the interior (inside the edge blend).
  const double p = layout.part_marker_mm;
  const double b = surface.edge_blend_mm;
  const double ix0 = surface.x_min_mm + b, ix1 = surface.x_max_mm - b;
  const double iy0 = surface.y_min_mm + b, iy1 = surface.y_max_mm - b;
  for (int j = layout.part_markers_y - 1; j >= 0; --j) {
    for (int i = 0; i < layout.part_markers_x; ++i) {
      const double mx = ix0 + (i + 0.5) * (ix1 - ix0) / layout.part_markers_x;
      const double my = iy0 + (j + 0.5) * (iy1 - iy0) / layout.part_markers_y;
      scene.markers.push_back({id++, {mx - p / 2, my + p / 2}, p, true});
    }
  }
  validate(scene);
  return scene;
}

std::vector<ControlPoint> marker_corners(const PartScene& scene, bool on_part) {
  std::vector<ControlPoint> points;
  for (const Marker& m : scene.markers) {
    if (m.on_part != on_part) continue;
    for (int c = 0; c < 4; ++c) {
      ControlPoint p;
      p.point_id = marker_corner_id(m.id, c);
      p.xyz_mm = scene.corner_world(m, c);
      points.push_back(p);
    }
  }
  return points;
}

void write_scene(std::ostream& out, const PartScene& s, const std::string& comment) {
  out << "# photomill synth-scene v1\n";
  if (!comment.empty()) {
    std::istringstream lines(comment);
    for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  }
  const HeightField& f = s.surface;
  out << "# part: z = h(x, y) = w(x, y) * (base + sum of terms) inside part_rect, 0 outside\n";
  out << "part_rect_mm " << str(f.x_min_mm) << " " << str(f.x_max_mm) << " " << str(f.y_min_mm)
      << " " << str(f.y_max_mm) << "\n";
  out << "edge_blend_mm " << str(f.edge_blend_mm) << "\n";
  out << "base_mm " << str(f.base_mm) << "\n";
  out << "# term KIND A X0 Y0 S1 S2\n";
  for (const ShapeTerm& t : f.terms) {
    out << "term " << to_string(t.kind) << " " << str(t.amplitude_mm) << " " << str(t.x0_mm)
        << " " << str(t.y0_mm) << " " << str(t.s1_mm) << " " << str(t.s2_mm) << "\n";
  }
  out << "plate_rect_mm " << str(s.plate_x_min_mm) << " " << str(s.plate_x_max_mm) << " "
      << str(s.plate_y_min_mm) << " " << str(s.plate_y_max_mm) << "\n";
  out << "dictionary " << s.dictionary << "\n";
  out << "quiet_zone_cells " << str(s.quiet_zone_cells) << "\n";
  out << "speckle " << s.speckle_seed << " " << str(s.speckle_mm) << "\n";
  out << "# marker ID X_TL Y_TL SIZE plate|part   (corner point_id = ID * 4 + corner)\n";
  for (const Marker& m : s.markers) {
    out << "marker " << m.id << " " << str(m.top_left_mm.x()) << " " << str(m.top_left_mm.y())
        << " " << str(m.size_mm) << " " << (m.on_part ? "part" : "plate") << "\n";
  }
}

namespace {

// Parses "key v1 v2 ..." records with a fixed number of fields per key.
class Records {
public:
  Records(std::istream& in, const std::string& source, const std::string& magic)
      : lines_(in, source, {.max_line_bytes = 1 << 16, .skip_comments_and_blank = false}) {
    // The first line must be the magic header.
    auto first = lines_.next();
    if (!first || trim(*first) != magic) {
      lines_.fail("expected '" + magic + "' as the first line");
    }
  }
  // Next record (comments and blank lines skipped); false at the end.
  bool next() {
    while (auto line = lines_.next()) {
      const std::string_view t = trim(*line);
      if (t.empty() || t.front() == '#') continue;
      fields_.clear();
      for (auto f : split_whitespace(t)) fields_.emplace_back(f);
      return true;
    }
    return false;
  }
  const std::string& key() const { return fields_.front(); }
  void expect(std::size_t values) const {
    if (fields_.size() != values + 1) {
      fail("'" + key() + "' needs " + std::to_string(values) + " values, got " +
           std::to_string(fields_.size() - 1));
    }
  }
  double number(std::size_t i) const {
    const auto v = parse_double(fields_.at(i));
    if (!v) fail("'" + key() + "': not a finite number: '" + fields_.at(i) + "'");
    return *v;
  }
  std::int64_t integer(std::size_t i) const {
    const auto v = parse_int(fields_.at(i));
    if (!v) fail("'" + key() + "': not an integer: '" + fields_.at(i) + "'");
    return *v;
  }
  const std::string& text(std::size_t i) const { return fields_.at(i); }
  [[noreturn]] void fail(const std::string& message) const { lines_.fail(message); }

private:
  LineReader lines_;
  std::vector<std::string> fields_;
};

}  // namespace

PartScene read_scene(std::istream& in, const std::string& source) {
  Records r(in, source, "# photomill synth-scene v1");
  PartScene s;
  s.markers.clear();
  std::set<std::string> seen;
  bool have_part = false, have_plate = false;
  while (r.next()) {
    const std::string key = r.key();
    if (key != "term" && key != "marker" && !seen.insert(key).second) {
      r.fail("'" + key + "' given twice");
    }
    if (key == "part_rect_mm") {
      r.expect(4);
      s.surface.x_min_mm = r.number(1);
      s.surface.x_max_mm = r.number(2);
      s.surface.y_min_mm = r.number(3);
      s.surface.y_max_mm = r.number(4);
      have_part = true;
    } else if (key == "edge_blend_mm") {
      r.expect(1);
      s.surface.edge_blend_mm = r.number(1);
    } else if (key == "base_mm") {
      r.expect(1);
      s.surface.base_mm = r.number(1);
    } else if (key == "term") {
      r.expect(6);
      ShapeTerm t;
      try {
        t.kind = shape_term_kind(r.text(1));
      } catch (const std::invalid_argument& e) {
        r.fail(e.what());
      }
      t.amplitude_mm = r.number(2);
      t.x0_mm = r.number(3);
      t.y0_mm = r.number(4);
      t.s1_mm = r.number(5);
      t.s2_mm = r.number(6);
      s.surface.terms.push_back(t);
    } else if (key == "plate_rect_mm") {
      r.expect(4);
      s.plate_x_min_mm = r.number(1);
      s.plate_x_max_mm = r.number(2);
      s.plate_y_min_mm = r.number(3);
      s.plate_y_max_mm = r.number(4);
      have_plate = true;
    } else if (key == "dictionary") {
      r.expect(1);
      s.dictionary = r.text(1);
    } else if (key == "quiet_zone_cells") {
      r.expect(1);
      s.quiet_zone_cells = r.number(1);
    } else if (key == "speckle") {
      r.expect(2);
      const auto seed = r.integer(1);
      if (seed < 0) r.fail("speckle seed must not be negative");
      s.speckle_seed = static_cast<std::uint64_t>(seed);
      s.speckle_mm = r.number(2);
    } else if (key == "marker") {
      r.expect(5);
      Marker m;
      const auto id = r.integer(1);
      if (id < 0 || id > 1 << 20) r.fail("marker id out of range");
      m.id = static_cast<int>(id);
      m.top_left_mm = {r.number(2), r.number(3)};
      m.size_mm = r.number(4);
      if (r.text(5) != "plate" && r.text(5) != "part") r.fail("marker must be 'plate' or 'part'");
      m.on_part = r.text(5) == "part";
      s.markers.push_back(m);
    } else {
      r.fail("unknown record '" + key + "'");
    }
  }
  if (!have_part) throw InputError(source, 0, "no part_rect_mm record");
  if (!have_plate) throw InputError(source, 0, "no plate_rect_mm record");
  try {
    validate(s);
  } catch (const std::invalid_argument& e) {
    throw InputError(source, 0, e.what());
  }
  return s;
}

void validate(const BoardSpec& b) {
  dictionary_info(b.dictionary);
  if (b.squares_x < 2 || b.squares_y < 2) throw std::invalid_argument("board needs >= 2x2 squares");
  if (!(b.square_mm > 0) || !(b.marker_mm > 0) || !(b.marker_mm < b.square_mm) ||
      !std::isfinite(b.square_mm)) {
    throw std::invalid_argument("board needs 0 < marker size < square size");
  }
  if (!(b.sheet_margin_mm >= 0) || !std::isfinite(b.sheet_margin_mm)) {
    throw std::invalid_argument("board sheet margin must be >= 0");
  }
  const int markers = (b.squares_x * b.squares_y) / 2;
  if (markers > dictionary_size(b.dictionary)) {
    throw std::invalid_argument("board needs " + std::to_string(markers) + " markers, more than " +
                                b.dictionary + " has");
  }
}

void write_board(std::ostream& out, const BoardSpec& b) {
  out << "# photomill synth-board v1\n"
      << "# OpenCV ChArUco board (cv::aruco::CharucoBoard::create), sizes in mm; charuco corner\n"
      << "# ids are the point ids of board_points.csv\n"
      << "squares_x " << b.squares_x << "\nsquares_y " << b.squares_y << "\nsquare_mm "
      << str(b.square_mm) << "\nmarker_mm " << str(b.marker_mm) << "\ndictionary " << b.dictionary
      << "\nsheet_margin_mm " << str(b.sheet_margin_mm) << "\n";
}

BoardSpec read_board(std::istream& in, const std::string& source) {
  Records r(in, source, "# photomill synth-board v1");
  BoardSpec b;
  std::set<std::string> seen;
  while (r.next()) {
    const std::string key = r.key();
    if (!seen.insert(key).second) r.fail("'" + key + "' given twice");
    r.expect(1);
    if (key == "squares_x" || key == "squares_y") {
      const auto v = r.integer(1);
      if (v < 2 || v > 1000) r.fail(key + " must be in 2..1000");
      (key == "squares_x" ? b.squares_x : b.squares_y) = static_cast<int>(v);
    } else if (key == "square_mm") {
      b.square_mm = r.number(1);
    } else if (key == "marker_mm") {
      b.marker_mm = r.number(1);
    } else if (key == "dictionary") {
      b.dictionary = r.text(1);
    } else if (key == "sheet_margin_mm") {
      b.sheet_margin_mm = r.number(1);
    } else {
      r.fail("unknown record '" + key + "'");
    }
  }
  try {
    validate(b);
  } catch (const std::invalid_argument& e) {
    throw InputError(source, 0, e.what());
  }
  return b;
}

}  // namespace photomill::synth
