// The pinhole camera with OpenCV's distortion model (k1 k2 p1 p2 k3), forwards (projection of
// world points, exactly as cv::projectPoints) and backwards (the viewing ray of a pixel, by
// Newton's method on the distortion). Pixel convention: OpenCV's, the centre of the top-left
// pixel is (0, 0), so pixel (i, j) covers [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5].
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "formats/camera.hpp"
#include "formats/tables.hpp"

namespace photomill::synth {

// Normalised image coordinates (x, y) = (X/Z, Y/Z) in the camera frame -> pixel (u, v).
Eigen::Vector2d distort_to_pixel(const Camera& camera, const Eigen::Vector2d& normalised);

// Pixel (u, v) -> normalised (x, y) with distort_to_pixel(camera, (x, y)) == (u, v) to 1e-12 px.
// nullopt if Newton's method does not converge (distortion not invertible there).
std::optional<Eigen::Vector2d> pixel_to_normalised(const Camera& camera, const Eigen::Vector2d& uv);

// World point (mm) -> pixel, nullopt if the point is not in front of the camera (Z <= 0).
std::optional<Eigen::Vector2d> project(const Camera& camera, const Pose& pose,
                                       const Eigen::Vector3d& world_mm);

// Pose of a camera at `centre` looking at `target`, with world direction `up` appearing upwards
// in the image (OpenCV camera frame: x right, y down, z forward). Throws std::invalid_argument if
// the viewing direction is parallel to `up`.
Pose look_at(const std::string& image, const Eigen::Vector3d& centre_mm,
             const Eigen::Vector3d& target_mm, const Eigen::Vector3d& up);

// Throws std::invalid_argument unless the camera has positive size and focal lengths, zero skew,
// 0, 4 or 5 distortion coefficients, and a distortion that pixel_to_normalised inverts over the
// whole image (checked along the image border and on a coarse interior grid) and that is
// one-to-one there.
void validate_synth_camera(const Camera& camera);

}  // namespace photomill::synth
