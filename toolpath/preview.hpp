// PNG preview of a tool path seen from above (issue 27: a picture read at a glance): x and y axes
// in mm, the surface's extent in light grey with its boundary polygon in green, feed moves
// coloured by the tool tip's height z (viridis, a colour bar in mm), rapids as red dashes, the
// start and end of the cut marked and labelled, gouge points as magenta rings, a line of figures.
// For a person to look at; nothing reads it back.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "formats/uncertainty.hpp"
#include "toolpath/toolpath.hpp"

namespace photomill::toolpath {

struct PreviewOptions {
  int width_px = 1200;       // image width, 400..8000; the height follows the part's aspect ratio
  int surface_cells = 200;   // parameter-grid cells per direction for the surface's extent
  // Uncertainty-aware stock (uncertain_stock.hpp): where stock_k * sigma exceeds stock_threshold_mm
  // the ground is orange, the deeper the more stock (up to the largest), and the legend says so.
  const UncertaintyGrid* stock = nullptr;
  double stock_k = 0;
  double stock_threshold_mm = 0;
};

// The image size render_preview_png produces for a part of extent_x x extent_y mm: width_px by
// the plot height (aspect ratio kept, clamped to 100..8000) plus the axes and the legend line.
Eigen::Vector2i preview_size_px(double extent_x_mm, double extent_y_mm, const PreviewOptions& options = {});

// The colours of the marks, BGR (the tests look for them).
inline const Eigen::Vector3i kRapidBgr(40, 40, 220), kGougeBgr(220, 0, 220), kStartBgr(0, 160, 0), kEndBgr(0, 0, 0),
    kStockBgr(0, 150, 255);

// Encoded PNG bytes. Throws GeometryError if the surface and path have no horizontal extent.
std::vector<std::uint8_t> render_preview_png(const BSplineSurface& surface, const ToolpathResult& path,
                                             const PreviewOptions& options = {});

}  // namespace photomill::toolpath
