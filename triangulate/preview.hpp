// PNG preview of a reconstruction (triangulate --preview FILE.png), for a person to look at:
// two orthographic views side by side of the point cloud coloured by a per-point quality
// (reprojection RMS in px or uncertainty sigma in mm, with a colour bar), control points marked by
// squares: an oblique view of the whole scene with every registered camera as a small frustum
// (apex at the centre, the far rectangle is the image, its top edge thicker) and its image name,
// and a top view framed on the points. The frames follow the bulk of the points (percentile box)
// and the cameras near it, so a few wild points or a far camera do not shrink the scene to a
// dot. Nothing reads it back.
#pragma once

#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "formats/camera.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"

namespace photomill::triangulate {

struct Reconstruction;

struct PreviewOptions {
  int width_px = 1600;            // the picture; the height is half of it
  std::string colour_by = "rms";  // "rms": the cloud's reproj_rms_px; "sigma": its sigma_mm
  double azimuth_deg = -60;       // oblique view: the viewer's direction around z from +x ...
  double elevation_deg = 35;      // ... and above the xy plane
  // Framing: the box from this percentile to its complement of the points' x, y and z, grown by
  // 5 % on every side (top view); with the cameras within `camera_frame_factor` box diagonals of
  // its centre (oblique view).
  double frame_percentile = 0.02;
  double camera_frame_factor = 4;
};

// Throws UsageError for options out of range.
void validate(const PreviewOptions& options);

// Encoded PNG bytes. `cloud` as make_point_cloud writes it (x y z, reproj_rms_px, sigma_mm,
// control; a missing property leaves the points grey / unmarked); `poses` of the registered
// images; `cameras` for the frusta: one per pose, or one for all. Throws GeometryError for an
// empty cloud, UsageError for another number of cameras.
std::vector<std::uint8_t> render_preview_png(const PointCloud& cloud, const std::vector<Pose>& poses,
                                             const std::vector<Camera>& cameras, const PreviewOptions& options = {});
inline std::vector<std::uint8_t> render_preview_png(const PointCloud& cloud, const std::vector<Pose>& poses,
                                                    const Camera& camera, const PreviewOptions& options = {}) {
  return render_preview_png(cloud, poses, std::vector<Camera>{camera}, options);
}

// Renders the preview of a reconstruction and writes the PNG bytes to `out`.
void write_preview(std::ostream& out, const Reconstruction& result, const PreviewOptions& options = {});

}  // namespace photomill::triangulate
