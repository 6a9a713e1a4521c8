// synth's own parts (tools/synth/height_field.hpp) as fitsurf test shapes, for fitsurf's tests
// and benchmark: h = w f over 150 x 100 mm, f synth's kind of shape, w the 20 mm blend down to the
// plate, 30 mm high (synth's defaults; the demo part is its "bumps"). Links photomill_synth.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fitsurf/test_shapes.hpp"
#include "tools/synth/height_field.hpp"

namespace photomill::fitsurf::test {

constexpr double kSynthHeightMm = 30, kSynthBlendMm = 20;

inline Shape synth_part(const std::string& name) {
  const synth::HeightField h = synth::make_shape(name, kXMax - kXMin, kYMax - kYMin, kSynthHeightMm, kSynthBlendMm);
  return {name, [h](double x, double y) { return h.height_mm(x, y); }};
}

// "synth_NAME": synth's part NAME; anything else: test::shape(NAME).
inline Shape shape_or_synth_part(const std::string& name) {
  const std::string prefix = "synth_";
  return name.rfind(prefix, 0) == 0 ? synth_part(name.substr(prefix.size())) : shape(name);
}

// 150 marker-like points (15 x 10, jittered by 0.3 of the smaller spacing, 0.01 mm noise) where
// synth puts a part's markers (synth::make_scene): over the interior inside the blend, 110 x 60 mm.
inline std::vector<Eigen::Vector3d> synth_interior_markers(const Shape& s, std::uint64_t seed) {
  const double x0 = kXMin + kSynthBlendMm, x1 = kXMax - kSynthBlendMm;
  const double y0 = kYMin + kSynthBlendMm, y1 = kYMax - kSynthBlendMm;
  const double jitter = 0.3 * std::min((x1 - x0) / 15, (y1 - y0) / 10);
  return sample_grid_over(s, x0, x1, y0, y1, 15, 10, jitter, 0.01, seed);
}

}  // namespace photomill::fitsurf::test
