// Marker corners against a ChArUco board's geometry (contract and method in marker_board_check.hpp).
#include "tools/marker_board_check.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace photomill::board_check {

void CornerErrors::add(double error, double outward_px) {
  sum_sq += error * error;
  max = std::max(max, error);
  outward += outward_px;
  ++count;
}

void CornerErrors::merge(const CornerErrors& other) {
  sum_sq += other.sum_sq;
  max = std::max(max, other.max);
  outward += other.outward;
  count += other.count;
  markers += other.markers;
}

double CornerErrors::rms() const { return count ? std::sqrt(sum_sq / static_cast<double>(count)) : 0; }
double CornerErrors::mean_outward() const { return count ? outward / static_cast<double>(count) : 0; }

namespace {

std::vector<cv::Point2f> undistort(const std::vector<cv::Point2f>& points, const cv::Mat& K, const cv::Mat& dist) {
  std::vector<cv::Point2f> out;
  if (!points.empty()) cv::undistortPoints(points, out, K, dist, cv::noArray(), K);
  return out;
}

}  // namespace

PhotoCheck check_charuco_photo(const cv::Mat& grey, const std::string& image_name, const CharucoBoardSpec& spec,
                               const cv::Mat& K, const cv::Mat& dist,
                               const std::vector<detect::MarkerDetectOptions>& methods) {
  const auto dictionary = detect::MarkerDictionary::predefined(spec.dictionary);
  const auto board = cv::aruco::CharucoBoard::create(spec.squares_x, spec.squares_y, static_cast<float>(spec.square),
                                                     static_cast<float>(spec.marker),
                                                     cv::Ptr<cv::aruco::Dictionary>(dictionary.opencv()));
  std::map<int, std::vector<cv::Point3f>> board_corners;  // marker id -> its corners on the board
  for (std::size_t k = 0; k < board->ids.size(); ++k) board_corners[board->ids[k]] = board->objPoints[k];
  PhotoCheck out;

  // The chessboard corners, started from the homography of OpenCV's unrefined polygons.
  detect::MarkerDetectOptions unrefined;
  unrefined.refinement = detect::CornerRefinement::None;
  const auto polygons = detect::detect_markers(grey, image_name, dictionary, unrefined);
  std::vector<cv::Point2f> board_xy, image_xy;
  for (std::size_t k = 0; k < polygons.marker_ids.size(); ++k) {
    const auto it = board_corners.find(polygons.marker_ids[k]);
    if (it == board_corners.end()) continue;
    for (std::size_t c = 0; c < 4; ++c) {
      board_xy.emplace_back(it->second[c].x, it->second[c].y);
      image_xy.emplace_back(static_cast<float>(polygons.corners[k][c].x()), static_cast<float>(polygons.corners[k][c].y()));
    }
  }
  if (board_xy.size() < 16) return out;
  const cv::Mat rough = cv::findHomography(board_xy, image_xy, 0);
  if (rough.empty()) return out;
  std::vector<cv::Point2f> chess_board, chess_image;
  for (const auto& p : board->chessboardCorners) chess_board.emplace_back(p.x, p.y);
  cv::perspectiveTransform(chess_board, chess_image, rough);
  // Half-window a fifth of a square, and within 0.8 of the white margin between a chessboard corner
  // and the nearest marker ((square - marker) / 2), so the window sees the saddle point only.
  const double px_per_unit = std::sqrt(std::abs(cv::determinant(rough(cv::Rect(0, 0, 2, 2)))));
  const double margin_px = 0.5 * (spec.square - spec.marker) * px_per_unit;
  out.half_window_px = std::max(2, static_cast<int>(std::min(spec.square * px_per_unit / 5, 0.8 * margin_px)));
  cv::cornerSubPix(grey, chess_image, cv::Size(out.half_window_px, out.half_window_px), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 0.001));
  const auto chess_undistorted = undistort(chess_image, K, dist);
  const cv::Mat H = cv::findHomography(chess_board, chess_undistorted, 0);
  if (H.empty()) return out;
  out.board_found = true;
  std::vector<cv::Point2f> chess_predicted;
  cv::perspectiveTransform(chess_board, chess_predicted, H);
  for (std::size_t k = 0; k < chess_predicted.size(); ++k) out.floor.add(cv::norm(chess_predicted[k] - chess_undistorted[k]), 0);

  std::vector<detect::MarkerDetection> found;
  for (const auto& m : methods) found.push_back(detect::detect_markers(grey, image_name, dictionary, m));
  std::set<int> common;
  for (const auto& [id, corners] : board_corners) common.insert(id);
  for (const auto& f : found) {
    std::set<int> kept(f.marker_ids.begin(), f.marker_ids.end()), both;
    std::set_intersection(common.begin(), common.end(), kept.begin(), kept.end(), std::inserter(both, both.begin()));
    common = both;
  }
  out.common_markers = common.size();
  for (const auto& f : found) {
    CornerErrors e, e_common;
    for (std::size_t k = 0; k < f.marker_ids.size(); ++k) {
      const int id = f.marker_ids[k];
      const auto it = board_corners.find(id);
      if (it == board_corners.end()) continue;
      std::vector<cv::Point2f> measured, on_board, predicted;
      for (std::size_t c = 0; c < 4; ++c) {
        measured.emplace_back(static_cast<float>(f.corners[k][c].x()), static_cast<float>(f.corners[k][c].y()));
        on_board.emplace_back(it->second[c].x, it->second[c].y);
      }
      const auto undistorted = undistort(measured, K, dist);
      cv::perspectiveTransform(on_board, predicted, H);
      const cv::Point2f centre = 0.25f * (predicted[0] + predicted[1] + predicted[2] + predicted[3]);
      const bool in_common = common.count(id) > 0;
      ++e.markers;
      if (in_common) ++e_common.markers;
      for (std::size_t c = 0; c < 4; ++c) {
        const double d = cv::norm(predicted[c] - undistorted[c]);
        const cv::Point2f diagonal = predicted[c] - centre;
        const double outward = (undistorted[c] - predicted[c]).dot(diagonal) / cv::norm(diagonal);
        e.add(d, outward);
        if (in_common) e_common.add(d, outward);
      }
    }
    out.methods.push_back(e);
    out.methods_common.push_back(e_common);
  }
  return out;
}

}  // namespace photomill::board_check
