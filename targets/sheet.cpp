// Layouts of the target sheets (see sheet.hpp).
#include "targets/sheet.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>

#include "detect/markers.hpp"
#include "formats/error.hpp"
#include "formats/text.hpp"
#include "geometry/board.hpp"

namespace photomill::targets {
namespace {

// Every text is set in Courier (one of PDF's 14 standard fonts, never embedded): each glyph is
// 0.6 em wide, so the layout knows the width of every line exactly.
constexpr double kCharWidthEm = 0.6;
constexpr double kTextMm = 2.5;        // instructions
constexpr double kSmallTextMm = 2.2;   // tick and marker labels
constexpr double kLineSpacing = 1.45;  // baseline to baseline, in font sizes

std::string mm(double v) { return format_double(std::round(v * 1e6) / 1e6); }

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string paper_name(const PageOptions& page, const Eigen::Vector2d& size) {
  return page.paper + (size.x() > size.y() ? " landscape" : " portrait");
}

// The marker's cells, row 0 at the top, true = black, border included ((bits + 2)^2 cells), as
// OpenCV draws it (cv::aruco::drawMarker with one border bit).
std::vector<std::vector<bool>> marker_cells(const detect::MarkerDictionary& dictionary, int id) {
  const int n = dictionary.bits_per_side() + 2;
  cv::Mat image;
  cv::aruco::drawMarker(dictionary.opencv(), id, n, image, 1);
  std::vector<std::vector<bool>> cells(static_cast<std::size_t>(n), std::vector<bool>(static_cast<std::size_t>(n)));
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) cells[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)] = image.at<unsigned char>(r, c) < 128;
  }
  return cells;
}

// Adds a marker whose top-left corner (corner 0) is at `top_left` (page frame, y up), side `side`:
// each row's runs of black cells as one rectangle.
void add_marker(Sheet& sheet, const std::vector<std::vector<bool>>& cells, const Eigen::Vector2d& top_left, double side) {
  const double cell = side / static_cast<double>(cells.size());
  for (std::size_t r = 0; r < cells.size(); ++r) {
    const auto& row = cells[r];
    for (std::size_t c = 0; c < row.size();) {
      if (!row[c]) {
        ++c;
        continue;
      }
      std::size_t end = c;
      while (end < row.size() && row[end]) ++end;
      sheet.black.push_back({top_left.x() + static_cast<double>(c) * cell, top_left.y() - static_cast<double>(r + 1) * cell,
                             static_cast<double>(end - c) * cell, cell});
      c = end;
    }
  }
}

void add_text(Sheet& sheet, double x, double y, double size, std::string text) {
  sheet.texts.push_back({x, y, size, std::move(text)});
}

// Splits a paragraph into lines of at most `width_chars` characters at spaces.
std::vector<std::string> wrap(const std::string& paragraph, std::size_t width_chars) {
  std::vector<std::string> lines;
  std::istringstream words(paragraph);
  std::string word, line;
  while (words >> word) {
    if (!line.empty() && line.size() + 1 + word.size() > width_chars) {
      lines.push_back(line);
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

// The footer: the 100 mm check line with its ticks at the bottom margin, the paragraphs above it.
// Returns the height it takes from the bottom margin up.
double footer_height(const std::vector<std::string>& paragraphs, double width_mm) {
  const auto chars = static_cast<std::size_t>(std::floor(width_mm / (kCharWidthEm * kTextMm)));
  std::size_t lines = 0;
  for (const auto& p : paragraphs) lines += wrap(p, chars).size();
  return 12.0 + static_cast<double>(lines) * kLineSpacing * kTextMm + 2.0;
}

void add_footer(Sheet& sheet, const std::vector<std::string>& paragraphs, double margin_mm) {
  const double width = sheet.width_mm - 2 * margin_mm;
  const double x0 = margin_mm;
  const double labels = margin_mm;  // baseline of the tick labels
  const double line_y = labels + 4.0;
  // 100.0 mm check line: the distance between the outer edges of the two end ticks' centre lines
  // is what the user measures; the line itself runs exactly from x0 to x0 + 100.
  sheet.lines.push_back({{x0, line_y}, {x0 + 100, line_y}, 0.25, 0});
  for (int t = 0; t <= 100; t += 10) {
    const double len = (t % 50 == 0) ? 4.0 : 2.0;
    sheet.lines.push_back({{x0 + t, line_y}, {x0 + t, line_y + len}, 0.25, 0});
  }
  for (int t = 1; t < 100; ++t) {
    if (t % 10 == 0) continue;
    sheet.lines.push_back({{x0 + t, line_y}, {x0 + t, line_y + 1.0}, 0.12, 0});
  }
  add_text(sheet, x0 - 0.5 * kCharWidthEm * kSmallTextMm, labels, kSmallTextMm, "0");
  add_text(sheet, x0 + 50 - 1.0 * kCharWidthEm * kSmallTextMm, labels, kSmallTextMm, "50");
  add_text(sheet, x0 + 100 - 1.5 * kCharWidthEm * kSmallTextMm, labels, kSmallTextMm, "100");
  add_text(sheet, x0 + 104, line_y, kTextMm, "<- must measure 100.0 mm");
  const auto chars = static_cast<std::size_t>(std::floor(width / (kCharWidthEm * kTextMm)));
  std::vector<std::string> lines;
  for (const auto& p : paragraphs) {
    const auto w = wrap(p, chars);
    lines.insert(lines.end(), w.begin(), w.end());
  }
  double y = labels + 12.0 + static_cast<double>(lines.size() - 1) * kLineSpacing * kTextMm;
  for (const auto& l : lines) {
    add_text(sheet, x0, y, kTextMm, l);
    y -= kLineSpacing * kTextMm;
  }
}

std::string print_paragraph(const std::string& if_wrong) {
  return "Print at 100 % (actual size, no 'fit to page'), on matte paper, and glue it flat on something stiff "
         "(foam board, glass, aluminium); keep the white space round the markers. The line below must measure "
         "100.0 mm: " + if_wrong;
}

std::string command_paragraph(const PageOptions& page) {
  return page.command.empty() ? "" : "Made by: " + page.command;
}

std::vector<std::string> non_empty(std::vector<std::string> v) {
  v.erase(std::remove(v.begin(), v.end(), std::string()), v.end());
  return v;
}

std::string id_range(int first, int last) {
  return first == last ? std::to_string(first) : std::to_string(first) + "-" + std::to_string(last);
}

detect::MarkerDictionary load_dictionary(const std::string& name, const std::string& file) {
  return file.empty() ? detect::MarkerDictionary::predefined(name) : detect::MarkerDictionary::from_file(file);
}

// The page sizes to try: the one asked for, or both orientations (`preferred` first).
std::vector<Eigen::Vector2d> candidate_pages(const PageOptions& page, bool landscape_first) {
  const Eigen::Vector2d p = paper_size_mm(page.paper);
  const Eigen::Vector2d portrait(std::min(p.x(), p.y()), std::max(p.x(), p.y()));
  const Eigen::Vector2d landscape(portrait.y(), portrait.x());
  switch (page.orientation) {
    case Orientation::Portrait: return {portrait};
    case Orientation::Landscape: return {landscape};
    case Orientation::Auto: break;
  }
  if (portrait.x() == portrait.y()) return {portrait};
  return landscape_first ? std::vector<Eigen::Vector2d>{landscape, portrait} : std::vector<Eigen::Vector2d>{portrait, landscape};
}

void check_margin(const PageOptions& page) {
  if (!(page.margin_mm >= 0) || !std::isfinite(page.margin_mm)) throw UsageError("--margin-mm must be 0 or more");
}

}  // namespace

Eigen::Vector2d paper_size_mm(const std::string& paper) {
  static const std::map<std::string, Eigen::Vector2d> sizes{
      {"a5", {148, 210}},       {"a4", {210, 297}},        {"a3", {297, 420}},        {"a2", {420, 594}},
      {"letter", {215.9, 279.4}}, {"legal", {215.9, 355.6}}, {"tabloid", {279.4, 431.8}}};
  const auto it = sizes.find(lower(paper));
  if (it != sizes.end()) return it->second;
  const auto x = paper.find_first_of("xX");
  if (x != std::string::npos) {
    const auto w = parse_double(paper.substr(0, x));
    const auto h = parse_double(paper.substr(x + 1));
    if (w && h && *w >= 50 && *h >= 50 && *w <= 5000 && *h <= 5000) return {*w, *h};
  }
  throw UsageError("--paper '" + paper + "': not A5, A4, A3, A2, Letter, Legal, Tabloid or WxH in mm (50 to 5000)");
}

TargetSheet charuco_sheet(const CharucoTarget& target, const PageOptions& page) {
  check_margin(page);
  geometry::BoardSpec spec;
  spec.kind = geometry::BoardKind::Charuco;
  spec.cols = target.squares_x;
  spec.rows = target.squares_y;
  spec.square_mm = target.square_mm;
  spec.marker_mm = target.marker_mm;
  spec.dictionary = target.dictionary;
  geometry::validate_board_geometry(spec);
  const auto dictionary = detect::MarkerDictionary::predefined(target.dictionary);
  const int squares = target.squares_x * target.squares_y;
  const int markers = squares / 2;
  if (markers > dictionary.marker_count()) {
    throw UsageError("a " + std::to_string(target.squares_x) + "x" + std::to_string(target.squares_y) + " ChArUco board needs " +
                     std::to_string(markers) + " markers; " + target.dictionary + " has " +
                     std::to_string(dictionary.marker_count()) + ": use a larger dictionary");
  }
  const double cell = target.marker_mm / (dictionary.bits_per_side() + 2);
  if (cell < 0.5) {
    throw UsageError("--marker-mm " + mm(target.marker_mm) + ": the marker's cells would be " + mm(cell) +
                     " mm, too small to print and to photograph (0.5 mm at least)");
  }
  const double board_w = target.squares_x * target.square_mm;
  const double board_h = target.squares_y * target.square_mm;

  TargetSheet out;
  const std::string size_text = std::to_string(target.squares_x) + "x" + std::to_string(target.squares_y);
  out.detect_options = {"--charuco", size_text,          "--square-mm", mm(target.square_mm),
                        "--marker-mm", mm(target.marker_mm), "--dict",      target.dictionary};
  const std::vector<std::string> paragraphs = non_empty(
      {"photomill ChArUco calibration board: " + size_text + " squares of " + mm(target.square_mm) + " mm, markers of " +
           mm(target.marker_mm) + " mm, " + target.dictionary + " ids 0-" + std::to_string(markers - 1) + ".",
       "Give detect and calib: --charuco " + size_text + " --square-mm S --marker-mm " + mm(target.marker_mm) +
           " --dict " + target.dictionary + " (Makefile.example: BOARD=" + size_text + " BOARD_SQUARE_MM=S BOARD_MARKER_MM=" +
           mm(target.marker_mm) + " BOARD_DICT=" + target.dictionary + "), S = " + mm(target.square_mm) +
           " mm if the check line measures 100.0 mm.",
       print_paragraph("if it measures L mm, the squares are " + mm(target.square_mm) +
                       " x L / 100 mm: measure one with a caliper and give that as S."),
       command_paragraph(page)});

  // Fit: the board in the printable area above the footer, in the orientation where it fits with
  // the most room (landscape first when the board is wider than high).
  std::optional<Eigen::Vector2d> chosen;
  double best_room = -1;
  std::ostringstream tried;
  for (const auto& size : candidate_pages(page, board_w > board_h)) {
    const double w = size.x() - 2 * page.margin_mm;
    const double h = size.y() - 2 * page.margin_mm - footer_height(paragraphs, w) - 3;
    const double room = std::min(w / board_w, h / board_h);
    tried << (tried.tellp() > 0 ? ", " : "") << mm(w) << " x " << mm(std::max(0.0, h)) << " mm ("
          << paper_name(page, size) << ")";
    if (room >= 1 && room > best_room) {
      best_room = room;
      chosen = size;
    }
  }
  if (!chosen) {
    throw UsageError("the " + size_text + " board of " + mm(target.square_mm) + " mm squares is " + mm(board_w) + " x " +
                     mm(board_h) + " mm and does not fit the printable area above the instructions, " + tried.str() +
                     ": give smaller --square-mm, fewer --squares or a larger --paper");
  }
  Sheet& sheet = out.sheet;
  sheet.width_mm = chosen->x();
  sheet.height_mm = chosen->y();
  sheet.title = "photomill ChArUco board " + size_text + ", " + mm(target.square_mm) + " mm, " + target.dictionary;
  const double footer = footer_height(paragraphs, sheet.width_mm - 2 * page.margin_mm);
  const double area_bottom = page.margin_mm + footer + 3;
  const double area_top = sheet.height_mm - page.margin_mm;
  const double left = (sheet.width_mm - board_w) / 2;
  const double bottom = (area_bottom + area_top - board_h) / 2;
  const double top = bottom + board_h;

  // OpenCV's board: which squares hold which marker (ids in its order), and whether its board
  // frame has y down (OpenCV 4.6: corner 3 of a marker below corner 0 at larger y) or up.
  const auto board = cv::aruco::CharucoBoard::create(target.squares_x, target.squares_y, static_cast<float>(target.square_mm),
                                                     static_cast<float>(target.marker_mm), dictionary.opencv());
  const bool y_down = board->objPoints.front()[3].y > board->objPoints.front()[0].y;
  std::vector<bool> holds_marker(static_cast<std::size_t>(squares), false);
  const double inset = (target.square_mm - target.marker_mm) / 2;
  for (std::size_t i = 0; i < board->objPoints.size(); ++i) {
    const auto& c = board->objPoints[i];
    const double cx = (c[0].x + c[2].x) / 2, cy = (c[0].y + c[2].y) / 2;
    const int sx = static_cast<int>(std::floor(cx / target.square_mm));
    const int sy = static_cast<int>(std::floor(cy / target.square_mm));
    holds_marker[static_cast<std::size_t>(sy * target.squares_x + sx)] = true;
    // Square (sx, sy) of the board frame on the page: its top edge.
    const double square_top = y_down ? top - sy * target.square_mm : bottom + (sy + 1) * target.square_mm;
    add_marker(sheet, marker_cells(dictionary, board->ids[i]),
               {left + sx * target.square_mm + inset, square_top - inset}, target.marker_mm);
    out.marker_ids.push_back(board->ids[i]);
  }
  for (int sy = 0; sy < target.squares_y; ++sy) {
    for (int sx = 0; sx < target.squares_x; ++sx) {
      if (holds_marker[static_cast<std::size_t>(sy * target.squares_x + sx)]) continue;
      const double square_bottom = y_down ? top - (sy + 1) * target.square_mm : bottom + sy * target.square_mm;
      sheet.black.push_back({left + sx * target.square_mm, square_bottom, target.square_mm, target.square_mm});
    }
  }
  add_footer(sheet, paragraphs, page.margin_mm);
  out.control_points = geometry::board_control_points(spec);
  return out;
}

namespace {

// The plate's measures (mm), checked.
struct PlateGeometry {
  double s = 0;           // side of a marker
  double cell = 0;        // side of one of its cells
  double pitch = 0;       // smallest distance between marker centres
  double label_room = 0;  // height a marker label takes under a marker
  bool labels = false;    // whether the markers get labels
  double bar_strip = 0;   // height of the scale bar's strip (0: no scale bar)
  std::string dict_name;  // the dictionary as the paragraphs name it
};

PlateGeometry plate_geometry(const PlateTarget& target, const detect::MarkerDictionary& dictionary) {
  PlateGeometry g;
  const double s = target.marker_mm;
  g.s = s;
  const double cell = s / (dictionary.bits_per_side() + 2);
  g.cell = cell;
  if (cell < 0.5) {
    throw UsageError("--marker-mm " + mm(s) + ": the marker's cells would be " + mm(cell) +
                     " mm, too small to print and to photograph (0.5 mm at least)");
  }
  // Quiet zone: at least one cell of white on each side of a marker (OpenCV's detector needs the
  // marker's black border to stand on white).
  const double min_pitch = s + 2 * cell;
  const double pitch = target.pitch_mm > 0 ? target.pitch_mm : 2 * s;
  g.pitch = pitch;
  if (pitch < min_pitch || !std::isfinite(pitch)) {
    throw UsageError("--pitch-mm " + mm(pitch) + ": markers of " + mm(s) + " mm need " + mm(min_pitch) +
                     " mm at least between centres (one cell of white on each side)");
  }
  // The marker labels ("id 12") go one cell below each marker, when the gap leaves room for them.
  g.label_room = cell + 1.2 * kSmallTextMm;
  g.labels = pitch - s >= cell + g.label_room;
  g.dict_name = target.dictionary_file.empty() ? target.dictionary : target.dictionary_file;
  g.bar_strip = target.scale_bar_mm > 0 ? s + 2 * cell + g.label_room + 6 : 0;
  return g;
}

// The plate's footer paragraphs for `count` markers.
std::vector<std::string> plate_paragraphs(const PlateTarget& target, const PageOptions& page, const PlateGeometry& g,
                                          const std::vector<std::string>& detect_options, int count) {
  const int last = target.first_id + count - 1;
  std::vector<std::string> p{
      "photomill marker plate: " + std::to_string(count) + " ArUco markers of " + mm(g.s) + " mm, " + g.dict_name + ", ids " +
          id_range(target.first_id, last) +
          ". Control points (the CSV written with this sheet): point_id = id x 4 + corner, corners 0 top-left, "
          "1 top-right, 2 bottom-right, 3 bottom-left; " +
          (target.layout == PlateLayout::Ring ? "origin at the cross" : "origin at the centre of the grid") +
          ", x right, y up, z = 0 on the sheet, mm. Find them with: detect " + detect_options[0] + " " +
          detect_options[1] + ".",
      print_paragraph("if it measures L mm, multiply the control points by L / 100 (or reprint).")};
  if (target.scale_bar_mm > 0) {
    p.push_back("Scale bar (the strip at the bottom): markers " + std::to_string(last + 1) + " and " +
                std::to_string(last + 2) + ", corresponding corners " + mm(target.scale_bar_mm) +
                " mm apart (the scale bars CSV written with this sheet); cut it out and glue it on a straight stiff bar.");
  }
  p.push_back(command_paragraph(page));
  return non_empty(p);
}

// Where the markers go on one page size.
struct MarkerLayout {
  Eigen::Vector2d page;
  std::vector<Eigen::Vector2d> top_left;  // page frame
  Eigen::Vector2d centre;
  double area_bottom = 0;
};

// The markers on a page of `size` whose footer is that of `count_guess` markers: a ring round the
// printable area or a grid over it, spread evenly with the first and last at its edges.
MarkerLayout layout_on(const PlateTarget& target, const PageOptions& page, const PlateGeometry& g,
                       const std::vector<std::string>& detect_options, const Eigen::Vector2d& size, int count_guess) {
  const double s = g.s;
  // Positions along one side of the area: n markers spread evenly, the first and last at its ends.
  auto spread = [&](double length) {
    const int n = static_cast<int>(std::floor((length - s) / g.pitch + 1e-9)) + 1;
    return n;
  };
  MarkerLayout l;
  l.page = size;
  const double w = size.x() - 2 * page.margin_mm;
  const double footer = footer_height(plate_paragraphs(target, page, g, detect_options, count_guess), w);
  l.area_bottom = page.margin_mm + footer + 3 + g.bar_strip;
  const double area_left = page.margin_mm, area_right = size.x() - page.margin_mm;
  const double area_top = size.y() - page.margin_mm;
  const double bottom = l.area_bottom + (g.labels ? g.label_room : 0);  // lowest marker's bottom edge
  const double aw = area_right - area_left, ah = area_top - bottom;
  if (aw < s || ah < s) return l;
  const int nx = spread(aw), ny = spread(ah);
  auto x_at = [&](int i, int n) { return n == 1 ? area_left + (aw - s) / 2 : area_left + i * (aw - s) / (n - 1); };
  auto y_at = [&](int j, int n) { return n == 1 ? area_top - (ah - s) / 2 : area_top - j * (ah - s) / (n - 1); };  // top edge
  if (target.layout == PlateLayout::Grid) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) l.top_left.push_back({x_at(i, nx), y_at(j, ny)});
    }
  } else if (nx >= 2 && ny >= 2) {
    for (int i = 0; i < nx; ++i) l.top_left.push_back({x_at(i, nx), y_at(0, ny)});
    for (int j = 1; j < ny - 1; ++j) l.top_left.push_back({x_at(nx - 1, nx), y_at(j, ny)});
    for (int i = nx - 1; i >= 0; --i) l.top_left.push_back({x_at(i, nx), y_at(ny - 1, ny)});
    for (int j = ny - 2; j >= 1; --j) l.top_left.push_back({x_at(0, nx), y_at(j, ny)});
  }
  l.centre = {area_left + aw / 2, bottom + ah / 2};
  return l;
}

// The page size (of those candidate_pages allows) that holds the most markers, 4 at least.
MarkerLayout choose_layout(const PlateTarget& target, const PageOptions& page, const PlateGeometry& g,
                           const std::vector<std::string>& detect_options) {
  std::optional<MarkerLayout> chosen;
  std::ostringstream tried;
  for (const auto& size : candidate_pages(page, true)) {
    // The footer's height depends on the id range's digits only: lay out twice to settle it.
    MarkerLayout l = layout_on(target, page, g, detect_options, size, 1);
    l = layout_on(target, page, g, detect_options, size, std::max<int>(1, static_cast<int>(l.top_left.size())));
    tried << (tried.tellp() > 0 ? ", " : "") << l.top_left.size() << " on " << paper_name(page, size);
    if (l.top_left.size() < 4) continue;
    if (!chosen || l.top_left.size() > chosen->top_left.size()) chosen = l;
  }
  if (!chosen) {
    throw UsageError("markers of " + mm(g.s) + " mm at a pitch of " + mm(g.pitch) + " mm: fewer than 4 fit the sheet (" +
                     tried.str() + "): give smaller --marker-mm or --pitch-mm, or a larger --paper");
  }
  return *chosen;
}

// The scale bar's strip under the area of `layout`: markers first_id + count and the next, their
// labels, the bar's length, cut lines, and the four scale bars (one per corner).
void add_scale_bar(const PlateTarget& target, const PageOptions& page, const PlateGeometry& g,
                   const detect::MarkerDictionary& dictionary, const MarkerLayout& layout, int count, TargetSheet& out) {
  Sheet& sheet = out.sheet;
  const double s = g.s, cell = g.cell;
  const double strip_top = layout.area_bottom - 3;
  const double strip_bottom = strip_top - g.bar_strip + 3;
  const double length = target.scale_bar_mm;
  if (length < s + 2 * cell || length + s > sheet.width_mm - 2 * page.margin_mm - 2 * cell) {
    throw UsageError("--scale-bar-mm " + mm(length) + ": the bar's two markers need " + mm(s + 2 * cell) +
                     " mm at least and " + mm(sheet.width_mm - 2 * page.margin_mm - 2 * cell - s) +
                     " mm at most on this sheet");
  }
  const double x0 = (sheet.width_mm - length - s) / 2;
  const double y_top = strip_top - cell;
  const int a = target.first_id + count, b = a + 1;
  add_marker(sheet, marker_cells(dictionary, a), {x0, y_top}, s);
  add_marker(sheet, marker_cells(dictionary, b), {x0 + length, y_top}, s);
  add_text(sheet, x0, y_top - s - cell - kSmallTextMm, kSmallTextMm, "id " + std::to_string(a));
  add_text(sheet, x0 + length, y_top - s - cell - kSmallTextMm, kSmallTextMm, "id " + std::to_string(b));
  add_text(sheet, x0 + s + 2 * cell, y_top - s / 2, kSmallTextMm, "scale bar: " + mm(length) + " mm, corner to corner");
  // Cut lines round the strip.
  const double l = x0 - 2 * cell, r = x0 + length + s + 2 * cell;
  const Eigen::Vector2d p[4] = {{l, strip_bottom}, {r, strip_bottom}, {r, strip_top}, {l, strip_top}};
  for (int k = 0; k < 4; ++k) sheet.lines.push_back({p[k], p[(k + 1) % 4], 0.15, 0.5});
  for (int c = 0; c < 4; ++c) {
    out.scale_bars.push_back({static_cast<PointId>(a) * 4 + c, static_cast<PointId>(b) * 4 + c, length, {}});
  }
}

}  // namespace

TargetSheet plate_sheet(const PlateTarget& target, const PageOptions& page) {
  check_margin(page);
  if (!(target.marker_mm > 0) || !std::isfinite(target.marker_mm)) throw UsageError("--marker-mm must be a positive number");
  if (target.first_id < 0) throw UsageError("--first-id must be 0 or more");
  if (!(target.scale_bar_mm >= 0) || !std::isfinite(target.scale_bar_mm)) throw UsageError("--scale-bar-mm must be 0 or more");
  const auto dictionary = load_dictionary(target.dictionary, target.dictionary_file);
  const PlateGeometry g = plate_geometry(target, dictionary);
  const double s = g.s;

  TargetSheet out;
  out.detect_options = target.dictionary_file.empty() ? std::vector<std::string>{"--aruco", target.dictionary}
                                                       : std::vector<std::string>{"--aruco-dict-file", target.dictionary_file};
  const MarkerLayout chosen = choose_layout(target, page, g, out.detect_options);
  const int count = static_cast<int>(chosen.top_left.size());
  const int extra = target.scale_bar_mm > 0 ? 2 : 0;
  if (target.first_id + count + extra > dictionary.marker_count()) {
    throw UsageError("the plate needs ids " + id_range(target.first_id, target.first_id + count + extra - 1) + "; " +
                     g.dict_name + " has " + std::to_string(dictionary.marker_count()) +
                     " markers: use a larger dictionary, a smaller --first-id, or larger --marker-mm or --pitch-mm");
  }

  Sheet& sheet = out.sheet;
  sheet.width_mm = chosen.page.x();
  sheet.height_mm = chosen.page.y();
  sheet.title = "photomill marker plate, " + g.dict_name + " ids " + id_range(target.first_id, target.first_id + count - 1) +
                ", " + mm(s) + " mm";
  const Eigen::Vector2d origin = chosen.centre;
  for (int k = 0; k < count; ++k) {
    const int id = target.first_id + k;
    const Eigen::Vector2d tl = chosen.top_left[static_cast<std::size_t>(k)];
    add_marker(sheet, marker_cells(dictionary, id), tl, s);
    out.marker_ids.push_back(id);
    const Eigen::Vector2d corners[4] = {tl, tl + Eigen::Vector2d(s, 0), tl + Eigen::Vector2d(s, -s), tl + Eigen::Vector2d(0, -s)};
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d w = corners[c] - origin;
      out.control_points.push_back({static_cast<PointId>(id) * 4 + c, Eigen::Vector3d(w.x(), w.y(), 0), {}});
    }
    if (g.labels) add_text(sheet, tl.x(), tl.y() - s - g.cell - kSmallTextMm, kSmallTextMm, "id " + std::to_string(id));
  }
  if (target.layout == PlateLayout::Ring) {
    // The frame's origin and axes, under the part.
    sheet.lines.push_back({origin - Eigen::Vector2d(5, 0), origin + Eigen::Vector2d(20, 0), 0.25, 0.4});
    sheet.lines.push_back({origin - Eigen::Vector2d(0, 5), origin + Eigen::Vector2d(0, 20), 0.25, 0.4});
    add_text(sheet, origin.x() + 21, origin.y() - 0.4 * kTextMm, kTextMm, "x");
    add_text(sheet, origin.x() - 0.3 * kTextMm, origin.y() + 21.5, kTextMm, "y");
  }
  if (target.scale_bar_mm > 0) add_scale_bar(target, page, g, dictionary, chosen, count, out);
  add_footer(sheet, plate_paragraphs(target, page, g, out.detect_options, count), page.margin_mm);
  return out;
}

}  // namespace photomill::targets
