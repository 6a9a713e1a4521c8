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
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

#include <Eigen/Dense>
#include <opencv2/imgcodecs.hpp>

#include "detect/gold_corners.hpp"
#include "detect/markers.hpp"

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

}  // namespace
}  // namespace photomill::detect
