#include "formats/tables.hpp"

#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>

#include "formats/csv.hpp"
#include "formats/error.hpp"
#include "formats/run.hpp"

namespace photomill {
namespace {

std::string num(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("cannot write a non-finite number");
  return format_double(v);
}

std::string id(std::int64_t v) {
  if (v < 0) throw std::invalid_argument("cannot write a negative id: " + std::to_string(v));
  return std::to_string(v);
}

std::string image_name(const std::string& image) {
  check_csv_text(image, "image name");
  return image;
}

}  // namespace

// --- observations: image,point_id,u_px,v_px -------------------------------------------------
std::vector<Observation> read_observations(std::istream& in, const std::string& source) {
  return read_observations_with_runs(in, source, nullptr);
}

std::vector<Observation> read_observations_with_runs(std::istream& in, const std::string& source,
                                                     std::map<std::string, std::string>* run_of_image) {
  CsvReader csv(in, source, {"image", "point_id", "u_px", "v_px"});
  std::vector<Observation> out;
  std::set<std::pair<std::string, PointId>> seen;
  while (csv.next()) {
    Observation o{std::string(csv.text(0)), csv.non_negative_integer(1), csv.number(2),
                  csv.number(3)};
    if (!seen.emplace(o.image, o.point_id).second) {
      csv.fail("point " + std::to_string(o.point_id) + " observed twice in image '" + o.image + "'");
    }
    if (run_of_image != nullptr && !csv.run_id().empty()) {
      const auto [at, added] = run_of_image->emplace(o.image, csv.run_id());
      if (!added && at->second != csv.run_id()) {
        csv.fail("image '" + o.image + "' has observations from two runs (" + at->second + ", " + csv.run_id() + ")");
      }
    }
    out.push_back(std::move(o));
  }
  return out;
}

void write_observations(std::ostream& out, const std::vector<Observation>& observations) {
  out << stamp_line(observations.size());
  write_csv_row(out, {"image", "point_id", "u_px", "v_px"});
  for (const auto& o : observations) {
    write_csv_row(out, {image_name(o.image), id(o.point_id), num(o.u_px), num(o.v_px)});
  }
}

// --- control points: point_id,x_mm,y_mm,z_mm[,sigma_mm] -------------------------------------
std::vector<ControlPoint> read_control_points(std::istream& in, const std::string& source) {
  CsvReader csv(in, source, {"point_id", "x_mm", "y_mm", "z_mm"}, {"sigma_mm"});
  std::vector<ControlPoint> out;
  std::set<PointId> seen;
  while (csv.next()) {
    ControlPoint p;
    p.point_id = csv.non_negative_integer(0);
    p.xyz_mm = {csv.number(1), csv.number(2), csv.number(3)};
    if (csv.has(4)) {
      p.sigma_mm = csv.number(4);
      if (*p.sigma_mm < 0) csv.fail("sigma_mm must not be negative");
    }
    if (!seen.insert(p.point_id).second) {
      csv.fail("control point " + std::to_string(p.point_id) + " defined twice");
    }
    out.push_back(p);
  }
  return out;
}

void write_control_points(std::ostream& out, const std::vector<ControlPoint>& points) {
  bool any_sigma = false;
  for (const auto& p : points) any_sigma = any_sigma || p.sigma_mm.has_value();
  std::vector<std::string> header{"point_id", "x_mm", "y_mm", "z_mm"};
  if (any_sigma) header.push_back("sigma_mm");
  out << stamp_line(points.size());
  write_csv_row(out, header);
  for (const auto& p : points) {
    std::vector<std::string> row{id(p.point_id), num(p.xyz_mm.x()), num(p.xyz_mm.y()),
                                 num(p.xyz_mm.z())};
    if (any_sigma) row.push_back(p.sigma_mm ? num(*p.sigma_mm) : "");
    write_csv_row(out, row);
  }
}

// --- tracks: track_id,image,u_px,v_px[,size_px] ---------------------------------------------
std::vector<TrackObservation> read_tracks(std::istream& in, const std::string& source) {
  CsvReader csv(in, source, {"track_id", "image", "u_px", "v_px"}, {"size_px"});
  std::vector<TrackObservation> out;
  std::set<std::pair<TrackId, std::string>> seen;
  while (csv.next()) {
    TrackObservation t{csv.non_negative_integer(0), std::string(csv.text(1)), csv.number(2),
                       csv.number(3)};
    if (csv.has(4)) {
      t.size_px = csv.number(4);
      if (!(*t.size_px > 0)) csv.fail("size_px must be positive");
    }
    if (!seen.emplace(t.track_id, t.image).second) {
      csv.fail("track " + std::to_string(t.track_id) + " observed twice in image '" + t.image + "'");
    }
    out.push_back(std::move(t));
  }
  return out;
}

void write_tracks(std::ostream& out, const std::vector<TrackObservation>& tracks) {
  bool any_size = false;
  for (const auto& t : tracks) any_size = any_size || t.size_px.has_value();
  std::vector<std::string> header{"track_id", "image", "u_px", "v_px"};
  if (any_size) header.push_back("size_px");
  out << stamp_line(tracks.size());
  write_csv_row(out, header);
  for (const auto& t : tracks) {
    std::vector<std::string> row{id(t.track_id), image_name(t.image), num(t.u_px), num(t.v_px)};
    if (any_size) row.push_back(t.size_px ? num(*t.size_px) : "");
    write_csv_row(out, row);
  }
}

// --- poses: image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm ---------------------------------------------
// A quaternion whose norm is off 1 by more than this is rejected as a typo, not normalised.
constexpr double kQuaternionNormTolerance = 1e-6;

std::vector<Pose> read_poses(std::istream& in, const std::string& source) { return read_poses_numbered(in, source, nullptr); }

std::vector<Pose> read_poses_numbered(std::istream& in, const std::string& source, std::vector<std::size_t>* lines) {
  CsvReader csv(in, source, {"image", "qw", "qx", "qy", "qz", "tx_mm", "ty_mm", "tz_mm"});
  std::vector<Pose> out;
  std::set<std::string> seen;
  while (csv.next()) {
    Pose p;
    p.image = std::string(csv.text(0));
    p.cam_from_world_rotation =
        Eigen::Quaterniond(csv.number(1), csv.number(2), csv.number(3), csv.number(4));
    const double norm = p.cam_from_world_rotation.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      csv.fail("rotation quaternion (qw,qx,qy,qz) is not a unit quaternion: norm " +
               format_double(norm));
    }
    p.cam_from_world_translation_mm = {csv.number(5), csv.number(6), csv.number(7)};
    if (!seen.insert(p.image).second) csv.fail("image '" + p.image + "' has two poses");
    if (lines) lines->push_back(csv.line_number());
    out.push_back(std::move(p));
  }
  return out;
}

void write_poses(std::ostream& out, const std::vector<Pose>& poses) {
  out << stamp_line(poses.size());
  write_csv_row(out, {"image", "qw", "qx", "qy", "qz", "tx_mm", "ty_mm", "tz_mm"});
  for (const auto& p : poses) {
    const auto& q = p.cam_from_world_rotation;
    const auto& t = p.cam_from_world_translation_mm;
    write_csv_row(out, {image_name(p.image), num(q.w()), num(q.x()), num(q.y()), num(q.z()),
                        num(t.x()), num(t.y()), num(t.z())});
  }
}

// --- scale bars: point_a,point_b,distance_mm[,sigma_mm] -------------------------------------
std::vector<ScaleBar> read_scale_bars(std::istream& in, const std::string& source) {
  CsvReader csv(in, source, {"point_a", "point_b", "distance_mm"}, {"sigma_mm"});
  std::vector<ScaleBar> out;
  while (csv.next()) {
    ScaleBar b{csv.non_negative_integer(0), csv.non_negative_integer(1), csv.number(2), {}};
    if (b.point_a == b.point_b) csv.fail("a scale bar needs two different points");
    if (b.distance_mm <= 0) csv.fail("distance_mm must be positive");
    if (csv.has(3)) {
      b.sigma_mm = csv.number(3);
      if (*b.sigma_mm < 0) csv.fail("sigma_mm must not be negative");
    }
    out.push_back(b);
  }
  return out;
}

void write_scale_bars(std::ostream& out, const std::vector<ScaleBar>& bars) {
  bool any_sigma = false;
  for (const auto& b : bars) any_sigma = any_sigma || b.sigma_mm.has_value();
  std::vector<std::string> header{"point_a", "point_b", "distance_mm"};
  if (any_sigma) header.push_back("sigma_mm");
  out << stamp_line(bars.size());
  write_csv_row(out, header);
  for (const auto& b : bars) {
    std::vector<std::string> row{id(b.point_a), id(b.point_b), num(b.distance_mm)};
    if (any_sigma) row.push_back(b.sigma_mm ? num(*b.sigma_mm) : "");
    write_csv_row(out, row);
  }
}

}  // namespace photomill
