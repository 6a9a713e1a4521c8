#include "toolpath/input.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>

#include <unistd.h>

#include "formats/cad.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "toolpath/iso_passes.hpp"

namespace photomill::toolpath {
namespace {

constexpr std::size_t kMaxInputBytes = std::size_t{1} << 30;

bool looks_like_cad(std::string_view head) {
  if (head.substr(0, 3) == "\xEF\xBB\xBF") head.remove_prefix(3);
  std::string_view trimmed = head;
  while (!trimmed.empty() && std::isspace(static_cast<unsigned char>(trimmed.front()))) trimmed.remove_prefix(1);
  if (trimmed.substr(0, 12) == "ISO-10303-21") return true;
  std::string_view line = head.substr(0, head.find('\n'));
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line.size() == 80 && (line[72] == 'S' || line[72] == 'G' || line[72] == 'C');
}

bool cad_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".step" || ext == ".stp" || ext == ".p21" || ext == ".iges" || ext == ".igs";
}

// A file in the temporary folder, removed when this goes out of scope.
class TempFile {
public:
  explicit TempFile(const std::string& contents) {
    static std::atomic<unsigned> counter{0};
    path_ = (std::filesystem::temp_directory_path() /
             ("photomill-toolpath-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + ".cad"))
                .string();
    std::ofstream out(path_, std::ios::binary);
    out << contents;
    if (!out) throw InputError("<stdin>", 0, "cannot buffer the input in a temporary file");
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::string& path() const { return path_; }

private:
  std::string path_;
};

// A tool path is in mm: a surface in another unit would be machined at a wrong scale, silently.
void require_mm(const BSplineSurface& surface, const std::string& source) {
  if (surface.in_mm()) return;
  throw InputError(source, 0,
                   "the surface's scale is " + surface.units +
                       " (fitted from a cloud oriented without a datum): a tool path needs mm; give triangulate "
                       "control points, scale bars, --marker-side-mm or known poses");
}

LoadedSurface pick(CadPart part, std::optional<std::size_t> face, const std::string& source) {
  std::vector<BSplineSurface>& faces = part.faces;
  if (faces.empty()) throw InputError(source, 0, "no faces");
  LoadedSurface out;
  out.faces = faces.size();
  out.face = face.value_or(0);
  if (out.face >= faces.size()) {
    throw UsageError("--face " + std::to_string(out.face) + ": " + source + " has " + std::to_string(faces.size()) +
                     " face" + (faces.size() == 1 ? "" : "s") + " (0.." + std::to_string(faces.size() - 1) + ")");
  }
  if (!face && faces.size() > 1) {
    log::warn(source + " has " + std::to_string(faces.size()) + " faces; using face 0 (choose one with --face N, or machine the whole part with --all-faces)");
  }
  // In a part of several faces, a face's orientation in its shell says where the material is:
  // one that faces down (or is a wall) cannot be finished from above, whichever way it is
  // parameterized. (A lone face says nothing: photomill's own STEP surfaces are one face.)
  if (faces.size() > 1) {
    const BSplineSurface outward = part.reversed[out.face] ? mirrored_u(faces[out.face]) : faces[out.face];
    const SurfaceFacing f = surface_facing(outward);
    if (f.down_mm2 > f.up_mm2) {
      log::warn(source + ": face " + std::to_string(out.face) +
                " faces down in its part (its outward normal points down): machined from above, the tool comes from the "
                "material's side (--all-faces reports such faces instead)");
    }
  }
  out.surface = std::move(faces[out.face]);
  require_mm(out.surface, source);
  return out;
}

}  // namespace

LoadedSurface load_surface(const std::string& path, std::optional<std::size_t> face) {
  const std::string source = tool::source_name(path);
  if (path != "-" && cad_extension(path)) return pick(read_cad_part(path, 0), face, source);
  const std::string data = tool::read_all(path, kMaxInputBytes);
  if (looks_like_cad(std::string_view(data).substr(0, 1024))) {
    if (path != "-") return pick(read_cad_part(path, 0), face, source);
    const TempFile tmp(data);
    try {
      return pick(read_cad_part(tmp.path(), 0), face, source);
    } catch (const InputError& e) {
      throw InputError(source, e.line(), e.message());
    }
  }
  if (face && *face != 0) throw UsageError("--face " + std::to_string(*face) + ": " + source + " holds one surface (face 0)");
  std::istringstream in(data);
  LoadedSurface out;
  out.surface = read_surface(in, source);
  require_mm(out.surface, source);
  return out;
}

namespace {

LoadedPart outward(CadPart part, const std::string& source) {
  for (const BSplineSurface& f : part.faces) require_mm(f, source);
  LoadedPart out;
  for (std::size_t i = 0; i < part.faces.size(); ++i) {
    out.faces.push_back(part.reversed[i] ? mirrored_u(part.faces[i]) : std::move(part.faces[i]));
  }
  out.mesh.vertices = std::move(part.mesh_vertices);
  out.mesh.triangles = std::move(part.mesh_triangles);
  out.triangle_face = std::move(part.triangle_face);
  return out;
}

}  // namespace

LoadedPart load_part(const std::string& path, double mesh_deflection_mm, bool mesh_one_face) {
  const std::string source = tool::source_name(path);
  if (path != "-" && cad_extension(path)) return outward(read_cad_part(path, mesh_deflection_mm, mesh_one_face), source);
  const std::string data = tool::read_all(path, kMaxInputBytes);
  if (!looks_like_cad(std::string_view(data).substr(0, 1024))) {
    throw InputError(source, 1, "not a STEP or IGES file: --all-faces machines a whole CAD part (a photomill surface is one face)");
  }
  if (path != "-") return outward(read_cad_part(path, mesh_deflection_mm, mesh_one_face), source);
  const TempFile tmp(data);
  try {
    return outward(read_cad_part(tmp.path(), mesh_deflection_mm, mesh_one_face), source);
  } catch (const InputError& e) {
    throw InputError(source, e.line(), e.message());
  }
}

}  // namespace photomill::toolpath
