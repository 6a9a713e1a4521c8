// Measurements against the camera they are used with: a pixel outside the camera's image means
// the camera file is for other photos (another size, another resolution setting), or the
// measurement is junk. Used by match and triangulate (docs/errors.md).
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "formats/camera.hpp"
#include "formats/error.hpp"
#include "formats/tables.hpp"

namespace photomill {

// Measurements outside the image area of `camera`, [-0.5, W - 0.5] x [-0.5, H - 0.5] px in
// OpenCV's pixel convention (pixel centres at integers), may be a few junk lines, which the
// robust stages reject as outliers; more than this share of them means the wrong camera file.
inline constexpr double kMaxShareOutsideImage = 0.01;

// Throws InputError(data_source, 0, ...) with the count and the first measurement outside the
// image when more than kMaxShareOutsideImage of `measurements` lie outside it. Obs is Observation
// or TrackObservation.
template <class Obs>
void check_inside_camera_image(const std::vector<Obs>& measurements, const std::string& data_source,
                               const Camera& camera, const std::string& camera_source) {
  const double w = camera.image_width_px, h = camera.image_height_px;
  std::size_t outside = 0;
  const Obs* first = nullptr;
  for (const Obs& m : measurements) {
    if (m.u_px >= -0.5 && m.u_px <= w - 0.5 && m.v_px >= -0.5 && m.v_px <= h - 0.5) continue;
    if (!first) first = &m;
    ++outside;
  }
  if (!first || static_cast<double>(outside) <= kMaxShareOutsideImage * static_cast<double>(measurements.size())) return;
  std::ostringstream s;
  s.precision(8);
  s << outside << " of " << measurements.size() << " measurements lie outside the " << camera.image_width_px << "x"
    << camera.image_height_px << " image of " << camera_source << " (first: " << first->image << " ";
  if constexpr (requires { first->track_id; }) {
    s << "track " << first->track_id;
  } else {
    s << "point " << first->point_id;
  }
  s << " at (" << first->u_px << ", " << first->v_px << ") px): is the camera file for these photos?";
  throw InputError(data_source, 0, s.str());
}

}  // namespace photomill
