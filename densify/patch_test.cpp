// PatchMatcher on photos rendered exactly (ray cast through the camera model onto a known
// surface with a smooth random texture): a plane and a curved surface are found to a few
// micrometres, curvature terms remove the planar fit's bias, and bad starts are refused.
#include "densify/patch.hpp"

#include <cmath>
#include <functional>
#include <iostream>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "densify/test_views.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::densify {
namespace {

using Surface = std::function<double(double, double)>;  // z = h(x, y), world mm

struct Scene {
  geometry::CameraModel camera;
  std::vector<PatchView> views;
};

geometry::CameraModel test_camera() { return test::small_camera(true); }

// A view from (azimuth, elevation) at `distance` mm looking at the origin; cam_from_world.
PatchView look_at(double azimuth_deg, double elevation_deg, double distance) {
  const double az = azimuth_deg * M_PI / 180, el = elevation_deg * M_PI / 180;
  return test::look_at_origin_from(
      {distance * std::cos(el) * std::cos(az), distance * std::cos(el) * std::sin(az), distance * std::sin(el)});
}

// A smooth random texture: a sum of sinusoids of 2-6 mm wavelength (8-24 px), grey 40-215.
struct Texture {
  std::vector<std::array<double, 4>> waves;  // kx, ky, phase, amplitude
  explicit Texture(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int k = 0; k < 40; ++k) {
      const double wl = 2 + 4 * u(rng), dir = 2 * M_PI * u(rng);
      waves.push_back({2 * M_PI / wl * std::cos(dir), 2 * M_PI / wl * std::sin(dir), 2 * M_PI * u(rng), 1.0});
    }
  }
  double operator()(double x, double y) const {
    double s = 0;
    for (const auto& w : waves) s += std::sin(w[0] * x + w[1] * y + w[2]);
    return 128 + 87 * std::tanh(s / std::sqrt(waves.size() / 2.0));
  }
};

// The world point a pixel sees on z = h(x, y), nullopt if none: the first sign change of
// g(s) = z(s) - h(x(s), y(s)) along the ray, marched in 1 mm steps from 40 mm before the ray
// meets z = 0 (the test surfaces lie within 20 mm of it in the views' middle), then found to
// 1e-10 mm by regula falsi with the Illinois modification (Dowell & Jarratt 1971, BIT 11:
// the retained end's value is halved when one end is kept twice, so it converges
// superlinearly and keeps the bracket).
// `xy` is the pixel's undistorted ray (x, y, 1) in the view's frame.
std::optional<Eigen::Vector3d> cast_ray(const PatchView& v, const Surface& h, const Eigen::Vector2d& xy) {
  const Eigen::Vector3d C = -v.rotation.transpose() * v.translation_mm;
  const Eigen::Vector3d d = v.rotation.transpose() * Eigen::Vector3d(xy.x(), xy.y(), 1).normalized();
  auto g = [&](double s) { const Eigen::Vector3d p = C + s * d; return p.z() - h(p.x(), p.y()); };
  if (!(d.z() < 0)) return std::nullopt;
  const double s0 = -C.z() / d.z();
  double lo = s0 - 40, glo = g(lo);
  if (!(glo > 0)) return std::nullopt;
  double hi = lo, ghi = glo;
  while (ghi > 0) {
    lo = hi;
    glo = ghi;
    hi += 1;
    if (hi > s0 + 40) return std::nullopt;
    ghi = g(hi);
  }
  for (int k = 0, kept = 0; k < 200 && hi - lo > 1e-10 && ghi != 0; ++k) {
    const double m = (lo * ghi - hi * glo) / (ghi - glo), gm = g(m);
    if (gm > 0) {
      lo = m;
      glo = gm;
      if (kept == 1) ghi /= 2;
      kept = 1;  // hi kept
    } else {
      hi = m;
      ghi = gm;
      if (kept == -1) glo /= 2;
      kept = -1;  // lo kept
    }
    if (gm == 0) lo = m;
  }
  return C + (ghi == 0 ? hi : (lo + hi) / 2) * d;
}

std::optional<Eigen::Vector3d> cast(const geometry::CameraModel& cam, const PatchView& v, const Surface& h,
                                    const Eigen::Vector2d& px) {
  const auto xy = geometry::undistort(cam, px);
  if (!xy) return std::nullopt;
  return cast_ray(v, h, *xy);
}

Scene render(const Surface& h, const std::vector<std::pair<double, double>>& az_el, unsigned seed = 7) {
  Scene s;
  s.camera = test_camera();
  const Texture tex(seed);
  // The views share the camera: each pixel's ray is undistorted once.
  std::vector<std::optional<Eigen::Vector2d>> rays;
  for (int y = 0; y < s.camera.height_px; ++y) {
    for (int x = 0; x < s.camera.width_px; ++x) rays.push_back(geometry::undistort(s.camera, Eigen::Vector2d(x, y)));
  }
  for (const auto& [az, el] : az_el) {
    PatchView v = look_at(az, el, 200);
    v.grey = cv::Mat(s.camera.height_px, s.camera.width_px, CV_32F, cv::Scalar(0));
    for (int y = 0; y < v.grey.rows; ++y) {
      for (int x = 0; x < v.grey.cols; ++x) {
        const auto& xy = rays[static_cast<size_t>(y) * v.grey.cols + x];
        if (!xy) continue;
        if (const auto p = cast_ray(v, h, *xy)) v.grey.at<float>(y, x) = static_cast<float>(tex(p->x(), p->y()));
      }
    }
    s.views.push_back(v);
  }
  return s;
}

// The plane facing the reference camera through its ray at `centre`, at depth z (camera frame).
Eigen::Vector3d facing_plane(const geometry::CameraModel& cam, const Eigen::Vector2i& centre, double z) {
  const auto xy = geometry::undistort(cam, centre.cast<double>());
  const Eigen::Vector3d X = Eigen::Vector3d(xy->x(), xy->y(), 1) * z;
  return X / X.squaredNorm();
}

// Distance along the reference ray from the measured point to the true surface point.
double ray_error(const Scene& s, const Surface& h, const Eigen::Vector2i& centre, const PatchResult& r) {
  const auto truth = cast(s.camera, s.views[0], h, centre.cast<double>());
  const Eigen::Vector3d X = s.views[0].rotation.transpose() * (r.point_ref - s.views[0].translation_mm);
  return (X - *truth).norm();
}

// The depth (reference camera's z) of the true surface point the reference pixel `centre` sees.
double true_depth(const Scene& s, const Surface& h, const Eigen::Vector2i& centre) {
  const auto truth = cast(s.camera, s.views[0], h, centre.cast<double>());
  return (s.views[0].rotation * *truth + s.views[0].translation_mm).z();
}

const std::vector<std::pair<double, double>> kRing = {{0, 60}, {20, 55}, {-20, 55}, {0, 45}};

// The plane z = 0.2 x - 0.1 y seen by kRing, and the reference pixel the tests measure at.
struct TiltedPlane {
  Surface plane = [](double x, double y) { return 0.2 * x - 0.1 * y; };
  Scene s = render(plane, kRing);
  Eigen::Vector2i centre{240, 180};
  double z = true_depth(s, plane, centre);
};

TEST(PatchMatcher, FindsATiltedPlaneToMicrometres) {
  const TiltedPlane t;
  const Surface& plane = t.plane;
  const Scene& s = t.s;
  const Eigen::Vector2i& centre = t.centre;
  const double z = t.z;
  const PatchMatcher m(s.camera, {});
  PatchResult r;
  // Started 0.5 mm off in depth, with the plane facing the camera (about 25 degrees off).
  ASSERT_EQ(m.measure(s.views, 0, centre, facing_plane(s.camera, centre, z + 0.5), {1, 2, 3}, &r), PatchFailure::None);
  // 0.005 mm is 0.02 px here (4 px per mm): what the cubic interpolation of point-sampled
  // renderings allows.
  EXPECT_LT(ray_error(s, plane, centre, r), 0.005);
  const Eigen::Vector3d normal = s.views[0].rotation.transpose() * (-r.plane.normalized());
  const Eigen::Vector3d true_normal = Eigen::Vector3d(-0.2, 0.1, 1).normalized();
  EXPECT_LT(std::acos(std::min(1.0, normal.dot(true_normal))) * 180 / M_PI, 1.0);
  EXPECT_EQ(r.views.size(), 3u);
  EXPECT_GT(r.correlation, 0.99);
  EXPECT_GT(r.sigma_along_ray, 0);
  EXPECT_LT(r.sigma_along_ray, 0.02);
}

TEST(PatchMatcher, CurvatureTermsRemoveThePlanarBiasOnACurvedSurface) {
  // A dome of 15 mm radius of curvature: a plane fitted over the 19 px (4.75 mm) window lies off
  // the centre's true point by a good part of the window's sagitta (~0.2 mm).
  const Surface dome = [](double x, double y) { return -(x * x + y * y) / 30; };
  const Scene s = render(dome, kRing);
  PatchOptions quadratic, planar;
  planar.quadratic = false;
  double err_q = 0, err_p = 0;
  int n = 0;
  for (const Eigen::Vector2i& centre : {Eigen::Vector2i(240, 180), Eigen::Vector2i(222, 168), Eigen::Vector2i(258, 192)}) {
    const double z = true_depth(s, dome, centre);
    PatchResult rq, rp;
    ASSERT_EQ(PatchMatcher(s.camera, quadratic).measure(s.views, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &rq),
              PatchFailure::None);
    ASSERT_EQ(PatchMatcher(s.camera, planar).measure(s.views, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &rp),
              PatchFailure::None);
    err_q = std::max(err_q, ray_error(s, dome, centre, rq));
    err_p = std::max(err_p, ray_error(s, dome, centre, rp));
    ++n;
  }
  EXPECT_LT(err_q, 0.01);
  EXPECT_GT(err_p, 10 * err_q);
  std::cerr << "largest error along the ray: quadratic " << err_q << " mm, planar " << err_p << " mm\n";
}

TEST(PatchMatcher, RefusesWhatItCannotMeasure) {
  const Surface plane = [](double, double) { return 0.0; };
  const Scene s = render(plane, kRing);
  const PatchMatcher m(s.camera, {});
  const Eigen::Vector2i centre(240, 180);
  const double z = true_depth(s, plane, centre);
  PatchResult r;
  // Too few views for min_views 3.
  EXPECT_EQ(m.measure(s.views, 0, centre, facing_plane(s.camera, centre, z), {1}, &r), PatchFailure::Views);
  // A plane behind the camera.
  EXPECT_EQ(m.measure(s.views, 0, centre, -facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::Behind);
  // The window beyond the photo's edge.
  EXPECT_EQ(m.measure(s.views, 0, Eigen::Vector2i(3, 180), facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::Border);
  // A start 8 mm off in depth (the window lands 10-20 px away in the other views): refused, or
  // found exactly; never accepted elsewhere.
  const PatchFailure far = m.measure(s.views, 0, centre, facing_plane(s.camera, centre, z + 8), {1, 2, 3}, &r);
  if (far == PatchFailure::None) {
    EXPECT_LT(ray_error(s, plane, centre, r), 0.005);
  }
  // No texture: a blank reference.
  std::vector<PatchView> blank = s.views;
  blank[0].grey = cv::Mat(s.camera.height_px, s.camera.width_px, CV_32F, cv::Scalar(100));
  EXPECT_EQ(m.measure(blank, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::Singular);
  // Another texture in one view: that view is dropped, and with min_views 4 the patch is refused.
  std::vector<PatchView> swapped = s.views;
  swapped[3].grey = render(plane, kRing, 99).views[3].grey;
  ASSERT_EQ(m.measure(swapped, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::None);
  EXPECT_EQ(r.views, (std::vector<int>{1, 2}));
  PatchOptions four;
  four.min_views = 4;
  EXPECT_NE(PatchMatcher(s.camera, four).measure(swapped, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r),
            PatchFailure::None);
}

// The reference pixel that sees world point X.
Eigen::Vector2i pixel_of(const Scene& s, const Eigen::Vector3d& X) {
  const Eigen::Vector3d Xc = s.views[0].rotation * X + s.views[0].translation_mm;
  double u, v;
  geometry::distort_to_pixel(geometry::shape_of(s.camera), s.camera.params.data(), Xc.x() / Xc.z(), Xc.y() / Xc.z(), &u, &v);
  return Eigen::Vector2i(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), std::abs(a.dot(b))) * 180 / M_PI;
}

TEST(PatchMatcher, RefusesAWindowAcrossACreaseAndProposesItsTwoFaces) {
  // A flat top (z = 0, x < 0) ending in a face that drops at 71.6 degrees (z = -3x): a wall's
  // rim, seen by every view. A window centred on the crease is fitted by a tight bend through
  // the solid's inside (no surface); it is refused, and its quadrants' planes are the two faces.
  const Surface rim = [](double x, double) { return x < 0 ? 0.0 : -3 * x; };
  const Scene s = render(rim, kRing);
  const PatchMatcher m(s.camera, {});
  const Eigen::Vector2i crease = pixel_of(s, Eigen::Vector3d(0, 0, 0));
  const double z = true_depth(s, rim, crease);
  PatchResult r;
  ASSERT_EQ(m.measure(s.views, 0, crease, facing_plane(s.camera, crease, z), {1, 2, 3}, &r), PatchFailure::Bent);
  const Eigen::Vector3d top(0, 0, 1), face = Eigen::Vector3d(3, 0, 1).normalized();
  double best_top = 180, best_face = 180;
  ASSERT_FALSE(r.bend_planes.empty());
  for (const Eigen::Vector3d& plane : r.bend_planes) {
    const Eigen::Vector3d normal = s.views[0].rotation.transpose() * plane.normalized();
    best_top = std::min(best_top, angle_deg(normal, top));
    best_face = std::min(best_face, angle_deg(normal, face));
  }
  EXPECT_LT(best_top, 15);
  EXPECT_LT(best_face, 15);
  // Without the check the same window is accepted, its point inside the solid, off the crease.
  PatchOptions no_check;
  no_check.max_bend_deg = 180;
  ASSERT_EQ(PatchMatcher(s.camera, no_check).measure(s.views, 0, crease, facing_plane(s.camera, crease, z), {1, 2, 3}, &r),
            PatchFailure::None);
  const double off = ray_error(s, rim, crease, r);
  std::cerr << "a window across the crease, accepted without the check: " << off << " mm off the surface\n";
  EXPECT_GT(off, 0.05);
  // A window wholly on the top, its edge a millimetre from the crease: accepted, exact.
  const Eigen::Vector2i on_top = pixel_of(s, Eigen::Vector3d(-3.5, 0, 0));
  ASSERT_EQ(m.measure(s.views, 0, on_top, facing_plane(s.camera, on_top, true_depth(s, rim, on_top)), {1, 2, 3}, &r),
            PatchFailure::None);
  EXPECT_LT(ray_error(s, rim, on_top, r), 0.005);
}

TEST(PatchMatcher, ReprojectionErrorIsTheViewsFreeMatchesOffTheProjection) {
  // Exact renderings: every view's window matches freely where the point projects. Then view 1's
  // photo is moved by 0.5 px across its epipolar line (a pose 0.5 px off), which no point on the
  // reference ray can follow: the free match in that view lands about 0.5 px from the projection.
  const TiltedPlane t;
  // (References, not a structured binding: clang 14's lambdas cannot capture one.)
  const Scene& s = t.s;
  const Eigen::Vector2i& centre = t.centre;
  const double z = t.z;
  const PatchMatcher m(s.camera, {});
  PatchResult r;
  ASSERT_EQ(m.measure(s.views, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::None);
  EXPECT_LT(r.reprojection_px, 0.03);

  // The epipolar line's direction in view 1 at the point: the projections of two depths.
  const auto project1 = [&](double depth) {
    const auto xy = geometry::undistort(s.camera, centre.cast<double>());
    const Eigen::Vector3d X = s.views[0].rotation.transpose() * (Eigen::Vector3d(xy->x(), xy->y(), 1) * depth - s.views[0].translation_mm);
    const Eigen::Vector3d Xc = s.views[1].rotation * X + s.views[1].translation_mm;
    double u, v;
    geometry::distort_to_pixel(geometry::shape_of(s.camera), s.camera.params.data(), Xc.x() / Xc.z(), Xc.y() / Xc.z(), &u, &v);
    return Eigen::Vector2d(u, v);
  };
  const Eigen::Vector2d along = (project1(z + 1) - project1(z - 1)).normalized();
  const Eigen::Vector2d across(-along.y(), along.x());
  std::vector<PatchView> moved = s.views;
  moved[1].grey = cv::Mat();  // (the copy shares the photo's pixels: warp into new ones)
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 0.5 * across.x(), 0, 1, 0.5 * across.y());
  cv::warpAffine(s.views[1].grey, moved[1].grey, shift, s.views[1].grey.size(), cv::INTER_CUBIC, cv::BORDER_REPLICATE);
  ASSERT_EQ(m.measure(moved, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r), PatchFailure::None);
  // Still matched in all three views (a 1 px move drops view 1 by its correlation). RMS over 4
  // observations of which one is ~0.5 px off: ~0.25 px.
  ASSERT_EQ(r.views.size(), 3u);
  EXPECT_GT(r.reprojection_px, 0.2);
  EXPECT_LT(r.reprojection_px, 0.3);
  std::cerr << "view 1 moved 0.5 px across its epipolar line: reprojection error " << r.reprojection_px << " px\n";
  // --max-reprojection-px refuses it, and keeps the exact views' point.
  PatchOptions strict;
  strict.max_reprojection_px = 0.2;
  EXPECT_EQ(PatchMatcher(s.camera, strict).measure(moved, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r),
            PatchFailure::Reprojection);
  EXPECT_EQ(PatchMatcher(s.camera, strict).measure(s.views, 0, centre, facing_plane(s.camera, centre, z), {1, 2, 3}, &r),
            PatchFailure::None);
}

}  // namespace
}  // namespace photomill::densify
