// Board geometry (see board.hpp).
#include "geometry/board.hpp"

#include <algorithm>
#include <cmath>

#include "formats/error.hpp"

namespace photomill::geometry {

std::pair<int, int> parse_grid(const std::string& text, const std::string& what) {
  const auto x = text.find_first_of("xX");
  auto parse = [&](const std::string& s) {
    if (s.empty() || s.size() > 4 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      throw UsageError(what + ": expected COLSxROWS such as 9x6, got '" + text + "'");
    }
    return std::stoi(s);
  };
  if (x == std::string::npos) throw UsageError(what + ": expected COLSxROWS such as 9x6, got '" + text + "'");
  return {parse(text.substr(0, x)), parse(text.substr(x + 1))};
}

void validate_board_geometry(const BoardSpec& spec) {
  if (!(spec.square_mm > 0) || !std::isfinite(spec.square_mm)) {
    throw UsageError("--square-mm must be a positive number");
  }
  if (spec.kind == BoardKind::Chessboard) {
    if (spec.cols < 2 || spec.rows < 2) throw UsageError("a chessboard needs at least 2x2 inner corners");
    return;
  }
  if (spec.cols < 2 || spec.rows < 2) throw UsageError("a ChArUco board needs at least 2x2 squares");
  if (!(spec.marker_mm > 0) || !(spec.marker_mm < spec.square_mm)) {
    throw UsageError("--marker-mm must be positive and smaller than --square-mm");
  }
}

int board_corner_count(const BoardSpec& spec) {
  return spec.kind == BoardKind::Chessboard ? spec.cols * spec.rows : (spec.cols - 1) * (spec.rows - 1);
}

std::vector<ControlPoint> board_control_points(const BoardSpec& spec) {
  // Only the geometry matters here (calib builds control points without marker or dictionary).
  if (!(spec.square_mm > 0) || !std::isfinite(spec.square_mm)) throw UsageError("--square-mm must be a positive number");
  if (spec.cols < 2 || spec.rows < 2) throw UsageError("a board needs at least 2x2 corners or squares");
  // Chessboard: corner (c, r) at (c, r) * square, as OpenCV's calibration sample builds it.
  // ChArUco: inner corner (c, r) at (c + 1, r + 1) * square (OpenCV 4.6 CharucoBoard::create).
  const int per_row = spec.kind == BoardKind::Chessboard ? spec.cols : spec.cols - 1;
  const int offset = spec.kind == BoardKind::Chessboard ? 0 : 1;
  std::vector<ControlPoint> points;
  for (int id = 0; id < board_corner_count(spec); ++id) {
    const int c = id % per_row;
    const int r = id / per_row;
    points.push_back({id, Eigen::Vector3d((c + offset) * spec.square_mm, (r + offset) * spec.square_mm, 0), {}});
  }
  return points;
}

}  // namespace photomill::geometry
