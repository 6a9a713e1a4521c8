// calib on the real OpenCV photos (reference values in ../shared/data/README.md), the detect | calib
// pipe, the report and plot outputs, and golden CLI cases (bad input names file and line, exit
// codes, no output left behind on failure).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "calib/calibrate.hpp"
#include "calib/rig.hpp"
#include "detect/boards.hpp"
#include "formats/camera.hpp"
#include "tests/run_tool.hpp"

namespace photomill::calib {
namespace {

const std::string kData = std::string(PHOTOMILL_SHARED_DIR) + "/data";

std::vector<std::string> images(const std::string& folder, const std::string& prefix, std::vector<int> numbers) {
  std::vector<std::string> out;
  for (int n : numbers) {
    std::ostringstream s;
    s << kData << "/" << folder << "/" << prefix << (n < 10 ? "0" : "") << n << ".jpg";
    out.push_back(s.str());
  }
  return out;
}

const std::vector<int> kChessboardNumbers{1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14};

// OpenCV's corners (findChessboardCorners + cornerSubPix 11 x 11, no window check): the
// README's references were computed from them.
detect::BoardDetectOptions opencv_corners() {
  detect::BoardDetectOptions o;
  o.chessboard_window_check_px = 0;
  return o;
}

std::vector<Observation> detect_all(const std::vector<std::string>& files, const detect::BoardSpec& spec,
                                    const detect::BoardDetectOptions& options = opencv_corners()) {
  std::vector<Observation> obs;
  for (const auto& r : detect::detect_boards(files, spec, options)) {
    EXPECT_TRUE(r.found) << r.image;
    obs.insert(obs.end(), r.observations.begin(), r.observations.end());
  }
  return obs;
}

struct ReferenceCase {
  const char* name;
  const char* prefix;
  double rms_px, fx, fy;   // the README's reference row
  const char* worst;       // the view with the largest RMS in the all-view calibration
};

void PrintTo(const ReferenceCase& c, std::ostream* os) { *os << c.name; }

class OpenCvChessboard : public ::testing::TestWithParam<ReferenceCase> {};

// With every view (the first pass) we reproduce Debian OpenCV 4.6's reference: RMS within 1 %,
// fx and fy within 0.3 %; the worst view is named; rejection then removes it.
TEST_P(OpenCvChessboard, ReproducesTheReferenceAndFlagsTheWorstView) {
  const auto& c = GetParam();
  detect::BoardSpec spec;
  spec.cols = 9;
  spec.rows = 6;
  const auto obs = detect_all(images("opencv-chessboard", c.prefix, kChessboardNumbers), spec);
  const auto r = calibrate(obs, detect::board_control_points(spec), {640, 480}, {});
  EXPECT_LT(std::abs(r.rms_all_views_px / c.rms_px - 1), 0.01) << r.rms_all_views_px;
  EXPECT_LT(std::abs(r.camera_all_views.fx() / c.fx - 1), 0.003) << r.camera_all_views.fx();
  EXPECT_LT(std::abs(r.camera_all_views.fy() / c.fy - 1), 0.003) << r.camera_all_views.fy();
  const auto worst = std::max_element(r.views.begin(), r.views.end(),
                                      [](const ViewReport& a, const ViewReport& b) { return a.first_rms_px < b.first_rms_px; });
  EXPECT_NE(worst->image.find(c.worst), std::string::npos) << worst->image;
  EXPECT_TRUE(worst->rejected);
  EXPECT_LT(r.rms_px, r.rms_all_views_px);
  // The camera stays close to the reference: within 1 % for the focal length.
  EXPECT_LT(std::abs(r.camera.fx() / c.fx - 1), 0.01);
}

INSTANTIATE_TEST_SUITE_P(Sets, OpenCvChessboard,
                         ::testing::Values(ReferenceCase{"left", "left", 0.40877, 536.074, 536.017, "left02"},
                                           ReferenceCase{"right", "right", 0.45872, 542.356, 541.616, "right02"}),
                         [](const auto& info) { return std::string(info.param.name); });

// The four real ChArUco calibration photos: RMS 0.17-0.20 px, focal length within 3 % of Debian
// OpenCV 4.6's calibrateCameraCharuco (fx 460.8, fy 463.6; four views fix it only to ~2 %).
TEST(OpenCvCharuco, FourPhotosCalibrate) {
  detect::BoardSpec spec;
  spec.kind = detect::BoardKind::Charuco;
  spec.cols = 5;
  spec.rows = 7;
  spec.square_mm = 40;
  spec.marker_mm = 20;
  std::vector<std::string> files;
  for (int i = 0; i < 4; ++i) files.push_back(kData + "/opencv-aruco/img_0" + std::to_string(i) + ".jpg");
  const auto r = calibrate(detect_all(files, spec), detect::board_control_points(spec), {640, 480}, {});
  EXPECT_GE(r.rms_px, 0.17);
  EXPECT_LE(r.rms_px, 0.20);
  EXPECT_LT(std::abs(r.camera.fx() / 460.8 - 1), 0.03) << r.camera.fx();
  EXPECT_LT(std::abs(r.camera.fy() / 463.6 - 1), 0.03) << r.camera.fy();
  for (const auto& v : r.views) EXPECT_FALSE(v.rejected) << v.image;
  // Four views at one orientation: calib says the geometry is weak.
  std::string all;
  for (const auto& w : r.warnings) all += w + "\n";
  EXPECT_NE(all.find("same orientation"), std::string::npos) << all;
}

// The pipe of the issue, through the executables: detect ... | calib --chessboard 9x6.
TEST(Pipe, DetectIntoCalibWritesCameraReportAndPlot) {
  // OpenCV's corners, with which left02 is the outlier view calib rejects.
  std::vector<std::string> args{"--chessboard", "9x6", "--chessboard-window-check", "0", "-q"};
  for (const auto& f : images("opencv-chessboard", "left", kChessboardNumbers)) args.push_back(f);
  const auto d = test::run_tool("detect", args);
  ASSERT_EQ(d.exit_code, 0) << d.err;
  test::TempDir dir;
  const auto cam = dir.path() / "cam.yaml";
  const auto json = dir.path() / "report.json";
  const auto png = dir.path() / "res.png";
  const auto c = test::run_tool("calib", {"--chessboard", "9x6", "--square-mm", "25", "-o", cam.string(), "--report",
                                          json.string(), "--plot", png.string()},
                                d.out);
  ASSERT_EQ(c.exit_code, 0) << c.err;
  EXPECT_EQ(c.out, "");
  EXPECT_NE(c.err.find("left02.jpg"), std::string::npos);
  EXPECT_NE(c.err.find("REJECTED"), std::string::npos) << c.err;
  EXPECT_NE(c.err.find("worst view: " + kData + "/opencv-chessboard/left02.jpg"), std::string::npos) << c.err;
  EXPECT_NE(c.err.find("residual vectors drawn x"), std::string::npos) << c.err;
  std::ifstream in(cam);
  const Camera camera = read_camera_yaml(in, cam.string());
  EXPECT_EQ(camera.image_width_px, 640);  // read from the images the observations name
  EXPECT_EQ(camera.distortion.size(), 5u);
  EXPECT_LT(std::abs(camera.fx() / 536.074 - 1), 0.01);
  const std::string report = test::read_file(json);
  for (const char* key : {"\"rms_px\"", "\"rms_all_views_px\"", "\"camera_all_views\"", "\"std_dev\"", "\"views\"",
                          "\"rejected\":true", "\"warnings\"", "\"optimizer_stats\"", "left02.jpg\",\"skipped_views\""}) {
    EXPECT_NE(report.find(key), std::string::npos) << key;
  }
  const cv::Mat plot = cv::imread(png.string());
  ASSERT_FALSE(plot.empty());
  EXPECT_GT(plot.cols, 1000);
}

// Golden cases: args, stdin, exit code, a substring of stderr; stdout must stay empty on failure.
struct CliCase {
  const char* name;
  std::vector<std::string> args;
  std::string stdin_text;
  int exit_code;
  std::string stderr_has;
};

void PrintTo(const CliCase& c, std::ostream* os) { *os << c.name; }

class CalibCli : public ::testing::TestWithParam<CliCase> {};

TEST_P(CalibCli, GoldenCase) {
  const auto& c = GetParam();
  const auto r = test::run_tool("calib", c.args, c.stdin_text);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  if (c.exit_code != 0) {
    EXPECT_EQ(r.out, "");
  }
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
}

const std::string kHeader = "image,point_id,u_px,v_px\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, CalibCli,
    ::testing::Values(
        CliCase{"missing_observations", {"--chessboard", "9x6", "/nonexistent/obs.csv"}, "", 1, "/nonexistent/obs.csv"},
        CliCase{"malformed_line", {"--chessboard", "9x6", "--image-size", "640x480"}, kHeader + "a.jpg,0,1,2\na.jpg,1,2\n",
                1, "<stdin>:3:"},
        CliCase{"missing_control_file", {"--control", "/nonexistent/ctl.csv"}, kHeader, 1, "/nonexistent/ctl.csv"},
        CliCase{"no_control", {"--image-size", "640x480"}, kHeader, 2, "--control FILE"},
        CliCase{"two_controls", {"--chessboard", "9x6", "--charuco", "5x7"}, kHeader, 2, "excludes"},
        CliCase{"unknown_optimizer", {"--chessboard", "9x6", "--optimizer", "newton"}, kHeader, 2, "newton"},
        CliCase{"image_size_unknown", {"--chessboard", "9x6"}, kHeader + "nowhere.jpg,0,1,2\n", 2, "--image-size"},
        // A size that cannot hold the observations (1 x 1 was accepted, exit 0): usage error.
        CliCase{"image_size_too_small", {"--chessboard", "9x6", "--image-size", "1x1"},
                kHeader + "a.jpg,0,1,2\n", 2, "point 0 of a.jpg at (1, 2) px lies off a 1 x 1 px image"},
        CliCase{"observation_beyond_the_image", {"--chessboard", "9x6", "--image-size", "640x480"},
                kHeader + "a.jpg,0,1,2\na.jpg,1,639.6,2\n", 2, "point 1 of a.jpg at (639.6, 2) px lies off"},
        // The size read from the image the observations name (640 x 480) does not hold them: input error.
        CliCase{"observation_beyond_the_image_file", {"--chessboard", "9x6"},
                kHeader + kData + "/opencv-chessboard/left01.jpg,0,700,2\n", 1,
                "at (700, 2) px lies off a 640 x 480 px image (its size read from the image file)"},
        CliCase{"no_matching_ids", {"--chessboard", "3x3", "--image-size", "640x480"}, kHeader + "a.jpg,99,1,2\n", 1,
                "no observation refers to a control point"},
        CliCase{"too_few_points", {"--chessboard", "9x6", "--image-size", "640x480"},
                kHeader + "a.jpg,0,1,2\na.jpg,1,5,2\na.jpg,2,9,2\n", 1, "no view has the 6 control points"},
        // Rigs (issue 23): one prefix is no rig; every photo must belong to one of its cameras.
        CliCase{"rig_of_one", {"--chessboard", "9x6", "--image-size", "640x480", "--rig", "left"},
                kHeader + "left01.jpg,0,1,2\n", 2, "--rig: give two image name prefixes or more"},
        CliCase{"rig_unknown_image", {"--chessboard", "9x6", "--image-size", "640x480", "--rig", "left", "--rig", "right"},
                kHeader + "left01.jpg,0,1,2\nright01.jpg,0,1,2\nmiddle01.jpg,0,1,2\n", 1,
                "<stdin>: image 'middle01.jpg' starts with none of the rig's prefixes ('left', 'right')"},
        CliCase{"rig_camera_without_images", {"--chessboard", "9x6", "--image-size", "640x480", "--rig", "left", "--rig", "right"},
                kHeader + "left01.jpg,0,1,2\n", 1, "no image starts with camera 1's prefix 'right'"},
        CliCase{"rig_and_plot", {"--chessboard", "9x6", "--rig", "left", "--rig", "right", "--plot", "x.png"},
                kHeader, 2, "excludes"}),
    [](const auto& info) { return std::string(info.param.name); });

// OpenCV's stereo pairs as a rig (../shared/data/README.md, "Stereo reference"). With every view
// kept (--reject-factor 0: the intrinsics of the README's two default calibrations) and the
// intrinsics held (--rig-fix-intrinsics) the rig is stereoCalibrate's with CALIB_FIX_INTRINSIC;
// by default (outlier views rejected, intrinsics adjusted with the rig) the baseline stays within
// issue 23's 0.5 %.
TEST(OpenCvStereo, RigReproducesStereoCalibrate) {
  detect::BoardSpec spec;
  spec.cols = 9;
  spec.rows = 6;
  auto obs = detect_all(images("opencv-chessboard", "left", kChessboardNumbers), spec);
  const auto right = detect_all(images("opencv-chessboard", "right", kChessboardNumbers), spec);
  obs.insert(obs.end(), right.begin(), right.end());
  RigCalibOptions all;
  all.camera.reject_factor = 0;
  all.fix_intrinsics = true;
  const RigResult r = calibrate_rig(obs, detect::board_control_points(spec), {"left", "right"}, {{640, 480}, {640, 480}},
                                    all, "obs");
  ASSERT_EQ(r.rig.cameras.size(), 2u);
  const RigCamera& c = r.rig.cameras[1];
  const Eigen::Vector3d t = c.cam_from_rig_translation_mm;
  EXPECT_NEAR(t.x(), -3.34425, 5e-5);
  EXPECT_NEAR(t.y(), 0.04172, 5e-5);
  EXPECT_NEAR(t.z(), 0.05298, 5e-5);
  EXPECT_NEAR(t.norm(), 3.34493, 5e-5);
  const Eigen::AngleAxisd aa(c.cam_from_rig_rotation);
  EXPECT_NEAR(aa.angle() * 180 / 3.14159265358979323846, 0.312, 5e-4);
  // The README gives the axis to 3 decimals (within ~0.1 degree).
  EXPECT_GT(aa.axis().dot(Eigen::Vector3d(0.049, 0.649, -0.759).normalized()), 0.99998);
  EXPECT_NEAR(r.rms_px, 0.44786, 1e-4);
  for (const auto& f : r.frames) EXPECT_TRUE(f.used) << f.frame;
  ASSERT_TRUE(c.cam_from_rig_sigma);
  // The baseline's sigma is a few thousandths of a square: OpenCV's value lies within 3 of it.
  EXPECT_GT(r.baseline_sigma_mm[1], 1e-4);
  EXPECT_LT(r.baseline_sigma_mm[1], 0.02);

  const RigResult d = calibrate_rig(obs, detect::board_control_points(spec), {"left", "right"}, {{640, 480}, {640, 480}},
                                    {}, "obs");
  const double baseline = d.rig.cameras[1].cam_from_rig_translation_mm.norm();
  EXPECT_LT(std::abs(baseline / 3.34493 - 1), 0.005) << baseline;
  EXPECT_LT(d.rms_px, r.rms_px);  // the views with ~1.2 px residuals are left out
  bool pair02_out = false;
  for (const auto& f : d.frames) pair02_out |= f.frame.find("02.jpg") != std::string::npos && !f.used;
  EXPECT_TRUE(pair02_out);
}

// The rig's worth for measuring: every pair triangulated from the rig alone (undistortPoints,
// P1 = [I | 0], P2 = [R | t], triangulatePoints; no board geometry), then the 93 neighbour
// distances per pair, which are 1 square. The README's reference (stereoCalibrate with
// CALIB_FIX_INTRINSIC): mean 1.00135, std 0.01554 over the 1 209 distances.
struct Spacing {
  double mean = 0, std = 0;
  std::size_t count = 0;
};

Spacing neighbour_spacing(const Rig& rig, const std::vector<Observation>& obs) {
  std::map<std::string, std::map<PointId, cv::Point2d>> by_image;
  for (const auto& o : obs) by_image[o.image][o.point_id] = {o.u_px, o.v_px};
  auto K = [](const Camera& c) {
    cv::Mat k(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r) for (int col = 0; col < 3; ++col) k.at<double>(r, col) = c.camera_matrix(r, col);
    return k;
  };
  cv::Mat P2(3, 4, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) P2.at<double>(r, col) = rig.cameras[1].cam_from_rig_rotation(r, col);
    P2.at<double>(r, 3) = rig.cameras[1].cam_from_rig_translation_mm[r];
  }
  const cv::Mat P1 = cv::Mat::eye(3, 4, CV_64F);
  std::vector<double> d;
  for (const auto& [image, left] : by_image) {
    const auto slash = image.find_last_of('/');
    if (image.compare(slash + 1, 4, "left") != 0) continue;
    const auto& right = by_image.at(image.substr(0, slash + 1) + "right" + image.substr(slash + 5));
    std::vector<cv::Point2d> l, r;
    for (PointId id = 0; id < 54; ++id) l.push_back(left.at(id)), r.push_back(right.at(id));
    std::vector<cv::Point2d> lu, ru;
    cv::undistortPoints(l, lu, K(rig.cameras[0].camera), rig.cameras[0].camera.distortion);
    cv::undistortPoints(r, ru, K(rig.cameras[1].camera), rig.cameras[1].camera.distortion);
    cv::Mat X;
    cv::triangulatePoints(P1, P2, lu, ru, X);
    auto point = [&](int i) {
      const double w = X.at<double>(3, i);
      return cv::Point3d(X.at<double>(0, i) / w, X.at<double>(1, i) / w, X.at<double>(2, i) / w);
    };
    for (int row = 0; row < 6; ++row) {
      for (int col = 0; col < 9; ++col) {
        const int i = row * 9 + col;
        if (col + 1 < 9) d.push_back(cv::norm(point(i + 1) - point(i)));
        if (row + 1 < 6) d.push_back(cv::norm(point(i + 9) - point(i)));
      }
    }
  }
  Spacing s;
  s.count = d.size();
  for (double v : d) s.mean += v / static_cast<double>(d.size());
  for (double v : d) s.std += (v - s.mean) * (v - s.mean) / static_cast<double>(d.size() - 1);
  s.std = std::sqrt(s.std);
  return s;
}

// detect's window check (its default) frees 32 of the 1 404 corners of OpenCV's stereo photos
// from another edge inside cornerSubPix's window (left02/right02 hold 12 of them): every view is
// then kept, each camera's residual falls by more than half, and the pairs triangulated from the
// rig measure the board twice as well as from OpenCV's corners. The baseline moves with the
// corners: stereoCalibrate's own procedure (every view, intrinsics held) on the checked corners
// gives 3.3283 squares, 0.50 % from the README's 3.34493 made from OpenCV's corners; calib's
// default rig agrees with it to 0.05 %.
TEST(OpenCvStereo, CheckedCornersKeepEveryViewAndMeasureTheBoardBetter) {
  detect::BoardSpec spec;
  spec.cols = 9;
  spec.rows = 6;
  auto obs = detect_all(images("opencv-chessboard", "left", kChessboardNumbers), spec, {});
  const auto right = detect_all(images("opencv-chessboard", "right", kChessboardNumbers), spec, {});
  obs.insert(obs.end(), right.begin(), right.end());
  for (const char* side : {"left", "right"}) {
    std::vector<Observation> one;
    for (const auto& o : obs) {
      if (o.image.find(std::string("/") + side) != std::string::npos) one.push_back(o);
    }
    const auto r = calibrate(one, detect::board_control_points(spec), {640, 480}, {});
    for (const auto& v : r.views) EXPECT_FALSE(v.rejected) << v.image;
    // Measured 0.176 (left) and 0.182 px (right), against 0.409 and 0.459 from OpenCV's corners.
    EXPECT_LT(r.rms_all_views_px, 0.2) << side;
  }
  RigCalibOptions stereo_calibrate;
  stereo_calibrate.camera.reject_factor = 0;
  stereo_calibrate.fix_intrinsics = true;
  const RigResult s = calibrate_rig(obs, detect::board_control_points(spec), {"left", "right"},
                                    {{640, 480}, {640, 480}}, stereo_calibrate, "obs");
  const RigResult d = calibrate_rig(obs, detect::board_control_points(spec), {"left", "right"},
                                    {{640, 480}, {640, 480}}, {}, "obs");
  const double bs = s.rig.cameras[1].cam_from_rig_translation_mm.norm();
  const double bd = d.rig.cameras[1].cam_from_rig_translation_mm.norm();
  EXPECT_LT(s.rms_px, 0.25);  // 0.196 px; 0.448 from OpenCV's corners
  EXPECT_LT(std::abs(bd / bs - 1), 0.001) << bd << " " << bs;
  for (const auto& f : d.frames) EXPECT_TRUE(f.used) << f.frame;
  const Spacing sp = neighbour_spacing(d.rig, obs);
  std::cout << "checked corners: stereoCalibrate's baseline " << bs << ", calib's " << bd << "; " << sp.count
            << " distances, mean " << sp.mean << ", std " << sp.std << "\n";
  EXPECT_EQ(sp.count, 1209u);
  EXPECT_LE(std::abs(sp.mean - 1), 0.0014);
  EXPECT_LT(sp.std, 0.01);  // 0.01554 in the README's reference
}

TEST(OpenCvStereo, TheRigMeasuresTheBoard) {
  detect::BoardSpec spec;
  spec.cols = 9;
  spec.rows = 6;
  auto obs = detect_all(images("opencv-chessboard", "left", kChessboardNumbers), spec);
  const auto right = detect_all(images("opencv-chessboard", "right", kChessboardNumbers), spec);
  obs.insert(obs.end(), right.begin(), right.end());
  for (bool fix : {true, false}) {
    for (double reject : {0.0, 3.0}) {
      RigCalibOptions o;
      o.fix_intrinsics = fix;
      o.camera.reject_factor = reject;
      const RigResult r = calibrate_rig(obs, detect::board_control_points(spec), {"left", "right"},
                                        {{640, 480}, {640, 480}}, o, "obs");
      const Spacing s = neighbour_spacing(r.rig, obs);
      std::cout << "fix_intrinsics " << fix << " reject_factor " << reject << ": baseline "
                << r.rig.cameras[1].cam_from_rig_translation_mm.norm() << ", " << s.count << " distances, mean "
                << s.mean << ", std " << s.std << "\n";
      EXPECT_EQ(s.count, 1209u);
      if (fix && reject == 0) {  // stereoCalibrate's rig: the README's figures
        EXPECT_NEAR(s.mean, 1.00135, 2e-5);
        EXPECT_NEAR(s.std, 0.01554, 2e-5);
      }
      if (!fix && reject > 0) {  // calib's defaults: issue 23's bounds
        EXPECT_LE(std::abs(s.mean - 1), 0.0014);
        EXPECT_LE(s.std, 0.0155);
      }
    }
  }
}

// The pipe with a rig: detect | calib --rig left --rig right writes rig.yaml, which reads back.
TEST(Pipe, DetectIntoCalibWritesARig) {
  std::vector<std::string> args{"--chessboard", "9x6", "-q"};
  for (const auto& f : images("opencv-chessboard", "left", {1, 3, 4, 6, 7})) args.push_back(f);
  for (const auto& f : images("opencv-chessboard", "right", {1, 3, 4, 6, 7})) args.push_back(f);
  const auto d = test::run_tool("detect", args);
  ASSERT_EQ(d.exit_code, 0) << d.err;
  test::TempDir dir;
  const auto rig_path = dir.path() / "rig.yaml";
  const auto json = dir.path() / "rig.json";
  const auto c = test::run_tool("calib", {"--chessboard", "9x6", "--rig", "left", "--rig", "right", "-o",
                                          rig_path.string(), "--report", json.string()},
                                d.out);
  ASSERT_EQ(c.exit_code, 0) << c.err;
  EXPECT_NE(c.err.find("camera 1 ('right') from camera 0: rotation"), std::string::npos) << c.err;
  std::ifstream in(rig_path);
  const Rig rig = read_rig_yaml(in, rig_path.string());
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.cameras[1].prefix, "right");
  EXPECT_EQ(rig.cameras[1].camera.image_width_px, 640);
  EXPECT_LT(std::abs(rig.cameras[1].cam_from_rig_translation_mm.norm() / 3.34493 - 1), 0.01);
  const std::string report = test::read_file(json);
  for (const char* key : {"\"baseline_mm\"", "\"baseline_sigma_mm\"", "\"sigma_rotation_deg\"", "\"frames\""}) {
    EXPECT_NE(report.find(key), std::string::npos) << key;
  }
  // --rig-fix-intrinsics keeps each camera's own calibration (here the left camera's, made
  // alone from the same photos); by default the rig adjustment moves it.
  std::string left_only;
  {
    std::istringstream in(d.out);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("image,", 0) == 0 || line.find("/left") != std::string::npos) left_only += line + "\n";
    }
  }
  const auto cam_path = dir.path() / "left.yaml";
  ASSERT_EQ(test::run_tool("calib", {"--chessboard", "9x6", "-q", "-o", cam_path.string()}, left_only).exit_code, 0);
  std::ifstream cam_in(cam_path);
  const Camera left = read_camera_yaml(cam_in, cam_path.string());
  const auto fixed_path = dir.path() / "fixed.yaml";
  const auto f = test::run_tool("calib", {"--chessboard", "9x6", "--rig", "left", "--rig", "right", "--rig-fix-intrinsics",
                                          "-q", "-o", fixed_path.string()},
                                d.out);
  ASSERT_EQ(f.exit_code, 0) << f.err;
  std::ifstream fixed_in(fixed_path);
  const Rig fixed = read_rig_yaml(fixed_in, fixed_path.string());
  EXPECT_EQ(fixed.cameras[0].camera.camera_matrix, left.camera_matrix);
  EXPECT_NE(rig.cameras[0].camera.camera_matrix, left.camera_matrix);
}

// A board given to the DLT: a GeometryError explains why, exit 1, and no camera file is left.
TEST(CalibCliFiles, DegenerateInputLeavesNoOutput) {
  std::vector<std::string> args{"--chessboard", "9x6", "-q"};
  for (const auto& f : images("opencv-chessboard", "left", {1, 3, 4})) args.push_back(f);
  const auto d = test::run_tool("detect", args);
  ASSERT_EQ(d.exit_code, 0);
  test::TempDir dir;
  const auto cam = dir.path() / "cam.yaml";
  const auto r = test::run_tool("calib", {"--chessboard", "9x6", "--method", "dlt", "-o", cam.string()}, d.out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("coplanar"), std::string::npos) << r.err;
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 0);
}

}  // namespace
}  // namespace photomill::calib
