// The parameter frame (PCA plane, degenerate clouds) and part selection (box, half-space,
// RANSAC dominant plane).
#include <gtest/gtest.h>

#include "fitsurf/frame.hpp"
#include "fitsurf/select.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {
namespace {

std::vector<Eigen::Vector3d> tilted_plane(std::size_t n, const Eigen::Vector3d& normal, std::uint64_t seed) {
  const Eigen::Vector3d nz = normal.normalized();
  const Eigen::Vector3d a = nz.unitOrthogonal(), b = nz.cross(a);
  test::Rng rng(seed);
  std::vector<Eigen::Vector3d> pts;
  for (std::size_t k = 0; k < n; ++k) {
    pts.push_back(Eigen::Vector3d(10, -20, 5) + rng.uniform(-80, 80) * a + rng.uniform(-40, 40) * b +
                  rng.uniform(-0.5, 0.5) * nz);
  }
  return pts;
}

class PcaFrame : public ::testing::TestWithParam<Eigen::Vector3d> {};

TEST_P(PcaFrame, IsRightHandedWithTheNormalUpAndFollowsThePlane) {
  const Eigen::Vector3d n = GetParam().normalized();
  const auto pts = tilted_plane(3000, n, 1);
  const PlaneFrame f = parameter_frame(pts, PlaneChoice::Pca);
  EXPECT_NEAR(f.axes.determinant(), 1.0, 1e-12);
  EXPECT_LT((f.axes.transpose() * f.axes - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_GT(f.axes.col(2).dot(n.z() >= 0 ? n : Eigen::Vector3d(-n)), 0.999);
  EXPECT_GE(f.axes(2, 2), 0.0);  // e3 towards world +z
  EXPECT_GT(f.spread_mm[0], f.spread_mm[1]);
  EXPECT_LT(f.spread_mm[2], 0.3);
  for (const auto& p : pts) EXPECT_LT((f.to_world(f.to_local(p)) - p).norm(), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Normals, PcaFrame,
                         ::testing::Values(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(0.3, -0.2, 1),
                                           Eigen::Vector3d(1, 0.5, 0.2), Eigen::Vector3d(0.1, 1, -0.3)));

struct Degenerate {
  std::string name;
  std::vector<Eigen::Vector3d> points;
  PlaneChoice plane;
  std::string message;
};

void PrintTo(const Degenerate& d, std::ostream* os) { *os << d.name; }

class DegenerateFrame : public ::testing::TestWithParam<Degenerate> {};

TEST_P(DegenerateFrame, ThrowsAGeometryErrorThatSaysWhy) {
  const Degenerate& d = GetParam();
  try {
    parameter_frame(d.points, d.plane);
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find(d.message), std::string::npos) << e.what();
  }
}

std::vector<Degenerate> degenerate_cases() {
  std::vector<Eigen::Vector3d> same(50, Eigen::Vector3d(1, 2, 3));
  std::vector<Eigen::Vector3d> line, wall;
  for (int k = 0; k < 50; ++k) {
    line.emplace_back(k * 2.0, k * 1.0, 5 - k * 0.5);
    wall.emplace_back(k * 1.0, 3.0, (k * 37) % 11);  // a vertical wall: a line seen from above
  }
  return {{"coincident", same, PlaneChoice::Pca, "coincide"},
          {"collinear", line, PlaneChoice::Pca, "line"},
          {"wall_seen_from_above", wall, PlaneChoice::Xy, "line"},
          {"empty", {}, PlaneChoice::Pca, "no points"}};
}

INSTANTIATE_TEST_SUITE_P(Clouds, DegenerateFrame, ::testing::ValuesIn(degenerate_cases()),
                         [](const auto& info) { return info.param.name; });

// A part (the bumps shape, 20-40 mm high) on a plate at z = 0 (a 300 x 240 mm plate, 0.05 mm
// noise), with a few points under the plate.
struct Scene {
  std::vector<Eigen::Vector3d> points;
  std::size_t part = 0, plate = 0, below = 0;
};

Scene part_on_plate() {
  Scene s;
  s.points = test::sample(test::shape("bumps"), 20000, 0.01, 3);
  s.part = s.points.size();
  test::Rng rng(5);
  for (int k = 0; k < 30000; ++k) {
    const double x = rng.uniform(-150, 150), y = rng.uniform(-120, 120);
    if (std::abs(x) < 76 && std::abs(y) < 51) continue;
    s.points.emplace_back(x, y, 0.05 * rng.normal());
    ++s.plate;
  }
  for (int k = 0; k < 500; ++k) {
    s.points.emplace_back(rng.uniform(-150, 150), rng.uniform(-120, 120), -rng.uniform(5, 30));
    ++s.below;
  }
  return s;
}

TEST(PartSelection, DropPlaneRemovesThePlateAndWhatLiesUnderIt) {
  const Scene sc = part_on_plate();
  SelectOptions o;
  o.drop_plane = true;
  const Selection sel = select_part(sc.points, o);
  ASSERT_TRUE(sel.plane.has_value());
  EXPECT_GT(sel.plane->normal.z(), 0.9999);
  EXPECT_NEAR(sel.plane->offset_mm, 0.0, 0.01);
  EXPECT_EQ(sel.dropped_plane, sc.plate);
  EXPECT_EQ(sel.dropped_beyond_plane, sc.below);
  EXPECT_EQ(sel.kept.size(), sc.part);
  for (std::size_t k : sel.kept) EXPECT_LT(k, sc.part);
}

TEST(PartSelection, BoxAndHalfSpaceKeepWhatTheySay) {
  const Scene sc = part_on_plate();
  SelectOptions o;
  o.keep_box_mm = std::array<double, 6>{-80, -55, 1, 80, 55, 100};
  Selection sel = select_part(sc.points, o);
  EXPECT_EQ(sel.kept.size(), sc.part);
  EXPECT_EQ(sel.dropped_box, sc.plate + sc.below);
  o.keep_box_mm.reset();
  o.keep_above = Plane{Eigen::Vector3d::UnitZ(), -1.0};  // z > 1
  sel = select_part(sc.points, o);
  EXPECT_EQ(sel.kept.size(), sc.part);
  EXPECT_EQ(sel.dropped_below, sc.plate + sc.below);
}

TEST(PartSelection, AFlatCloudHasNothingAboveItsPlane) {
  const auto pts = tilted_plane(5000, Eigen::Vector3d(0.1, 0.2, 1), 7);
  SelectOptions o;
  o.drop_plane = true;
  o.plane_threshold_mm = 0.6;
  try {
    select_part(pts, o);
    FAIL() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("the cloud is flat"), std::string::npos) << e.what();
  }
}

TEST(PartSelection, NoDominantPlaneInABlob) {
  test::Rng rng(2);
  std::vector<Eigen::Vector3d> blob;
  for (int k = 0; k < 3000; ++k) blob.emplace_back(rng.normal() * 30, rng.normal() * 30, rng.normal() * 30);
  SelectOptions o;
  o.drop_plane = true;
  o.plane_threshold_mm = 0.1;
  EXPECT_THROW(select_part(blob, o), GeometryError);
}

TEST(PartSelection, EmptyBoxIsAnError) {
  const Scene sc = part_on_plate();
  SelectOptions o;
  o.keep_box_mm = std::array<double, 6>{500, 500, 500, 600, 600, 600};
  EXPECT_THROW(select_part(sc.points, o), GeometryError);
}

}  // namespace
}  // namespace photomill::fitsurf
