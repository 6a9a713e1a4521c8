// STEP (AP214) and IGES (5.3) import/export of B-spline faces through Open CASCADE 7.6.
// Lengths are millimetres in both directions; knots, poles and weights are carried exactly
// (written with 17 significant digits). Open CASCADE never prints to stdout from these calls.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/surface.hpp"

namespace photomill {

// What a written file's header says of it: STEP's FILE_NAME and FILE_DESCRIPTION (ISO 10303-21,
// 8.2), IGES's global section (file name, system, author, company). The author is the user's
// login name, the originating system photomill and its version, the preprocessor Open CASCADE
// and its version, the time stamp the time of writing; unknown fields (organisation,
// authorisation) are empty, never placeholders.
struct CadHeader {
  std::string file_name;  // the name the file will have (empty: the path's own file name)
  std::string description = "B-spline surface fitted by photomill, units mm";
};

// Writes `surface` as one face: trimmed by its boundary polygon (straight edges in (u,v)) when
// boundary_uv is set, else bounded by its whole parameter domain. The file says millimetres.
// Throws InputError(path, 0, ...) when the surface is invalid (validate_surface), when a
// boundary vertex lies outside the domain or a value is beyond +-1e99, when Open CASCADE
// rejects the geometry, or when the file cannot be written.
void write_step(const BSplineSurface& surface, const std::string& path, const CadHeader& header = {});
void write_iges(const BSplineSurface& surface, const std::string& path, const CadHeader& header = {});

// Reads every face of the file, in file order, as a B-spline surface in mm (the file's unit is
// converted). Faces on other surfaces (planes, cylinders, Bezier, offsets...) are converted to
// NURBS by Open CASCADE, exactly where the geometry allows. boundary_uv is the face's outer
// wire in (u,v) - its vertices where edges are straight in (u,v), 32 samples per curved edge -
// and stays empty when that wire is the whole parameter rectangle; holes are dropped.
// Weights that are all equal come back as a non-rational surface (Open CASCADE's convention).
// Throws InputError(path, 0, reason) for a missing, empty or unreadable file, a file of the
// wrong kind, a file without faces, and any Open CASCADE failure.
std::vector<BSplineSurface> read_step(const std::string& path);
std::vector<BSplineSurface> read_iges(const std::string& path);
// read_step or read_iges, chosen by extension (.step .stp .p21 / .iges .igs, any case), else by
// the first line (ISO-10303-21 for STEP, an 80-column line with 'S' or 'G' in column 73 for IGES).
std::vector<BSplineSurface> read_cad(const std::string& path);

// A whole part: every face as read_cad gives it, which way each faces, and a triangle mesh of
// all of them (Open CASCADE's BRepMesh_IncrementalMesh, every triangle within
// `mesh_deflection_mm` of its face; faces share their edges' nodes, so the mesh has no gaps).
// A surface not in mm (units arbitrary) is written with "units arbitrary: NOT mm" in STEP's
// FILE_DESCRIPTION or on a line of IGES's start section (the files themselves can only say
// millimetres); the readers give such a file's faces units arbitrary.
struct CadPart {
  std::vector<BSplineSurface> faces;
  // Per face: true where the face is reversed in its shell, i.e. its outward normal (away from
  // the solid's material) is -(S_u x S_v); false: S_u x S_v.
  std::vector<bool> reversed;
  std::vector<Eigen::Vector3d> mesh_vertices;    // mm
  std::vector<std::array<int, 3>> mesh_triangles;  // indices into mesh_vertices
  std::vector<int> triangle_face;                // the face of each triangle
};
// A file of one face is meshed only when `mesh_one_face` (nothing else to check it against);
// a deflection of 0 meshes nothing. Throws InputError as read_cad does, and for a negative or
// non-finite deflection or a face that Open CASCADE could not mesh.
CadPart read_cad_part(const std::string& path, double mesh_deflection_mm, bool mesh_one_face = false);

}  // namespace photomill
