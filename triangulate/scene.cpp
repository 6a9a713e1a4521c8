// The reconstruction state (see scene.hpp).
#include "triangulate/scene.hpp"

#include <algorithm>
#include <array>
#include <unordered_map>

#include <Eigen/Geometry>

namespace photomill::triangulate {

const char* to_string(TrackIssue issue) {
  switch (issue) {
    case TrackIssue::None: return "none";
    case TrackIssue::SeenOnce: return "seen_once";
    case TrackIssue::NotRegistered: return "images_not_registered";
    case TrackIssue::SmallAngle: return "small_angle";
    case TrackIssue::BehindCamera: return "behind_camera";
    case TrackIssue::LargeError: return "large_error";
    case TrackIssue::TooFewInliers: return "too_few_inliers";
  }
  return "unknown";
}

std::optional<std::size_t> Scene::find_track(TrackId id) const {
  const auto it = track_by_id.find(id);
  if (it == track_by_id.end()) return std::nullopt;
  return it->second;
}

std::vector<std::size_t> Scene::active_observations(std::size_t track) const {
  std::vector<std::size_t> out;
  for (std::size_t o : tracks[track].observations) {
    const ObservationRef& ob = observations[o];
    if (ob.usable && ob.inlier && images[ob.image].registered) out.push_back(o);
  }
  return out;
}

std::size_t Scene::registered_count() const {
  std::size_t n = 0;
  for (const auto& im : images) n += im.registered ? 1 : 0;
  return n;
}

const char* to_string(ObservationClass c) { return c == ObservationClass::Coded ? "coded" : "natural"; }

Scene build_scene(const std::vector<TrackObservation>& tracks, const CameraModel& camera,
                  const std::vector<ControlPoint>& control_points, TrackId coded_id_limit,
                  bool weight_by_size) {
  return build_scene(tracks, std::vector<CameraModel>{camera}, [](const std::string&) { return std::size_t{0}; },
                     control_points, coded_id_limit, weight_by_size);
}

Scene build_scene(const std::vector<TrackObservation>& tracks, const std::vector<CameraModel>& cameras,
                  const std::function<std::size_t(const std::string&)>& camera_of_image,
                  const std::vector<ControlPoint>& control_points, TrackId coded_id_limit,
                  bool weight_by_size) {
  Scene s;
  s.cameras = cameras;
  std::unordered_map<std::string, std::size_t> image_index;
  std::unordered_map<TrackId, std::size_t>& track_index = s.track_by_id;
  s.observations.reserve(tracks.size());
  for (const TrackObservation& t : tracks) {
    auto [im, new_image] = image_index.try_emplace(t.image, s.images.size());
    if (new_image) s.images.push_back({t.image, camera_of_image(t.image), {}, false, {}});
    auto [tr, new_track] = track_index.try_emplace(t.track_id, s.tracks.size());
    if (new_track) {
      SceneTrack track;
      track.id = t.track_id;
      s.tracks.push_back(track);
    }
    ObservationRef ob;
    ob.image = im->second;
    ob.track = tr->second;
    ob.uv_px = Eigen::Vector2d(t.u_px, t.v_px);
    const auto xy = undistort(s.camera_of(ob.image), ob.uv_px);
    ob.usable = xy.has_value();
    ob.xy = xy.value_or(Eigen::Vector2d::Zero());
    const std::size_t index = s.observations.size();
    s.observations.push_back(ob);
    s.images[ob.image].observations.push_back(index);
    s.tracks[ob.track].observations.push_back(index);
  }
  for (const ControlPoint& c : control_points) {
    const auto it = track_index.find(c.point_id);
    if (it == track_index.end()) continue;
    s.tracks[it->second].control_mm = c.xyz_mm;
    s.tracks[it->second].control_sigma_mm = c.sigma_mm;
  }
  for (ObservationRef& ob : s.observations) {
    const SceneTrack& t = s.tracks[ob.track];
    ob.cls = t.id < coded_id_limit || t.control_mm ? ObservationClass::Coded : ObservationClass::Natural;
  }
  if (weight_by_size) {
    std::array<std::vector<double>, kObservationClasses> sizes;
    for (std::size_t k = 0; k < tracks.size(); ++k) {
      if (tracks[k].size_px) sizes[static_cast<std::size_t>(s.observations[k].cls)].push_back(*tracks[k].size_px);
    }
    std::array<double, kObservationClasses> median{};
    for (std::size_t c = 0; c < kObservationClasses; ++c) {
      auto& v = sizes[c];
      if (v.empty()) continue;
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      median[c] = v[v.size() / 2];
    }
    for (std::size_t k = 0; k < tracks.size(); ++k) {
      if (!tracks[k].size_px) continue;
      ObservationRef& ob = s.observations[k];
      ob.rel_sigma = std::max(*tracks[k].size_px / median[static_cast<std::size_t>(ob.cls)], kMinRelativeSigma);
    }
  }
  return s;
}

Pose to_pose(const std::string& image, const PoseBlock& pose) {
  Pose p;
  p.image = image;
  Eigen::Quaterniond q(rotation_of(pose));
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1;
  p.cam_from_world_rotation = q;
  p.cam_from_world_translation_mm = translation_of(pose);
  return p;
}

}  // namespace photomill::triangulate
