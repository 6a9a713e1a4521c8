// Writes a sheet (sheet.hpp) as a one-page PDF 1.4 or as SVG, both at exact scale: the PDF's unit
// is scaled to mm by 72 / 25.4 (PDF 1.4 reference, section 4.2: 1 unit = 1/72 inch by default);
// the SVG's width and height are given in mm with a viewBox in mm (SVG 1.1, section 7.10).
#pragma once

#include <iosfwd>

#include "targets/sheet.hpp"

namespace photomill::targets {

// Text: Courier (a standard font: never embedded), printable ASCII only (others are written '?').
// The black rectangles are one path filled with the non-zero winding rule, so touching cells
// leave no anti-aliasing seams. Throws std::invalid_argument for a non-finite coordinate.
void write_pdf(std::ostream& out, const Sheet& sheet);
void write_svg(std::ostream& out, const Sheet& sheet);

}  // namespace photomill::targets
