#include "tests/fuzz/targets.hpp"

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <unistd.h>

#include "formats/cad.hpp"
#include "formats/camera.hpp"
#include "formats/cl_data.hpp"
#include "formats/features.hpp"
#include "formats/json_value.hpp"
#include "formats/point_cloud.hpp"
#include "formats/surface.hpp"
#include "formats/tables.hpp"
#include "formats/uncertainty.hpp"
#include "triangulate/cli.hpp"

namespace photomill::fuzz {
namespace {

template <auto Reader>
void from_stream(const std::string& data) {
  std::istringstream in(data);
  Reader(in, "fuzz");
}

// Open CASCADE reads by path: write the bytes to a private temporary file first.
template <auto Reader>
void from_file(const std::string& data, const char* ext) {
  char name[] = "/tmp/photomill-fuzz-XXXXXX";
  const int fd = ::mkstemp(name);
  if (fd < 0) return;
  ::close(fd);
  const std::string path = std::string(name) + ext;
  std::rename(name, path.c_str());
  {
    std::ofstream f(path, std::ios::binary);
    f << data;
  }
  struct Remove {
    std::string p;
    ~Remove() { std::remove(p.c_str()); }
  } cleanup{path};
  Reader(path);
}

void observations(const std::string& d) { from_stream<read_observations>(d); }
void control_points(const std::string& d) { from_stream<read_control_points>(d); }
void tracks(const std::string& d) { from_stream<read_tracks>(d); }
void poses(const std::string& d) { from_stream<read_poses>(d); }
void scale_bars(const std::string& d) { from_stream<read_scale_bars>(d); }
// The grid is also sampled, as toolpath does, inside, between and beyond its nodes.
void uncertainty_grid(const std::string& d) {
  std::istringstream in(d);
  const UncertaintyGrid g = read_uncertainty_grid(in, "fuzz");
  const double w = g.step_mm * static_cast<double>(g.nx), h = g.step_mm * static_cast<double>(g.ny);
  for (double t : {-1.0, 0.0, 0.37, 1.0, 2.0}) {
    (void)g.sample(g.x0_mm + t * w, g.y0_mm + t * h);
    (void)g.max_within(g.x0_mm + t * w, g.y0_mm + (1 - t) * h, 3 * g.step_mm);
  }
}
void point_cloud(const std::string& d) {
  std::istringstream in(d);
  read_point_cloud(in, "fuzz");
}
// What is read is written back and read again unchanged, its unit (`units arbitrary`) included:
// a surface that lost its unit on the way would be machined as mm.
void surface(const std::string& d) {
  std::istringstream in(d);
  const BSplineSurface s = read_surface(in, "fuzz");
  std::stringstream io;
  write_surface(io, s);
  if (!(read_surface(io, "fuzz (written back)") == s)) throw std::logic_error("the surface changed in a write-read round trip");
}
void cl_data(const std::string& d) { from_stream<read_cl>(d); }
void camera_yaml(const std::string& d) {
  std::istringstream in(d);
  read_camera_yaml(in, "fuzz");
}
void rig_yaml(const std::string& d) {
  std::istringstream in(d);
  read_rig_yaml(in, "fuzz");
}
void features(const std::string& d) {
  std::istringstream in(d);
  read_features(in, "fuzz");
}
void step(const std::string& d) { from_file<read_step>(d, ".step"); }
void iges(const std::string& d) { from_file<read_iges>(d, ".igs"); }
// triangulate --known-poses: a poses CSV or COLMAP's images.txt.
void known_poses(const std::string& d) {
  std::istringstream in(d);
  std::vector<std::size_t> lines;
  triangulate::read_known_poses(in, "fuzz", &lines);
}

// The stages' JSON reports, as report reads them back.
void json(const std::string& d) { parse_json(d, "fuzz"); }

}  // namespace

const std::vector<Target>& targets() {
  static const std::vector<Target> all{
      {"observations", observations}, {"control_points", control_points}, {"tracks", tracks},
      {"poses", poses},               {"scale_bars", scale_bars},         {"point_cloud", point_cloud},
      {"surface", surface},           {"cl_data", cl_data},               {"camera_yaml", camera_yaml}, {"rig_yaml", rig_yaml},
      {"features", features},         {"step", step},                     {"iges", iges},
      {"known_poses", known_poses},   {"json", json}, {"uncertainty_grid", uncertainty_grid},
  };
  return all;
}

const Target* find_target(std::string_view name) {
  for (const auto& t : targets()) {
    if (name == t.name) return &t;
  }
  return nullptr;
}

}  // namespace photomill::fuzz
