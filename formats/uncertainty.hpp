// The uncertainty grid (fitsurf --uncertainty -> toolpath --stock-uncertainty): the standard
// deviation of the fitted surface's height, sigma_mm, on a regular grid over the fit's x, y in the
// world frame (mm). CSV `x_mm,y_mm,sigma_mm`, one row per node, every node of the grid once, under
// a stamp (formats/run.hpp); docs/formats.md, "Uncertainty grids".
#pragma once

#include <cstddef>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

namespace photomill {

struct UncertaintyGrid {
  double x0_mm = 0, y0_mm = 0;  // the first node (smallest x, smallest y)
  double step_mm = 1;           // node spacing, the same along x and y, > 0
  std::size_t nx = 0, ny = 0;   // nodes along x and y (each >= 1)
  std::vector<double> sigma_mm; // nx * ny values, row by row: sigma_mm[j * nx + i] at (x0 + i step, y0 + j step)

  double at(std::size_t i, std::size_t j) const { return sigma_mm[j * nx + i]; }
  // Bilinear between the nodes; outside the grid, the nearest node on its edge (clamped).
  double sample(double x_mm, double y_mm) const;
  // The largest sigma of the nodes within radius_mm of (x, y) and of the bilinear sample there:
  // what a ball of that footprint radius standing at (x, y) must stay above.
  double max_within(double x_mm, double y_mm, double radius_mm) const;
  bool operator==(const UncertaintyGrid&) const = default;
};

// Largest grid a reader accepts (nodes): a 4 m x 4 m part at 1 mm.
constexpr std::size_t kMaxUncertaintyNodes = 16'000'000;

// Throws InputError("source:line: problem") for a missing column, a number that is not one, a
// negative or non-finite sigma, a node given twice, nodes not on one regular grid with equal
// spacing along x and y, a missing node, or no rows.
UncertaintyGrid read_uncertainty_grid(std::istream& in, const std::string& source);
// Throws std::invalid_argument for a grid that is not well formed (sizes, non-finite values).
void write_uncertainty_grid(std::ostream& out, const UncertaintyGrid& grid);

}  // namespace photomill
