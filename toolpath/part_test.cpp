#include "toolpath/part.hpp"

#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill::toolpath {
namespace {

// A bilinear patch through four corners: S(0,0) = a, S(1,0) = b, S(0,1) = c, S(1,1) = d.
BSplineSurface patch(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  BSplineSurface s;
  s.degree_u = s.degree_v = 1;
  s.num_poles_u = s.num_poles_v = 2;
  s.knots_u = s.knots_v = {0, 0, 1, 1};
  s.poles_mm = {a, c, b, d};  // P[i][j] at i * 2 + j: (0,0) (0,1) (1,0) (1,1)
  return s;
}

void add_quad(TriangleMesh& m, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const int base = static_cast<int>(m.vertices.size());
  m.vertices.insert(m.vertices.end(), {a, b, c, d});
  m.triangles.push_back({base, base + 1, base + 3});
  m.triangles.push_back({base, base + 3, base + 2});
}

// A step block 40 x 20 mm: a low plate z = 0 over x in [0, 20], a wall x = 20 up to z = 10, a
// high plate z = 10 over x in [20, 40], and its underside (facing down). Faces outward.
struct StepBlock {
  std::vector<BSplineSurface> faces;
  TriangleMesh mesh;
  std::vector<int> triangle_face;
  StepBlock() {
    using V = Eigen::Vector3d;
    faces.push_back(patch(V(0, 0, 0), V(20, 0, 0), V(0, 20, 0), V(20, 20, 0)));       // low plate, up
    faces.push_back(patch(V(20, 0, 0), V(20, 20, 0), V(20, 0, 10), V(20, 20, 10)));   // wall, S_u x S_v horizontal
    faces.push_back(patch(V(20, 0, 10), V(40, 0, 10), V(20, 20, 10), V(40, 20, 10))); // high plate, up
    faces.push_back(patch(V(0, 0, -5), V(0, 20, -5), V(40, 0, -5), V(40, 20, -5)));   // underside, down
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const BSplineSurface& f = faces[i];
      add_quad(mesh, f.pole(0, 0), f.pole(1, 0), f.pole(0, 1), f.pole(1, 1));
      triangle_face.insert(triangle_face.end(), 2, static_cast<int>(i));
    }
  }
};

PartToolpathOptions options() {
  PartToolpathOptions o;
  o.toolpath.tool_radius_mm = 3;
  o.toolpath.scallop_mm = 0.05;
  o.toolpath.chord_tol_mm = 0.02;
  return o;
}

TEST(PartToolpath, ClassifiesFacesAndMachinesOnlyThoseFacingUp) {
  const StepBlock part;
  std::vector<std::size_t> reported;
  const PartToolpathResult r = generate_part_toolpath(part.faces, part.mesh, part.triangle_face, options(),
                                                      [&](const PartFace& f, std::size_t of) {
                                                        EXPECT_EQ(of, 4u);
                                                        reported.push_back(f.index);
                                                      });
  EXPECT_EQ(reported, (std::vector<std::size_t>{0, 1, 2, 3}));
  ASSERT_EQ(r.faces.size(), 4u);
  EXPECT_EQ(r.faces[0].kind, PartFace::Kind::Machined);
  EXPECT_EQ(r.faces[1].kind, PartFace::Kind::Wall);
  EXPECT_EQ(r.faces[2].kind, PartFace::Kind::Machined);
  EXPECT_EQ(r.faces[3].kind, PartFace::Kind::Down);
  EXPECT_EQ(r.machined, 2u);
  EXPECT_EQ(r.walls, 1u);
  EXPECT_EQ(r.down, 1u);
  EXPECT_NEAR(r.faces[1].min_mm.z(), 0, 1e-9);
  EXPECT_NEAR(r.faces[1].max_mm.z(), 10, 1e-9);
  EXPECT_GT(r.faces[0].stats.cl_points, 0u);
  EXPECT_GT(r.faces[2].stats.cl_points, 0u);
  EXPECT_NEAR(r.safe_z_mm, 10 + options().toolpath.retract_mm, 1e-9);
}

// The low plate's own passes run up to x = 20, where the ball would cut into the wall and the
// high plate's edge: the whole-part check raises them onto the edge, and no move cuts below any
// face (z-map against all faces); the low plate is finished where the ball reaches it.
TEST(PartToolpath, WholePartCheckKeepsTheBallOutOfNeighbouringFaces) {
  const StepBlock part;
  const PartToolpathOptions o = options();
  const PartToolpathResult r = generate_part_toolpath(part.faces, part.mesh, part.triangle_face, o);
  EXPECT_GT(r.mesh_lifted_points, 0u);
  EXPECT_NEAR(r.max_mesh_lift_mm, 10, 1e-6);  // a ball centred on the wall's foot rests on its top edge
  const PartZmapResult z = verify_part_zmap(part.mesh, part.triangle_face, r.faces, r.cl, o.toolpath.tool_radius_mm, 0.1, 0);
  EXPECT_GT(z.nodes, 70000u);
  EXPECT_LE(z.max_gouge_mm, 1e-3);
  EXPECT_LE(z.max_penetration_mm, 1e-3);
  // Material is left where the ball cannot reach: in the inner corner at the wall's foot (at
  // most the step's height, measured vertically right beside the wall).
  EXPECT_GT(z.max_left_mm, 2);
  EXPECT_LE(z.max_left_mm, 10 + 1e-9);
  EXPECT_LT(z.max_left_at.x(), 20.05);
  EXPECT_GT(z.max_left_at.x(), 17);
  // A face's own triangles are not used against it: one face alone is not checked at all.
  const PartToolpathResult alone = generate_part_toolpath({part.faces[0]}, {}, {}, o);
  EXPECT_EQ(alone.mesh_lifted_points + alone.mesh_split_points, 0u);
  EXPECT_THROW(generate_part_toolpath(part.faces, part.mesh, {}, o), UsageError);
  // Without the whole-part check, the same passes cut into the high plate's edge.
  ClData unchecked = r.cl;
  unchecked.moves.clear();
  for (const std::size_t f : {0u, 2u}) {
    ToolpathOptions t = o.toolpath;
    t.safe_z_mm = r.safe_z_mm;
    const ToolpathResult one = generate_toolpath(part.faces[f], t);
    unchecked.moves.insert(unchecked.moves.end(), one.cl.moves.begin(), one.cl.moves.end());
  }
  const PartZmapResult bad = verify_part_zmap(part.mesh, part.triangle_face, r.faces, unchecked, o.toolpath.tool_radius_mm, 0.1, 0);
  EXPECT_GT(bad.max_gouge_mm, 1.0);
  EXPECT_GT(bad.max_penetration_mm, 1.0);
}

TEST(PartToolpath, NothingFacingUpIsAnError) {
  StepBlock part;
  const std::vector<BSplineSurface> walls_only = {part.faces[1], part.faces[3]};
  EXPECT_THROW(generate_part_toolpath(walls_only, part.mesh, part.triangle_face, options()), GeometryError);
  PartToolpathOptions bad = options();
  bad.wall_share = 0;
  EXPECT_THROW(generate_part_toolpath(part.faces, part.mesh, part.triangle_face, bad), UsageError);
  bad = options();
  bad.toolpath.safe_z_mm = 5;  // below the high plate
  EXPECT_THROW(generate_part_toolpath(part.faces, part.mesh, part.triangle_face, bad), UsageError);
}

// A surface is oriented as a whole: a plate whose S_u x S_v points down is mirrored in u, and a
// vertical wall is refused by generate_toolpath with the reason.
TEST(PartToolpath, OrientationIsPerSurfaceAndWallsAreRefused) {
  using V = Eigen::Vector3d;
  const BSplineSurface down = patch(V(0, 0, 0), V(0, 10, 0), V(10, 0, 0), V(10, 10, 0));
  const SurfaceFacing f = surface_facing(down);
  EXPECT_NEAR(f.area_mm2, 100, 1e-9);
  EXPECT_NEAR(f.down_mm2, 100, 1e-9);
  EXPECT_NEAR(f.up_mm2, 0, 1e-9);
  const BSplineSurface up = upward_oriented(down);
  EXPECT_NEAR(surface_facing(up).up_mm2, 100, 1e-9);
  for (double u : {0.0, 0.3, 1.0}) {
    EXPECT_LT((surface_point(up, u, 0.7) - surface_point(down, 1 - u, 0.7)).norm(), 1e-12);
  }
  const BSplineSurface wall = patch(V(0, 0, 0), V(10, 0, 0), V(0, 0, 10), V(10, 0, 10));
  try {
    generate_toolpath(wall, ToolpathOptions{});
    ADD_FAILURE() << "a vertical wall gave a path";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("vertical wall"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace photomill::toolpath
