// PNG preview of a tool path over its surface, seen from above: the surface shaded by height
// (dark low, light high), the boundary polygon, feed moves in dark blue, rapids in red, gouge
// points as magenta rings. For a person to look at; nothing reads it back.
#pragma once

#include <cstdint>
#include <vector>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "toolpath/toolpath.hpp"

namespace photomill::toolpath {

struct PreviewOptions {
  int width_px = 1200;       // image width; the height follows the part's aspect ratio
  int surface_cells = 200;   // parameter-grid cells per direction for shading the surface
};

// Encoded PNG bytes. Throws GeometryError if the surface and path have no horizontal extent.
std::vector<std::uint8_t> render_preview_png(const BSplineSurface& surface, const ToolpathResult& path,
                                             const PreviewOptions& options = {});

}  // namespace photomill::toolpath
