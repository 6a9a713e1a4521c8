// The renderer: per-pixel ray casting of a scene through the distorted pinhole camera, with
// supersampled anti-aliasing, Lambertian shading, Gaussian noise; multi-threaded and
// deterministic (the image depends on the inputs and the seed, never on the thread count).
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "tools/synth/scene.hpp"
#include "tools/synth/texture.hpp"

namespace photomill::synth {

// The first surface a ray meets.
struct Hit {
  double t_mm = 0;              // distance along the (unit) ray
  Eigen::Vector3d point_mm;     // world
  Eigen::Vector3d normal;       // unit, world
  bool wall = false;            // on a walled part's vertical side (normal horizontal)
};

// Something rays can be cast against.
class RayScene {
public:
  virtual ~RayScene() = default;
  // First hit along origin + t * direction, t > 0; `direction` is a unit vector.
  virtual std::optional<Hit> trace(const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction) const = 0;
  // Albedo at a hit, box-filtered over a footprint of the given size (mm).
  virtual double albedo(const Hit& hit, double footprint_mm) const = 0;
  // Radiance of rays that hit nothing.
  virtual double background() const { return 0.2; }
};

// Tolerances and limits of the height-field ray caster.
struct TraceOptions {
  double hit_tolerance_mm = 1e-7;  // a hit is accepted when the ray is this close above h
  int max_steps = 1000;            // safety net; rays that need more are reported as hits
};

// The part on its plate. Ray marching on the height field uses two rigorous lower bounds of the
// distance along the ray to the surface, at height g above it (g(t) = z(t) - h(x(t), y(t))):
//   Lipschitz:  g / (|d_z| + L |d_xy|),                       L >= |grad h|
//   quadratic:  the first root of g + g' s - K s^2 / 2,        K >= |d_xy|^2 ||Hessian h||
// and steps by the larger; the quadratic bound makes the last steps converge quadratically
// (a Newton step that can never overshoot), so no bisection is needed and no hit is missed.
// A walled part's sides are the faces of the box around its rectangle below the top: a ray that
// enters that box through a side below f hits the wall there.
class PartRayScene : public RayScene {
public:
  explicit PartRayScene(const PartScene& scene, TraceOptions options = {});
  std::optional<Hit> trace(const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& direction) const override;
  double albedo(const Hit& hit, double footprint_mm) const override;
  const PartScene& scene() const { return scene_; }

private:
  std::optional<Hit> march(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0,
                           double t1) const;
  const PartScene& scene_;
  TraceOptions options_;
  PartTexture texture_;
  double slope_bound_;
  double curvature_bound_;
  double z_min_, z_max_;  // bounds of h over the part rectangle
};

// The ChArUco board lying in the plane z = 0 of its own frame (the world of a board view).
class BoardRayScene : public RayScene {
public:
  explicit BoardRayScene(const BoardTexture& texture) : texture_(texture) {}
  std::optional<Hit> trace(const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& direction) const override;
  double albedo(const Hit& hit, double footprint_mm) const override;

private:
  const BoardTexture& texture_;
};

struct RenderOptions {
  int supersampling = 2;          // n: n x n samples per pixel on a regular grid
  double noise_sigma = 0;         // Gaussian noise, grey levels (0..255)
  std::uint64_t seed = 1;         // noise seed (combined with the view index)
  int threads = 0;                // 0: all hardware threads
  // Lambertian shading: radiance = albedo (ambient + (1 - ambient) max(0, n . light)) * gain.
  Eigen::Vector3d light_direction = Eigen::Vector3d(0.35, -0.45, 0.82);  // towards the light
  double ambient = 0.3;
  double gain = 255;              // grey level of a white surface facing the light
};

// Renders one 8-bit grey image of camera.image_width_px x image_height_px. Sample (a, b) of
// pixel (i, j) is at u = i + (a + 0.5)/n - 0.5, v = j + (b + 0.5)/n - 0.5 (OpenCV convention).
// Throws std::invalid_argument for bad options or a camera synth cannot invert.
cv::Mat render(const RayScene& scene, const Camera& camera, const Pose& pose,
               const RenderOptions& options, std::uint64_t view_index);

// True if the world point is seen by the camera: in front, inside the image, and the first hit
// of the ray from the camera centre to it is within `tolerance_mm` of it.
bool visible(const RayScene& scene, const Camera& camera, const Pose& pose,
             const Eigen::Vector3d& world_mm, double tolerance_mm = 1e-3);

}  // namespace photomill::synth
