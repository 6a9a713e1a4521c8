// A whole CAD part in one run: every face that faces up is finished by the iso-parametric passes
// of toolpath.hpp (the paper's section 5), then the whole program is checked against all faces
// of the part by a drop cutter over a triangle mesh of its other faces (as OpenCAMLib's
// drop-cutter does over a whole solid): each CL point is raised to where the ball touches no
// other face, and each feed move is split where its straight line would cut into one. Vertical walls and
// faces that face down are reported, not machined: a ball end from above cannot follow them.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "formats/cl_data.hpp"
#include "formats/surface.hpp"
#include "toolpath/mesh_drop.hpp"
#include "toolpath/toolpath.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {

// What became of one face.
struct PartFace {
  enum class Kind { Machined, Wall, Down };
  std::size_t index = 0;       // 0-based, file order
  Kind kind = Kind::Machined;
  double area_mm2 = 0;
  double up_share = 0;         // share of the area's projection onto xy where the face faces up
  double down_share = 0;       // ... and where it faces down (an undercut where the face is machined)
  Eigen::Vector3d min_mm = Eigen::Vector3d::Zero(), max_mm = Eigen::Vector3d::Zero();  // bounding box of its samples
  ToolpathStats stats;         // Machined only
  std::size_t gouge_runs = 0;  // gouge runs against the face itself (toolpath.hpp)
};

struct PartToolpathOptions {
  ToolpathOptions toolpath;
  // A face whose projection onto xy is below this share of its area is a vertical wall.
  double wall_share = 0.02;
  // Feed moves are split until the ball's straight move stays within this of the mesh's drop
  // height (mm); the CL points themselves are raised to it exactly.
  double mesh_gouge_tol_mm = 0.0005;
};

struct PartToolpathResult {
  ClData cl;
  std::vector<PartFace> faces;
  std::size_t machined = 0, walls = 0, down = 0;
  std::size_t mesh_lifted_points = 0;  // CL points the whole-part check raised by more than the tolerance
  double max_mesh_lift_mm = 0;         // and by how much at most
  std::size_t mesh_split_points = 0;   // points it inserted into feed moves
  std::size_t cl_points = 0;
  double feed_length_mm = 0, rapid_length_mm = 0;
  double safe_z_mm = 0;
  double seconds = 0;
};

// Per-face progress: called after each face with its report (from the calling thread).
using PartProgress = std::function<void(const PartFace& face, std::size_t of)>;

// `faces` must face outwards (S_u x S_v away from the material: CadPart's reversed faces mirrored
// with mirrored_u). `mesh` and `triangle_face` (the face of each triangle): the part's mesh;
// each face's moves are checked against the triangles of the other faces (its own are met
// exactly by its passes); empty for a part of one face. Throws UsageError for bad options or
// a triangle_face of the wrong size, GeometryError when no face can be machined (all walls or
// facing down) or a face gives no path.
PartToolpathResult generate_part_toolpath(const std::vector<BSplineSurface>& faces, const TriangleMesh& mesh,
                                          const std::vector<int>& triangle_face, const PartToolpathOptions& options,
                                          const PartProgress& progress = {});

// The part's top over a grid, from its mesh (the highest triangle over each node: within the
// mesh's deflection of the faces, trimmed exactly where faces meet), then the grid cut by the
// program (a ball of radius R): gouge = how far the cut went below the part (against the faces
// it is at most that plus the mesh's deflection); left = how far above the machined faces the
// material stayed, vertically and along the surface normal (vertical times n_z: a cusp on a
// steep flank is tall measured vertically).
struct PartZmapResult {
  double cell_mm = 0;
  std::size_t nodes = 0;             // nodes over the machined faces
  double max_gouge_mm = 0;           // deepest cut below any face (0: none)
  Eigen::Vector3d max_gouge_at = Eigen::Vector3d::Zero();
  double max_left_mm = 0, p95_left_mm = 0;  // vertical
  Eigen::Vector3d max_left_at = Eigen::Vector3d::Zero();
  double max_left_normal_mm = 0, p95_left_normal_mm = 0;  // along the normal
  Eigen::Vector3d max_left_normal_at = Eigen::Vector3d::Zero();
  double max_gouge_normal_mm = 0;    // the z-map's gouges times n_z, as for the material left
  // The swept ball in 3D: the deepest any ball position along the moves (sampled every
  // penetration_step_mm along them) reaches into the mesh, R - distance(centre, mesh), and the
  // mesh point it reaches. A gouge measured along the normal, also on vertical walls.
  double max_penetration_mm = 0;
  Eigen::Vector3d max_penetration_at = Eigen::Vector3d::Zero();
  double penetration_step_mm = 0;
};
// `triangle_face`: the face of each mesh triangle (CadPart::triangle_face).
PartZmapResult verify_part_zmap(const TriangleMesh& mesh, const std::vector<int>& triangle_face,
                                const std::vector<PartFace>& report, const ClData& cl, double tool_radius_mm,
                                double cell_mm, int threads);

}  // namespace photomill::toolpath
