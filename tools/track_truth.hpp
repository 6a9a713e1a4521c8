// Judges tracks against a synth scene's exact geometry (test and benchmark support, not part of
// the match library): for each observation of a track, the ray through it from the true camera
// meets the true surface at a point; projected into the track's other images, that point must
// land on their observations. A track's error is the smallest, over its observations, of the
// largest such reprojection distance; above the threshold the track is an outlier.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "tools/synth/scene.hpp"

namespace photomill::match::truth {

struct TrackJudgement {
  TrackId track_id = 0;
  std::size_t length = 0;
  double error_px = 0;  // infinite if no observation's ray meets the surface
};

// Image names are matched to poses by file name (tracks may carry folders). Throws
// std::invalid_argument for an image without a pose.
std::vector<TrackJudgement> judge_tracks(const std::vector<TrackObservation>& tracks, const synth::PartScene& scene,
                                         const Camera& camera, const std::vector<Pose>& poses);

struct TrackTruthSummary {
  std::size_t tracks = 0, outliers = 0;          // tracks of length >= min_length
  double outlier_percent() const { return tracks ? 100.0 * static_cast<double>(outliers) / static_cast<double>(tracks) : 0; }
};
TrackTruthSummary summarise(const std::vector<TrackJudgement>& judged, std::size_t min_length, double threshold_px,
                            TrackId min_track_id = 0);

}  // namespace photomill::match::truth
