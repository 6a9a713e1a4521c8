// Writes a synthetic data set: images and truth (see dataset.hpp and docs/synth.md).
#include "tools/synth/dataset.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "tools/synth/camera_model.hpp"
#include "tools/synth/random.hpp"

namespace photomill::synth {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

// Independent random streams for the different uses of the seed.
enum class Stream : std::uint64_t { Speckle = 1, PartViews = 2, BoardViews = 3, PartNoise = 4, BoardNoise = 5 };
std::uint64_t stream_seed(std::uint64_t seed, Stream s) {
  return splitmix64(seed ^ (static_cast<std::uint64_t>(s) * 0xD1B54A32D192ED03ull));
}

std::string numbered(const std::string& prefix, int view, int count, const std::string& ext) {
  const int digits = std::max(2, static_cast<int>(std::to_string(std::max(count - 1, 0)).size()));
  std::string number = std::to_string(view);
  number.insert(0, static_cast<std::size_t>(std::max(0, digits - static_cast<int>(number.size()))), '0');
  return prefix + number + "." + ext;
}

void check_options(const SynthOptions& o) {
  validate_synth_camera(o.camera);
  if (o.views.count < 0 || o.calibration.count < 0) throw std::invalid_argument("view counts must be >= 0");
  if (o.views.elevations_deg.empty()) throw std::invalid_argument("give at least one elevation");
  for (double e : o.views.elevations_deg) {
    if (!(e > 0 && e < 89)) throw std::invalid_argument("elevations must be in (0, 89) degrees");
  }
  if (!(o.views.distance_mm > 0)) throw std::invalid_argument("distance must be positive");
  if (!(o.views.jitter >= 0)) throw std::invalid_argument("jitter must be >= 0");
  const auto& c = o.calibration;
  if (!(c.min_tilt_deg >= 0 && c.min_tilt_deg <= c.max_tilt_deg && c.max_tilt_deg < 80)) {
    throw std::invalid_argument("board tilts must satisfy 0 <= min <= max < 80 degrees");
  }
  if (!(c.min_fill > 0 && c.min_fill <= c.max_fill)) throw std::invalid_argument("board fill must satisfy 0 < min <= max");
  validate(c.board);
  if (o.image_format != "jpg" && o.image_format != "png") throw std::invalid_argument("image format must be jpg or png");
  if (o.jpeg_quality < 1 || o.jpeg_quality > 100) throw std::invalid_argument("JPEG quality must be 1..100");
  if (!(o.surface_step_mm > 0)) throw std::invalid_argument("surface step must be positive");
  if (!(o.part_height_mm > 0)) throw std::invalid_argument("part height must be positive");
}

// Writes through a temporary file renamed on success (no half-written truth on failure; inside
// tool::run once the whole data set is written). Returns the bytes written.
template <typename Writer>
std::size_t write_file(const std::filesystem::path& path, const Writer& writer) {
  tool::OutputFile out(path.string());
  writer(out.stream());
  const auto bytes = static_cast<std::size_t>(out.stream().tellp());
  out.commit();
  return bytes;
}

}  // namespace

PartScene make_part_scene(const SynthOptions& o) {
  const HeightField field = make_shape(o.shape, o.part_x_mm, o.part_y_mm, o.part_height_mm, o.edge_blend_mm);
  // The speckle seed is stored in the scene file, so keep it readable (63 bits, non-negative).
  const std::uint64_t speckle_seed = stream_seed(o.seed, Stream::Speckle) >> 1;
  return make_scene(field, o.dictionary, o.layout, speckle_seed, o.speckle_mm);
}

std::string part_image_name(const SynthOptions& o, int view) {
  return numbered("part_", view, o.views.count, o.image_format);
}
std::string board_image_name(const SynthOptions& o, int view) {
  return numbered("board_", view, o.calibration.count, o.image_format);
}

std::vector<Pose> part_view_poses(const SynthOptions& o) {
  Rng rng(stream_seed(o.seed, Stream::PartViews));
  const ViewOptions& v = o.views;
  std::vector<Pose> poses;
  for (int k = 0; k < v.count; ++k) {
    const double j = v.jitter;
    const double az = (v.azimuth_offset_deg + 360.0 * k / v.count + j * rng.uniform(-5, 5)) * kDeg;
    const double el = (v.elevations_deg[k % v.elevations_deg.size()] + j * rng.uniform(-3, 3)) * kDeg;
    const double dist = v.distance_mm * (1 + j * rng.uniform(-0.05, 0.05));
    const Eigen::Vector3d target(j * rng.uniform(-10, 10), j * rng.uniform(-10, 10), o.part_height_mm / 3);
    const Eigen::Vector3d centre =
        target + dist * Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    poses.push_back(look_at(part_image_name(o, k), centre, target, Eigen::Vector3d::UnitZ()));
  }
  return poses;
}

RenderOptions board_render_options(const SynthOptions& o) {
  RenderOptions r = o.render;
  r.light_direction.z() *= BoardTexture(o.calibration.board).printed_side();
  return r;
}

std::vector<Pose> board_view_poses(const SynthOptions& o) {
  const double side = BoardTexture(o.calibration.board).printed_side();
  Rng rng(stream_seed(o.seed, Stream::BoardViews));
  const CalibrationOptions& c = o.calibration;
  const double bw = c.board.squares_x * c.board.square_mm;
  const double bh = c.board.squares_y * c.board.square_mm;
  const double f = 0.5 * (o.camera.fx() + o.camera.fy());
  std::vector<Pose> poses;
  for (int k = 0; k < c.count; ++k) {
    const double tilt = rng.uniform(c.min_tilt_deg, c.max_tilt_deg) * kDeg;
    // Spread the tilt directions evenly (with a random start) so every view adds information.
    const double azimuth = (360.0 * k / std::max(1, c.count) + rng.uniform(0, 360.0 / std::max(1, c.count))) * kDeg;
    const double fill = rng.uniform(c.min_fill, c.max_fill);
    const double dist = f * std::max(bw / (fill * o.camera.image_width_px), bh / (fill * o.camera.image_height_px));
    const Eigen::Vector3d aim(bw * (0.5 + rng.uniform(-0.15, 0.15)), bh * (0.5 + rng.uniform(-0.15, 0.15)), 0);
    const Eigen::Vector3d centre =
        aim + dist * Eigen::Vector3d(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth), side * std::cos(tilt));
    Pose pose = look_at(board_image_name(o, k), centre, aim, Eigen::Vector3d::UnitY());
    // Roll about the optical axis: R' = Rz(roll) R, t' = Rz(roll) t.
    const Eigen::Matrix3d roll =
        Eigen::AngleAxisd(rng.uniform(-c.max_roll_deg, c.max_roll_deg) * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d R = roll * pose.rotation();
    pose.cam_from_world_rotation = Eigen::Quaterniond(R).normalized();
    if (pose.cam_from_world_rotation.w() < 0) pose.cam_from_world_rotation.coeffs() *= -1;
    pose.cam_from_world_translation_mm = roll * pose.cam_from_world_translation_mm;
    poses.push_back(pose);
  }
  return poses;
}

std::vector<Observation> marker_observations(const PartRayScene& scene, const Camera& camera,
                                             const Pose& pose) {
  std::vector<Observation> out;
  for (const Marker& m : scene.scene().markers) {
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector3d X = scene.scene().corner_world(m, c);
      if (!visible(scene, camera, pose, X)) continue;
      const Eigen::Vector2d uv = *project(camera, pose, X);
      out.push_back({pose.image, marker_corner_id(m.id, c), uv.x(), uv.y()});
    }
  }
  return out;
}

std::vector<Observation> board_observations(const BoardTexture& board, const Camera& camera,
                                            const Pose& pose) {
  const BoardRayScene scene(board);
  std::vector<Observation> out;
  for (const ControlPoint& p : board.corners()) {
    if (!visible(scene, camera, pose, p.xyz_mm)) continue;
    const Eigen::Vector2d uv = *project(camera, pose, p.xyz_mm);
    out.push_back({pose.image, p.point_id, uv.x(), uv.y()});
  }
  return out;
}

PointCloud surface_samples(const HeightField& f, double step_mm) {
  if (!(step_mm > 0)) throw std::invalid_argument("surface step must be positive");
  const int nx = static_cast<int>(std::ceil((f.x_max_mm - f.x_min_mm) / step_mm - 1e-9));
  const int ny = static_cast<int>(std::ceil((f.y_max_mm - f.y_min_mm) / step_mm - 1e-9));
  PointCloud cloud;
  std::vector<double> nxs, nys, nzs;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const double x = std::min(f.x_min_mm + i * step_mm, f.x_max_mm);
      const double y = std::min(f.y_min_mm + j * step_mm, f.y_max_mm);
      cloud.points_mm.emplace_back(x, y, f.height_mm(x, y));
      const Eigen::Vector3d n = f.normal(x, y);
      nxs.push_back(n.x());
      nys.push_back(n.y());
      nzs.push_back(n.z());
    }
  }
  cloud.properties = {{"nx", PlyScalar::Float64, nxs}, {"ny", PlyScalar::Float64, nys},
                      {"nz", PlyScalar::Float64, nzs}};
  return cloud;
}

std::vector<std::uint8_t> encode_image(const cv::Mat& image, const std::string& format, int jpeg_quality) {
  std::vector<std::uint8_t> bytes;
  std::vector<int> params;
  if (format == "jpg") {
    params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality, cv::IMWRITE_JPEG_OPTIMIZE, 1};
  } else if (format == "png") {
    params = {cv::IMWRITE_PNG_COMPRESSION, 6};
  } else {
    throw std::invalid_argument("image format must be jpg or png");
  }
  if (!cv::imencode("." + format, image, bytes, params)) {
    throw std::runtime_error("OpenCV could not encode a " + format + " image");
  }
  return bytes;
}

DatasetSummary write_dataset(const SynthOptions& o, const std::string& folder) {
  check_options(o);
  namespace fs = std::filesystem;
  const fs::path dir(folder);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    throw InputError(folder, 0, "cannot create the output folder" + (ec ? ": " + ec.message() : ""));
  }
  DatasetSummary summary;
  auto add = [&](const std::string& name, std::size_t bytes) {
    summary.files.push_back(name);
    summary.bytes += bytes;
  };

  const PartScene scene = make_part_scene(o);
  const PartRayScene part(scene);
  const BoardTexture board(o.calibration.board);
  const BoardRayScene board_scene(board);
  const auto part_poses = part_view_poses(o);
  const auto board_poses = board_view_poses(o);

  std::ostringstream comment;
  comment << "made by: " << (o.command_line.empty() ? "photomill synth" : o.command_line);
  add("scene.txt", write_file(dir / "scene.txt", [&](std::ostream& s) { write_scene(s, scene, comment.str()); }));
  add("board.txt", write_file(dir / "board.txt", [&](std::ostream& s) { write_board(s, o.calibration.board); }));
  add("camera.yaml", write_file(dir / "camera.yaml", [&](std::ostream& s) { write_camera_yaml(s, o.camera); }));
  add("control_points.csv", write_file(dir / "control_points.csv", [&](std::ostream& s) {
        write_control_points(s, marker_corners(scene, false));
      }));
  add("part_points.csv", write_file(dir / "part_points.csv", [&](std::ostream& s) {
        write_control_points(s, marker_corners(scene, true));
      }));
  add("board_points.csv", write_file(dir / "board_points.csv", [&](std::ostream& s) {
        write_control_points(s, board.corners());
      }));
  add("poses.csv", write_file(dir / "poses.csv", [&](std::ostream& s) { write_poses(s, part_poses); }));
  add("board_poses.csv", write_file(dir / "board_poses.csv", [&](std::ostream& s) { write_poses(s, board_poses); }));
  add("surface.ply", write_file(dir / "surface.ply", [&](std::ostream& s) {
        write_ply(s, surface_samples(scene.surface, o.surface_step_mm), PlyEncoding::BinaryLittleEndian,
                  "photomill synth: true surface z = h(x, y) of scene.txt, normals nx ny nz");
      }));

  std::vector<Observation> observations, board_obs;
  auto render_views = [&](const RayScene& rs, const std::vector<Pose>& poses, RenderOptions ro, Stream noise_stream,
                          std::vector<Observation>& obs, auto&& observe) {
    ro.seed = stream_seed(o.seed, noise_stream);
    for (std::size_t k = 0; k < poses.size(); ++k) {
      const auto start = std::chrono::steady_clock::now();
      const cv::Mat image = render(rs, o.camera, poses[k], ro, k);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      summary.render_seconds += seconds;
      log::debug(poses[k].image + ": rendered in " + std::to_string(seconds) + " s");
      const auto bytes = encode_image(image, o.image_format, o.jpeg_quality);
      add(poses[k].image, write_file(dir / poses[k].image, [&](std::ostream& s) {
            s.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
          }));
      const auto seen = observe(poses[k]);
      obs.insert(obs.end(), seen.begin(), seen.end());
    }
  };
  render_views(part, part_poses, o.render, Stream::PartNoise, observations,
               [&](const Pose& p) { return marker_observations(part, o.camera, p); });
  render_views(board_scene, board_poses, board_render_options(o), Stream::BoardNoise, board_obs,
               [&](const Pose& p) { return board_observations(board, o.camera, p); });
  add("observations.csv", write_file(dir / "observations.csv", [&](std::ostream& s) { write_observations(s, observations); }));
  add("board_observations.csv", write_file(dir / "board_observations.csv", [&](std::ostream& s) {
        write_observations(s, board_obs);
      }));
  summary.part_images = static_cast<int>(part_poses.size());
  summary.board_images = static_cast<int>(board_poses.size());
  summary.observations = observations.size();
  summary.board_observations = board_obs.size();
  return summary;
}

}  // namespace photomill::synth
