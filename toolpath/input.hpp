// toolpath's input: one B-spline surface from a photomill surface text file, or one face of a
// STEP or IGES file (through formats/cad.hpp), from a path or stdin ("-").
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include <vector>

#include "formats/surface.hpp"
#include "toolpath/mesh_drop.hpp"

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
// unset: the first. Throws InputError for unreadable input and for a surface not in mm (`units
// arbitrary`: toolpath, rough and cutsim work in mm), UsageError for a face out of range.
LoadedSurface load_surface(const std::string& path, std::optional<std::size_t> face);

// A whole STEP or IGES part (path or "-"): every face with S_u x S_v pointing out of the material
// (faces reversed in their shell mirrored in u, iso_passes.hpp's mirrored_u), and a triangle mesh
// of all faces within `mesh_deflection_mm` of them (a part of one face only when
// `mesh_one_face`: it has no neighbours to check against). Throws InputError for input that is not
// STEP/IGES (a photomill surface text is one surface: no part) or that Open CASCADE refuses.
struct LoadedPart {
  std::vector<BSplineSurface> faces;
  TriangleMesh mesh;
  std::vector<int> triangle_face;  // the face of each mesh triangle
};
LoadedPart load_part(const std::string& path, double mesh_deflection_mm, bool mesh_one_face);

}  // namespace photomill::toolpath
