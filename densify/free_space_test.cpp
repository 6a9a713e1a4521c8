// The free-space check (densify.hpp): a point in front of a face that a view saw is found; points
// on the face, behind it or within the gap are not.
#include <cmath>

#include <gtest/gtest.h>

#include "densify/densify.hpp"
#include "densify/test_views.hpp"

namespace photomill::densify {
namespace {

geometry::CameraModel camera() { return test::small_camera(false); }
PatchView look_at(const Eigen::Vector3d& C) { return test::look_at_origin_from(C); }

SurfaceSample sample(const Eigen::Vector3d& p, const Eigen::Vector3d& n, std::vector<int> seen_by) {
  SurfaceSample s;
  s.xyz = p;
  s.normal = n.normalized();
  s.footprint = 0.25;
  s.seen_by = std::move(seen_by);
  return s;
}

TEST(FreeSpace, APointInFrontOfAFaceAViewSawViolatesIt) {
  // A wall's face x = 0 (normal +x) seen by view 0 from the +x side; view 1 looks from +y.
  const Eigen::Vector3d c0(200, 0, 100), c1(0, 200, 100);
  const std::vector<PatchView> views = {look_at(c0), look_at(c1)};
  std::vector<SurfaceSample> pts;
  for (double y = -5; y <= 5; y += 0.25) {
    for (double z = -5; z <= 5; z += 0.25) pts.push_back(sample({0, y, z}, {1, 0, 0}, {0}));
  }
  const std::size_t face = pts.size();
  // A top-like point 1.2 mm in front of the face on view 0's ray to the face's centre (what a
  // window centred past a rim puts in the air), matched in view 1 only.
  const Eigen::Vector3d in_air = (c0 - Eigen::Vector3d::Zero()).normalized() * 1.2;
  pts.push_back(sample(in_air, {0, 0, 1}, {1}));
  // On that ray too: 0.3 mm in front of the face (within the gap of 2 footprints), and 1 mm behind it.
  pts.push_back(sample(c0.normalized() * 0.3, {0, 0, 1}, {1}));
  pts.push_back(sample(-c0.normalized() * 1.0, {0, 0, 1}, {1}));
  // Beside the face, nowhere on a ray view 0 saw it by.
  pts.push_back(sample({1.2, 0, 8}, {0, 0, 1}, {1}));
  for (int threads : {1, 2}) {
    const std::vector<int> v = free_space_violations(pts, views, camera(), 2, threads);
    ASSERT_EQ(v.size(), pts.size());
    for (std::size_t k = 0; k < face; ++k) ASSERT_EQ(v[k], 0) << "a point of the face, " << pts[k].xyz.transpose();
    EXPECT_GE(v[face], 1) << "the point in the air";
    EXPECT_EQ(v[face + 1], 0) << "within the gap";
    EXPECT_EQ(v[face + 2], 0) << "behind the face";
    EXPECT_EQ(v[face + 3], 0) << "beside it";
  }
  // The face seen by no view: no evidence against the point in the air.
  for (std::size_t k = 0; k < face; ++k) pts[k].seen_by = {};
  EXPECT_EQ(free_space_violations(pts, views, camera(), 2)[face], 0);
}

}  // namespace
}  // namespace photomill::densify
