// Surface meshes: binary STL and OBJ (mesh.hpp).
#include "fitsurf/mesh.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fitsurf/outline.hpp"
#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "formats/text.hpp"

namespace photomill::fitsurf {
namespace {

void put_u32(std::string& b, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) b.push_back(static_cast<char>((v >> (8 * k)) & 0xff));
}
void put_f32(std::string& b, double v) { put_u32(b, std::bit_cast<std::uint32_t>(static_cast<float>(v))); }

// Largest length of the iso-curves along u (along = 0) or v, measured on a coarse grid.
double iso_length(const BSplineSurface& s, int along) {
  const auto [u0, u1] = domain_u(s);
  const auto [v0, v1] = domain_v(s);
  constexpr int n = 33;
  double longest = 0;
  for (int a = 0; a < 5; ++a) {
    double len = 0;
    Eigen::Vector3d prev;
    for (int b = 0; b < n; ++b) {
      const double t = static_cast<double>(b) / (n - 1), c = a / 4.0;
      const double u = along == 0 ? u0 + t * (u1 - u0) : u0 + c * (u1 - u0);
      const double v = along == 0 ? v0 + c * (v1 - v0) : v0 + t * (v1 - v0);
      const Eigen::Vector3d x = surface_point(s, u, v);
      if (b) len += (x - prev).norm();
      prev = x;
    }
    longest = std::max(longest, len);
  }
  return longest;
}

}  // namespace

MeshFormat mesh_format_for(const std::string& path) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".stl") return MeshFormat::Stl;
  if (ext == ".obj") return MeshFormat::Obj;
  throw UsageError("--mesh: '" + path + "' must end in .stl or .obj");
}

MeshCounts write_mesh(std::ostream& out, const BSplineSurface& s, MeshFormat format, const MeshOptions& o) {
  if (!(o.step_mm > 0)) throw UsageError("--mesh-step-mm must be positive");
  // Plain variables, not structured bindings: lambdas capture them in clang 14 too.
  const std::pair<double, double> du = domain_u(s), dv = domain_v(s);
  const double u0 = du.first, u1 = du.second, v0 = dv.first, v1 = dv.second;
  auto samples = [&](double len) {
    return std::clamp(static_cast<int>(std::ceil(len / o.step_mm)) + 1, 2, std::max(2, o.max_samples));
  };
  const int nu = samples(iso_length(s, 0)), nv = samples(iso_length(s, 1));
  auto param = [](double a, double b, int k, int n) { return a + (b - a) * k / (n - 1); };

  // Cells kept: all, or those whose centre lies inside the boundary polygon.
  std::vector<std::uint8_t> cell(static_cast<std::size_t>(nu - 1) * (nv - 1), 1);
  if (!s.boundary_uv.empty()) {
    for (int a = 0; a + 1 < nu; ++a) {
      for (int b = 0; b + 1 < nv; ++b) {
        const Eigen::Vector2d c(0.5 * (param(u0, u1, a, nu) + param(u0, u1, a + 1, nu)),
                                0.5 * (param(v0, v1, b, nv) + param(v0, v1, b + 1, nv)));
        cell[static_cast<std::size_t>(a) * (nv - 1) + b] = point_in_polygon(s.boundary_uv, c);
      }
    }
  }
  // Vertices used by a kept cell, numbered from 1 (OBJ's convention).
  std::vector<std::uint32_t> id(static_cast<std::size_t>(nu) * nv, 0);
  std::vector<Eigen::Vector3d> pos, nrm;
  auto vertex = [&](int a, int b) {
    std::uint32_t& v = id[static_cast<std::size_t>(a) * nv + b];
    if (v == 0) {
      const SurfaceDerivatives d = surface_derivatives(s, param(u0, u1, a, nu), param(v0, v1, b, nv));
      pos.push_back(d.p);
      nrm.push_back(d.normal());
      v = static_cast<std::uint32_t>(pos.size());
    }
    return v;
  };
  std::vector<std::array<std::uint32_t, 3>> tris;
  for (int a = 0; a + 1 < nu; ++a) {
    for (int b = 0; b + 1 < nv; ++b) {
      if (!cell[static_cast<std::size_t>(a) * (nv - 1) + b]) continue;
      const std::uint32_t p00 = vertex(a, b), p10 = vertex(a + 1, b), p11 = vertex(a + 1, b + 1), p01 = vertex(a, b + 1);
      // Counter-clockwise in (u,v): the triangles face along S_u x S_v.
      tris.push_back({p00, p10, p11});
      tris.push_back({p00, p11, p01});
    }
  }
  std::string buf;
  if (format == MeshFormat::Stl) {
    buf = "photomill fitsurf surface mesh, mm";
    buf.resize(80, ' ');  // the fixed 80-byte header (must not start with "solid")
    put_u32(buf, static_cast<std::uint32_t>(tris.size()));
    for (const auto& t : tris) {
      const Eigen::Vector3d& a = pos[t[0] - 1];
      const Eigen::Vector3d& b = pos[t[1] - 1];
      const Eigen::Vector3d& c = pos[t[2] - 1];
      Eigen::Vector3d n = (b - a).cross(c - a);
      n = n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
      const Eigen::Vector3d* corners[] = {&n, &a, &b, &c};
      for (const Eigen::Vector3d* x : corners) {
        for (int k = 0; k < 3; ++k) put_f32(buf, (*x)[k]);
      }
      buf.append(2, '\0');
      if (buf.size() > (1 << 16)) {
        out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
        buf.clear();
      }
    }
  } else {
    buf = "# photomill fitsurf surface mesh, mm\n";
    for (const auto& x : pos) {
      buf += "v " + format_double(x.x()) + " " + format_double(x.y()) + " " + format_double(x.z()) + "\n";
    }
    for (const auto& n : nrm) {
      buf += "vn " + format_double(n.x()) + " " + format_double(n.y()) + " " + format_double(n.z()) + "\n";
    }
    for (const auto& t : tris) {
      buf += "f";
      for (std::uint32_t v : t) buf += " " + std::to_string(v) + "//" + std::to_string(v);
      buf += "\n";
    }
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  return {pos.size(), tris.size()};
}

}  // namespace photomill::fitsurf
