// Marker corners on a real photo with known geometry: OpenCV's grid-board photo gboriginal.png
// (../shared/data/README.md: 5 x 7 markers of the tutorial dictionary, ids 0-34 row by row, equal
// marker size and spacing). Whatever the print's scale and the camera's perspective, the top edges
// of one row's five markers lie on one straight line, and so do their bottom edges, the left edges
// of one column's seven markers and their right edges: 24 lines through 10 or 14 corners each.
// The spread of the corners about those lines is an accuracy measure that needs no reference
// coordinates. It compares our corners with OpenCV's gold corners for this photo (OpenCV's unrefined
// polygon rounded to whole pixels, which issue #5 asks us to stay within 1 px of), OpenCV's
// unrefined corners themselves and OpenCV's cornerSubPix refinement.
//
// Line fit: total least squares (the line through the centroid along the principal axis of the
// points' scatter matrix; e.g. Golub & Van Loan, "Matrix Computations", 12.3 / orthogonal
// regression); spread = RMS orthogonal distance with N - 2 degrees of freedom per line.
// No lens model is applied: the photo's distortion bends these lines by well under 0.1 px over a
// marker row (tutorial_camera_params.yml, k1 = 0.0995 at f = 628 px); it is the same for every method.
//
// And the four real ChArUco calibration photos img_00..03.jpg (5 x 7 squares, DICT_6X6_250 markers
// of 2.5-4 px per cell) against the board's geometry, placed by its chessboard corners with
// OpenCV's published calibration of these photos (tools/marker_board_check.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

#include <Eigen/Dense>
#include <opencv2/imgcodecs.hpp>

#include "detect/gold_corners.hpp"
#include "detect/markers.hpp"
#include "tools/marker_board_check.hpp"

namespace photomill::detect {
namespace {

const std::string kAruco = std::string(PHOTOMILL_SHARED_DIR) + "/data/opencv-aruco/";
constexpr int kColumns = 5;
constexpr int kMarkers = 35;

using Corners = std::map<int, std::array<Eigen::Vector2d, 4>>;  // marker id -> TL TR BR BL

Corners gold_corners() { return read_gold_corners(kAruco + "gold_corners.txt", "gboriginal.png"); }

Corners detected(CornerRefinement refinement) {
  const cv::Mat grey = cv::imread(kAruco + "gboriginal.png", cv::IMREAD_GRAYSCALE);
  MarkerDetectOptions o;
  o.refinement = refinement;
  const MarkerDetection d =
      detect_markers(grey, "gboriginal.png", MarkerDictionary::from_file(kAruco + "tutorial_dict.yml"), o);
  Corners c;
  for (std::size_t k = 0; k < d.marker_ids.size(); ++k) c[d.marker_ids[k]] = d.corners[k];
  return c;
}

// RMS orthogonal distance of the corners from the 24 row and column lines (see the file comment).
double line_spread_px(const Corners& c) {
  std::map<std::string, std::vector<Eigen::Vector2d>> lines;
  for (const auto& [id, q] : c) {
    const int row = id / kColumns, col = id % kColumns;
    for (int j = 0; j < 4; ++j) {
      lines["row" + std::to_string(row) + (j < 2 ? "top" : "bottom")].push_back(q[j]);
      lines["col" + std::to_string(col) + (j == 0 || j == 3 ? "left" : "right")].push_back(q[j]);
    }
  }
  double sum = 0;
  int dof = 0;
  for (const auto& [name, p] : lines) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& x : p) mean += x;
    mean /= static_cast<double>(p.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (const auto& x : p) scatter += (x - mean) * (x - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
    sum += eig.eigenvalues()[0];  // the sum of squared distances along the smallest axis
    dof += static_cast<int>(p.size()) - 2;
  }
  return std::sqrt(sum / dof);
}

TEST(GridBoardPhoto, EdgeFitCornersLieOnTheBoardsStraightLinesBetterThanGoldAndOpenCV) {
  const Corners gold = gold_corners();
  ASSERT_EQ(gold.size(), static_cast<std::size_t>(kMarkers));
  const Corners edges = detected(CornerRefinement::Edges);
  const Corners none = detected(CornerRefinement::None);
  const Corners subpix = detected(CornerRefinement::Subpix);
  ASSERT_EQ(edges.size(), static_cast<std::size_t>(kMarkers));
  ASSERT_EQ(none.size(), static_cast<std::size_t>(kMarkers));
  ASSERT_EQ(subpix.size(), static_cast<std::size_t>(kMarkers));
  const double s_gold = line_spread_px(gold), s_edges = line_spread_px(edges), s_none = line_spread_px(none),
               s_subpix = line_spread_px(subpix);
  std::cout << "[ detect   ] gboriginal.png, corner spread about the board's 24 straight lines: edge fit " << s_edges
            << " px, OpenCV gold " << s_gold << " px, OpenCV unrefined " << s_none << " px, OpenCV cornerSubPix "
            << s_subpix << " px\n";
  // Rounding alone gives gold 1/sqrt(12) = 0.29 px per coordinate; measured 0.49 px. The edge fit
  // was measured at 0.32 px (2026-11-24). A regression to gold's level fails here.
  EXPECT_LT(s_edges, 0.8 * s_gold);
  EXPECT_LT(s_edges, 0.8 * s_none);
  EXPECT_LT(s_edges, s_subpix);
}

TEST(CharucoPhotos, EdgeFitCornersFitTheBoardBetterThanOpenCVsWithoutTheirInwardBias) {
  cv::FileStorage fs(kAruco + "tutorial_camera_charuco.yml", cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat K, dist;
  fs["camera_matrix"] >> K;
  fs["distortion_coefficients"] >> dist;
  std::vector<MarkerDetectOptions> methods(5);
  for (auto& m : methods) m.edges.gamma = 2.2;  // sRGB JPEGs
  methods[1].edges.model_code = false;
  methods[2].refinement = CornerRefinement::Subpix;
  methods[3].refinement = CornerRefinement::Contour;
  methods[4].refinement = CornerRefinement::None;
  const char* names[] = {"edge fit", "edge fit without the code", "OpenCV subpix", "OpenCV contour", "OpenCV unrefined"};
  std::vector<board_check::CornerErrors> all(methods.size());
  board_check::CornerErrors floor;
  for (const char* photo : {"img_00.jpg", "img_01.jpg", "img_02.jpg", "img_03.jpg"}) {
    const cv::Mat grey = cv::imread(kAruco + photo, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << photo;
    const auto check = board_check::check_charuco_photo(grey, photo, {}, K, dist, methods);
    ASSERT_TRUE(check.board_found) << photo;
    floor.merge(check.floor);
    for (std::size_t m = 0; m < methods.size(); ++m) all[m].merge(check.methods[m]);
  }
  std::cerr << "[ detect   ] OpenCV's 4 ChArUco photos against the board (chessboard corners " << floor.rms()
            << " px about it):";
  for (std::size_t m = 0; m < methods.size(); ++m) {
    std::cerr << "\n             " << names[m] << ": " << all[m].markers << " markers, RMS " << all[m].rms()
              << " px, mean outwards " << all[m].mean_outward() << " px";
  }
  std::cerr << "\n";
  // OpenCV finds 67 markers in the four photos; the edge fit keeps nearly all of them (64 when
  // measured; 50 without the code cells, which refused a quarter as "edge contrast inverted").
  EXPECT_GE(all[4].markers, 65u);
  EXPECT_GE(all[0].markers, 60u);
  EXPECT_GT(all[0].markers, all[1].markers);
  // Measured 0.53 px against OpenCV's 0.91-1.47 px, whose corners lie 0.8-1.15 px inside the
  // board's squares; the edge fit's 0.14 px.
  for (std::size_t m = 2; m < methods.size(); ++m) EXPECT_LT(all[0].rms(), 0.7 * all[m].rms()) << names[m];
  EXPECT_LT(std::abs(all[0].mean_outward()), 0.3);
}

}  // namespace
}  // namespace photomill::detect
