// One case per densify option (issue 22): each changes the dense cloud the way it says, on a
// 16 x 12 mm patch of the demo seen by four photos with their true camera and poses.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include <gtest/gtest.h>

#include "densify/test_demo.hpp"
#include "formats/point_cloud.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::densify {
namespace {

namespace fs = std::filesystem;
using photomill::test::read_file;
using photomill::test::run_tool;
using photomill::test::TempDir;

using test::kDemo;

// The job's files, made once: poses of four photos, the true camera, and seeds: the demo's true
// surface samples over x in [-50, -34], y in [-44, -32] (so that the default box is that patch's).
class Files {
public:
  Files() {
    test::write_demo_poses(dir_.path() / "poses.csv", {"part_00.jpg", "part_01.jpg", "part_10.jpg", "part_11.jpg"});
    fs::copy_file(kDemo / "camera.yaml", dir_.path() / "camera.yaml");
    std::ifstream ply(kDemo / "surface.ply", std::ios::binary);
    const PointCloud surface = read_ply(ply, "surface.ply");
    std::ofstream xyz(dir_.path() / "seeds.xyz");
    xyz.precision(17);
    for (const auto& p : surface.points_mm) {
      if (p.x() >= -50 && p.x() <= -34 && p.y() >= -44 && p.y() <= -32) xyz << p.x() << " " << p.y() << " " << p.z() << "\n";
    }
  }
  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }

private:
  TempDir dir_;
};

const Files& files() {
  static const Files f;
  return f;
}

// densify's output with `options` added to the job's command line (the run must succeed).
PointCloud run(const std::vector<std::string>& options, const std::string& name) {
  const Files& f = files();
  std::vector<std::string> a = {f.path("seeds.xyz"), "--camera", f.path("camera.yaml"), "--poses", f.path("poses.csv"),
                                "--image-dir", kDemo.string(), "--observations", (kDemo / "observations.csv").string(),
                                "-q", "--output", f.path(name + ".ply")};
  a.insert(a.end(), options.begin(), options.end());
  const auto r = run_tool("densify", a);
  EXPECT_EQ(r.exit_code, 0) << name << ": " << r.err;
  std::ifstream in(f.path(name + ".ply"), std::ios::binary);
  return read_ply(in, name);
}

const PointCloud& baseline() {
  static const PointCloud c = run({}, "baseline");
  return c;
}

double min_of(const PointCloud& c, const char* p) {
  const auto& v = c.find(p)->values;
  return *std::min_element(v.begin(), v.end());
}
double max_of(const PointCloud& c, const char* p) {
  const auto& v = c.find(p)->values;
  return *std::max_element(v.begin(), v.end());
}

TEST(DensifyOptions, BaselineHasPoints) {
  EXPECT_GT(baseline().points_mm.size(), 500u);
  EXPECT_EQ(max_of(baseline(), "views"), 4);  // every photo
}

TEST(DensifyOptions, SpacingPx) {
  const auto c = run({"--spacing-px", "4"}, "spacing");
  EXPECT_LT(c.points_mm.size(), baseline().points_mm.size() / 2);
}

TEST(DensifyOptions, MaxViewsAndMinViews) {
  EXPECT_LE(max_of(run({"--max-views", "2"}, "maxviews"), "views"), 3);
  EXPECT_GE(min_of(run({"--min-views", "4"}, "minviews"), "views"), 4);
}

TEST(DensifyOptions, AngleRangeDecidesTheNeighbours) {
  // part_00's neighbours lie 25-60 degrees away at the scene's centre: a range below them leaves
  // no reference with enough neighbours.
  const Files& f = files();
  const auto r = run_tool("densify", {f.path("seeds.xyz"), "--camera", f.path("camera.yaml"), "--poses", f.path("poses.csv"),
                                      "--image-dir", kDemo.string(), "--min-angle-deg", "1", "--max-angle-deg", "5", "-o",
                                      f.path("angle.ply")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no patch was accepted"), std::string::npos) << r.err;
  EXPECT_LT(run({"--max-angle-deg", "40"}, "maxangle").points_mm.size(), baseline().points_mm.size());
  EXPECT_NE(run({"--min-angle-deg", "25"}, "minangle").points_mm, baseline().points_mm);
}

TEST(DensifyOptions, BoxAndBoxMargin) {
  const auto c = run({"--box", "-48,-42,-5,-38,-34,60"}, "box");
  ASSERT_FALSE(c.points_mm.empty());
  EXPECT_LT(c.points_mm.size(), baseline().points_mm.size());
  for (const auto& p : c.points_mm) {
    EXPECT_TRUE(p.x() >= -48 && p.x() <= -38 && p.y() >= -42 && p.y() <= -34) << p.transpose();
  }
  EXPECT_LT(run({"--box-margin", "0"}, "boxmargin").points_mm.size(), baseline().points_mm.size());
}

TEST(DensifyOptions, MinCorrelation) {
  EXPECT_GE(min_of(run({"--min-correlation", "0.99"}, "corr"), "correlation"), 0.99);
  EXPECT_LT(min_of(baseline(), "correlation"), 0.99);
}

TEST(DensifyOptions, MaxReprojectionPx) {
  // The baseline's points reproject within a few tenths of a pixel; a limit below its largest
  // refuses the rest.
  const double largest = max_of(baseline(), "reprojection_px");
  ASSERT_GT(largest, 0.02);
  const auto c = run({"--max-reprojection-px", "0.02"}, "reproj");
  ASSERT_FALSE(c.points_mm.empty());
  EXPECT_LE(max_of(c, "reprojection_px"), 0.02);
  EXPECT_LT(c.points_mm.size(), baseline().points_mm.size());
}

TEST(DensifyOptions, WindowShapeAndModel) {
  for (const auto& [opt, value] : std::vector<std::pair<std::string, std::string>>{
           {"--half-window-px", "6"}, {"--window-stride-px", "1"}, {"--planar", ""}, {"--max-obliquity-deg", "45"},
           {"--converged-px", "0.1"}, {"--centre-half-window-px", "6"}, {"--min-centre-correlation", "0.95"}, {"--max-iterations", "8"}, {"--max-shift-px", "0.2"}, {"--max-attempts", "1"},
           {"--tile-cells", "8"}}) {
    std::vector<std::string> o = {opt};
    if (!value.empty()) o.push_back(value);
    EXPECT_NE(run(o, opt.substr(2)).points_mm, baseline().points_mm) << opt;
  }
  // Fewer iterations (seeds start facing the camera, 30-55 degrees off the surface, and take 6-10)
  // or a steeper obliquity limit only refuse more.
  EXPECT_LT(run({"--max-iterations", "8"}, "iter").points_mm.size(), baseline().points_mm.size());
  EXPECT_LT(run({"--max-obliquity-deg", "45"}, "oblique").points_mm.size(), baseline().points_mm.size());
}

TEST(DensifyOptions, MaxBendDegAndTheSmallerWindow) {
  // The patch is curved (the demo's blend): a bend limit of 4 degrees refuses windows the default
  // accepts; 180 turns the check off and accepts at least as many.
  const auto tight = run({"--max-bend-deg", "4", "--bend-check-half-window-px", "0"}, "bend1");
  EXPECT_LT(tight.points_mm.size(), baseline().points_mm.size());
  EXPECT_GE(run({"--max-bend-deg", "180"}, "bend180").points_mm.size(), baseline().points_mm.size());
  // The smaller window keeps the points of a smooth surface the limit refuses (its bend shrinks
  // with the window); with a ratio of 0 it keeps none of them.
  const auto small = run({"--max-bend-deg", "4"}, "bend1small");
  std::cerr << "bend limit 4 degrees: " << tight.points_mm.size() << " points, " << small.points_mm.size()
            << " with the smaller window; " << baseline().points_mm.size() << " at the defaults\n";
  EXPECT_GT(small.points_mm.size(), tight.points_mm.size());
  EXPECT_EQ(run({"--max-bend-deg", "4", "--bend-shrink-ratio", "0"}, "bend1ratio0").points_mm, tight.points_mm);
}

TEST(DensifyOptions, FreeSpaceGapAndMinViolations) {
  // With no gap, a point of the convex blend lies in front of its neighbours as their views see
  // them (its tangent plane is above the surface next to it): the check removes points, and a
  // minimum of violations no point reaches removes none.
  const auto no_gap = run({"--free-space-gap", "0"}, "gap0");
  EXPECT_LT(no_gap.points_mm.size(), baseline().points_mm.size());
  EXPECT_GT(run({"--free-space-gap", "0", "--free-space-min-violations", "1000000"}, "gap0many").points_mm.size(),
            no_gap.points_mm.size());
  EXPECT_GE(run({"--free-space-min-violations", "0"}, "nocheck").points_mm.size(), baseline().points_mm.size());
}

TEST(DensifyOptions, MarkerMargin) {
  // Marker 17's quiet zone reaches into the patch (x -41.7..-31.7, y -20..-10 grown by half its
  // side): a wider margin masks more.
  const auto wide = run({"--marker-margin", "1.5", "--box", "-50,-44,-5,-34,-22,60"}, "margin");
  const auto dflt = run({"--box", "-50,-44,-5,-34,-22,60"}, "margin0");
  EXPECT_LT(wide.points_mm.size(), dflt.points_mm.size());
}

}  // namespace
}  // namespace photomill::densify
