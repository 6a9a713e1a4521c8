// detect --draw: the drawings of markers, features and board corners over the photos (draw.hpp).
// Photos: data/demo and ../shared/data/opencv-chessboard. Library: a drawing has the expected size and shows the marks in colour over the grey photo.
// Command line: every mode writes one decodable picture per photo of the expected size, in
// parallel runs too; a failed run leaves none; '-' (stdout) is refused.
#include "detect/draw.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <tuple>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::detect {
namespace {

namespace fs = std::filesystem;
using photomill::test::run_tool;
using photomill::test::TempDir;

std::string demo(const std::string& name) { return std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/" + name; }
std::string chessboard(const std::string& name) {
  return std::string(PHOTOMILL_SHARED_DIR) + "/data/opencv-chessboard/" + name;
}

// Pixels of a clearly saturated colour: the photo is drawn in grey, so these are the marks.
int coloured(const cv::Mat& bgr) {
  int n = 0;
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b c = bgr.at<cv::Vec3b>(y, x);
      n += std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]}) > 60 ? 1 : 0;
    }
  }
  return n;
}

// Pixels close to a colour (BGR).
int near_colour(const cv::Mat& bgr, cv::Vec3b want, int tolerance = 40) {
  int n = 0;
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b c = bgr.at<cv::Vec3b>(y, x);
      n += std::abs(c[0] - want[0]) + std::abs(c[1] - want[1]) + std::abs(c[2] - want[2]) < tolerance ? 1 : 0;
    }
  }
  return n;
}

TEST(Draw, MarkersOverTheDemoPhoto) {
  const cv::Mat grey = cv::imread(demo("part_03.jpg"), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(grey.empty());
  const MarkerDetection m = detect_markers(grey, "part_03.jpg", MarkerDictionary::predefined("DICT_4X4_100"), {});
  ASSERT_GE(m.marker_ids.size(), 15u);

  DrawOptions o;  // default: at most 1600 px wide
  const cv::Mat small = draw_photo(grey, &m, nullptr, o);
  EXPECT_EQ(small.type(), CV_8UC3);
  EXPECT_EQ(small.cols, 1600);
  EXPECT_EQ(small.rows, 1200);
  // Every marker's outline (green) and its four corner colours are there.
  EXPECT_GT(near_colour(small, {0, 220, 0}), static_cast<int>(m.marker_ids.size()) * 200) << "marker outlines";
  for (const cv::Vec3b& corner : {cv::Vec3b(40, 40, 255), cv::Vec3b(0, 230, 255), cv::Vec3b(255, 120, 0), cv::Vec3b(255, 0, 255)}) {
    EXPECT_GT(near_colour(small, corner), static_cast<int>(m.marker_ids.size()) * 15) << "corner colour " << corner;
  }

  // Rulers in photo px along the bottom and right edges: white ticks (the dimmed photo stays
  // below 211) in the last rows and columns, numbered.
  const auto bright = [](const cv::Mat& m) {
    int n = 0;
    for (int y = 0; y < m.rows; ++y) {
      for (int x = 0; x < m.cols; ++x) n += std::min({m.at<cv::Vec3b>(y, x)[0], m.at<cv::Vec3b>(y, x)[1], m.at<cv::Vec3b>(y, x)[2]}) > 225;
    }
    return n;
  };
  EXPECT_GT(bright(small(cv::Rect(0, small.rows - 8, small.cols, 8))), 20) << "u ruler ticks";
  EXPECT_GT(bright(small(cv::Rect(small.cols - 8, 0, 8, small.rows))), 20) << "v ruler ticks";

  o.max_width_px = 0;  // full size
  const cv::Mat full = draw_photo(grey, &m, nullptr, o);
  EXPECT_EQ(full.cols, grey.cols);
  EXPECT_EQ(full.rows, grey.rows);

  // Features add their circles.
  FeatureSet f;
  f.image = "part_03.jpg";
  for (int k = 0; k < 400; ++k) f.keypoints.push_back({100.0 + 4.5 * k, 300.0 + 2.0 * k, 8, 0, 1});
  const cv::Mat with_features = draw_photo(grey, &m, &f, DrawOptions{});
  EXPECT_GT(near_colour(with_features, {255, 230, 0}), 1000) << "feature circles";
}

TEST(Draw, BoardCornersOverAChessboardPhoto) {
  const cv::Mat grey = cv::imread(chessboard("left01.jpg"), cv::IMREAD_GRAYSCALE);
  if (grey.empty()) GTEST_SKIP() << "no ../shared/data/opencv-chessboard";
  BoardSpec spec;
  spec.cols = 9, spec.rows = 6;
  const ImageDetection d = detect_board(grey, "left01.jpg", spec, {});
  ASSERT_TRUE(d.found);
  const cv::Mat img = draw_board(grey, d, spec, DrawOptions{});
  EXPECT_EQ(img.cols, grey.cols) << "smaller photos are not scaled";
  EXPECT_EQ(img.rows, grey.rows);
  EXPECT_GT(coloured(img), 54 * 30) << "54 corners with ids and 6 row lines";
}

TEST(Draw, RejectsBadOptions) {
  for (const auto& [format, width, dir] : {std::tuple{"gif", 1600, "d"}, std::tuple{"jpg", -1, "d"},
                                           std::tuple{"jpg", 50, "d"}, std::tuple{"png", 1600, "-"}}) {
    DrawOptions o;
    o.format = format, o.max_width_px = width, o.dir = dir;
    EXPECT_THROW(validate(o), UsageError) << format << " " << width << " " << dir;
  }
}

// One command line ("DIR": the drawings folder, "FEAT": a features folder) and the drawings it
// must write (file name, width, height).
struct DrawCase {
  const char* name;
  std::vector<std::string> args;  // "DIR" stands for the drawings folder
  std::vector<std::tuple<std::string, int, int>> files;
};
void PrintTo(const DrawCase& c, std::ostream* os) { *os << c.name; }

class DetectDraw : public ::testing::TestWithParam<DrawCase> {};

TEST_P(DetectDraw, WritesOnePicturePerPhoto) {
  const DrawCase& c = GetParam();
  TempDir tmp;
  const fs::path dir = tmp.path() / "drawings";
  std::vector<std::string> args;
  for (const auto& a : c.args) args.push_back(a == "DIR" ? dir.string() : a == "FEAT" ? (tmp.path() / "feat").string() : a);
  args.insert(args.end(), {"-o", (tmp.path() / "out.csv").string()});
  const auto r = run_tool("detect", args);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "") << "drawings never go to stdout";
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    ++files;
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << "temporary left: " << e.path();
  }
  EXPECT_EQ(files, c.files.size());
  for (const auto& [name, width, height] : c.files) {
    const cv::Mat img = cv::imread((dir / name).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty()) << name << " missing or not an image";
    EXPECT_EQ(img.cols, width) << name;
    EXPECT_EQ(img.rows, height) << name;
    EXPECT_GT(coloured(img), 2000) << name << ": no marks drawn";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Detect, DetectDraw,
    ::testing::Values(
        DrawCase{"markers_parallel",
                 {"--aruco", "DICT_4X4_100", "--draw", "DIR", "-j", "2", demo("part_00.jpg"), demo("part_03.jpg"),
                  demo("part_07.jpg")},
                 {{"part_00.jpg", 1600, 1200}, {"part_03.jpg", 1600, 1200}, {"part_07.jpg", 1600, 1200}}},
        DrawCase{"markers_features_png",
                 {"--aruco", "DICT_4X4_100", "--features", "FEAT", "--mask-markers", "--max-features", "500", "--draw", "DIR",
                  "--draw-format", "png", "--draw-max-width-px", "800", demo("part_05.jpg")},
                 {{"part_05.png", 800, 600}}},
        DrawCase{"charuco_full_size",
                 {"--charuco", "7x5", "--dict", "DICT_5X5_100", "--square-mm", "30", "--marker-mm", "22", "--draw",
                  "DIR", "--draw-max-width-px", "0", demo("board_00.jpg"), demo("board_01.jpg")},
                 {{"board_00.jpg", 2000, 1500}, {"board_01.jpg", 2000, 1500}}}));

// A drawing is named by the photo's stem and its own extension (part_05.jpg -> part_05.jpg):
// two photos of one stem in one run would write one file, and are refused before any work.
TEST(Draw, TwoPhotosOfOneStemAreRefused) {
  TempDir tmp;
  const fs::path dir = tmp.path() / "drawings";
  fs::copy_file(demo("part_00.jpg"), tmp.path() / "part_00.png");
  const auto r = run_tool("detect", {"--aruco", "DICT_4X4_100", "--draw", dir.string(), demo("part_00.jpg"),
                                     (tmp.path() / "part_00.png").string(), "-o", (tmp.path() / "out.csv").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("would both write part_00.jpg"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "out.csv"));
  EXPECT_TRUE(!fs::exists(dir) || fs::is_empty(dir));
}

// A failed run leaves no drawing: the pictures of the photos done before the failure are removed.
struct FailCase {
  const char* name;
  std::vector<std::string> args;
  int exit_code;
};
void PrintTo(const FailCase& c, std::ostream* os) { *os << c.name; }

class DetectDrawFails : public ::testing::TestWithParam<FailCase> {};

TEST_P(DetectDrawFails, LeavesNoPicture) {
  const FailCase& c = GetParam();
  TempDir tmp;
  const fs::path dir = tmp.path() / "drawings";
  std::vector<std::string> args;
  for (const auto& a : c.args) args.push_back(a == "DIR" ? dir.string() : a == "BAD" ? (tmp.path() / "bad.jpg").string() : a);
  std::ofstream(tmp.path() / "bad.jpg") << "not an image";
  args.insert(args.end(), {"-o", (tmp.path() / "out.csv").string()});
  const auto r = run_tool("detect", args);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_FALSE(fs::exists(tmp.path() / "out.csv"));
  if (fs::exists(dir)) {
    EXPECT_TRUE(fs::is_empty(dir)) << "drawings left behind by a failed run";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Detect, DetectDrawFails,
    ::testing::Values(
        // The good photo is drawn first (one job), then the unreadable one stops the run.
        FailCase{"unreadable_photo", {"--aruco", "DICT_4X4_100", "--draw", "DIR", "-j", "1", demo("part_00.jpg"), "BAD"}, 1},
        FailCase{"no_board_anywhere", {"--chessboard", "9x6", "--draw", "DIR", "-j", "1", demo("part_00.jpg")}, 1},
        FailCase{"to_stdout", {"--aruco", "DICT_4X4_100", "--draw", "-", demo("part_00.jpg")}, 2},
        FailCase{"bad_format", {"--aruco", "DICT_4X4_100", "--draw", "DIR", "--draw-format", "gif", demo("part_00.jpg")}, 2}));

}  // namespace
}  // namespace photomill::detect
