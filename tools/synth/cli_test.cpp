// synth on the command line: the tool contract, option errors, and a small run whose truth files
// are read back with photomill's readers and checked against each other.
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "formats/camera.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"
#include "tools/synth/camera_model.hpp"
#include "tools/synth/scene.hpp"

namespace photomill::test {
namespace {

struct SynthCase {
  std::vector<std::string> args;
  int exit_code;
  std::string stdout_has;  // empty: stdout must be empty
  std::string stderr_has;
};

void PrintTo(const SynthCase& c, std::ostream* os) {
  *os << "synth";
  for (const auto& a : c.args) *os << " " << a;
}

class SynthCli : public ::testing::TestWithParam<SynthCase> {};

TEST_P(SynthCli, GoldenCase) {
  const SynthCase& c = GetParam();
  TempDir dir;
  std::vector<std::string> args = c.args;
  for (auto& a : args) {
    if (a == "OUT") a = (dir.path() / "out").string();
  }
  const ToolResult r = run_tool(tools_path("synth"), args);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  if (c.stdout_has.empty()) {
    EXPECT_EQ(r.out, "");
  } else {
    EXPECT_NE(r.out.find(c.stdout_has), std::string::npos) << r.out;
  }
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
}

INSTANTIATE_TEST_SUITE_P(
    Golden, SynthCli,
    ::testing::Values(SynthCase{{"--help"}, 0, "Example:", ""},
                      SynthCase{{"--version"}, 0, "synth (photomill) ", ""},
                      SynthCase{{"-o", "OUT", "--no-such-option"}, 2, "", "--no-such-option"},
                      SynthCase{{"--views", "2"}, 2, "", "--output-dir is required"},
                      SynthCase{{"-o", "OUT", "--shape", "cube"}, 2, "", "--shape"},
                      SynthCase{{"-o", "OUT", "--views", "many"}, 2, "", "--views"},
                      SynthCase{{"-o", "OUT", "--fx", "-3"}, 2, "", "--fx"},
                      SynthCase{{"-o", "OUT", "--jpeg-quality", "101"}, 2, "", "--jpeg-quality"},
                      SynthCase{{"-o", "OUT", "--dictionary", "DICT_9X9_1"}, 2, "", "--dictionary"},
                      SynthCase{{"-o", "OUT", "--k1", "-3"}, 2, "", "distortion cannot be inverted"},
                      SynthCase{{"-o", "OUT", "--edge-blend-mm", "80"}, 2, "", "edge blend"},
                      SynthCase{{"-o", "OUT", "--board-marker-mm", "40"}, 2, "", "marker size < square size"},
                      SynthCase{{"-o", "/dev/null/x", "--views", "0", "--calib-views", "0"}, 1, "",
                                "/dev/null/x: cannot create the output folder"}));

TEST(SynthRun, WritesConsistentTruthFiles) {
  TempDir dir;
  const auto out = dir.path() / "set";
  const ToolResult r = run_tool(tools_path("synth"), {"-o", out.string(), "--width", "320", "--height", "240", "--fx", "400",
                                          "--views", "3", "--calib-views", "2", "--noise-sigma", "2",
                                          "--surface-step-mm", "10", "--seed", "5", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "");
  for (const char* f : {"scene.txt", "board.txt", "camera.yaml", "control_points.csv", "part_points.csv",
                        "board_points.csv", "poses.csv", "board_poses.csv", "observations.csv",
                        "board_observations.csv", "surface.ply", "part_00.jpg", "part_02.jpg", "board_01.jpg"}) {
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  }
  auto open = [&](const char* name) { return std::ifstream(out / name, std::ios::binary); };
  auto cam_in = open("camera.yaml");
  const Camera cam = read_camera_yaml(cam_in, "camera.yaml");
  EXPECT_EQ(cam.fx(), 400);
  EXPECT_EQ(cam.cx(), 159.5);
  ASSERT_EQ(cam.distortion.size(), 5u);
  auto scene_in = open("scene.txt");
  const synth::PartScene scene = synth::read_scene(scene_in, "scene.txt");
  auto poses_in = open("poses.csv");
  const auto poses = read_poses(poses_in, "poses.csv");
  ASSERT_EQ(poses.size(), 3u);
  std::map<PointId, Eigen::Vector3d> points;
  for (const char* f : {"control_points.csv", "part_points.csv"}) {
    auto in = open(f);
    for (const ControlPoint& p : read_control_points(in, f)) points[p.point_id] = p.xyz_mm;
  }
  EXPECT_EQ(points.size(), scene.markers.size() * 4);
  // Every observation is the projection of its control point through the written camera and pose.
  auto obs_in = open("observations.csv");
  const auto observations = read_observations(obs_in, "observations.csv");
  ASSERT_GT(observations.size(), 40u);
  for (const Observation& o : observations) {
    const auto pose = std::find_if(poses.begin(), poses.end(), [&](const Pose& p) { return p.image == o.image; });
    ASSERT_NE(pose, poses.end());
    ASSERT_TRUE(points.count(o.point_id));
    const auto uv = synth::project(cam, *pose, points[o.point_id]);
    ASSERT_TRUE(uv);
    EXPECT_NEAR(uv->x(), o.u_px, 1e-9);
    EXPECT_NEAR(uv->y(), o.v_px, 1e-9);
  }
  // The surface sample lies on the described surface.
  auto ply_in = open("surface.ply");
  const PointCloud cloud = read_ply(ply_in, "surface.ply");
  ASSERT_EQ(cloud.points_mm.size(), 16u * 11u);
  for (const auto& p : cloud.points_mm) EXPECT_EQ(p.z(), scene.surface.height_mm(p.x(), p.y()));
  ASSERT_NE(cloud.find("nz"), nullptr);
  // The command that made the set is recorded.
  EXPECT_NE(read_file(out / "scene.txt").find("# made by: synth -o"), std::string::npos);
}

// The same seed gives the same files when the runs also share their run id (the stamp in every
// photomill file, formats/run.hpp, set through PHOTOMILL_RUN_ID, which the children inherit).
TEST(SynthRun, SameSeedSameFilesDifferentSeedDifferentImages) {
  TempDir dir;
  ::setenv("PHOTOMILL_RUN_ID", "synth-test", 1);
  auto run = [&](const std::string& name, const std::string& seed) {
    const ToolResult r = run_tool(tools_path("synth"), {"-o", (dir.path() / name).string(), "--width", "160", "--height", "120",
                                            "--fx", "200", "--views", "1", "--calib-views", "1", "--noise-sigma",
                                            "2", "--surface-step-mm", "25", "--seed", seed, "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
  };
  run("a", "3");
  run("b", "3");
  run("c", "4");
  for (const char* f : {"part_00.jpg", "board_00.jpg", "observations.csv", "poses.csv"}) {
    EXPECT_EQ(read_file(dir.path() / "a" / f), read_file(dir.path() / "b" / f)) << f;
  }
  EXPECT_NE(read_file(dir.path() / "a" / "part_00.jpg"), read_file(dir.path() / "c" / "part_00.jpg"));
  ::unsetenv("PHOTOMILL_RUN_ID");
}

}  // namespace
}  // namespace photomill::test
