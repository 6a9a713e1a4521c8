// targets' options (see cli.hpp).
#include "targets/cli.hpp"

#include <sstream>

#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "formats/text.hpp"
#include "geometry/board.hpp"

namespace photomill::targets {
namespace {

void add_page_options(CLI::App& sub, TargetsCli& c) {
  const std::string g = "Page and outputs";
  sub.add_option("-o,--output", c.output, "PDF to write (default: stdout)")->group(g);
  sub.add_option("--svg", c.svg, "Also write the sheet as SVG (mm units) here")->group(g);
  sub.add_option("--control-points", c.control_points,
                 "Write the target's control points CSV (point_id,x_mm,y_mm,z_mm) here")
      ->group(g);
  sub.add_option("--paper", c.page.paper, "A5, A4, A3, A2, Letter, Legal, Tabloid, or WxH in mm")
      ->group(g)->capture_default_str();
  sub.add_option("--orientation", c.orientation, "auto (the one the target fits best), portrait or landscape")
      ->group(g)->capture_default_str()->check(CLI::IsMember({"auto", "portrait", "landscape"}));
  sub.add_option("--margin-mm", c.page.margin_mm, "Unprinted border of the sheet, mm")
      ->group(g)->capture_default_str()->check(CLI::Range(0.0, 100.0));
}

}  // namespace

void add_options(CLI::App& app, TargetsCli& c) {
  app.require_subcommand(0, 1);  // none: make_sheet says which there are (CLI11 would not name a bad option)
  auto* ch = app.add_subcommand("charuco", "A ChArUco calibration board (for calib)");
  c.charuco_command = ch;
  ch->add_option("--squares", c.squares, "Squares along x and y, COLSxROWS (OpenCV's squaresX x squaresY)")
      ->capture_default_str();
  ch->add_option("--square-mm", c.charuco.square_mm, "Side of a square, mm")->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  ch->add_option("--marker-mm", c.charuco.marker_mm, "Side of a marker, mm (< --square-mm)")->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  ch->add_option("--dict", c.charuco.dictionary, "ArUco dictionary (OpenCV's predefined names, as detect --dict)")
      ->capture_default_str();
  add_page_options(*ch, c);

  auto* pl = app.add_subcommand("plate", "A plate of ArUco markers round the part (the control points)");
  c.plate_command = pl;
  pl->add_option("--layout", c.layout, "ring: markers round a free middle for the part; grid: markers all over")
      ->capture_default_str()->check(CLI::IsMember({"ring", "grid"}));
  pl->add_option("--marker-mm", c.plate.marker_mm, "Side of a marker, mm")->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  pl->add_option("--pitch-mm", c.plate.pitch_mm,
                 "Smallest distance between marker centres, mm (0: 2 x --marker-mm); the markers spread evenly "
                 "to the edges of the printable area")
      ->capture_default_str()->check(CLI::Range(0.0, 5000.0));
  pl->add_option("--first-id", c.plate.first_id, "Id of the first marker (top left; ring: then clockwise)")
      ->capture_default_str()->check(CLI::Range(0, 100000));
  auto* dict = pl->add_option("--dict", c.plate.dictionary, "ArUco dictionary (as detect --aruco)")->capture_default_str();
  pl->add_option("--dict-file", c.plate.dictionary_file, "A custom dictionary (OpenCV's YAML, as detect --aruco-dict-file)")
      ->excludes(dict);
  pl->add_option("--scale-bar-mm", c.plate.scale_bar_mm,
                 "Add a coded scale bar: two markers (the next ids) this far apart, corner to corner, on a strip to "
                 "cut off (0: none)")
      ->capture_default_str()->check(CLI::Range(0.0, 5000.0));
  pl->add_option("--scale-bars", c.scale_bars, "Write the scale bar's scale bars CSV (point_a,point_b,distance_mm) here");
  add_page_options(*pl, c);
}

TargetSheet make_sheet(TargetsCli& c, const std::string& command) {
  c.page.command = command;
  c.page.orientation = c.orientation == "portrait"    ? Orientation::Portrait
                       : c.orientation == "landscape" ? Orientation::Landscape
                                                      : Orientation::Auto;
  if (!c.charuco_command->parsed() && !c.plate_command->parsed()) {
    throw UsageError("give what to make: targets charuco [OPTIONS] or targets plate [OPTIONS] (--help on each)");
  }
  if (c.charuco_command->parsed()) {
    const auto [x, y] = geometry::parse_grid(c.squares, "--squares");
    c.charuco.squares_x = x;
    c.charuco.squares_y = y;
    return charuco_sheet(c.charuco, c.page);
  }
  if (!c.scale_bars.empty() && !(c.plate.scale_bar_mm > 0)) throw UsageError("--scale-bars needs --scale-bar-mm");
  if (c.plate.scale_bar_mm > 0 && c.scale_bars.empty()) {
    throw UsageError("--scale-bar-mm needs --scale-bars FILE: the bar's length is of no use without its CSV");
  }
  c.plate.layout = c.layout == "grid" ? PlateLayout::Grid : PlateLayout::Ring;
  return plate_sheet(c.plate, c.page);
}

std::string describe(const TargetsCli& c, const TargetSheet& t) {
  std::ostringstream s;
  s << (c.output == "-" ? std::string("<stdout>") : c.output) << ": " << format_double(t.sheet.width_mm) << " x "
    << format_double(t.sheet.height_mm) << " mm, " << t.marker_ids.size() << " markers";
  if (!t.marker_ids.empty()) s << " (ids " << t.marker_ids.front() << "-" << t.marker_ids.back() << ")";
  s << ", " << t.control_points.size() << " control points";
  if (!c.control_points.empty()) s << " in " << c.control_points;
  s << "; detect";
  for (const auto& o : t.detect_options) s << " " << o;
  return s.str();
}

}  // namespace photomill::targets
