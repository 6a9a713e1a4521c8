// calib and detect's board modes on a small scene rendered by synth (tools/synth, docs/synth.md):
// ChArUco board views with the true camera, and part views with the true 3D marker corners and
// their true projections. The scene takes about 10 s to render, and ctest runs every TEST in its own
// process, so one TEST renders it once and checks the three claims in turn.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <random>

#include "calib/calibrate.hpp"
#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"

namespace photomill::calib {
namespace {

// 12 views of a 10x8-square ChArUco board and 3 part views, 1000x750 px, synth's default noise.
class Scene {
public:
  Scene() {
    const auto r = test::run_tool(test::tools_path("synth"), {"-q", "-o", dir().string(), "--views", "3", "--calib-views", "12",
                                            "--width", "1000", "--height", "750", "--fx", "1200", "--board-squares-x",
                                            "10", "--board-squares-y", "8", "--board-square-mm", "25",
                                            "--board-marker-mm", "18"});
    rendered = r.exit_code == 0;
    EXPECT_TRUE(rendered) << "synth failed (is the synth target built?): " << r.err;
  }
  const std::filesystem::path& dir() const { return dir_.path(); }
  Camera truth() const {
    std::ifstream in(dir() / "camera.yaml");
    return read_camera_yaml(in, "camera.yaml");
  }
  template <typename T, typename Read>
  std::vector<T> read(const std::string& name, Read reader) const {
    std::ifstream in(dir() / name);
    return reader(in, name);
  }
  static std::vector<std::string> board_detect_args() {
    std::vector<std::string> args{"-q", "--charuco", "10x8", "--square-mm", "25", "--marker-mm", "18", "--dict",
                                  "DICT_5X5_100"};
    for (int i = 0; i < 12; ++i) args.push_back("board_" + std::string(i < 10 ? "0" : "") + std::to_string(i) + ".jpg");
    return args;
  }
  bool rendered = false;

private:
  test::TempDir dir_;
};

// Done-when: from synth's calibration views, focal length within 0.1 % and principal point within
// 1 px of the truth, through the pipe detect | calib.
void board_views_give_the_true_camera(const Scene& scene) {
  const auto d = test::run_tool("detect", Scene::board_detect_args(), "", scene.dir());
  ASSERT_EQ(d.exit_code, 0) << d.err;
  const auto c = test::run_tool("calib", {"--charuco", "10x8", "--square-mm", "25", "-o", "cam.yaml"}, d.out, scene.dir());
  ASSERT_EQ(c.exit_code, 0) << c.err;
  std::ifstream in(scene.dir() / "cam.yaml");
  const Camera cam = read_camera_yaml(in, "cam.yaml");
  const Camera t = scene.truth();
  EXPECT_EQ(cam.image_width_px, t.image_width_px);
  EXPECT_LT(std::abs(cam.fx() / t.fx() - 1), 0.001) << cam.fx();
  EXPECT_LT(std::abs(cam.fy() / t.fy() - 1), 0.001) << cam.fy();
  EXPECT_LT(std::abs(cam.cx() - t.cx()), 1.0) << cam.cx();
  EXPECT_LT(std::abs(cam.cy() - t.cy()), 1.0) << cam.cy();
  EXPECT_NEAR(cam.distortion[0], t.distortion[0], 0.01);
}

// OpenCV 4.6's interpolated ChArUco corners against synth's true projections: shifted by +0.5 px
// (OpenCV issue 25539); ours are not.
void charuco_corners_against_the_true_projections(const Scene& scene) {
  const auto truth_obs = scene.read<Observation>("board_observations.csv", read_observations);
  std::map<std::pair<std::string, PointId>, Eigen::Vector2d> t;
  for (const auto& o : truth_obs) t[{o.image, o.point_id}] = {o.u_px, o.v_px};
  for (const bool raw : {true, false}) {
    auto args = Scene::board_detect_args();
    if (raw) args.push_back("--no-charuco-refine");
    const auto d = test::run_tool("detect", args, "", scene.dir());
    ASSERT_EQ(d.exit_code, 0) << d.err;
    std::istringstream in(d.out);
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    double sse = 0;
    int n = 0;
    for (const auto& o : read_observations(in, "detect")) {
      const auto it = t.find({o.image, o.point_id});
      ASSERT_NE(it, t.end()) << o.image << " " << o.point_id;
      const Eigen::Vector2d e = Eigen::Vector2d(o.u_px, o.v_px) - it->second;
      mean += e;
      sse += e.squaredNorm();
      ++n;
    }
    mean /= n;
    const double rms = std::sqrt(sse / n);
    EXPECT_GT(n, 0.95 * static_cast<double>(truth_obs.size()));
    if (raw) {
      EXPECT_NEAR(mean.x(), 0.5, 0.1);
      EXPECT_NEAR(mean.y(), 0.5, 0.1);
    } else {
      EXPECT_LT(mean.cwiseAbs().maxCoeff(), 0.02);
      EXPECT_LT(rms, 0.08);
    }
    std::cout << (raw ? "OpenCV 4.6 interpolated" : "refined") << ": mean error (" << mean.x() << ", " << mean.y()
              << ") px, rms " << rms << " px over " << n << " corners\n";
  }
}

// Done-when: from non-coplanar control points (the plate and part marker corners) in synth's part
// views, the focal length within 0.3 %. synth's observations are exact projections; 0.1 px of
// seeded Gaussian noise (twice the marker-corner accuracy detect aims at) stands for detection.
void part_views_with_non_coplanar_control(const Scene& scene) {
  auto control = scene.read<ControlPoint>("control_points.csv", read_control_points);
  const auto part = scene.read<ControlPoint>("part_points.csv", read_control_points);
  control.insert(control.end(), part.begin(), part.end());
  const auto exact = scene.read<Observation>("observations.csv", read_observations);
  const Camera t = scene.truth();
  const cv::Size size(t.image_width_px, t.image_height_px);
  CalibOptions o;
  // Exact projections give the exact camera: synth's and calib's camera models agree.
  const auto e = calibrate(exact, control, size, o);
  EXPECT_EQ(e.method, Method::Dlt);
  EXPECT_LT(std::abs(e.camera.fx() / t.fx() - 1), 1e-7);
  EXPECT_LT(e.rms_px, 1e-4);
  auto noisy = exact;
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0, 0.1);
  for (auto& ob : noisy) {
    ob.u_px += noise(rng);
    ob.v_px += noise(rng);
  }
  const auto lm = calibrate(noisy, control, size, o);
  EXPECT_LT(std::abs(lm.camera.fx() / t.fx() - 1), 0.003) << lm.camera.fx();
  EXPECT_LT(std::abs(lm.camera.fy() / t.fy() - 1), 0.003) << lm.camera.fy();
  o.optimizer = Optimizer::Simplex;
  const auto nm = calibrate(noisy, control, size, o);
  EXPECT_LT(std::abs(nm.rms_px / lm.rms_px - 1), 0.01);
  std::cout << "LM " << lm.stats.seconds << " s, " << lm.stats.iterations << " iterations; simplex "
            << nm.stats.seconds << " s, " << nm.stats.evaluations << " evaluations; rms " << lm.rms_px << " / "
            << nm.rms_px << " px\n";
}

TEST(Synth, SmallScene) {
  const Scene scene;
  ASSERT_TRUE(scene.rendered);
  {
    SCOPED_TRACE("board views");
    board_views_give_the_true_camera(scene);
  }
  {
    SCOPED_TRACE("ChArUco corners");
    charuco_corners_against_the_true_projections(scene);
  }
  {
    SCOPED_TRACE("part views");
    part_views_with_non_coplanar_control(scene);
  }
}

}  // namespace
}  // namespace photomill::calib
