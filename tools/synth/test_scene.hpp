// Small synth settings shared by the tests: images a few hundred pixels wide so the suite is fast,
// with the same geometry (part, plate, distances) as the full-size defaults.
#pragma once

#include "tools/synth/dataset.hpp"

namespace photomill::synth::test {

inline Camera small_camera(int width = 800, int height = 600, double f = 960) {
  Camera c;
  c.image_width_px = width;
  c.image_height_px = height;
  c.camera_matrix << f, 0, (width - 1) / 2.0 + 3.25, 0, f * 1.001, (height - 1) / 2.0 - 2.5, 0, 0, 1;
  c.distortion = {-0.08, 0.06, 0.0004, -0.0003, 0.0};
  return c;
}

inline SynthOptions small_options() {
  SynthOptions o;
  o.camera = small_camera();
  o.views.count = 4;
  o.calibration.count = 10;
  o.render.noise_sigma = 0;
  o.render.supersampling = 2;
  o.image_format = "png";
  o.surface_step_mm = 5;
  o.seed = 7;
  return o;
}

}  // namespace photomill::synth::test
