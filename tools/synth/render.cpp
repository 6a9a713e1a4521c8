// Ray casting, shading and sampling (see render.hpp).
#include "tools/synth/render.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "geometry/parallel.hpp"
#include "tools/synth/camera_model.hpp"
#include "tools/synth/random.hpp"

namespace photomill::synth {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Slab test: the parameter interval [t0, t1] in which origin + t dir is inside the box.
bool intersect_box(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& lo,
                   const Eigen::Vector3d& hi, double& t0, double& t1) {
  t0 = -kInf;
  t1 = kInf;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0) {
      if (o[k] < lo[k] || o[k] > hi[k]) return false;
      continue;
    }
    double a = (lo[k] - o[k]) / d[k];
    double b = (hi[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1;
}

}  // namespace

PartRayScene::PartRayScene(const PartScene& scene, TraceOptions options)
    : scene_(scene), options_(options), texture_(scene) {
  validate(scene);
  const HeightField& f = scene.surface;
  slope_bound_ = f.slope_bound();
  curvature_bound_ = f.curvature_bound();
  // Height range over the rectangle: sampled extremes widened by the Lipschitz bound times the
  // largest distance from any point to the nearest sample.
  const double step = 1.0;
  const int nx = static_cast<int>(std::ceil((f.x_max_mm - f.x_min_mm) / step));
  const int ny = static_cast<int>(std::ceil((f.y_max_mm - f.y_min_mm) / step));
  double lo = 0, hi = 0;
  for (int i = 0; i <= nx; ++i) {
    for (int j = 0; j <= ny; ++j) {
      const double h = f.height_mm(f.x_min_mm + (f.x_max_mm - f.x_min_mm) * i / nx,
                                   f.y_min_mm + (f.y_max_mm - f.y_min_mm) * j / ny);
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
  }
  const double spacing = std::hypot((f.x_max_mm - f.x_min_mm) / nx, (f.y_max_mm - f.y_min_mm) / ny);
  const double margin = slope_bound_ * spacing / 2 + 1e-6;
  z_min_ = std::min(0.0, lo - margin);
  z_max_ = hi + margin;
}

std::optional<Hit> PartRayScene::march(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t0,
                                       double t1) const {
  const HeightField& f = scene_.surface;
  const double dxy = std::hypot(d.x(), d.y());
  const double den = std::abs(d.z()) + slope_bound_ * dxy;
  const double K = curvature_bound_ * dxy * dxy;
  double t = t0;
  for (int step = 0; step < options_.max_steps; ++step) {
    const Eigen::Vector3d p = o + t * d;
    Eigen::Vector2d grad;
    const double h = f.evaluate(p.x(), p.y(), grad);
    const double g = p.z() - h;
    if (g <= options_.hit_tolerance_mm) {
      return Hit{t, p, Eigen::Vector3d(-grad.x(), -grad.y(), 1.0).normalized()};
    }
    const double gp = d.z() - grad.x() * d.x() - grad.y() * d.y();  // dg/dt
    const double s_lip = den > 0 ? g / den : kInf;
    double s_quad;
    if (K > 0) {
      s_quad = (gp + std::sqrt(gp * gp + 2 * K * g)) / K;
    } else {
      s_quad = gp < 0 ? g / -gp : kInf;
    }
    t += std::max(s_lip, s_quad);
    if (t > t1) return std::nullopt;
  }
  // Only a ray grazing the surface for a very long way gets here; it is (almost) on it.
  const Eigen::Vector3d p = o + t * d;
  return Hit{t, p, f.normal(p.x(), p.y())};
}

std::optional<Hit> PartRayScene::trace(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  const HeightField& f = scene_.surface;
  // The plate plane z = 0 outside the part rectangle.
  double t_plane = kInf;
  if (d.z() != 0) {
    const double t = -o.z() / d.z();
    if (t > 0) {
      const Eigen::Vector3d p = o + t * d;
      if (!f.contains(p.x(), p.y())) t_plane = t;
    }
  }
  double ta, tb;
  if (intersect_box(o, d, {f.x_min_mm, f.y_min_mm, z_min_}, {f.x_max_mm, f.y_max_mm, z_max_}, ta,
                    tb)) {
    ta = std::max(ta, 0.0);
    if (ta <= tb && ta < t_plane && f.walled()) {
      // Entering through a side below the top's rim: the wall (never through the top, z_max_ is
      // above every f, nor the bottom, at the plate).
      const Eigen::Vector3d p = o + ta * d;
      if (p.z() < f.wall_top_mm(p.x(), p.y())) {
        const double gaps[4] = {std::abs(p.x() - f.x_min_mm), std::abs(p.x() - f.x_max_mm),
                                std::abs(p.y() - f.y_min_mm), std::abs(p.y() - f.y_max_mm)};
        const Eigen::Vector3d outward[4] = {-Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitX(),
                                            -Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitY()};
        const auto side = std::min_element(gaps, gaps + 4) - gaps;
        return Hit{ta, p, outward[side], true};
      }
    }
    if (ta <= tb && ta < t_plane) {
      if (auto hit = march(o, d, ta, std::min(tb, t_plane))) return hit;
    }
  }
  if (t_plane < kInf) return Hit{t_plane, o + t_plane * d, Eigen::Vector3d::UnitZ()};
  return std::nullopt;
}

double PartRayScene::albedo(const Hit& hit, double footprint_mm) const {
  if (hit.wall) {
    // The wall's own speckle, unrolled: along the side (x or y) and up (z); each side elsewhere
    // in the pattern so opposite walls do not repeat each other.
    const Eigen::Vector3d& n = hit.normal;
    const double along = n.x() != 0 ? hit.point_mm.y() : hit.point_mm.x();
    const double side = 2 * n.x() + n.y();  // -2, 2, -1, 1
    return texture_.wall_albedo(along + 1000 * side, hit.point_mm.z(), footprint_mm);
  }
  return texture_.albedo(hit.point_mm.x(), hit.point_mm.y(), footprint_mm);
}

std::optional<Hit> BoardRayScene::trace(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  if (d.z() == 0) return std::nullopt;
  const double t = -o.z() / d.z();
  if (!(t > 0)) return std::nullopt;
  return Hit{t, o + t * d, Eigen::Vector3d(0, 0, texture_.printed_side())};
}

double BoardRayScene::albedo(const Hit& hit, double footprint_mm) const {
  return texture_.albedo(hit.point_mm.x(), hit.point_mm.y(), footprint_mm);
}

cv::Mat render(const RayScene& scene, const Camera& camera, const Pose& pose,
               const RenderOptions& options, std::uint64_t view_index) {
  validate_synth_camera(camera);
  if (options.supersampling < 1 || options.supersampling > 16) {
    throw std::invalid_argument("supersampling must be 1..16");
  }
  if (!(options.noise_sigma >= 0) || !std::isfinite(options.noise_sigma)) {
    throw std::invalid_argument("noise sigma must be >= 0");
  }
  if (!(options.light_direction.norm() > 0) || !(options.ambient >= 0 && options.ambient <= 1)) {
    throw std::invalid_argument("bad lighting");
  }
  const int W = camera.image_width_px, H = camera.image_height_px;
  const int n = options.supersampling;
  const Eigen::Matrix3d world_from_cam = pose.rotation().transpose();
  const Eigen::Vector3d centre = pose.centre_mm();
  const Eigen::Vector3d light = options.light_direction.normalized();
  const double focal = 0.5 * (camera.fx() + camera.fy());
  cv::Mat image(H, W, CV_8UC1);

  auto render_row = [&](int j) {
    Rng noise(splitmix64(options.seed ^ splitmix64(view_index * 0x100000001B3ull + static_cast<std::uint64_t>(j))));
    auto* row = image.ptr<std::uint8_t>(j);
    for (int i = 0; i < W; ++i) {
      double sum = 0;
      for (int b = 0; b < n; ++b) {
        for (int a = 0; a < n; ++a) {
          const Eigen::Vector2d uv(i + (a + 0.5) / n - 0.5, j + (b + 0.5) / n - 0.5);
          const auto xy = pixel_to_normalised(camera, uv);
          if (!xy) {
            sum += scene.background();
            continue;
          }
          const Eigen::Vector3d ray_cam(xy->x(), xy->y(), 1.0);
          const double len = ray_cam.norm();
          const Eigen::Vector3d dir = world_from_cam * (ray_cam / len);
          const auto hit = scene.trace(centre, dir);
          if (!hit) {
            sum += scene.background();
            continue;
          }
          // Side of the sample's footprint on a surface facing the ray at distance t.
          const double footprint = hit->t_mm / (focal * len * n);
          const double shade =
              options.ambient + (1 - options.ambient) * std::max(0.0, hit->normal.dot(light));
          sum += scene.albedo(*hit, footprint) * shade;
        }
      }
      double v = options.gain * sum / (n * n);
      if (options.noise_sigma > 0) v += options.noise_sigma * noise.normal();
      row[i] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  };

  geometry::parallel_for(static_cast<std::size_t>(H), options.threads,
                         [&](std::size_t j) { render_row(static_cast<int>(j)); });
  return image;
}

bool visible(const RayScene& scene, const Camera& camera, const Pose& pose,
             const Eigen::Vector3d& world_mm, double tolerance_mm) {
  const auto uv = project(camera, pose, world_mm);
  if (!uv) return false;
  if (uv->x() < 0 || uv->y() < 0 || uv->x() > camera.image_width_px - 1 ||
      uv->y() > camera.image_height_px - 1) {
    return false;
  }
  const Eigen::Vector3d centre = pose.centre_mm();
  const Eigen::Vector3d to = world_mm - centre;
  const double dist = to.norm();
  const auto hit = scene.trace(centre, to / dist);
  return hit && hit->t_mm >= dist - tolerance_mm;
}

}  // namespace photomill::synth
