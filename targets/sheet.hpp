// targets: print-ready sheets of the targets photomill measures with: a ChArUco calibration board
// and a plate of ArUco markers (the control points), with a 100 mm check line and the printing
// instructions on the sheet, at exact scale. A sheet is a list of vector shapes in mm; pdf.cpp and
// svg.cpp write it. The layouts and their control points are built here.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"

namespace photomill::targets {

// Page frame: mm, origin at the lower-left corner of the page, x right, y up (PDF's own frame).
struct Rect {
  double x_mm = 0, y_mm = 0;   // lower-left corner
  double w_mm = 0, h_mm = 0;
};

struct Line {
  Eigen::Vector2d a_mm = Eigen::Vector2d::Zero(), b_mm = Eigen::Vector2d::Zero();
  double width_mm = 0.2;
  double grey = 0;  // 0 black .. 1 white
};

struct Text {
  double x_mm = 0, y_mm = 0;  // start of the baseline
  double size_mm = 3;         // font size (em height)
  std::string text;           // printable ASCII
};

struct Sheet {
  std::string title;
  double width_mm = 0, height_mm = 0;
  std::vector<Rect> black;  // filled black, as one union (no seams between touching rectangles)
  std::vector<Line> lines;
  std::vector<Text> texts;
};

// Paper: a name (A5, A4, A3, A2, Letter, Legal, Tabloid; any case) or WxH in mm ("300x200").
// Returns portrait (width <= height) for names, as given for WxH. Throws UsageError.
Eigen::Vector2d paper_size_mm(const std::string& paper);

enum class Orientation { Auto, Portrait, Landscape };

struct PageOptions {
  std::string paper = "A4";
  Orientation orientation = Orientation::Auto;  // Auto: the one that fits the target best
  double margin_mm = 8;                         // unprinted border (printers cannot print to the edge)
  std::string command;                          // the command line that made the sheet, printed on it
};

struct CharucoTarget {
  int squares_x = 7, squares_y = 5;   // OpenCV's squaresX, squaresY
  double square_mm = 30;
  double marker_mm = 22;
  std::string dictionary = "DICT_5X5_100";  // predefined name, or a YAML file (dictionary_file)
  std::string dictionary_file;
};

enum class PlateLayout { Ring, Grid };

struct PlateTarget {
  PlateLayout layout = PlateLayout::Ring;
  double marker_mm = 24;
  double pitch_mm = 0;   // smallest distance between marker centres; 0: 2 x marker_mm
  int first_id = 0;
  std::string dictionary = "DICT_4X4_100";
  std::string dictionary_file;
  // A coded scale bar: two markers (the ids after the plate's) whose top-left corners are this far
  // apart, on a strip to cut off the sheet; 0: none.
  double scale_bar_mm = 0;
};

struct TargetSheet {
  Sheet sheet;
  // ChArUco: the board's corners in the board frame (as detect --print-board writes them).
  // Plate: the marker corners (point_id = id x 4 + corner), world frame: origin at the centre of
  // the ring (or grid), x right, y up, z = 0 on the sheet. Without the scale bar's markers.
  std::vector<ControlPoint> control_points;
  // Plate with a scale bar: the bar's four corner-to-corner distances.
  std::vector<ScaleBar> scale_bars;
  std::vector<int> marker_ids;
  std::vector<std::string> detect_options;  // what to give detect (and calib) for this target
};

// Throws UsageError: sizes that do not fit the page (naming the sizes and what would fit), a
// dictionary with too few markers, a marker not smaller than its square.
TargetSheet charuco_sheet(const CharucoTarget& target, const PageOptions& page);
TargetSheet plate_sheet(const PlateTarget& target, const PageOptions& page);

}  // namespace photomill::targets
