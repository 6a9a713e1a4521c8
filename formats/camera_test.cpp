// camera.yaml: round trip, OpenCV interoperability in both directions, the real sample files
// OpenCV ships, and malformed or hostile files.
#include "formats/camera.hpp"

#include <chrono>
#include <fstream>
#include <sstream>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "formats/error.hpp"
#include "tests/temp_dir.hpp"

namespace photomill {
namespace {

Camera sample_camera() {
  Camera c;
  c.image_width_px = 2000;
  c.image_height_px = 1500;
  c.camera_matrix << 2400.123456789012, 0, 999.5 + 1.0 / 3, 0, 2399.9, 749.25, 0, 0, 1;
  c.distortion = {-0.1, 0.05, 1e-4, -2e-5, 0.0};
  c.avg_reprojection_error_px = 0.123;
  return c;
}

TEST(CameraYaml, RoundTripsExactly) {
  std::stringstream s;
  write_camera_yaml(s, sample_camera());
  EXPECT_EQ(read_camera_yaml(s, "cam.yaml"), sample_camera()) << s.str();
}

TEST(CameraYaml, OpenCvReadsWhatWeWrite) {
  test::TempDir dir;
  const auto path = (dir.path() / "cam.yaml").string();
  {
    std::ofstream f(path);
    write_camera_yaml(f, sample_camera());
  }
  cv::FileStorage fs(path, cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat k, d;
  fs["camera_matrix"] >> k;
  fs["distortion_coefficients"] >> d;
  EXPECT_EQ(static_cast<int>(fs["image_width"]), 2000);
  EXPECT_EQ(k.at<double>(0, 0), sample_camera().fx());
  EXPECT_EQ(k.at<double>(0, 2), sample_camera().cx());
  EXPECT_EQ(d.total(), 5u);
  EXPECT_EQ(d.at<double>(2), 1e-4);
  EXPECT_EQ(static_cast<double>(fs["avg_reprojection_error"]), 0.123);
}

TEST(CameraYaml, WeReadWhatOpenCvWrites) {
  test::TempDir dir;
  const auto path = (dir.path() / "cv.yaml").string();
  {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    fs << "image_width" << 640 << "image_height" << 480;
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << 500, 0, 320, 0, 501, 240, 0, 0, 1);
    fs << "distortion_coefficients" << (cv::Mat_<double>(1, 8) << 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8);
  }
  std::ifstream f(path);
  const Camera c = read_camera_yaml(f, path);
  EXPECT_EQ(c.fy(), 501);
  EXPECT_EQ(c.distortion.size(), 8u);
  EXPECT_FALSE(c.avg_reprojection_error_px);
}

class OpenCvSampleFiles : public ::testing::TestWithParam<std::tuple<const char*, double, double>> {};

TEST_P(OpenCvSampleFiles, AreRead) {
  const auto [file, fx, err] = GetParam();
  const std::string path = std::string(PHOTOMILL_SHARED_DIR) + "/data/" + file;
  std::ifstream f(path);
  if (!f) GTEST_SKIP() << "shared data not found: " << path;
  const Camera c = read_camera_yaml(f, path);
  EXPECT_NEAR(c.fx(), fx, 1e-3);
  EXPECT_EQ(c.image_width_px, 640);
  EXPECT_EQ(c.distortion.size(), 5u);
  ASSERT_TRUE(c.avg_reprojection_error_px);
  EXPECT_NEAR(*c.avg_reprojection_error_px, err, 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Shared, OpenCvSampleFiles,
                         ::testing::Values(std::tuple{"opencv-chessboard/left_intrinsics.yml", 535.9157, 0.39259},
                                           std::tuple{"opencv-aruco/tutorial_camera_charuco.yml", 452.5107, 0.18235}));

std::string camera_error(const std::string& text) {
  std::istringstream in(text);
  try {
    read_camera_yaml(in, "cam.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string good_yaml() {
  std::ostringstream s;
  write_camera_yaml(s, sample_camera());
  return s.str();
}

// Replaces `from` in a good file; a missing `from` yields a marker the test then fails on.
std::string with(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  if (pos == std::string::npos) return "test bug: '" + from + "' not in the sample";
  return text.replace(pos, from.size(), to);
}

struct BadCamera {
  const char* name;
  std::string text;
  const char* message;
};

class CameraMalformed : public ::testing::TestWithParam<BadCamera> {};

TEST_P(CameraMalformed, IsRejected) {
  const auto start = std::chrono::steady_clock::now();
  const std::string e = camera_error(GetParam().text);
  EXPECT_NE(e.find(GetParam().message), std::string::npos) << e;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

INSTANTIATE_TEST_SUITE_P(
    Cases, CameraMalformed,
    ::testing::Values(
        BadCamera{"empty", "", "cam.yaml: empty input"},
        BadCamera{"junk", std::string("\x00\x01\x02", 3), "binary data"},
        BadCamera{"not_yaml", "this is not: [yaml", "cam.yaml:1: not an OpenCV camera YAML file"},
        // Found by fuzzing: inputs on which OpenCV 4.6's own YAML parser never returns.
        BadCamera{"opencv_hang_1", " L:0\n%m--\ni", "cam.yaml:1: not an OpenCV camera YAML file"},
        BadCamera{"opencv_hang_2", "[i{:&,|]]{\n->", "cam.yaml:1: not an OpenCV camera YAML file"},
        BadCamera{"duplicate", good_yaml() + "image_width: 640\n", "duplicate key 'image_width'"},
        BadCamera{"unclosed_data", with(good_yaml(), " 0., 0., 1. ]", " 0., 0., 1."), "'camera_matrix' data is not a list"},
        BadCamera{"nested_data", with(good_yaml(), "[ 2400.", "[ [ 2400."), "'camera_matrix' data is not a list"},
        BadCamera{"directive", "%TAG ! x\n" + good_yaml(), "cam.yaml:1: not an OpenCV camera YAML file: unsupported directive"},
        BadCamera{"missing_matrix", "image_width: 640\nimage_height: 480\n", "missing key 'camera_matrix'"},
        BadCamera{"missing_width", with(good_yaml(), "image_width: 2000\n", ""), "missing key 'image_width'"},
        BadCamera{"huge_matrix", with(good_yaml(), "rows: 3", "rows: 1000000"), "cam.yaml:7: 'camera_matrix' matrix declares rows: 1000000"},
        BadCamera{"huge_matrix_2", with(good_yaml(), "cols: 3", "cols: 99999999999999"), "cam.yaml:8: 'camera_matrix' matrix declares cols: 99999999999999"},
        // Found by fuzzing: OpenCV reads a non-numeric dimension as INT_MAX and allocated 48 GB.
        BadCamera{"text_dim", with(good_yaml(), "cols: 3", "cols: \xe0" "3"), "cam.yaml:8: 'camera_matrix' cols: '\xe0" "3' is not an integer"},
        BadCamera{"huge_dist", with(good_yaml(), "rows: 5", "rows: 4000000"), "'distortion_coefficients' matrix declares rows: 4000000"},
        BadCamera{"zero_rows", with(good_yaml(), "rows: 3", "rows: 0"), "matrix declares rows: 0"},
        BadCamera{"short_data", with(good_yaml(), "rows: 3", "rows: 4"), "cam.yaml:10: 'camera_matrix' data has 9 values; rows x cols = 4 x 3 needs 12"},
        BadCamera{"channels", with(good_yaml(), "dt: d", "dt: \"3d\""), "cam.yaml:9: 'camera_matrix' dt: '3d' is not a one-channel"},
        BadCamera{"not_a_map", "image_width: 640\nimage_height: 480\ncamera_matrix: [1, 0, 0]\n", "cam.yaml:3: 'camera_matrix' is not an !!opencv-matrix"},
        BadCamera{"word_in_data", with(good_yaml(), "2400.123456789012", "abc"), "'camera_matrix' data has a value that is not a number"},
        BadCamera{"wrong_size", with(with(good_yaml(), "rows: 3", "rows: 1"), "cols: 3", "cols: 9"), "camera_matrix must be 3x3"},
        BadCamera{"negative_f", with(good_yaml(), "2400.123456789012", "-5."), "focal lengths fx, fy must be positive"},
        BadCamera{"nan", with(good_yaml(), "2400.123456789012", ".nan"), "non-finite"},
        BadCamera{"dist_count", with(with(good_yaml(), "rows: 5", "rows: 3"), "0.05, 1e-04, -2e-05, 0.", "0.05, 1e-04"), "distortion_coefficients has 3 values"},
        BadCamera{"image_size", with(good_yaml(), "image_height: 1500", "image_height: 0"), "image size 2000x0 is not plausible"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(CameraYaml, OversizedInputIsRefusedBeforeParsing) {
  std::istringstream in(std::string(2 << 20, ' '));
  EXPECT_THROW(read_camera_yaml(in, "big.yaml"), InputError);
}

}  // namespace
}  // namespace photomill

// ---------------------------------------------------------------------------------------------
// rig.yaml

namespace photomill {
namespace {

Rig sample_rig() {
  Rig rig;
  RigCamera left;
  left.prefix = "left";
  left.camera = sample_camera();
  RigCamera right;
  right.prefix = "cams/right_";
  right.camera = sample_camera();
  right.camera.camera_matrix(0, 0) = 2410.5;
  right.camera.distortion = {-0.2, 0.01, 0, 0};
  right.camera.avg_reprojection_error_px.reset();
  right.cam_from_rig_rotation = Eigen::AngleAxisd(0.01, Eigen::Vector3d(0.1, 0.6, -0.7).normalized()).toRotationMatrix();
  right.cam_from_rig_translation_mm = {-83.6123456789, 1.04, 1.3 + 1.0 / 3};
  right.cam_from_rig_sigma = Eigen::Matrix<double, 6, 1>();
  *right.cam_from_rig_sigma << 0.01, 0.02, 0.003, 0.05, 0.06, 0.7;
  rig.cameras = {left, right};
  rig.avg_reprojection_error_px = 0.25;
  return rig;
}

std::string good_rig() {
  std::ostringstream s;
  write_rig_yaml(s, sample_rig());
  return s.str();
}

std::string rig_error(const std::string& text) {
  std::istringstream in(text);
  try {
    read_rig_yaml(in, "rig.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(RigYaml, RoundTripsExactly) {
  std::stringstream s;
  write_rig_yaml(s, sample_rig());
  EXPECT_EQ(read_rig_yaml(s, "rig.yaml"), sample_rig()) << s.str();
}

TEST(RigYaml, OpenCvReadsWhatWeWrite) {
  test::TempDir dir;
  const auto path = (dir.path() / "rig.yaml").string();
  {
    std::ofstream f(path);
    write_rig_yaml(f, sample_rig());
  }
  cv::FileStorage fs(path, cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  EXPECT_EQ(static_cast<int>(fs["rig_cameras"]), 2);
  EXPECT_EQ(static_cast<std::string>(fs["camera_1_prefix"]), "cams/right_");
  cv::Mat r, t;
  fs["camera_1_cam_from_rig_rotation"] >> r;
  fs["camera_1_cam_from_rig_translation_mm"] >> t;
  EXPECT_EQ(r.at<double>(1, 2), sample_rig().cameras[1].cam_from_rig_rotation(1, 2));
  EXPECT_EQ(t.at<double>(0), -83.6123456789);
}

TEST(RigYaml, MatchesImagesByPrefix) {
  const std::vector<std::string> prefixes{"left", "right", "cam1/", "cam10/"};
  EXPECT_EQ(match_rig_prefix(prefixes, "left01.jpg"), (RigMatch{0, "01.jpg"}));
  EXPECT_EQ(match_rig_prefix(prefixes, "/data/set/right01.jpg"), (RigMatch{1, "/data/set/01.jpg"}));
  EXPECT_EQ(match_rig_prefix(prefixes, "cam1/0001.png"), (RigMatch{2, "0001.png"}));
  EXPECT_EQ(match_rig_prefix(prefixes, "cam10/0001.png"), (RigMatch{3, "0001.png"}));  // the longer prefix
  EXPECT_EQ(match_rig_prefix(prefixes, "x/cam1/0001.png"), std::nullopt);  // a prefix with '/' starts the name
  EXPECT_EQ(match_rig_prefix(prefixes, "middle.jpg"), std::nullopt);
  // A prefix without '/' starts the file name only: both photos of one frame pair up.
  EXPECT_EQ(match_rig_prefix(prefixes, "leftovers/left01.jpg"), (RigMatch{0, "leftovers/01.jpg"}));
  EXPECT_EQ(match_rig_prefix(prefixes, "leftovers/right01.jpg"), (RigMatch{1, "leftovers/01.jpg"}));
  EXPECT_EQ(match_rig_prefix(prefixes, "leftovers/x.jpg"), std::nullopt);
}

struct BadRig {
  const char* name;
  std::string text;
  const char* message;
};

class RigMalformed : public ::testing::TestWithParam<BadRig> {};

TEST_P(RigMalformed, IsRejected) {
  const std::string e = rig_error(GetParam().text);
  EXPECT_NE(e.find(GetParam().message), std::string::npos) << e;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RigMalformed,
    ::testing::Values(
        BadRig{"empty", "", "rig.yaml: empty input: expected an OpenCV rig YAML file"},
        BadRig{"not_yaml", "this is not: [yaml", "rig.yaml:1: not an OpenCV rig YAML file"},
        BadRig{"a_camera_file", good_yaml(), "rig.yaml: missing key 'rig_cameras'"},
        BadRig{"no_cameras", with(good_rig(), "rig_cameras: 2", "rig_cameras: 0"), "rig.yaml:4: rig_cameras: 0; a rig has 1 to 64"},
        BadRig{"missing_camera", with(good_rig(), "rig_cameras: 2", "rig_cameras: 3"), "missing key 'camera_2_prefix'"},
        BadRig{"extra_camera", with(good_rig(), "rig_cameras: 2", "rig_cameras: 1"), "is for camera 1 but rig_cameras is 1"},
        BadRig{"stray_camera_key", good_rig() + "camera_3_image_width: 640\n", "'camera_3_image_width' is for camera 3 but rig_cameras is 2"},
        BadRig{"misspelt_sigma", with(good_rig(), "camera_1_cam_from_rig_sigma:", "camera_1_cam_from_rig_sigmas:"), "unknown key 'camera_1_cam_from_rig_sigmas'"},
        BadRig{"padded_index", with(good_rig(), "camera_1_prefix", "camera_01_prefix"), "unknown key 'camera_01_prefix'"},
        BadRig{"unknown_rig_key", good_rig() + "rig_baseline: 3\n", "unknown key 'rig_baseline'"},
        BadRig{"space_prefix", with(good_rig(), "\"cams/right_\"", "\" \""), "camera 1's prefix holds a quote, a backslash, a control character or a leading or trailing space"},
        BadRig{"huge_translation", with(good_rig(), "-83.6123456789", "1e300"), "camera 1's pose in the rig has a non-finite or implausible value"},
        BadRig{"same_prefix", with(good_rig(), "\"cams/right_\"", "\"left\""), "rig.yaml:29: cameras 0 and 1 have the same image name prefix 'left'"},
        BadRig{"empty_prefix", with(good_rig(), "\"cams/right_\"", "\"\""), "camera 1 has an empty image name prefix"},
        BadRig{"quote_in_prefix", with(good_rig(), "\"cams/right_\"", "\"a\"b\""), "is not a plain quoted string"},
        BadRig{"not_rotation", with(good_rig(), "camera_0_cam_from_rig_rotation: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.", "camera_0_cam_from_rig_rotation: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 2."), "camera 0's cam_from_rig_rotation is not a rotation matrix"},
        BadRig{"nan_translation", with(good_rig(), "-83.6123456789", ".nan"), "camera 1's pose in the rig has a non-finite or implausible value"},
        BadRig{"short_translation", with(good_rig(), "cam_from_rig_translation_mm: !!opencv-matrix\n   rows: 3", "cam_from_rig_translation_mm: !!opencv-matrix\n   rows: 2"), "data has 3 values; rows x cols = 2 x 1 needs 2"},
        BadRig{"negative_sigma", with(good_rig(), "[ 0.01, 0.02", "[ -0.01, 0.02"), "camera 1's cam_from_rig_sigma must be 6 non-negative numbers"},
        BadRig{"bad_camera", with(good_rig(), "camera_1_image_width: 2000", "camera_1_image_width: 0"), "rig.yaml (camera_1): image size 0x1500 is not plausible"},
        BadRig{"misspelt_matrix", with(good_rig(), "camera_1_camera_matrix", "camera_1_camera_matrixx"), "rig.yaml:32: unknown key 'camera_1_camera_matrixx'"},
        BadRig{"missing_matrix", with(good_rig(), "camera_1_camera_matrix", "other_camera_matrix"), "missing key 'camera_1_camera_matrix'"}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill
