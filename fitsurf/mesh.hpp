// A triangle mesh of a B-spline surface for viewers (MeshLab, CloudCompare, FreeCAD, slicers):
// binary STL or Wavefront OBJ with vertex normals. The surface is sampled on a regular (u,v) grid
// of about step_mm in space; when it has a boundary polygon only the grid cells whose centre
// lies inside it are kept. Units mm.
#pragma once

#include <ostream>
#include <string>

#include "formats/surface.hpp"

namespace photomill::fitsurf {

enum class MeshFormat { Stl, Obj };

// By extension: .stl or .obj (any case). Throws UsageError otherwise.
MeshFormat mesh_format_for(const std::string& path);

struct MeshOptions {
  double step_mm = 1.0;    // target spacing of the samples along each direction
  int max_samples = 2000;  // per direction, at most
};

struct MeshCounts {
  std::size_t vertices = 0, triangles = 0;
};

// Throws UsageError for a non-positive step.
MeshCounts write_mesh(std::ostream& out, const BSplineSurface& surface, MeshFormat format,
                      const MeshOptions& options = {});

}  // namespace photomill::fitsurf
