// fitsurf's height uncertainty (uncertainty.hpp): small where the data are dense, growing into a
// gap, scaled by the points' sigma and residuals.
#include "fitsurf/uncertainty.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill::fitsurf {
namespace {

struct Cloud {
  std::vector<Eigen::Vector3d> p;
  std::vector<double> r, w, s;
};

// A plane z = 5 sampled every 1 mm over 0..40 x 0..40, no points within `hole` mm of (20, 20);
// residuals alternating +-0.01 mm, heights off the plane by the same.
Cloud plate(double hole, double sigma = 0) {
  Cloud c;
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 40; ++j) {
      if (std::hypot(i - 20.0, j - 20.0) < hole) continue;
      const double e = (i + j) % 2 == 0 ? 0.01 : -0.01;
      c.p.emplace_back(i, j, 5 + e);
      c.r.push_back(e);
      c.w.push_back(1);
      if (sigma > 0) c.s.push_back(sigma);
    }
  }
  return c;
}

UncertaintyGrid grid_of(const Cloud& c, UncertaintySummary* sum = nullptr) {
  UncertaintyOptions o;
  o.resolution_mm = 2;
  return surface_uncertainty(c.p, c.r, c.w, c.s, o, sum);
}

TEST(SurfaceUncertainty, SmallWhereDenseAndGrowingIntoAGap) {
  UncertaintySummary sum;
  const UncertaintyGrid g = grid_of(plate(8), &sum);
  EXPECT_EQ(g.nx, 41u);
  EXPECT_EQ(g.ny, 41u);
  EXPECT_NEAR(sum.spacing_mm, 1, 1e-9);
  const double dense = g.sample(5, 5);
  EXPECT_GT(dense, 0);
  EXPECT_LT(dense, 0.01);  // the standard error of a mean of the ~13 points within 2 mm
  // From the hole's rim to its centre sigma grows, to several times the dense value.
  double last = g.sample(20 + 8, 20);
  for (double x = 27; x >= 20; x -= 1) {
    const double s = g.sample(x, 20);
    EXPECT_GE(s, last - 1e-12) << x;
    last = s;
  }
  EXPECT_GT(g.sample(20, 20), 10 * dense);
  EXPECT_NEAR(sum.max_mm, g.sample(20, 20), 1e-12);
}

TEST(SurfaceUncertainty, ScalesWithThePointsSigmaAndLeavesOutliersOut) {
  const UncertaintyGrid small = grid_of(plate(0));
  const UncertaintyGrid noisy = grid_of(plate(0, 0.1));  // sigma 0.1 mm outweighs the 0.01 mm residuals
  // At a point, with the 13 points within the resolution (2 mm): 0.1 / sqrt(13).
  EXPECT_NEAR(noisy.sample(10, 10), 0.1 / std::sqrt(13.0), 1e-9);
  EXPECT_LT(small.sample(10, 10), 0.1 * noisy.sample(10, 10) * 2);
  // An outlier (weight 0) does not count: neither its residual nor its place.
  Cloud c = plate(0);
  c.r[0] = 50;
  c.w[0] = 0;
  EXPECT_EQ(grid_of(c).sample(10, 10), small.sample(10, 10));
}

TEST(SurfaceUncertainty, RefusesTooFewPointsAndBadOptions) {
  Cloud c = plate(0);
  UncertaintyOptions o;
  o.cell_mm = 0;
  EXPECT_THROW(surface_uncertainty(c.p, c.r, c.w, c.s, o), UsageError);
  o = {};
  o.cell_mm = 1e-4;  // 400 million nodes
  EXPECT_THROW(surface_uncertainty(c.p, c.r, c.w, c.s, o), UsageError);
  c.w.assign(c.w.size(), 0);
  EXPECT_THROW(surface_uncertainty(c.p, c.r, c.w, c.s, {}), GeometryError);
}

}  // namespace
}  // namespace photomill::fitsurf
