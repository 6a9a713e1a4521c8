// Ground truth for triangulate from the synth renderer's scene (tools/synth, docs/synth.md)
// without rendering: its true camera, view poses, plate- and part-marker corners and the true
// projections of every visible corner, turned into tracks (track_id = point_id) with Gaussian
// noise added. Test and benchmark support only.
#pragma once

#include <cstdint>

#include "tools/synth/dataset.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate::test {

// synth's defaults as its command line sets them (2000 x 1500, f = 2400, 12 views).
synth::SynthOptions synth_default_options();

// Natural features stand-in (until match exists): random points on the part's surface, seen
// where synth's ray caster says so, with their own noise and tracks cut to a random subset of
// their views, as feature matching gives. Ids from 1000000 (above every marker corner id).
struct NaturalFeatures {
  std::size_t count = 0;
  double noise_px = 0.2;
  std::size_t max_track_length = 8;
};
constexpr PointId kNaturalIdOffset = 1000000;

// The scene of `options` as SceneTruth: plate_points = plate-marker corners (control),
// part_points = part-marker corners (then the natural features), tracks = true observations +
// N(0, noise_px^2) per coordinate.
SceneTruth synth_truth(const synth::SynthOptions& options, double noise_px, std::uint64_t noise_seed,
                       const NaturalFeatures& natural = {});

}  // namespace photomill::triangulate::test
