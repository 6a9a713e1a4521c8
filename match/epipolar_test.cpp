// EpipolarPencil against a brute-force Sampson test: every point of b within the threshold of a
// point of a must be visited, wherever the epipole lies.
#include "match/epipolar.hpp"

#include <cmath>
#include <random>
#include <set>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace photomill::match {
namespace {

Pose pose_at(const Eigen::Matrix3d& cam_from_world, const Eigen::Vector3d& centre_mm) {
  Pose p;
  p.cam_from_world_rotation = Eigen::Quaterniond(cam_from_world);
  p.cam_from_world_translation_mm = -(cam_from_world * centre_mm);
  return p;
}

struct PencilCase {
  const char* name;
  Eigen::Vector3d centre_b_mm;  // camera a at the origin looking along +z; b looks along +z too, turned by:
  double yaw_deg;
};

class Pencil : public ::testing::TestWithParam<PencilCase> {};

TEST_P(Pencil, VisitsEveryPointThatPassesTheSampsonTest) {
  const auto& c = GetParam();
  Eigen::Matrix3d K;
  K << 1500, 0, 1000, 0, 1500, 750, 0, 0, 1;
  const Pose a = pose_at(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  const Pose b = pose_at(Eigen::AngleAxisd(c.yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                         c.centre_b_mm);
  const Eigen::Matrix3d F = fundamental_from_poses(K, a, b);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-200, 2200), uy(-200, 1700);
  std::vector<Eigen::Vector2d> pa(400), pb(20000);
  for (auto& p : pa) p = {ux(rng), uy(rng)};
  for (auto& p : pb) p = {ux(rng), uy(rng)};
  // The epipole in b itself, and a point that is not finite (left out).
  const Eigen::Vector3d e = F.transpose().jacobiSvd(Eigen::ComputeFullV).matrixV().col(2);
  if (std::abs(e.z()) > 1e-9) pb.push_back(e.hnormalized());
  pb.push_back({std::nan(""), 5.0});
  const EpipolarPencil pencil(pb, F);
  const double thr_px = 1.5;
  std::size_t found = 0, visited = 0;
  for (const auto& xa : pa) {
    const Eigen::Vector3d fa = F * xa.homogeneous();
    std::set<std::size_t> seen;
    pencil.near(fa, thr_px, [&](std::size_t k) {
      EXPECT_TRUE(seen.insert(k).second) << "point " << k << " visited twice";
    });
    visited += seen.size();
    for (std::size_t k = 0; k < pb.size(); ++k) {
      if (!(sampson_distance_px(F, xa, pb[k]) <= thr_px)) continue;
      ++found;
      EXPECT_TRUE(seen.count(k)) << c.name << ": point " << k << " passes the Sampson test but was not visited";
      EXPECT_DOUBLE_EQ(pencil.ftb2(k), (F.transpose() * pb[k].homogeneous()).head<2>().squaredNorm());
    }
  }
  EXPECT_GT(found, 400u);  // the test has points to find
  // And it looks at few others: the whole point of the index.
  EXPECT_LT(visited, 6 * found) << c.name;
}

INSTANTIATE_TEST_SUITE_P(
    Epipoles, Pencil,
    ::testing::Values(PencilCase{"epipole inside the image (b in front of a)", {20, 10, 300}, 3},
                      PencilCase{"epipole far outside (b beside a, turned)", {300, 20, 30}, -25},
                      PencilCase{"epipole at infinity (b beside a, parallel)", {200, 0, 0}, 0},
                      PencilCase{"epipole nearly at infinity", {200, 1e-7, 1e-7}, 1e-6}),
    [](const auto& info) { return std::to_string(info.index); });

}  // namespace
}  // namespace photomill::match
