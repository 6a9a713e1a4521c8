// The whole path on test surfaces with known geometry (150 x 100 mm, R = 3, h = 0.01, e = 0.005
// by default), verified by the z-map simulation and by independent dense chord checks: the
// issue's "done when" cases.
#include "toolpath/toolpath.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "formats/bspline.hpp"
#include "formats/error.hpp"
#include "toolpath/forward_step.hpp"
#include "toolpath/test_surfaces.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {
namespace {

// The maximum chord error of every pass segment, sampled 32 times per segment (independently of
// the forward step's own check).
double dense_max_chord_error(const BSplineSurface& s, const ToolpathResult& r) {
  double worst = 0;
  for (const PassSegment& seg : r.segments) {
    const PassDirection dir = seg.direction;
    const double w = dir == PassDirection::U ? seg.points.front().uv.y() : seg.points.front().uv.x();
    const IsoCurve curve(s, dir, w);
    for (std::size_t k = 1; k < seg.points.size(); ++k) {
      const double t0 = dir == PassDirection::U ? seg.points[k - 1].uv.x() : seg.points[k - 1].uv.y();
      const double t1 = dir == PassDirection::U ? seg.points[k].uv.x() : seg.points[k].uv.y();
      for (int i = 1; i < 32; ++i) {
        worst = std::max(worst, distance_to_segment(curve.point(t0 + (t1 - t0) * i / 32.0), seg.points[k - 1].cc,
                                                    seg.points[k].cc));
      }
    }
  }
  return worst;
}

// Rapids only straight up, straight down or level at the safe plane; feeds positive; the
// program starts and ends at the safe plane.
void expect_sane_moves(const ToolpathResult& r) {
  const auto& m = r.cl.moves;
  ASSERT_GE(m.size(), 4u);
  const double safe = r.stats.safe_z_mm;
  EXPECT_EQ(m.front().kind, ClMove::Kind::Rapid);
  EXPECT_EQ(m.front().tip_mm.z(), safe);
  EXPECT_EQ(m.back().kind, ClMove::Kind::Rapid);
  EXPECT_EQ(m.back().tip_mm.z(), safe);
  for (std::size_t k = 1; k < m.size(); ++k) {
    const Eigen::Vector3d d = m[k].tip_mm - m[k - 1].tip_mm;
    if (m[k].kind == ClMove::Kind::Rapid) {
      const bool vertical = d.head<2>().norm() == 0;
      const bool level_at_safe = d.z() == 0 && m[k].tip_mm.z() == safe;
      EXPECT_TRUE(vertical || level_at_safe) << "rapid " << k;
    } else {
      EXPECT_GT(m[k].feed_mm_per_min, 0);
    }
    EXPECT_TRUE(m[k].tip_mm.allFinite());
  }
}

struct DoneWhenCase {
  const char* surface;
  PassDirection direction;
  Pattern pattern;
};

void PrintTo(const DoneWhenCase& c, std::ostream* os) { *os << c.surface; }

class DoneWhen : public ::testing::TestWithParam<DoneWhenCase> {};

TEST_P(DoneWhen, ScallopChordAndGougeWithinTolerances) {
  const DoneWhenCase& c = GetParam();
  const BSplineSurface s = test::named_surface(c.surface);
  ToolpathOptions o;
  o.direction = c.direction;
  o.pattern = c.pattern;
  const ToolpathResult r = generate_toolpath(s, o);
  expect_sane_moves(r);
  EXPECT_EQ(r.stats.gouge_points, 0u) << "no concave radius below R on this surface";
  EXPECT_LE(r.stats.max_chord_error_mm, o.chord_tol_mm);
  EXPECT_LE(dense_max_chord_error(s, r), o.chord_tol_mm);
  if (c.pattern == Pattern::ZigZag) {
    EXPECT_EQ(r.stats.retracts, 0u);
  } else {
    EXPECT_EQ(r.stats.retracts, r.stats.passes - 1);
  }

  ZmapOptions z;
  z.cell_mm = 0.1;
  const ZmapResult v = simulate_zmap(s, r.cl, z);
  EXPECT_EQ(v.unmachined, 0u);
  EXPECT_LE(v.max_scallop_mm, o.scallop_mm);
  EXPECT_LE(v.max_gouge_mm, 0.001);
  // The side step is not wastefully small: the cusps come close to h.
  EXPECT_GT(v.max_scallop_mm, 0.6 * o.scallop_mm);
  RecordProperty("max_scallop_mm", std::to_string(v.max_scallop_mm));
  RecordProperty("max_gouge_mm", std::to_string(v.max_gouge_mm));
}

INSTANTIATE_TEST_SUITE_P(Surfaces, DoneWhen,
                         ::testing::Values(DoneWhenCase{"bumps", PassDirection::U, Pattern::ZigZag},
                                           DoneWhenCase{"wave", PassDirection::V, Pattern::OneWay}),
                         [](const auto& info) { return std::string(info.param.surface); });

// Across a cylinder the cusp is known: with the curvature-corrected side step it comes to h
// (a flat-surface side step would exceed it on the ridge and waste passes in the trough).
struct CylinderCase {
  const char* name;
  double radius_mm;
  bool convex;
  bool rational = false;
};

class SideStepOnCylinders : public ::testing::TestWithParam<CylinderCase> {};

TEST_P(SideStepOnCylinders, CuspsReachButDoNotExceedH) {
  const CylinderCase& c = GetParam();
  const BSplineSurface s = c.rational ? test::rational_ridge_surface(c.radius_mm) : test::cylinder_surface(c.radius_mm, c.convex);
  ToolpathOptions o;
  const ToolpathResult r = generate_toolpath(s, o);
  ZmapOptions z;
  z.cell_mm = 0.05;
  z.window_min = Eigen::Vector2d(10, -20);  // away from the ends of the passes
  z.window_max = Eigen::Vector2d(50, 30);
  const ZmapResult v = simulate_zmap(s, r.cl, z);
  EXPECT_EQ(v.unmachined, 0u);
  EXPECT_LE(v.max_scallop_mm, o.scallop_mm);
  EXPECT_GT(v.max_scallop_mm, 0.9 * o.scallop_mm);
  EXPECT_LE(v.max_gouge_mm, 0.001);
}

INSTANTIATE_TEST_SUITE_P(Strips, SideStepOnCylinders,
                         ::testing::Values(CylinderCase{"plane", 0, true}, CylinderCase{"ridge_r20", 20, true},
                                           CylinderCase{"trough_r20", 20, false},
                                           CylinderCase{"rational_ridge_r20", 20, true, true}),
                         [](const auto& info) { return std::string(info.param.name); });

class SlantedEdges : public ::testing::TestWithParam<PassDirection> {};

// The tent's edges cross the passes at a slant (and one edge is collapsed to a point): edge
// passes keep the slivers between pass ends within h.
TEST_P(SlantedEdges, EdgePassesKeepTheScallopWithinH) {
  const BSplineSurface s = test::tent_surface();
  ToolpathOptions o;
  o.direction = GetParam();
  const ToolpathResult r = generate_toolpath(s, o);
  expect_sane_moves(r);
  EXPECT_EQ(r.stats.edge_passes, GetParam() == PassDirection::U ? 1u : 2u) << "the apex end needs none";
  ZmapOptions z;
  z.cell_mm = 0.1;
  const ZmapResult v = simulate_zmap(s, r.cl, z);
  EXPECT_EQ(v.unmachined, 0u);
  EXPECT_LE(v.max_scallop_mm, o.scallop_mm);
  EXPECT_LE(v.max_gouge_mm, 0.001);
  EXPECT_LE(dense_max_chord_error(s, r), o.chord_tol_mm);
}

INSTANTIATE_TEST_SUITE_P(Tent, SlantedEdges, ::testing::Values(PassDirection::U, PassDirection::V),
                         [](const auto& info) { return std::string(info.param == PassDirection::U ? "u" : "v"); });

TEST(Gouges, GrooveTighterThanTheBallIsFlaggedAndMadeSafe) {
  const BSplineSurface s = test::groove_surface();
  ToolpathOptions o;
  const ToolpathResult lifted = generate_toolpath(s, o);
  ASSERT_FALSE(lifted.gouges.empty());
  EXPECT_GT(lifted.stats.gouge_points, 0u);
  for (const GougeRun& g : lifted.gouges) {
    EXPECT_TRUE(g.lifted);
    // Every run lies on the groove x = 75 + 0.3 (y - 50) (within the ball's reach).
    EXPECT_NEAR(g.first_cc.x(), 75 + 0.3 * (g.first_cc.y() - 50), 4.0);
  }
  const auto tight = std::count_if(lifted.gouges.begin(), lifted.gouges.end(),
                                   [&](const GougeRun& g) { return g.min_concave_radius_mm < o.tool_radius_mm; });
  EXPECT_GT(tight, 0) << "the groove's concave radius is below R";
  ZmapOptions z;
  z.cell_mm = 0.1;
  z.window_min = Eigen::Vector2d(50, 0);
  z.window_max = Eigen::Vector2d(100, 100);
  const ZmapResult safe = simulate_zmap(s, lifted.cl, z);
  EXPECT_LE(safe.max_gouge_mm, 0.001);
  EXPECT_EQ(safe.unmachined, 0u);

  // Report only: the same places, and the z-map shows the gouge is real.
  o.lift = false;
  const ToolpathResult reported = generate_toolpath(s, o);
  EXPECT_EQ(reported.gouges.size() > 0, true);
  for (const GougeRun& g : reported.gouges) EXPECT_FALSE(g.lifted);
  const ZmapResult cut = simulate_zmap(s, reported.cl, z);
  EXPECT_GT(cut.max_gouge_mm, 0.05);
  // On the groove's flanks, within the ball's reach of its axis (R + the groove's half width).
  EXPECT_NEAR(cut.max_gouge_at.x(), 75 + 0.3 * (cut.max_gouge_at.y() - 50), 4.5);
}

TEST(Boundary, PassesStayInThePolygonAndCoverIt) {
  BSplineSurface s = test::bumps_surface();
  // A pentagon with slanted edges, in (u, v).
  s.boundary_uv = {{0.15, 0.2}, {0.8, 0.1}, {0.9, 0.6}, {0.5, 0.9}, {0.1, 0.7}};
  ToolpathOptions o;
  const ToolpathResult r = generate_toolpath(s, o);
  expect_sane_moves(r);
  // Every CC point lies in the polygon or at most half a side step beyond a slanted edge.
  for (const PassSegment& seg : r.segments) {
    for (const CutterLocation& p : seg.points) {
      EXPECT_GE(p.uv.x(), 0.1 - 1e-9);
      EXPECT_LE(p.uv.x(), 0.9 + 1e-9);
      EXPECT_GE(p.uv.y(), 0.1 - 1e-9);
      EXPECT_LE(p.uv.y(), 0.9 + 1e-9);
    }
  }
  ZmapOptions z;
  z.cell_mm = 0.1;
  const ZmapResult v = simulate_zmap(s, r.cl, z);  // only nodes inside the polygon count
  EXPECT_EQ(v.unmachined, 0u);
  EXPECT_LE(v.max_scallop_mm, o.scallop_mm);
  EXPECT_LE(v.max_gouge_mm, 0.001);
}

TEST(Stock, AllowanceIsLeftEverywhere) {
  // On the tilted plane the z-map's normal distances are exact.
  const BSplineSurface s = test::cylinder_surface(0, true);
  ToolpathOptions o;
  o.stock_mm = 0.5;
  o.scallop_mm = 0.02;
  o.chord_tol_mm = 0.005;
  const ToolpathResult r = generate_toolpath(s, o);
  ZmapOptions z;
  z.cell_mm = 0.05;
  z.stock_mm = o.stock_mm;
  z.window_min = Eigen::Vector2d(5, 0);
  z.window_max = Eigen::Vector2d(55, 30);
  const ZmapResult v = simulate_zmap(s, r.cl, z);
  EXPECT_LE(v.max_gouge_mm, 0.001) << "nothing cut closer than the allowance";
  EXPECT_LE(v.max_scallop_mm, o.scallop_mm);
  EXPECT_GT(v.max_scallop_mm, 0.5 * o.scallop_mm);
}

TEST(Degenerate, SurfacesWithoutANormalAreGeometryErrors) {
  BSplineSurface point = test::cylinder_surface(0, true);
  for (auto& p : point.poles_mm) p = Eigen::Vector3d(1, 2, 3);
  EXPECT_THROW(generate_toolpath(point, {}), GeometryError);
  BSplineSurface line = test::cylinder_surface(0, true);
  for (auto& p : line.poles_mm) p.y() = 0, p.z() = 0;  // every point on the x axis
  EXPECT_THROW(generate_toolpath(line, {}), GeometryError);
}

TEST(Options, OutOfRangeValuesAreUsageErrors) {
  const BSplineSurface s = test::cylinder_surface(0, true);
  const auto with = [](auto set) {
    ToolpathOptions o;
    set(o);
    return o;
  };
  EXPECT_THROW(generate_toolpath(s, with([](ToolpathOptions& o) { o.chord_tol_mm = o.scallop_mm; })), UsageError);
  EXPECT_THROW(generate_toolpath(s, with([](ToolpathOptions& o) { o.tool_radius_mm = 0; })), UsageError);
  EXPECT_THROW(generate_toolpath(s, with([](ToolpathOptions& o) { o.scallop_mm = std::nan(""); })), UsageError);
  EXPECT_THROW(generate_toolpath(s, with([](ToolpathOptions& o) { o.stock_mm = -1; })), UsageError);
  EXPECT_THROW(generate_toolpath(s, with([](ToolpathOptions& o) { o.safe_z_mm = 0.0; })), UsageError);
}

TEST(Structure, ZigZagAlternatesAndSafeZIsAboveEverything) {
  const BSplineSurface s = test::cylinder_surface(20, true);
  ToolpathOptions o;
  o.scallop_mm = 0.05;
  o.chord_tol_mm = 0.02;
  const ToolpathResult r = generate_toolpath(s, o);
  ASSERT_GE(r.segments.size(), 3u);
  for (std::size_t k = 0; k < r.segments.size(); ++k) {
    const auto& pts = r.segments[k].points;
    const double dx = pts.back().cc.x() - pts.front().cc.x();
    EXPECT_EQ(dx > 0, k % 2 == 0) << "segment " << k;
  }
  EXPECT_NEAR(r.stats.safe_z_mm, std::max(10.0 + 20.0, r.stats.safe_z_mm - o.retract_mm) + o.retract_mm, 0.01);
  std::size_t points = 0;
  for (const auto& seg : r.segments) points += seg.points.size();
  EXPECT_EQ(points, r.stats.cl_points);
  EXPECT_EQ(r.cl.moves.size(), r.stats.moves);
  EXPECT_EQ(r.cl.tool_diameter_mm, 6.0);
}

}  // namespace
}  // namespace photomill::toolpath

namespace photomill::toolpath {
namespace {

// A bicubic 7 x 4 net over 150 x 100 mm whose heights rise to a ridge at u = 0.5, with the given
// interior knots along u: three equal ones make a crease there (only C0, a convex edge).
BSplineSurface ridge_with_knots_u(const std::vector<double>& interior) {
  BSplineSurface s;
  s.degree_u = s.degree_v = 3;
  s.num_poles_u = 7;
  s.num_poles_v = 4;
  s.knots_u = {0, 0, 0, 0};
  s.knots_u.insert(s.knots_u.end(), interior.begin(), interior.end());
  s.knots_u.insert(s.knots_u.end(), {1, 1, 1, 1});
  s.knots_v = {0, 0, 0, 0, 1, 1, 1, 1};
  for (int i = 0; i < 7; ++i) {
    for (int j = 0; j < 4; ++j) {
      s.poles_mm.emplace_back(-75 + 25.0 * i, -50 + 100.0 * j / 3,
                              5 + 20 * std::sin(std::numbers::pi * i / 6) * std::sin(std::numbers::pi * j / 3));
    }
  }
  return s;
}

// Issue #25: a crease (knots 0.5 0.5 0.5), and nearly coincident knots (0.5, 0.5 + 1e-15,
// 0.5 + 2e-15), ran for hours: next to the crease the shortened step rounded to the same t again
// and again, and a golden-section search on a sub-curve a few ulp long asked for a bracket below
// rounding. Both are now the kink error, in under a second; the work limit makes the old code
// fail this test instead of hanging it.
TEST(Toolpath, CreaseIsAKinkErrorNotAnEndlessMarch) {
  for (const auto& interior : {std::vector<double>{0.5, 0.5, 0.5}, std::vector<double>{0.5, 0.5 + 1e-15, 0.5 + 2e-15}}) {
    ToolpathOptions o;
    o.scallop_mm = 0.05;
    o.chord_tol_mm = 0.02;
    o.max_cl_points = 200'000;  // the whole path is ~10 000
    try {
      generate_toolpath(ridge_with_knots_u(interior), o);
      ADD_FAILURE() << "a crease gave a path";
    } catch (const GeometryError& e) {
      EXPECT_NE(std::string(e.what()).find("kink"), std::string::npos) << e.what();
    }
  }
}

// The work limit: more CL points computed than --max-cl-points is an error naming the option.
TEST(Toolpath, WorkLimitStopsThePathNamingTheOption) {
  ToolpathOptions o;
  o.scallop_mm = 0.05;
  o.chord_tol_mm = 0.02;
  o.max_cl_points = 500;
  try {
    generate_toolpath(ridge_with_knots_u({0.25, 0.5, 0.75}), o);
    ADD_FAILURE() << "the limit did not stop the path";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("--max-cl-points"), std::string::npos) << e.what();
  }
  o.max_cl_points = 0;
  EXPECT_THROW(validate(o), UsageError);
}

TEST(Toolpath, AbsurdToolRadiusIsBadUsage) {
  ToolpathOptions o;
  o.tool_radius_mm = 1e9;
  EXPECT_THROW(validate(o), UsageError);
  o.tool_radius_mm = kMaxToolRadiusMm;
  EXPECT_NO_THROW(validate(o));
}

}  // namespace
}  // namespace photomill::toolpath
