// Foot points (Newton, NURBS Book 6.1) and the fast non-rational evaluation they use.
#include "fitsurf/project.hpp"

#include <gtest/gtest.h>

#include "fitsurf/evaluate.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/bspline.hpp"

namespace photomill::fitsurf {
namespace {

// A wavy bicubic-by-quadratic surface over about 150 x 100 mm with non-uniform knots.
BSplineSurface wavy() {
  BSplineSurface s;
  s.degree_u = 3;
  s.degree_v = 2;
  s.num_poles_u = 8;
  s.num_poles_v = 6;
  s.knots_u = {0, 0, 0, 0, 0.15, 0.4, 0.55, 0.8, 1, 1, 1, 1};
  s.knots_v = {0, 0, 0, 0.25, 0.5, 0.7, 1, 1, 1};
  test::Rng rng(9);
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 6; ++j) s.poles_mm.emplace_back(150.0 * i / 7, 100.0 * j / 5, 30 + rng.uniform(-8, 8));
  }
  return s;
}

TEST(FastEvaluate, AgreesWithSurfaceDerivatives) {
  const BSplineSurface s = wavy();
  test::Rng rng(2);
  for (int k = 0; k < 500; ++k) {
    const double u = k == 0 ? 0.0 : k == 1 ? 1.0 : rng.uniform(), v = k == 0 ? 1.0 : k == 1 ? 0.0 : rng.uniform();
    const SurfaceDerivatives a = evaluate(s, u, v);
    const SurfaceDerivatives b = surface_derivatives(s, u, v);
    EXPECT_LT((a.p - b.p).norm(), 1e-10);
    EXPECT_LT((a.su - b.su).norm(), 1e-9);
    EXPECT_LT((a.sv - b.sv).norm(), 1e-9);
    EXPECT_LT((a.suu - b.suu).norm(), 1e-8);
    EXPECT_LT((a.suv - b.suv).norm(), 1e-8);
    EXPECT_LT((a.svv - b.svv).norm(), 1e-8);
  }
}

// A point placed at signed distance d along the normal of S(u, v) projects back to (u, v) and d,
// from a start 0.05 away in both parameters.
class FootPoints : public ::testing::TestWithParam<double> {};

TEST_P(FootPoints, RecoverParametersAndSignedDistance) {
  const double offset = GetParam();
  const BSplineSurface s = wavy();
  test::Rng rng(4);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector2d uv(rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9));
    const SurfaceDerivatives d = surface_derivatives(s, uv.x(), uv.y());
    const Eigen::Vector3d q = d.p + offset * d.normal();
    ProjectionOptions tight;
    tight.step_tolerance_mm = 1e-9;
    const FootPoint fp = project_point(s, q, uv + Eigen::Vector2d(0.05, -0.05), tight);
    EXPECT_NEAR(fp.signed_distance_mm, offset, 1e-9) << "at " << uv.transpose();
    // The position is found only to ~sqrt(eps * distance): the distance is stationary there.
    EXPECT_LT((fp.point - d.p).norm(), 1e-6) << "at " << uv.transpose();
    // The default tolerance stops within step_tolerance_mm of the foot point; the distance is
    // then off by at most that much (much less away from the surface: it is stationary there).
    const ProjectionOptions loose;
    const FootPoint fl = project_point(s, q, uv + Eigen::Vector2d(0.05, -0.05), loose);
    EXPECT_NEAR(fl.signed_distance_mm, offset, loose.step_tolerance_mm) << "at " << uv.transpose();
    EXPECT_LT((fl.point - d.p).norm(), loose.step_tolerance_mm) << "at " << uv.transpose();
  }
}

INSTANTIATE_TEST_SUITE_P(Offsets, FootPoints, ::testing::Values(-2.0, -0.01, 0.0, 0.01, 0.5, 3.0));

TEST(FootPoints, BeyondTheDomainClampToTheEdge) {
  const BSplineSurface s = wavy();
  // Beyond u = 1 (x > 150): the foot point is on the edge u = 1, the distance is to that edge.
  const Eigen::Vector3d edge = surface_point(s, 1.0, 0.5);
  const Eigen::Vector3d q = edge + Eigen::Vector3d(20, 0, 0);
  const FootPoint fp = project_point(s, q, Eigen::Vector2d(0.9, 0.5));
  EXPECT_DOUBLE_EQ(fp.uv.x(), 1.0);
  EXPECT_NEAR(std::abs(fp.signed_distance_mm), (q - fp.point).norm(), 1e-12);
  EXPECT_LT(std::abs(fp.signed_distance_mm), 20.0 + 1e-9);
}

TEST(FootPoints, ParallelProjectionEqualsOneByOne) {
  const BSplineSurface s = wavy();
  test::Rng rng(8);
  std::vector<Eigen::Vector3d> q;
  std::vector<Eigen::Vector2d> uv;
  for (int k = 0; k < 5000; ++k) {
    q.emplace_back(rng.uniform(0, 150), rng.uniform(0, 100), rng.uniform(20, 40));
    uv.emplace_back(q.back().x() / 150, q.back().y() / 100);
  }
  std::vector<Eigen::Vector2d> uv2 = uv;
  std::vector<double> d;
  project_points(s, q, uv2, d, {}, 3);
  for (std::size_t k = 0; k < q.size(); k += 97) {
    const FootPoint fp = project_point(s, q[k], uv[k]);
    EXPECT_EQ(fp.uv, uv2[k]);
    EXPECT_EQ(fp.signed_distance_mm, d[k]);
  }
}

}  // namespace
}  // namespace photomill::fitsurf
