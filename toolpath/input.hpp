// toolpath's input: one B-spline surface from a photomill surface text file, or one face of a
// STEP or IGES file (through formats/cad.hpp), from a path or stdin ("-").
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "formats/surface.hpp"

namespace photomill::toolpath {

struct LoadedSurface {
  BSplineSurface surface;
  std::size_t face = 0;    // index of the face used (0-based, file order)
  std::size_t faces = 1;   // faces in the input
};

// The kind is chosen by content: a file whose first line starts with ISO-10303-21 is STEP, one
// whose first line is an 80-column IGES record (or whose name ends in .step/.stp/.p21/.iges/.igs)
// goes to Open CASCADE, anything else is read as photomill surface text (so its errors name the
// line). STEP/IGES from stdin pass through a temporary file. `face` picks a face of a CAD file;
// unset: the first. Throws InputError for unreadable input, UsageError for a face out of range.
LoadedSurface load_surface(const std::string& path, std::optional<std::size_t> face);

}  // namespace photomill::toolpath
