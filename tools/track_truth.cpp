// Tracks against the synth truth (see track_truth.hpp).
#include "tools/track_truth.hpp"

#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <stdexcept>

#include "tools/synth/camera_model.hpp"
#include "tools/synth/render.hpp"

namespace photomill::match::truth {

std::vector<TrackJudgement> judge_tracks(const std::vector<TrackObservation>& tracks, const synth::PartScene& scene,
                                         const Camera& camera, const std::vector<Pose>& poses) {
  std::map<std::string, const Pose*> pose_of;
  for (const auto& p : poses) pose_of[std::filesystem::path(p.image).filename().string()] = &p;
  auto pose = [&](const std::string& image) -> const Pose& {
    const auto it = pose_of.find(std::filesystem::path(image).filename().string());
    if (it == pose_of.end()) throw std::invalid_argument("no true pose for image " + image);
    return *it->second;
  };
  const synth::PartRayScene rays(scene);
  std::map<TrackId, std::vector<const TrackObservation*>> by_track;
  for (const auto& t : tracks) by_track[t.track_id].push_back(&t);
  std::vector<TrackJudgement> out;
  for (const auto& [id, obs] : by_track) {
    TrackJudgement j{id, obs.size(), std::numeric_limits<double>::infinity()};
    for (const TrackObservation* from : obs) {
      const Pose& p = pose(from->image);
      const auto xy = synth::pixel_to_normalised(camera, {from->u_px, from->v_px});
      if (!xy) continue;
      const Eigen::Matrix3d R = p.rotation();
      const Eigen::Vector3d direction = (R.transpose() * Eigen::Vector3d(xy->x(), xy->y(), 1)).normalized();
      const auto hit = rays.trace(p.centre_mm(), direction);
      if (!hit) continue;
      double worst = 0;
      for (const TrackObservation* to : obs) {
        if (to == from) continue;
        const auto uv = synth::project(camera, pose(to->image), hit->point_mm);
        worst = std::max(worst, uv ? std::hypot(uv->x() - to->u_px, uv->y() - to->v_px) : std::numeric_limits<double>::infinity());
      }
      j.error_px = std::min(j.error_px, worst);
    }
    out.push_back(j);
  }
  return out;
}

TrackTruthSummary summarise(const std::vector<TrackJudgement>& judged, std::size_t min_length, double threshold_px,
                            TrackId min_track_id) {
  TrackTruthSummary s;
  for (const auto& j : judged) {
    if (j.length < min_length || j.track_id < min_track_id) continue;
    ++s.tracks;
    if (!(j.error_px <= threshold_px)) ++s.outliers;
  }
  return s;
}

}  // namespace photomill::match::truth
