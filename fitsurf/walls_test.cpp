// Walls under a part's top (walls.hpp): a walled part on a plate gives its top alone, with or
// without points on the walls' faces and with a gap at their foot; a blended part with steep
// flanks, gross outliers and --walls off leave the selection as it was.
#include <cmath>
#include <ostream>

#include <gtest/gtest.h>

#include "fitsurf/select.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/error.hpp"

namespace photomill::fitsurf {
namespace {

constexpr double kX = 50, kY = 30;  // the top's half sizes, mm

double top_height(double x, double y, double wall_mm) {
  return wall_mm + 3 + 3 * std::sin(x / 20) * std::cos(y / 15);
}

struct WalledCloud {
  std::vector<Eigen::Vector3d> points;
  std::vector<int> kind;  // 0 top, 1 wall face, 2 plate
};

// A walled part (top over [-kX, kX] x [-kY, kY], walls from the plate up to it) on a plate 10 mm
// wider all round; points about every 1 mm with 0.02 mm of noise. `face_step_mm` > 0 puts points
// on the walls' faces that far apart; plate points start `gap_mm` from the walls' foot.
WalledCloud walled_part(double wall_mm, double face_step_mm, double gap_mm, std::uint64_t seed) {
  test::Rng rng(seed);
  WalledCloud c;
  auto add = [&](double x, double y, double z, int kind) {
    c.points.emplace_back(x + rng.uniform(-0.02, 0.02), y + rng.uniform(-0.02, 0.02), z + rng.uniform(-0.02, 0.02));
    c.kind.push_back(kind);
  };
  for (double x = -kX - 10; x <= kX + 10; x += 1) {
    for (double y = -kY - 10; y <= kY + 10; y += 1) {
      const double jx = x + rng.uniform(-0.4, 0.4), jy = y + rng.uniform(-0.4, 0.4);
      const bool on_top = std::abs(jx) <= kX && std::abs(jy) <= kY;
      if (on_top) {
        add(jx, jy, top_height(jx, jy, wall_mm), 0);
      } else if (std::abs(jx) > kX + gap_mm || std::abs(jy) > kY + gap_mm) {
        add(jx, jy, 0, 2);
      }
    }
  }
  if (face_step_mm > 0) {
    for (double t = -1; t <= 1; t += face_step_mm / kX) {
      for (const double side : {-1.0, 1.0}) {
        const double x = side * kX, y = t * kY, xs = t * kX, ys = side * kY;
        for (double z = face_step_mm; z < top_height(x, y, wall_mm) - 0.5; z += face_step_mm) add(x, y, z, 1);
        for (double z = face_step_mm; z < top_height(xs, ys, wall_mm) - 0.5; z += face_step_mm) add(xs, ys, z, 1);
      }
    }
  }
  return c;
}

struct WallCase {
  double wall_mm, face_step_mm, gap_mm;
};

void PrintTo(const WallCase& c, std::ostream* os) {
  *os << c.wall_mm << " mm high, " << (c.face_step_mm > 0 ? "face points" : "bare faces") << ", gap " << c.gap_mm << " mm";
}

class Walls : public ::testing::TestWithParam<WallCase> {};

TEST_P(Walls, LeaveTheTopAloneWithThePlateAndTheFacesDropped) {
  const WallCase w = GetParam();
  const WalledCloud c = walled_part(w.wall_mm, w.face_step_mm, w.gap_mm, 3);
  const Selection sel = select_part(c.points, SelectOptions{});
  ASSERT_TRUE(sel.walls.has_value());
  std::size_t top = 0, top_kept = 0, plate_kept = 0, face_kept = 0;
  for (int k : c.kind) top += k == 0;
  for (std::size_t k : sel.kept) {
    top_kept += c.kind[k] == 0;
    plate_kept += c.kind[k] == 2;
    const bool low_face = c.kind[k] == 1 && c.points[k].z() < top_height(c.points[k].x(), c.points[k].y(), w.wall_mm) - 3;
    face_kept += low_face;
    if (low_face) ADD_FAILURE() << "a point of a wall kept: " << c.points[k].transpose();
  }
  EXPECT_EQ(plate_kept, 0u);
  EXPECT_EQ(face_kept, 0u) << "points of the walls more than 3 mm under the rim";
  EXPECT_GE(static_cast<double>(top_kept), 0.97 * static_cast<double>(top));
  EXPECT_EQ(sel.walls->top_points, sel.kept.size());
  EXPECT_NEAR(sel.walls->floor_z_mm, 0, 0.05);
  EXPECT_NEAR(sel.walls->box_min.x(), -kX, 1);
  EXPECT_NEAR(sel.walls->box_max.y(), kY, 1);
  // Off: nothing is dropped.
  SelectOptions off;
  off.walls.enabled = false;
  const Selection all = select_part(c.points, off);
  EXPECT_FALSE(all.walls.has_value());
  EXPECT_EQ(all.kept.size(), c.points.size());
}

INSTANTIATE_TEST_SUITE_P(Heights, Walls,
                         ::testing::Values(WallCase{15, 0, 0}, WallCase{15, 0.5, 0}, WallCase{5, 0, 0},
                                           WallCase{5, 0.5, 0}, WallCase{15, 0, 2}, WallCase{5, 1, 1.5}));

// A blended part: the same top meeting the plate through a ramp as steep as 70 degrees.
TEST(Walls, NoneOnABlendedPartWithSteepFlanks) {
  test::Rng rng(5);
  std::vector<Eigen::Vector3d> pts;
  const double ramp = 5;  // mm wide, the top's edge 15 mm high: up to ~70 degrees
  for (double x = -kX - 10; x <= kX + 10; x += 0.7) {
    for (double y = -kY - 10; y <= kY + 10; y += 0.7) {
      const double jx = x + rng.uniform(-0.3, 0.3), jy = y + rng.uniform(-0.3, 0.3);
      const double d = std::max(std::abs(jx) - kX, std::abs(jy) - kY);  // > 0 outside the top
      const double t = std::clamp(1 - d / ramp, 0.0, 1.0);                  // 1 on the top, 0 on the plate
      const double s = t * t * (3 - 2 * t);
      pts.emplace_back(jx, jy, s * top_height(jx, jy, 12) + rng.uniform(-0.02, 0.02));
    }
  }
  const Selection sel = select_part(pts, SelectOptions{});
  EXPECT_FALSE(sel.walls.has_value());
  EXPECT_EQ(sel.kept.size(), pts.size());
}

// Gross points far above and below a smooth top (two-view points with a wrong depth) make no wall.
TEST(Walls, NoneFromGrossOutliers) {
  WalledCloud c = walled_part(10, 0, 0, 7);
  std::vector<Eigen::Vector3d> top;
  for (std::size_t k = 0; k < c.points.size(); ++k) {
    if (c.kind[k] == 0) top.push_back(c.points[k]);
  }
  test::Rng rng(9);
  const std::size_t n = top.size();
  for (int k = 0; k < 150; ++k) {
    const Eigen::Vector3d& p = top[static_cast<std::size_t>(rng.uniform(0, static_cast<double>(n - 1)))];
    top.push_back(p + Eigen::Vector3d(0, 0, rng.uniform(-40, 40)));
  }
  const Selection sel = select_part(top, SelectOptions{});
  EXPECT_FALSE(sel.walls.has_value());
  EXPECT_EQ(sel.kept.size(), top.size());
}

}  // namespace
}  // namespace photomill::fitsurf
