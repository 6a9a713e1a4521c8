// Marker corners on real photos of a ChArUco board against the board's own geometry (benchmark
// and test support: tools/detect_marker_board_check, detect/board_lines_test). The board's
// chessboard corners are measured independently of the markers (OpenCV's cornerSubPix on the
// saddle points, started from the homography of OpenCV's unrefined marker polygons); with the
// lens distortion removed (a calibration: camera matrix and OpenCV's distortion coefficients) the
// board plane maps to the photo by a homography, fitted by least squares to those corners
// (cv::findHomography, method 0). A marker corner's error is its distance, undistorted, from
// where that homography puts the board's marker corner: it includes the board's printing and
// the calibration, whose size the chessboard corners' own residual about the homography shows.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "detect/markers.hpp"

namespace photomill::board_check {

struct CharucoBoardSpec {
  std::string dictionary = "DICT_6X6_250";
  int squares_x = 5, squares_y = 7;
  double square = 0.04, marker = 0.02;  // any unit, the same for both
};

// Corner errors, px.
struct CornerErrors {
  double sum_sq = 0, max = 0;
  double outward = 0;  // sum of the errors' components along the marker's diagonals, outwards
  std::size_t count = 0, markers = 0;
  void add(double error, double outward_px);
  void merge(const CornerErrors& other);
  double rms() const;
  double mean_outward() const;  // > 0: corners found outside the board's marker square
};

struct PhotoCheck {
  bool board_found = false;  // at least 4 of the board's markers, so the chessboard corners could be placed
  int half_window_px = 0;    // cornerSubPix's half-window on the chessboard corners
  CornerErrors floor;        // the chessboard corners about the homography
  std::vector<CornerErrors> methods;         // per method, every marker it kept
  std::vector<CornerErrors> methods_common;  // per method, the markers every method kept
  std::size_t common_markers = 0;
};

// Detects the markers of `grey` with each of `methods` and judges their corners.
PhotoCheck check_charuco_photo(const cv::Mat& grey, const std::string& image_name, const CharucoBoardSpec& board,
                               const cv::Mat& camera_matrix, const cv::Mat& distortion,
                               const std::vector<detect::MarkerDetectOptions>& methods);

}  // namespace photomill::board_check
