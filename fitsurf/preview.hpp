// PNG preview of a fit (issue #9), seen along the normal of the parameter plane: the fitted
// surface shaded by its normal (grey, lit from the upper left), trimmed to the data outline; the
// fitted points as dots coloured by their signed residual (blue below the surface, white on it,
// red above; the scale is symmetric, ±the 99th percentile of |residual|, beyond it saturated);
// robust outliers as black crosses; u and v axes in mm of the parameter plane (issue 27), a colour
// bar in mm and a line of figures. For a person to
// look at; nothing reads it back. Drawn like toolpath's --preview (toolpath/preview.cpp): OpenCV
// polygons on a white canvas, 16x sub-pixel coordinates.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/fitsurf.hpp"

namespace photomill::fitsurf {

struct PreviewOptions {
  int width_px = 1200;          // image width, 400..8000; the height follows the part's aspect ratio
  int surface_cells = 160;      // parameter-grid cells per direction for shading the surface
  std::size_t max_dots = 100000;  // at most this many points drawn (an even subsample, largest |residual| kept)
};

// The image size render_preview_png produces for a part of extent_u x extent_v mm (parameter
// plane): width_px by the plot height (aspect ratio kept, clamped to 100..8000) plus the axes and
// the legend.
Eigen::Vector2i preview_size_px(double extent_u_mm, double extent_v_mm, const PreviewOptions& options = {});

// Encoded PNG bytes. `points` are the fitted points in world mm, in the order of result.fit
// (residual_mm, weight): the input points at result.selection.kept.
std::vector<std::uint8_t> render_preview_png(const Result& result, const std::vector<Eigen::Vector3d>& points,
                                             const PreviewOptions& options = {});

}  // namespace photomill::fitsurf
