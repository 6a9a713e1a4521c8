// The synthetic scene: the part's height field on a flat plate, ArUco markers on the plate (the
// control points) and on the part, and a speckle texture; plus its text description
// ("photomill synth-scene v1", docs/synth.md) from which tests evaluate the truth exactly.
// World frame: mm, plate top z = 0, z up, part centred at the origin.
#pragma once

#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"
#include "tools/synth/height_field.hpp"

namespace photomill::synth {

// ArUco dictionaries by OpenCV's names ("DICT_4X4_50", ...).
std::vector<std::string> dictionary_names();
// OpenCV's cv::aruco::PREDEFINED_DICTIONARY_NAME value; throws std::invalid_argument.
int dictionary_id(const std::string& name);
// Number of markers in the dictionary.
int dictionary_size(const std::string& name);
// Bits per side (4 for 4X4): a marker is bits + 2 cells wide, its black border included.
int dictionary_bits(const std::string& name);

// A square ArUco marker printed flat in the plate plane (z = 0) or draped vertically onto the
// part (each point (x, y) of the print goes to (x, y, h(x, y))). Its corners, in OpenCV's order
// (the order cv::aruco::detectMarkers returns them), as seen from above with +y up:
//   0 TL (x, y), 1 TR (x + s, y), 2 BR (x + s, y - s), 3 BL (x, y - s).
// The square includes the marker's black border (what the detector measures); a white quiet
// zone surrounds it.
struct Marker {
  int id = 0;                                             // dictionary id
  Eigen::Vector2d top_left_mm = Eigen::Vector2d::Zero();  // corner 0, plate plane (x, y)
  double size_mm = 0;                                     // s, black border included
  bool on_part = false;                                   // draped on the part, else on the plate
  bool operator==(const Marker&) const = default;
};

// Point id of a marker corner: marker_id * 4 + corner (corner 0..3 as above).
inline PointId marker_corner_id(int marker_id, int corner) {
  return static_cast<PointId>(marker_id) * 4 + corner;
}

struct PartScene {
  HeightField surface;
  // The plate: a rectangle at z = 0 around the part (a table of uniform grey lies beyond it).
  double plate_x_min_mm = -150, plate_x_max_mm = 150;
  double plate_y_min_mm = -120, plate_y_max_mm = 120;
  std::string dictionary = "DICT_4X4_100";
  std::vector<Marker> markers;
  double quiet_zone_cells = 2;       // white margin around each marker, in marker cells
  std::uint64_t speckle_seed = 1;    // the speckle pattern is a function of (x, y, seed)
  double speckle_mm = 1.2;           // speckle grain size
  bool operator==(const PartScene&) const = default;

  // Corner k (0..3) of a marker in the plate plane, and in the world (z = 0 or h(x, y)).
  static Eigen::Vector2d corner_xy(const Marker& m, int corner);
  Eigen::Vector3d corner_world(const Marker& m, int corner) const;
};

// Throws std::invalid_argument: bad height field, part not inside the plate, marker ids out of
// the dictionary or repeated, markers overlapping (quiet zones included), a part marker not
// inside the part rectangle or a plate marker overlapping it, non-positive sizes.
void validate(const PartScene& scene);

// How make_scene lays the markers out.
struct LayoutOptions {
  double plate_marker_mm = 24;      // side of the plate markers
  double part_marker_mm = 10;       // side of the part markers
  double marker_gap_mm = 12;        // from the part rectangle to the ring of plate markers
  double marker_pitch = 2.0;        // centre spacing along the ring, in marker sizes
  double plate_margin_mm = 35;      // plate beyond the ring of markers
  int part_markers_x = 3;           // part markers on a grid over the part's flat-ish interior
  int part_markers_y = 2;
};

// A scene: the given height field, a ring of plate markers (ids 0..n-1, from the corner at
// (-x, +y) clockwise), a grid of part markers (ids n..), the plate sized to hold them.
PartScene make_scene(const HeightField& surface, const std::string& dictionary,
                     const LayoutOptions& layout, std::uint64_t speckle_seed, double speckle_mm);

// Control points: every corner of the plate markers (on_part false) or of the part markers.
std::vector<ControlPoint> marker_corners(const PartScene& scene, bool on_part);

// The text description, "# photomill synth-scene v1" then one record per line:
//   part_rect_mm XMIN XMAX YMIN YMAX | edge_blend_mm B | base_mm F0
//   term gauss|wave|saddle A X0 Y0 S1 S2
//   plate_rect_mm XMIN XMAX YMIN YMAX | dictionary NAME | quiet_zone_cells Q
//   speckle SEED GRAIN_MM | marker ID X_TL Y_TL SIZE plate|part
// '#' comments and blank lines are skipped; `comment` (may be multi-line) is written as
// comments after the header. read_scene throws InputError("source:line: ...").
void write_scene(std::ostream& out, const PartScene& scene, const std::string& comment = "");
PartScene read_scene(std::istream& in, const std::string& source);

// The ChArUco calibration board (OpenCV's cv::aruco::CharucoBoard layout, mm).
struct BoardSpec {
  int squares_x = 7;
  int squares_y = 5;
  double square_mm = 30;
  double marker_mm = 22;
  std::string dictionary = "DICT_5X5_100";  // differs from the plate's so no id is ambiguous
  double sheet_margin_mm = 15;  // white paper around the chessboard
  bool operator==(const BoardSpec&) const = default;
};
void validate(const BoardSpec& board);
// "# photomill synth-board v1" then squares_x, squares_y, square_mm, marker_mm, dictionary,
// sheet_margin_mm, one "key value" per line.
void write_board(std::ostream& out, const BoardSpec& board);
BoardSpec read_board(std::istream& in, const std::string& source);

}  // namespace photomill::synth
