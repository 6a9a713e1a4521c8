// What the surfaces look like: albedo (0..1) as a function of the plate-plane position, with a
// box pre-filter of the given footprint so that marker edges render with their exact area
// coverage (unbiased sub-pixel edges) instead of stair steps.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "formats/tables.hpp"
#include "tools/synth/scene.hpp"

namespace photomill::synth {

// Reflectances of the printed inks and surroundings.
struct Palette {
  double black = 0.05;     // marker and board ink
  double white = 0.90;     // paper, marker quiet zone
  double speckle_dark = 0.12;
  double speckle_light = 0.85;
  double table = 0.30;     // beyond the plate / around the board sheet
};

// Hash-based value noise in [0, 1) on the integer lattice with quintic interpolation: smooth,
// infinite, a pure function of (x, y, seed).
double value_noise(double x, double y, std::uint64_t seed);

// The bits of an ArUco marker, border included: (bits + 2)^2 cells, row 0 at the top (the
// marker's corners 0 and 1), 1 = white, as cv::aruco::drawMarker draws them.
struct MarkerBits {
  int cells = 0;  // bits + 2
  std::vector<std::uint8_t> white;  // cells * cells, row-major
};
MarkerBits marker_bits(const std::string& dictionary, int id);

// Texture of the plate and the part (both use plate-plane coordinates (x, y); part markers are
// draped vertically onto the surface).
class PartTexture {
public:
  explicit PartTexture(const PartScene& scene, Palette palette = {});
  // Albedo at (x, y) averaged over a square footprint of side `footprint_mm` (0: point sample).
  double albedo(double x, double y, double footprint_mm) const;
  // Albedo of a walled part's side at (along the side, height): the same speckle, no markers.
  double wall_albedo(double along_mm, double z_mm, double footprint_mm) const;

private:
  struct Placed {
    const Marker* marker;
    MarkerBits bits;
    double cell_mm;
    double x0, x1, y0, y1;  // quiet-zone box
  };
  const PartScene& scene_;
  Palette palette_;
  std::vector<Placed> markers_;
  // Uniform grid over the plate: for each cell, the indices of the markers whose box touches it.
  double grid_mm_ = 8;
  int grid_nx_ = 0, grid_ny_ = 0;
  std::vector<std::vector<int>> grid_;
  double speckle(double x, double y, double footprint_mm) const;
};

// The ChArUco board as OpenCV defines it (cv::aruco::CharucoBoard::create with lengths in mm),
// in the board frame: chessboard in [0, nx s] x [0, ny s] at z = 0, markers where OpenCV puts
// them, a white sheet margin around it.
class BoardTexture {
public:
  explicit BoardTexture(const BoardSpec& spec, Palette palette = {});
  double albedo(double x, double y, double footprint_mm) const;
  // ChArUco corners (inner chessboard corners) as control points: point_id = charuco corner id.
  const std::vector<ControlPoint>& corners() const { return corners_; }
  // Sheet extent in the board frame.
  double x_min() const { return -spec_.sheet_margin_mm; }
  double y_min() const { return -spec_.sheet_margin_mm; }
  double x_max() const { return spec_.squares_x * spec_.square_mm + spec_.sheet_margin_mm; }
  double y_max() const { return spec_.squares_y * spec_.square_mm + spec_.sheet_margin_mm; }
  const BoardSpec& spec() const { return spec_; }
  // +1 or -1: the printed side faces +z or -z of the board frame. OpenCV's board frame has y
  // down the printed page, so its printed side faces -z (cameras see it from z < 0).
  double printed_side() const { return printed_side_; }

private:
  struct Square {
    int marker = -1;  // index into markers_, -1: black square
  };
  struct BoardMarker {
    MarkerBits bits;
    Eigen::Vector2d origin;   // corner 0
    Eigen::Vector2d ex, ey;   // unit vectors corner 0 -> 1 and corner 0 -> 3
    double cell_mm;
  };
  BoardSpec spec_;
  Palette palette_;
  std::vector<Square> squares_;  // squares_x * squares_y, index j * squares_x + i
  std::vector<BoardMarker> markers_;
  std::vector<ControlPoint> corners_;
  double printed_side_ = -1;
  double square_value(int i, int j, double x, double y, double footprint_mm) const;
};

}  // namespace photomill::synth
