// The cutting simulation (cutsim.hpp): material left and gouges against a plane whose answers are
// known, rapids and plunges into material counted, the reach of a ball in a groove narrower than
// it, and a whole chain (rough, then toolpath's finishing) on a dome.
#include "toolpath/cutsim.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "toolpath/roughing.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/toolpath.hpp"

namespace photomill::toolpath {
namespace {

// A plane z = 10 over 40 x 40 mm.
BSplineSurface plane() { return test::interpolate_height_field([](double, double) { return 10.0; }, -20, 20, -20, 20, 5, 5); }

const StockBox kStock{{-20, -20, 0}, {20, 20, 12}};

ClMove rapid(double x, double y, double z) { return {ClMove::Kind::Rapid, {x, y, z}, std::nullopt, 0}; }
ClMove feed(double x, double y, double z) { return {ClMove::Kind::Feed, {x, y, z}, std::nullopt, 500}; }

// A raster of a flat 6 mm end mill at height z over the stock, 2 mm apart, entered from outside.
ClData raster(double z) {
  ClData cl;
  cl.tool_diameter_mm = 6;
  cl.moves.push_back(rapid(-25, -22, 20));
  cl.moves.push_back(rapid(-25, -22, z));
  for (int k = 0; k <= 22; ++k) {
    const double y = -22 + 2 * k;
    cl.moves.push_back(feed(k % 2 ? 25 : -25, y, z));
    cl.moves.push_back(feed(k % 2 ? 25 : -25, y + 2, z));
  }
  cl.moves.push_back(rapid(25, 24, 20));
  return cl;
}

CutsimOptions options() {
  CutsimOptions o;
  o.stock = kStock;
  o.cell_mm = 0.25;
  return o;
}

TEST(Cutsim, ARasterAtTheSurfaceLeavesNothingAndOneBelowItGougesByTheDifference) {
  const CutsimResult on = simulate_cutting(plane(), {{"on", raster(10), {3, 0}}}, options());
  EXPECT_GT(on.nodes, 20000u);
  EXPECT_NEAR(on.max_left_mm, 0, 1e-9);
  EXPECT_NEAR(on.max_gouge_mm, 0, 1e-9);
  EXPECT_EQ(on.programs[0].rapids_into_material, 0u);
  EXPECT_EQ(on.programs[0].plunges, 0u) << on.programs[0].first_fault;
  const CutsimResult below = simulate_cutting(plane(), {{"below", raster(9.5), {3, 0}}}, options());
  EXPECT_NEAR(below.max_gouge_mm, 0.5, 1e-9);
  // 0.3 mm above it: everything left is 0.3 mm, and an allowance of 0.3 takes it away.
  const CutsimResult above = simulate_cutting(plane(), {{"above", raster(10.3), {3, 0}}}, options());
  EXPECT_NEAR(above.max_left_mm, 0.3, 1e-9);
  EXPECT_NEAR(above.p95_left_mm, 0.3, 1e-9);
  CutsimOptions with_allowance = options();
  with_allowance.allowance_mm = 0.3;
  EXPECT_NEAR(simulate_cutting(plane(), {{"above", raster(10.3), {3, 0}}}, with_allowance).max_left_mm, 0, 1e-9);
  // Programs run in turn: the second cuts what the first left.
  const CutsimResult both = simulate_cutting(plane(), {{"above", raster(10.3), {3, 0}}, {"on", raster(10), {3, 0}}}, options());
  EXPECT_NEAR(both.max_left_mm, 0, 1e-9);
  EXPECT_EQ(both.programs.size(), 2u);
  EXPECT_GT(both.programs[1].feed_length_mm, 1000);
}

TEST(Cutsim, RapidsAndPlungesIntoMaterialAreCountedAndNamed) {
  ClData cl = raster(10);
  // A rapid straight down into the stock in its middle, and a feed straight down.
  cl.moves.insert(cl.moves.begin() + 1, {rapid(0, 0, 20), rapid(0, 0, 11), rapid(0, 0, 20), rapid(5, 5, 20), feed(5, 5, 10.5),
                                         rapid(5, 5, 20), rapid(-25, -22, 20)});
  const CutsimResult r = simulate_cutting(plane(), {{"crash", cl, {3, 0}}}, options());
  EXPECT_EQ(r.programs[0].rapids_into_material, 1u);
  EXPECT_EQ(r.programs[0].plunges, 1u);
  EXPECT_NE(r.programs[0].first_fault.find("rapid move 3 to (0.000, 0.000, 11.000) cuts 1.000 mm"), std::string::npos)
      << r.programs[0].first_fault;
  // A shallow descent is no plunge, a steep one is.
  CutsimOptions steep = options();
  steep.plunge_angle_deg = 89;
  EXPECT_EQ(simulate_cutting(plane(), {{"crash", cl, {3, 0}}}, steep).programs[0].plunges, 1u) << "vertical stays a plunge";
}

TEST(Cutsim, ABallCannotReachTheBottomOfAGrooveNarrowerThanIt) {
  // groove_surface: a groove whose bottom's concave radius (~0.5 mm) is far below a 3 mm ball's.
  const BSplineSurface groove = test::groove_surface();
  ToolpathOptions t;
  t.tool_radius_mm = 3;
  t.scallop_mm = 0.05;
  t.chord_tol_mm = 0.02;
  const ToolpathResult fin = generate_toolpath(groove, t);
  CutsimOptions o;
  o.cell_mm = 0.25;
  const CutsimResult r = simulate_cutting(groove, {{"finish", fin.cl, {3, 3}}}, o);
  EXPECT_GT(r.unreachable_nodes, 100u);
  EXPECT_GT(r.max_left_mm, 0.5) << "the groove's bottom is left";
  // Where the ball reaches, what is left is the scallop (p95); the largest is at the surface's
  // edge inside the groove, where toolpath's lifting (at its CL points) stays above the ball's
  // reach computed from the surface alone.
  EXPECT_LT(r.p95_left_reachable_mm, 0.05);
  EXPECT_LT(r.max_left_reachable_mm, r.max_left_mm);
  EXPECT_LT(r.max_gouge_mm, 0.002);
}

TEST(Cutsim, RoughThenFinishLeavesTheScallopAndNoGouge) {
  const BSplineSurface dome =
      test::interpolate_height_field([](double x, double y) { return 8 * std::exp(-(x * x + y * y) / 50.0); }, -20, 20, -20, 20, 21, 21);
  RoughingOptions ro;
  ro.cell_mm = 0.25;
  const RoughingResult rough = generate_roughing(dome, ro);
  ToolpathOptions t;
  t.tool_radius_mm = 3;
  t.scallop_mm = 0.02;
  t.chord_tol_mm = 0.01;
  const ToolpathResult fin = generate_toolpath(dome, t);
  CutsimOptions o;
  o.stock = rough.stats.stock;
  o.cell_mm = 0.2;
  const CutsimResult r = simulate_cutting(dome, {{"rough", rough.cl, {3, 0}}, {"finish", fin.cl, {3, 3}}}, o);
  EXPECT_EQ(r.programs[0].rapids_into_material + r.programs[0].plunges, 0u) << r.programs[0].first_fault;
  EXPECT_EQ(r.programs[1].rapids_into_material, 0u) << r.programs[1].first_fault;
  // The finishing leaves at most its scallop (measured at the nodes, so a little under it).
  EXPECT_LT(r.max_left_reachable_mm, t.scallop_mm + 1e-3);
  EXPECT_LT(r.max_gouge_mm, 1e-3);
  const auto png = render_cutsim_png(r, 0);
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png[1], 'P');
}

TEST(Cutsim, BadOptionsAndAProgramWithoutACutterAreUsageErrors) {
  CutsimOptions o = options();
  o.cell_mm = 0;
  EXPECT_THROW(simulate_cutting(plane(), {{"a", raster(10), {3, 0}}}, o), UsageError);
  o = options();
  o.plunge_angle_deg = 0;
  EXPECT_THROW(simulate_cutting(plane(), {{"a", raster(10), {3, 0}}}, o), UsageError);
  EXPECT_THROW(simulate_cutting(plane(), {{"csv", raster(10), {0, 0}}}, options()), UsageError);
  EXPECT_THROW(simulate_cutting(plane(), {}, options()), UsageError);
  o = options();
  o.stock = StockBox{{100, 100, 0}, {120, 120, 5}};
  EXPECT_THROW(simulate_cutting(plane(), {{"a", raster(10), {3, 0}}}, o), GeometryError);
}

}  // namespace
}  // namespace photomill::toolpath
