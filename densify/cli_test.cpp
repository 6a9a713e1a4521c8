// densify end to end on the demo's photos with their true camera and poses (a patch of the part,
// to stay quick): accuracy against synth's exact surface, determinism across thread counts, and
// every bad input named on one line with exit 1 and no output.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "densify/test_demo.hpp"
#include "formats/point_cloud.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "tools/synth/scene.hpp"
#include "tools/synth/surface_distance.hpp"

namespace photomill::densify {
namespace {

namespace fs = std::filesystem;
using photomill::test::read_file;
using photomill::test::run_tool;
using photomill::test::TempDir;

using test::kDemo;
// Five views around part_00 and a 40 x 30 mm patch of the part with a bump's flank and a part
// marker in it (masked: its cells repeat at 1.7 mm, and a match one cell off correlates as well).
const std::vector<std::string> kPhotos = {"part_00.jpg", "part_01.jpg", "part_02.jpg", "part_10.jpg", "part_11.jpg"};
const std::string kBox = "-60,-45,-5,-20,-15,60";

// The demo's poses of kPhotos (with `edit` applied to each row's fields), the true camera, and
// the true surface's samples as the sparse cloud.
class Job {
public:
  explicit Job(const std::function<void(std::vector<std::string>&)>& edit = {}) {
    test::write_demo_poses(dir_.path() / "poses.csv", kPhotos, edit);
    fs::copy_file(kDemo / "camera.yaml", dir_.path() / "camera.yaml");
    fs::copy_file(kDemo / "surface.ply", dir_.path() / "seeds.ply");
  }
  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }
  std::vector<std::string> args(const std::vector<std::string>& more = {}) const {
    std::vector<std::string> a = {path("seeds.ply"), "--camera", path("camera.yaml"), "--poses", path("poses.csv"),
                                  "--image-dir", kDemo.string(), "--observations", (kDemo / "observations.csv").string(),
                                  "--box", kBox, "-q", "-o", path("dense.ply")};
    a.insert(a.end(), more.begin(), more.end());
    return a;
  }

private:
  TempDir dir_;
};

PointCloud read_cloud(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return read_ply(in, path);
}

TEST(DensifyCli, MeasuresThePartToHundredthsOfAMillimetre) {
  const Job job;
  const auto r = run_tool("densify", job.args({"--jobs", "2"}));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  const PointCloud cloud = read_cloud(job.path("dense.ply"));
  for (const char* p : {"nx", "ny", "nz", "sigma_mm", "views", "ref_image", "correlation", "reprojection_px", "marker_corner", "window_mm"}) {
    EXPECT_NE(cloud.find(p), nullptr) << p;
  }
  std::ifstream scene_in(kDemo / "scene.txt");
  const synth::PartScene scene = synth::read_scene(scene_in, "scene.txt");
  std::vector<double> d;
  for (const auto& p : cloud.points_mm) d.push_back(synth::distance_to_surface(scene.surface, p, 0.01));
  ASSERT_FALSE(d.empty());
  std::sort(d.begin(), d.end());
  double ss = 0;
  for (double x : d) ss += x * x;
  const double rms = std::sqrt(ss / static_cast<double>(d.size())), median = d[d.size() / 2];
  std::cerr << d.size() << " points, distance to the true surface: median " << median << " mm, RMS " << rms << " mm, max "
            << d.back() << " mm\n";
  // Issue 28's bounds for the whole demo (median 0.015, RMS 0.03 mm), here on a patch of it.
  EXPECT_LT(median, 0.015);
  EXPECT_LT(rms, 0.03);
  // 40 x 30 mm at ~5 px per mm and a point per 1.8 px: up to ~8 points per mm^2 from part_00 alone;
  // with these five photos about 4 pass the correlation of 0.95 in 3 of them.
  EXPECT_GT(d.size(), 4000u);
  // Normals face the cameras (up, on a part seen from above).
  const PointProperty* nz = cloud.find("nz");
  EXPECT_GT(*std::min_element(nz->values.begin(), nz->values.end()), 0.0);
  // With the true camera and poses the views' free matches lie where the points project: the
  // whole demo's median is 0.03 px (docs/measurements/densify.md).
  std::vector<double> reprojection = cloud.find("reprojection_px")->values;
  std::sort(reprojection.begin(), reprojection.end());
  EXPECT_LT(reprojection[reprojection.size() / 2], 0.06);
  // Each point's window: 9 px (5 px where the bend check's window gave it) at ~0.1-0.2 mm per px
  // (fx 2400 px, photos 250-450 mm from the part).
  std::vector<double> window = cloud.find("window_mm")->values;
  std::sort(window.begin(), window.end());
  EXPECT_GT(window.front(), 5 * 0.08);
  EXPECT_LT(window.back(), 9 * 0.25);
  EXPECT_GT(window[window.size() / 2] / 9, 0.1);
  EXPECT_LT(window[window.size() / 2] / 9, 0.2);

  // The same bytes on one thread.
  const std::string two = read_file(job.path("dense.ply"));
  const auto r1 = run_tool("densify", job.args({"--jobs", "1"}));
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  EXPECT_EQ(read_file(job.path("dense.ply")), two);
}

struct ErrorCase {
  const char* name;
  std::function<void(std::vector<std::string>&)> edit_pose;      // a poses.csv row's fields
  std::function<void(const Job&, std::vector<std::string>&)> args;  // the command line
  int exit_code;
  const char* stderr_has;
};
void PrintTo(const ErrorCase& c, std::ostream* os) { *os << c.name; }

class DensifyErrors : public testing::TestWithParam<ErrorCase> {};

TEST_P(DensifyErrors, OneLineExitCodeNoOutput) {
  const ErrorCase& c = GetParam();
  const Job job(c.edit_pose);
  std::vector<std::string> a = job.args();
  if (c.args) c.args(job, a);
  const auto r = run_tool("densify", a);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(job.path("dense.ply")));
  EXPECT_TRUE(r.out.empty());
}

void set_arg(std::vector<std::string>& a, const std::string& option, const std::string& value) {
  const auto it = std::find(a.begin(), a.end(), option);
  if (it != a.end()) {
    *(it + 1) = value;
  } else {
    a.push_back(option);
    a.push_back(value);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, DensifyErrors,
    testing::Values(
        ErrorCase{"MissingPhoto", [](auto& f) { if (f[0] == "part_02.jpg") f[0] = "part_99.jpg"; }, {}, 1,
                  "photo " },
        ErrorCase{"CameraOfAnotherSize", {}, [](const Job& j, auto& a) {
                    std::string y = read_file(j.path("camera.yaml"));
                    y.replace(y.find("image_width: 2000"), 17, "image_width: 1999");
                    std::ofstream(j.path("camera.yaml")) << y;
                    (void)a;
                  }, 1, "the camera is 1999 x 1500 px but photo"},
        ErrorCase{"CloudAndPosesOfTwoRuns", {}, [](const Job& j, auto& a) {
                    const std::string p = read_file(j.path("poses.csv"));
                    std::ofstream(j.path("poses.csv")) << "# photomill run=first rows=5\n" << p;
                    const std::string c = read_file(j.path("seeds.ply"));
                    std::string s = c;
                    s.insert(s.find("element vertex"), "comment photomill run=second\n");
                    std::ofstream(j.path("seeds.ply"), std::ios::binary) << s;
                    (void)a;
                  }, 1, "made by another run"},
        ErrorCase{"MalformedCloud", {}, [](const Job& j, auto& a) {
                    std::ofstream(j.path("seeds.ply")) << "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\n"
                                                          "property double y\nproperty double z\nend_header\n1 2 3\n4 5\n";
                    (void)a;
                  }, 1, "seeds.ply"},
        ErrorCase{"NoSeedInTheBox", {}, [](const Job&, auto& a) { set_arg(a, "--box", "500,500,500,600,600,600"); }, 1,
                  "no point of the sparse cloud lies inside the box"},
        ErrorCase{"NoCamera", {}, [](const Job&, auto& a) {
                    const auto it = std::find(a.begin(), a.end(), "--camera");
                    a.erase(it, it + 2);
                  }, 2, "--camera FILE --poses FILE"},
        ErrorCase{"NoCloud", {}, [](const Job&, auto& a) { a.erase(a.begin()); }, 2, "give the sparse cloud"},
        ErrorCase{"BoxInsideOut", {}, [](const Job&, auto& a) { set_arg(a, "--box", "10,0,0,0,10,10"); }, 2,
                  "each minimum must be below its maximum"},
        ErrorCase{"AngleRangeEmpty", {}, [](const Job&, auto& a) { set_arg(a, "--min-angle-deg", "40"); set_arg(a, "--max-angle-deg", "30"); },
                  2, "--min-angle-deg must be below --max-angle-deg"},
        ErrorCase{"BendWindowNotSmaller", {}, [](const Job&, auto& a) { set_arg(a, "--bend-check-half-window-px", "9"); }, 2,
                  "--bend-check-half-window-px must be below --half-window-px"},
        // Poses 15 mm off along x (another job's, or a wrong unit): no patch matches anywhere.
        ErrorCase{"PosesThatDoNotFitThePhotos", [](auto& f) { f[5] = std::to_string(std::stod(f[5]) + 15); }, {}, 1,
                  "no patch was accepted"}),
    [](const testing::TestParamInfo<ErrorCase>& i) { return std::string(i.param.name); });

}  // namespace
}  // namespace photomill::densify
