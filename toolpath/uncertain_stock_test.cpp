// Uncertainty-aware stock (uncertain_stock.hpp): the path over a region of large sigma is k sigma
// higher, and unchanged elsewhere.
#include "toolpath/uncertain_stock.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/toolpath.hpp"

namespace photomill::toolpath {
namespace {

// sigma 0.1 mm where x >= 30, 0 elsewhere, on a 1 mm grid over -5..65 x -5..45.
UncertaintyGrid half_uncertain() {
  UncertaintyGrid g;
  g.x0_mm = -5, g.y0_mm = -5, g.step_mm = 1, g.nx = 71, g.ny = 51;
  for (std::size_t j = 0; j < g.ny; ++j) {
    for (std::size_t i = 0; i < g.nx; ++i) g.sigma_mm.push_back(g.x0_mm + static_cast<double>(i) >= 30 ? 0.1 : 0);
  }
  return g;
}

TEST(UncertainStock, ThePathIsKSigmaHigherWhereSigmaIsLargeAndUnchangedElsewhere) {
  const BSplineSurface plane = test::interpolate_height_field([](double, double) { return 10.0; }, 0, 60, 0, 40, 31, 21);
  UncertainStockStats st;
  const BSplineSurface raised = offset_by_uncertainty(plane, half_uncertain(), 2, 0.01, &st);
  EXPECT_DOUBLE_EQ(st.k, 2);
  EXPECT_DOUBLE_EQ(st.sigma_max_mm, 0.1);
  EXPECT_NEAR(st.max_mm, 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(st.area_mm2, 36.0 * 51);  // the nodes at x = 30..65
  ToolpathOptions o;
  o.scallop_mm = 0.05, o.chord_tol_mm = 0.02;
  const ToolpathResult before = generate_toolpath(plane, o), after = generate_toolpath(raised, o);
  std::size_t low = 0, high = 0;
  for (const ClMove& m : after.cl.moves) {
    if (m.kind != ClMove::Kind::Feed || m.tip_mm.z() > 10.5) continue;  // cutting moves only
    if (m.tip_mm.x() < 20) {
      EXPECT_NEAR(m.tip_mm.z(), 10, 1e-6) << m.tip_mm.transpose();
      ++low;
    }
    if (m.tip_mm.x() > 40) {
      EXPECT_NEAR(m.tip_mm.z(), 10.2, 1e-6) << m.tip_mm.transpose();
      ++high;
    }
  }
  EXPECT_GT(low, 20u);
  EXPECT_GT(high, 20u);
  for (const ClMove& m : before.cl.moves) {
    if (m.kind == ClMove::Kind::Feed && m.tip_mm.z() < 10.5) {
      EXPECT_NEAR(m.tip_mm.z(), 10, 1e-6);
    }
  }
}

TEST(UncertainStock, KZeroChangesNothingAndANegativeKIsRefused) {
  const BSplineSurface plane = test::interpolate_height_field([](double, double) { return 10.0; }, 0, 60, 0, 40, 31, 21);
  EXPECT_EQ(offset_by_uncertainty(plane, half_uncertain(), 0, 0.01), plane);
  EXPECT_THROW(offset_by_uncertainty(plane, half_uncertain(), -1, 0.01), UsageError);
  EXPECT_THROW(offset_by_uncertainty(plane, half_uncertain(), std::nan(""), 0.01), UsageError);
}

}  // namespace
}  // namespace photomill::toolpath
