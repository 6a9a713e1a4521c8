// Surface meshes: binary STL and OBJ, read back independently.
#include "fitsurf/mesh.hpp"

#include <cstring>
#include <sstream>

#include <gtest/gtest.h>

#include "fitsurf/outline.hpp"
#include "formats/bspline.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {
namespace {

// A dome-like bicubic patch over 150 x 100 mm; poles at the Greville abscissae, so that
// x = 150 u and y = 100 v exactly.
BSplineSurface patch() {
  BSplineSurface s;
  s.num_poles_u = s.num_poles_v = 5;
  s.knots_u = s.knots_v = clamped_uniform_knots(5, 3);
  const double greville[5] = {0, 1.0 / 6, 0.5, 5.0 / 6, 1};
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) {
      s.poles_mm.emplace_back(150 * greville[i], 100 * greville[j], 20 + 10 * (i % 4 != 0) * (j % 4 != 0));
    }
  }
  return s;
}

struct StlTriangle {
  Eigen::Vector3d normal, a, b, c;
};

std::vector<StlTriangle> read_stl(const std::string& bytes) {
  EXPECT_GE(bytes.size(), 84u);
  std::uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 80, 4);
  EXPECT_EQ(bytes.size(), 84u + 50u * n);
  std::vector<StlTriangle> t(n);
  for (std::uint32_t k = 0; k < n; ++k) {
    float f[12];
    std::memcpy(f, bytes.data() + 84 + 50 * k, sizeof f);
    t[k] = {{f[0], f[1], f[2]}, {f[3], f[4], f[5]}, {f[6], f[7], f[8]}, {f[9], f[10], f[11]}};
  }
  return t;
}

TEST(SurfaceMesh, StlTrianglesLieOnTheSurfaceAndFaceUp) {
  const BSplineSurface s = patch();
  std::ostringstream out;
  const MeshCounts n = write_mesh(out, s, MeshFormat::Stl, {2.0, 2000});
  const auto tris = read_stl(out.str());
  ASSERT_EQ(tris.size(), n.triangles);
  EXPECT_GT(n.triangles, 2u * 70 * 45);  // about 150/2 x 100/2 cells
  for (std::size_t k = 0; k < tris.size(); k += 13) {
    EXPECT_GT(tris[k].normal.z(), 0.0);
    EXPECT_NEAR(tris[k].normal.norm(), 1.0, 1e-6);
    // Each vertex on the surface: its foot point (by x, y: the patch is a graph) matches in z.
    const Eigen::Vector3d x = tris[k].a;
    const Eigen::Vector3d on = surface_point(s, x.x() / 150, x.y() / 100);
    EXPECT_NEAR(on.z(), x.z(), 1e-3);
  }
}

TEST(SurfaceMesh, ObjIndicesAreValidAndTheBoundaryTrims) {
  BSplineSurface s = patch();
  std::ostringstream full;
  const MeshCounts all = write_mesh(full, s, MeshFormat::Obj, {2.0, 2000});
  s.boundary_uv = {{0, 0}, {0.5, 0}, {0.5, 1}, {0, 1}};  // the half u <= 0.5
  std::ostringstream half;
  const MeshCounts some = write_mesh(half, s, MeshFormat::Obj, {2.0, 2000});
  EXPECT_NEAR(static_cast<double>(some.triangles), 0.5 * static_cast<double>(all.triangles), 0.02 * static_cast<double>(all.triangles));
  std::istringstream in(half.str());
  std::string line;
  std::size_t v = 0, vn = 0, f = 0;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) ++v;
    if (line.rfind("vn ", 0) == 0) ++vn;
    if (line.rfind("f ", 0) == 0) {
      ++f;
      std::istringstream fs(line.substr(2));
      std::string corner;
      while (fs >> corner) {
        const auto idx = std::stoul(corner.substr(0, corner.find('/')));
        EXPECT_GE(idx, 1u);
        EXPECT_LE(idx, some.vertices);
      }
    }
  }
  EXPECT_EQ(v, some.vertices);
  EXPECT_EQ(vn, some.vertices);
  EXPECT_EQ(f, some.triangles);
}

TEST(SurfaceMesh, FormatFromTheExtension) {
  EXPECT_EQ(mesh_format_for("a/b/part.STL"), MeshFormat::Stl);
  EXPECT_EQ(mesh_format_for("part.obj"), MeshFormat::Obj);
  EXPECT_THROW(mesh_format_for("part.ply"), UsageError);
  EXPECT_THROW(mesh_format_for("stl"), UsageError);
}

}  // namespace
}  // namespace photomill::fitsurf
