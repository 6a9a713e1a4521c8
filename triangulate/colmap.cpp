// COLMAP text model export (see colmap.hpp).
#include "triangulate/colmap.hpp"

#include <filesystem>
#include <cmath>
#include <map>
#include <set>

#include "formats/error.hpp"
#include "formats/text.hpp"
#include "triangulate/bundle.hpp"

namespace photomill::triangulate {
namespace {

// COLMAP's pixel convention minus OpenCV's.
constexpr double kColmapPixelOffset = 0.5;

std::string num(double v) { return format_double(v); }

void check_name(const std::string& name) {
  if (name.find_first_of(" \t") != std::string::npos) {
    throw InputError(name, 0, "COLMAP's text model cannot hold an image name with blanks");
  }
}

// Image ids (1-based, registered images in input order) and each observation's index among its
// image's POINTS2D.
struct Ids {
  std::vector<std::size_t> image_id;        // per image, 0 = not registered
  std::vector<std::size_t> point2d_index;   // per observation
};

Ids make_ids(const Reconstruction& r) {
  Ids ids;
  const Scene& s = r.scene;
  ids.image_id.assign(s.images.size(), 0);
  ids.point2d_index.assign(s.observations.size(), 0);
  std::size_t next = 1;
  for (std::size_t i = 0; i < s.images.size(); ++i) {
    if (!s.images[i].registered) continue;
    ids.image_id[i] = next++;
    std::size_t k = 0;
    for (std::size_t o : s.images[i].observations) ids.point2d_index[o] = k++;
  }
  return ids;
}

// True if the observation is an inlier of a point in the output.
bool linked(const Reconstruction& r, std::size_t o) {
  const ObservationRef& ob = r.scene.observations[o];
  return r.in_result[ob.track] && ob.usable && ob.inlier && r.scene.images[ob.image].registered;
}

// How many of an image's or a track's observations are linked.
std::size_t linked_count(const Reconstruction& r, const std::vector<std::size_t>& observations) {
  std::size_t n = 0;
  for (std::size_t o : observations) n += linked(r, o) ? 1 : 0;
  return n;
}

// A header's mean per item (observations per image, track length): 0 without items.
double mean_per_item(std::size_t total, std::size_t items) {
  return items ? static_cast<double>(total) / static_cast<double>(items) : 0.0;
}

}  // namespace

ColmapCamera to_colmap_camera(const Camera& camera, const std::string& source) {
  if (camera.camera_matrix(0, 1) != 0) throw InputError(source, 0, "COLMAP has no camera model with skew");
  std::vector<double> d = camera.distortion;
  for (std::size_t i = 8; i < d.size(); ++i) {
    if (d[i] != 0) throw InputError(source, 0, "COLMAP has no camera model with thin-prism or tilt coefficients");
  }
  d.resize(std::min<std::size_t>(d.size(), 8));
  ColmapCamera c;
  c.params = {camera.fx(), camera.fy(), camera.cx() + kColmapPixelOffset, camera.cy() + kColmapPixelOffset};
  bool any = false, beyond_opencv = false;
  for (std::size_t i = 0; i < d.size(); ++i) {
    any = any || d[i] != 0;
    beyond_opencv = beyond_opencv || (i >= 4 && d[i] != 0);
  }
  if (!any) {
    c.model = "PINHOLE";
    return c;
  }
  d.resize(beyond_opencv ? 8 : 4, 0.0);
  c.model = beyond_opencv ? "FULL_OPENCV" : "OPENCV";
  c.params.insert(c.params.end(), d.begin(), d.end());
  return c;
}

void check_colmap_camera(const Camera& camera, const std::string& source) { (void)to_colmap_camera(camera, source); }

void write_colmap_cameras(std::ostream& out, const Reconstruction& r) {
  const std::vector<Camera> cameras = r.cameras.empty() ? std::vector<Camera>{r.camera} : r.cameras;
  out << "# Camera list with one line of data per camera:\n"
      << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      << "# Number of cameras: " << cameras.size() << "\n"
      << "# photomill triangulate: principal point in COLMAP's convention (OpenCV's + 0.5 px)\n";
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    const ColmapCamera c = to_colmap_camera(cameras[k], "camera " + std::to_string(k));
    out << k + 1 << " " << c.model << " " << cameras[k].image_width_px << " " << cameras[k].image_height_px;
    for (double p : c.params) out << " " << num(p);
    out << "\n";
  }
}

void write_colmap_images(std::ostream& out, const Reconstruction& r) {
  const Ids ids = make_ids(r);
  const Scene& s = r.scene;
  std::size_t registered = 0, observations = 0;
  for (std::size_t i = 0; i < s.images.size(); ++i) {
    if (!ids.image_id[i]) continue;
    check_name(s.images[i].name);
    ++registered;
    observations += linked_count(r, s.images[i].observations);
  }
  out << "# Image list with two lines of data per image:\n"
      << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      << "# Number of images: " << registered << ", mean observations per image: "
      << mean_per_item(observations, registered) << "\n";
  for (std::size_t i = 0; i < s.images.size(); ++i) {
    if (!ids.image_id[i]) continue;
    const Pose p = to_pose(s.images[i].name, s.images[i].cam_from_world);
    const auto& q = p.cam_from_world_rotation;
    const auto& t = p.cam_from_world_translation_mm;
    out << ids.image_id[i] << " " << num(q.w()) << " " << num(q.x()) << " " << num(q.y()) << " " << num(q.z()) << " "
        << num(t.x()) << " " << num(t.y()) << " " << num(t.z()) << " " << s.images[i].camera + 1 << " "
        << s.images[i].name << "\n";
    bool first = true;
    for (std::size_t o : s.images[i].observations) {
      const ObservationRef& ob = s.observations[o];
      out << (first ? "" : " ") << num(ob.uv_px.x() + kColmapPixelOffset) << " " << num(ob.uv_px.y() + kColmapPixelOffset)
          << " ";
      if (linked(r, o)) {
        out << s.tracks[ob.track].id;
      } else {
        out << -1;
      }
      first = false;
    }
    out << "\n";
  }
}

void write_colmap_points(std::ostream& out, const Reconstruction& r) {
  const Ids ids = make_ids(r);
  const Scene& s = r.scene;
  std::size_t points = 0, length = 0;
  for (std::size_t t = 0; t < s.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    ++points;
    length += linked_count(r, s.tracks[t].observations);
  }
  out << "# 3D point list with one line of data per point:\n"
      << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      << "# Number of points: " << points << ", mean track length: "
      << mean_per_item(length, points) << "\n";
  for (std::size_t t = 0; t < s.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    const SceneTrack& track = s.tracks[t];
    // ERROR: COLMAP's mean reprojection error of the point, pixels.
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t o : track.observations) {
      if (!linked(r, o)) continue;
      sum += reprojection_error_px(s, o);
      ++n;
    }
    // Grey points, control points red so they stand out in the GUI.
    const char* rgb = track.at_control ? "255 0 0" : "200 200 200";
    out << track.id << " " << num(track.xyz_mm.x()) << " " << num(track.xyz_mm.y()) << " " << num(track.xyz_mm.z())
        << " " << rgb << " " << num(n ? sum / static_cast<double>(n) : 0.0);
    for (std::size_t o : track.observations) {
      if (!linked(r, o)) continue;
      out << " " << ids.image_id[s.observations[o].image] << " " << ids.point2d_index[o];
    }
    out << "\n";
  }
}

std::vector<Pose> read_colmap_images(std::istream& in, const std::string& source, std::vector<std::size_t>* lines) {
  // A unit quaternion as COLMAP writes it (17 digits) meets this easily; a typo does not.
  constexpr double kQuaternionNormTolerance = 1e-6;
  LineReaderOptions options;
  options.skip_comments_and_blank = false;  // an image without points has an empty POINTS2D line
  LineReader reader(in, source, options);
  std::vector<Pose> poses;
  std::set<std::string> names;
  std::set<std::int64_t> ids;
  while (const auto raw = reader.next()) {
    const std::string_view line = trim(*raw);
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> f = split_whitespace(line);
    if (f.size() != 10) {
      reader.fail("expected an image line of COLMAP's images.txt, 10 fields IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID "
                  "NAME; found " + std::to_string(f.size()));
    }
    const auto id = parse_int(f[0]);
    if (!id || *id < 0) reader.fail("IMAGE_ID '" + std::string(f[0]) + "' is not a non-negative integer");
    if (!ids.insert(*id).second) reader.fail("IMAGE_ID " + std::string(f[0]) + " appears twice");
    static const char* const kNames[] = {"", "QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    double v[8] = {};
    for (std::size_t k = 1; k < 8; ++k) {
      const auto x = parse_double(f[k]);
      if (!x) reader.fail(std::string(kNames[k]) + " '" + std::string(f[k]) + "' is not a finite number");
      v[k] = *x;
    }
    if (!parse_int(f[8])) reader.fail("CAMERA_ID '" + std::string(f[8]) + "' is not an integer");
    Pose p;
    p.image = std::string(f[9]);
    p.cam_from_world_rotation = Eigen::Quaterniond(v[1], v[2], v[3], v[4]);
    const double norm = p.cam_from_world_rotation.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      reader.fail("QW QX QY QZ is not a unit quaternion: norm " + format_double(norm));
    }
    p.cam_from_world_translation_mm = {v[5], v[6], v[7]};
    if (!names.insert(p.image).second) reader.fail("image '" + p.image + "' has two poses");
    if (lines) lines->push_back(reader.line_number());
    poses.push_back(std::move(p));
    // Its POINTS2D line: X Y POINT3D_ID triples. An image line in its place means one was dropped.
    if (const auto points = reader.next()) {
      const std::size_t n = split_whitespace(trim(*points)).size();
      if (n % 3 != 0) {
        reader.fail("expected the POINTS2D line of image '" + poses.back().image + "' (X Y POINT3D_ID triples); found " +
                    std::to_string(n) + " fields");
      }
    }
  }
  return poses;
}

ColmapModelFiles::ColmapModelFiles(std::string folder) : folder_(std::move(folder)) {}
ColmapModelFiles::~ColmapModelFiles() = default;

void ColmapModelFiles::write(const Reconstruction& r) {
  std::error_code ec;
  std::filesystem::create_directories(folder_, ec);
  if (!std::filesystem::is_directory(folder_)) {
    throw InputError(folder_, 0, "cannot create the COLMAP model folder" + (ec ? ": " + ec.message() : ""));
  }
  const std::filesystem::path dir(folder_);
  using Writer = void (*)(std::ostream&, const Reconstruction&);
  const std::pair<const char*, Writer> parts[] = {
      {"cameras.txt", write_colmap_cameras}, {"images.txt", write_colmap_images}, {"points3D.txt", write_colmap_points}};
  for (const auto& [name, writer] : parts) {
    files_.push_back(std::make_unique<tool::OutputFile>((dir / name).string()));
    writer(files_.back()->stream(), r);
  }
}

void ColmapModelFiles::commit() {
  for (auto& f : files_) f->commit();
}

}  // namespace photomill::triangulate
