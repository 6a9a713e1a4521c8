// Golden command-line cases for triangulate (after PROJ's test_cct.yaml): bad inputs name the
// file and line and leave no output; degenerate input is explained; a good run writes every
// output, readable by photomill's own readers; stdin/stdout work as a filter.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "formats/camera.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

using photomill::test::run_tool;
using photomill::test::TempDir;
namespace fs = std::filesystem;

// A scene's files in a temporary folder: tracks.csv, camera.yaml, control.csv, bars.csv.
class SceneFiles {
public:
  SceneFiles() : truth_(test::make_scene({})) {
    write("tracks.csv", [&](std::ostream& s) { write_tracks(s, truth_.tracks); });
    write("camera.yaml", [&](std::ostream& s) { write_camera_yaml(s, truth_.camera); });
    write("control.csv", [&](std::ostream& s) { write_control_points(s, truth_.plate_points); });
    std::vector<ScaleBar> bars;
    const auto& p = truth_.plate_points;
    bars.push_back({p.front().point_id, p.back().point_id, (p.front().xyz_mm - p.back().xyz_mm).norm(), 0.001});
    write("bars.csv", [&](std::ostream& s) { write_scale_bars(s, bars); });
  }
  template <typename F>
  void write(const std::string& name, const F& f) {
    std::ofstream out(dir_.path() / name, std::ios::binary);
    f(out);
  }
  std::string path(const std::string& name) const { return (dir_.path() / name).string(); }
  std::string text(const std::string& name) const { return photomill::test::read_file(dir_.path() / name); }
  const test::SceneTruth& truth() const { return truth_; }

private:
  TempDir dir_;
  test::SceneTruth truth_;
};

struct ErrorCase {
  const char* name;
  std::function<std::vector<std::string>(SceneFiles&)> args;
  int exit_code;
  const char* stderr_has;
};

void PrintTo(const ErrorCase& c, std::ostream* os) { *os << c.name; }

class TriangulateCliError : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(TriangulateCliError, FailsCleanly) {
  SceneFiles f;
  const ErrorCase& c = GetParam();
  auto args = c.args(f);
  if (std::find(args.begin(), args.end(), "--preview") == args.end()) args.insert(args.end(), {"--preview", f.path("preview.png")});
  const auto r = run_tool("triangulate", args);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_FALSE(fs::exists(f.path("cloud.ply"))) << "no output may be left behind";
  EXPECT_FALSE(fs::exists(f.path("poses.csv")));
  EXPECT_FALSE(fs::exists(f.path("preview.png")));
}

const std::vector<ErrorCase> kErrors = {
    {"missing_tracks",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("nope.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply")}; },
     1, "nope.csv: cannot open"},
    {"missing_camera_file",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("none.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply")}; },
     1, "none.yaml"},
    {"malformed_line",
     [](SceneFiles& f) {
       f.write("bad.csv", [](std::ostream& s) { s << "track_id,image,u_px,v_px\n1,a.png,1,2\n2,a.png,3\n"; });
       return std::vector<std::string>{f.path("bad.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply")};
     },
     1, "bad.csv:3:"},
    {"malformed_control_points",
     [](SceneFiles& f) {
       f.write("badc.csv", [](std::ostream& s) { s << "point_id,x_mm,y_mm,z_mm\n1,0,0,nan\n"; });
       return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("badc.csv"), "-o", f.path("cloud.ply")};
     },
     1, "badc.csv:2:"},
    {"camera_required",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-o", f.path("cloud.ply")}; }, 2,
     "--camera"},
    {"no_datum",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "-o", f.path("cloud.ply"), "--poses", f.path("poses.csv")}; },
     2, "no datum"},
    {"two_outputs_on_stdout",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--arbitrary-scale", "--poses", "-"}; },
     2, "stdout"},
    {"preview_to_stdout",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply"), "--preview", "-"}; },
     2, "never to stdout"},
    {"bad_loss",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--loss", "tukey"}; },
     2, "--loss"},
    {"bad_marker_ids",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--marker-side-mm", "24", "--marker-ids", "9-3", "-o", f.path("cloud.ply")}; },
     2, "--marker-ids"},
    {"one_image",
     [](SceneFiles& f) {
       f.write("one.csv", [&](std::ostream& s) {
         std::vector<TrackObservation> t;
         for (const auto& o : f.truth().tracks) {
           if (o.image == f.truth().poses[0].image) t.push_back(o);
         }
         write_tracks(s, t);
       });
       return std::vector<std::string>{f.path("one.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply"), "--poses", f.path("poses.csv")};
     },
     1, "one image"},
    // Several cameras (issue 23).
    {"camera_for_syntax",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "--camera-for", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply")}; },
     2, "expected PREFIX=FILE"},
    {"camera_and_camera_for",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--camera-for", "view_=" + f.path("camera.yaml"), "-o", f.path("cloud.ply")}; },
     2, "excludes"},
    {"image_of_no_camera",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "--camera-for", "view_1=" + f.path("camera.yaml"), "--control-points", f.path("control.csv"), "-o", f.path("cloud.ply")}; },
     1, "' starts with none of the cameras' prefixes ('view_1'): give its camera"},
    {"several_cameras_one_refined_camera",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "--camera-for", "view_0=" + f.path("camera.yaml"), "--camera-for", "view_1=" + f.path("camera.yaml"), "--control-points", f.path("control.csv"), "--refine-intrinsics", "all", "--refined-camera", f.path("k.yaml"), "-o", f.path("cloud.ply")}; },
     2, "--refined-camera writes one camera; with several (--camera-for, --rig) write each with --refined-camera-for PREFIX=FILE"},
    {"refined_camera_for_unknown_prefix",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "--camera-for", "view_0=" + f.path("camera.yaml"), "--camera-for", "view_1=" + f.path("camera.yaml"), "--control-points", f.path("control.csv"), "--refine-intrinsics", "all", "--refined-camera-for", "left=" + f.path("k.yaml"), "-o", f.path("cloud.ply")}; },
     2, "--refined-camera-for: 'left' is none of the cameras' prefixes ('view_0', 'view_1')"},
    {"refined_camera_for_one_camera",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points", f.path("control.csv"), "--refine-intrinsics", "all", "--refined-camera-for", "view_0=" + f.path("k.yaml"), "-o", f.path("cloud.ply")}; },
     2, "--refined-camera-for names one of several cameras"},
    {"refined_camera_for_without_refinement",
     [](SceneFiles& f) { return std::vector<std::string>{f.path("tracks.csv"), "--camera-for", "view_0=" + f.path("camera.yaml"), "--camera-for", "view_1=" + f.path("camera.yaml"), "--control-points", f.path("control.csv"), "--refined-camera-for", "view_0=" + f.path("k.yaml"), "-o", f.path("cloud.ply")}; },
     2, "--refined-camera-for needs --refine-intrinsics"},
    {"rig_and_known_poses",
     [](SceneFiles& f) {
       f.write("rig.yaml", [&](std::ostream& s) {
         Rig rig;
         rig.cameras.push_back({"view_0", f.truth().camera, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}});
         rig.cameras.push_back({"view_1", f.truth().camera, Eigen::Matrix3d::Identity(), Eigen::Vector3d(-80, 0, 0), {}});
         write_rig_yaml(s, rig);
       });
       return std::vector<std::string>{f.path("tracks.csv"), "--rig", f.path("rig.yaml"), "--known-poses", f.path("tracks.csv"), "-o", f.path("cloud.ply")};
     },
     2, "--rig places the photos by the rig's relative poses; --known-poses would replace them"},
    {"rig_without_a_shared_frame",
     [](SceneFiles& f) {
       f.write("rig.yaml", [&](std::ostream& s) {
         Rig rig;
         rig.cameras.push_back({"view_0", f.truth().camera, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}});
         rig.cameras.push_back({"view_1", f.truth().camera, Eigen::Matrix3d::Identity(), Eigen::Vector3d(-80, 0, 0), {}});
         write_rig_yaml(s, rig);
       });
       return std::vector<std::string>{f.path("tracks.csv"), "--rig", f.path("rig.yaml"), "-o", f.path("cloud.ply")};
     },
     1, "no frame of the rig has photos from two of its cameras (12 frames, e.g. '00.png')"},
};

INSTANTIATE_TEST_SUITE_P(Triangulate, TriangulateCliError, ::testing::ValuesIn(kErrors));

// Several cameras self-calibrated (issue 23): each camera's refined camera.yaml is written where
// --refined-camera-for names it, and the report lists each by its prefix.
TEST(TriangulateCli, WritesEachRefinedCameraOfSeveral) {
  SceneFiles f;
  const auto r = run_tool("triangulate", {f.path("tracks.csv"), "--camera-for", "view_0=" + f.path("camera.yaml"),
                                          "--camera-for", "view_1=" + f.path("camera.yaml"), "--control-points",
                                          f.path("control.csv"), "--refine-intrinsics", "focal", "--refined-camera-for",
                                          "view_1=" + f.path("k1.yaml"), "--refined-camera-for", "view_0=" + f.path("k0.yaml"),
                                          "--report", f.path("report.json"), "-o", f.path("cloud.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* name : {"k0.yaml", "k1.yaml"}) {
    std::ifstream in(f.path(name));
    const Camera k = read_camera_yaml(in, name);
    EXPECT_NEAR(k.fx(), f.truth().camera.fx(), 2e-3 * f.truth().camera.fx()) << name;
  }
  const std::string report = photomill::test::read_file(f.path("report.json"));
  EXPECT_NE(report.find("\"refined_cameras\":[{\"prefix\":\"view_0\",\"camera\":["), std::string::npos) << report;
  EXPECT_NE(report.find("{\"prefix\":\"view_1\",\"camera\":["), std::string::npos) << report;
  EXPECT_EQ(report.find("\"refined_camera\":"), std::string::npos) << report;
}

// A stereo rig over six frames (issue 23): every photo posed, the report says how, the cloud is
// in the rig's frame at frame 00 and in mm (the rig's baseline is the scale).
TEST(TriangulateCli, RigOverSeveralFrames) {
  const test::RigSceneTruth t = test::make_rig_scene(6, 0.05, 5);
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  {
    std::ofstream rig(p("rig.yaml"));
    write_rig_yaml(rig, t.rig);
    std::ofstream tracks(p("tracks.csv"));
    write_tracks(tracks, t.tracks);
  }
  const auto r = run_tool("triangulate", {p("tracks.csv"), "--rig", p("rig.yaml"), "--report", p("report.json"), "--poses",
                                          p("poses.csv"), "-o", p("cloud.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("rig: 6 of 6 frames placed, frame 00.png is the world"), std::string::npos) << r.err;
  const std::string report = photomill::test::read_file(dir.path() / "report.json");
  EXPECT_NE(report.find("\"rig\":{\"frames\":6,\"frames_placed\":6,\"reference_frame\":\"00.png\""), std::string::npos) << report;
  std::ifstream poses_in(p("poses.csv"));
  const std::vector<Pose> poses = read_poses(poses_in, "poses.csv");
  ASSERT_EQ(poses.size(), 12u);
  for (const Pose& got : poses) {
    const auto truth = std::find_if(t.poses.begin(), t.poses.end(), [&](const Pose& q) { return q.image == got.image; });
    ASSERT_NE(truth, t.poses.end()) << got.image;
    EXPECT_LT((got.centre_mm() - truth->centre_mm()).norm(), 0.1) << got.image;
  }
}

TEST(TriangulateCli, WritesEveryOutput) {
  SceneFiles f;
  const auto r = run_tool("triangulate", {f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points",
                                          f.path("control.csv"), "-o", f.path("cloud.ply"), "--poses", f.path("poses.csv"),
                                          "--report", f.path("report.json"), "--colmap", f.path("model")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_NE(r.err.find("datum: control_points"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("reprojection RMS"), std::string::npos) << r.err;

  std::istringstream ply(f.text("cloud.ply"));
  const PointCloud cloud = read_ply(ply, "cloud.ply");
  EXPECT_EQ(cloud.points_mm.size(), f.truth().plate_points.size() + f.truth().part_points.size());
  for (const char* p : {"track_id", "views", "reproj_rms_px", "sigma_mm", "control"}) EXPECT_NE(cloud.find(p), nullptr) << p;

  std::istringstream poses_text(f.text("poses.csv"));
  const auto poses = read_poses(poses_text, "poses.csv");
  ASSERT_EQ(poses.size(), f.truth().poses.size());
  std::map<std::string, Eigen::Vector3d> truth;
  for (const auto& p : f.truth().poses) truth[p.image] = p.centre_mm();
  for (const auto& p : poses) EXPECT_LT((p.centre_mm() - truth.at(p.image)).norm(), 0.1) << p.image;

  const std::string report = f.text("report.json");
  for (const char* key : {"\"datum\":{\"type\":\"control_points\"", "\"final_rms_px\":", "\"per_image\":[",
                          "\"removed_observations\":[", "\"scale_bars\":[", "\"uncertainty\":{\"method\":"}) {
    EXPECT_NE(report.find(key), std::string::npos) << key << " in " << report;
  }
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt"}) EXPECT_TRUE(fs::exists(f.path("model/") + file)) << file;
}

// --preview: a PNG of the cloud and the cameras, only when the run succeeds (FailsCleanly above).
TEST(TriangulateCli, WritesAPreview) {
  SceneFiles f;
  const auto r = run_tool("triangulate", {f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points",
                                          f.path("control.csv"), "-o", f.path("cloud.ply"), "--preview",
                                          f.path("preview.png"), "--preview-colour", "sigma"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  const cv::Mat img = cv::imread(f.path("preview.png"), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << "preview.png is not an image";
  EXPECT_EQ(img.cols, 1600);
  EXPECT_EQ(img.rows, 800);
  int coloured = 0;  // the points' colours (viridis) and the cameras' orange edges
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b c = img.at<cv::Vec3b>(y, x);
      coloured += std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]}) > 60 ? 1 : 0;
    }
  }
  EXPECT_GT(coloured, 5000);
  for (const auto& e : fs::directory_iterator(f.path(""))) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << "temporary left: " << e.path();
  }
}

// Without any datum (--arbitrary-scale) the cloud says its unit is no mm: the PLY header, the
// report's datum and warning; with control points the header says mm.
TEST(TriangulateCli, AnArbitraryScaleIsSaid) {
  SceneFiles f;
  const auto r = run_tool("triangulate", {f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--arbitrary-scale",
                                          "--ply-encoding", "ascii", "--report", f.path("report.json"), "-o", f.path("cloud.ply")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("the scale is arbitrary"), std::string::npos) << r.err;
  const std::string text = f.text("cloud.ply");
  EXPECT_NE(text.find("comment photomill point cloud, units arbitrary: not mm"), std::string::npos) << text.substr(0, 300);
  std::istringstream ply(text);
  EXPECT_EQ(read_ply(ply, "cloud.ply").units, "arbitrary");
  EXPECT_NE(f.text("report.json").find("\"datum\":{\"type\":\"arbitrary_scale\""), std::string::npos);
  const auto mm = run_tool("triangulate", {f.path("tracks.csv"), "-c", f.path("camera.yaml"), "--control-points",
                                           f.path("control.csv"), "-o", f.path("mm.ply")});
  ASSERT_EQ(mm.exit_code, 0) << mm.err;
  std::istringstream mm_ply(f.text("mm.ply"));
  EXPECT_EQ(read_ply(mm_ply, "mm.ply").units, "mm");
}

TEST(TriangulateCli, WorksAsAFilter) {
  SceneFiles f;
  const auto r = run_tool("triangulate", {"-", "-c", f.path("camera.yaml"), "--scale-bars", f.path("bars.csv"),
                                          "--ply-encoding", "ascii", "-q"},
                          f.text("tracks.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "") << "-q keeps stderr quiet";
  std::istringstream ply(r.out);
  const PointCloud cloud = read_ply(ply, "<stdout>");
  EXPECT_EQ(cloud.points_mm.size(), f.truth().plate_points.size() + f.truth().part_points.size());
}

}  // namespace
}  // namespace photomill::triangulate
