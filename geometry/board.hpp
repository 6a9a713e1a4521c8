// The geometry of planar calibration boards (chessboard, ChArUco): their size, corner numbering
// and control points. Shared by detect (which finds the corners in photos) and calib (which
// needs only the board's geometry); what the ArUco dictionaries hold stays in detect.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "formats/tables.hpp"

namespace photomill::geometry {

enum class BoardKind { Chessboard, Charuco };

// A planar calibration board. Board frame: origin at the corner of the first square (ChArUco) or
// at inner corner 0 (chessboard), x along a row, y along a column, z = 0 on the board, mm.
struct BoardSpec {
  BoardKind kind = BoardKind::Chessboard;
  // Chessboard: inner corners per row and per column (OpenCV's patternSize, "9x6").
  // ChArUco: squares along x and along y (OpenCV's squaresX, squaresY, "5x7").
  int cols = 0;
  int rows = 0;
  double square_mm = 1;                      // side of one chessboard square
  double marker_mm = 0;                      // ChArUco: side of one marker (< square_mm)
  std::string dictionary = "DICT_6X6_250";   // ChArUco: OpenCV's predefined dictionary name
};

// Parses "9x6" (also "9X6") into two positive integers; throws UsageError naming `what`.
std::pair<int, int> parse_grid(const std::string& text, const std::string& what);

// Checks the board's sizes (square, grid, marker < square); throws UsageError. detect's
// validate_board adds the dictionary's checks.
void validate_board_geometry(const BoardSpec& spec);

// Number of corners of the board and their control points: point_id = corner index (row-major,
// as OpenCV numbers them), xyz in the board frame, mm, z = 0.
int board_corner_count(const BoardSpec& spec);
std::vector<ControlPoint> board_control_points(const BoardSpec& spec);

}  // namespace photomill::geometry
