// Chessboard and ChArUco corner detection (see boards.hpp for the contract).
#include "detect/boards.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <set>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/image_decode.hpp"
#include "geometry/parallel.hpp"

namespace photomill::detect {
namespace {

cv::Ptr<cv::aruco::CharucoBoard> make_charuco(const BoardSpec& spec) {
  return cv::aruco::CharucoBoard::create(spec.cols, spec.rows, static_cast<float>(spec.square_mm),
                                         static_cast<float>(spec.marker_mm),
                                         cv::aruco::getPredefinedDictionary(aruco_dictionary_id(spec.dictionary)));
}

cv::TermCriteria subpix_criteria(const BoardDetectOptions& o) {
  return {cv::TermCriteria::EPS + cv::TermCriteria::COUNT, o.subpix_max_iterations, o.subpix_epsilon_px};
}

void detect_chessboard(const cv::Mat& grey, const BoardSpec& spec, const BoardDetectOptions& options,
                       ImageDetection& out) {
  std::vector<cv::Point2f> corners;
  const cv::Size pattern(spec.cols, spec.rows);
  out.found = cv::findChessboardCorners(grey, pattern, corners,
                                        cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  if (!out.found) return;
  const int w = options.chessboard_half_window_px;
  const std::vector<cv::Point2f> start = corners;
  cv::cornerSubPix(grey, corners, cv::Size(w, w), cv::Size(-1, -1), subpix_criteria(options));
  if (options.chessboard_window_check_px > 0) {
    // cornerSubPix solves sum_q (grad I(q) . (q - p))^2 = min over the window: every gradient in
    // it must point at p. An edge that is not the corner's (the board's outer edge) inside the
    // window pulls p towards it, by less than the window, so a move check cannot see it; a window
    // half as large that leaves it out lands elsewhere.
    std::vector<cv::Point2f> small = start;
    const int ws = std::max(2, w / 2);
    cv::cornerSubPix(grey, small, cv::Size(ws, ws), cv::Size(-1, -1), subpix_criteria(options));
    for (std::size_t i = 0; i < corners.size(); ++i) {
      if (cv::norm(corners[i] - small[i]) <= options.chessboard_window_check_px) continue;
      corners[i] = small[i];
      ++out.corrected;
    }
  }
  for (std::size_t i = 0; i < corners.size(); ++i) {
    out.observations.push_back({out.image, static_cast<PointId>(i), corners[i].x, corners[i].y});
  }
}

// Refines interpolated ChArUco corners on the image. The half-window w of each corner is chosen
// so the (2w+1)^2 window stays off the neighbouring markers: the nearest marker corner lies at
// image distance d on the square's diagonal, and every marker pixel is at least d/sqrt(2) away in
// the max-norm whatever the board's rotation, so w = floor(d/sqrt(2)) - 1, clamped to the options.
// A corner that cornerSubPix moves further than its half-window has locked onto another edge and
// is dropped (counted in `rejected`).
void refine_charuco(const cv::Mat& grey, const std::vector<std::vector<cv::Point2f>>& marker_corners,
                    const BoardDetectOptions& options, std::vector<cv::Point2f>& corners, std::vector<int>& ids,
                    int& rejected) {
  std::vector<cv::Point2f> kept;
  std::vector<int> kept_ids;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    double d = 1e30;
    for (const auto& marker : marker_corners) {
      for (const auto& m : marker) d = std::min(d, static_cast<double>(cv::norm(m - corners[i])));
    }
    const int w = std::clamp(static_cast<int>(std::floor(d / std::sqrt(2.0))) - 1,
                             options.charuco_min_half_window_px, options.charuco_max_half_window_px);
    std::vector<cv::Point2f> p{corners[i]};
    cv::cornerSubPix(grey, p, cv::Size(w, w), cv::Size(-1, -1), subpix_criteria(options));
    if (cv::norm(p[0] - corners[i]) > w) {
      ++rejected;
      continue;
    }
    kept.push_back(p[0]);
    kept_ids.push_back(ids[i]);
  }
  corners = std::move(kept);
  ids = std::move(kept_ids);
}

void detect_charuco(const cv::Mat& grey, const BoardSpec& spec, const BoardDetectOptions& options,
                    ImageDetection& out) {
  const auto board = make_charuco(spec);
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  cv::aruco::detectMarkers(grey, board->dictionary, marker_corners, marker_ids);
  out.markers = static_cast<int>(marker_ids.size());
  if (marker_ids.empty()) return;
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, grey, board, corners, ids, cv::noArray(),
                                       cv::noArray(), options.charuco_min_markers);
  if (options.charuco_refine) refine_charuco(grey, marker_corners, options, corners, ids, out.rejected);
  out.found = !ids.empty();
  for (std::size_t i = 0; i < ids.size(); ++i) {
    out.observations.push_back({out.image, ids[i], corners[i].x, corners[i].y});
  }
  std::sort(out.observations.begin(), out.observations.end(),
            [](const Observation& a, const Observation& b) { return a.point_id < b.point_id; });
}

}  // namespace

const std::vector<std::string>& aruco_dictionary_names() {
  static const std::vector<std::string> names{
      "DICT_4X4_50",         "DICT_4X4_100",        "DICT_4X4_250",        "DICT_4X4_1000",
      "DICT_5X5_50",         "DICT_5X5_100",        "DICT_5X5_250",        "DICT_5X5_1000",
      "DICT_6X6_50",         "DICT_6X6_100",        "DICT_6X6_250",        "DICT_6X6_1000",
      "DICT_7X7_50",         "DICT_7X7_100",        "DICT_7X7_250",        "DICT_7X7_1000",
      "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_16h5",  "DICT_APRILTAG_25h9",  "DICT_APRILTAG_36h10",
      "DICT_APRILTAG_36h11"};
  return names;
}

int aruco_dictionary_id(const std::string& name) {
  const auto& names = aruco_dictionary_names();
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw UsageError("unknown ArUco dictionary '" + name + "'");
  return static_cast<int>(it - names.begin());  // the names are listed in OpenCV's enum order
}

void validate_board(const BoardSpec& spec) {
  geometry::validate_board_geometry(spec);
  if (spec.kind == BoardKind::Chessboard) return;
  const int markers = spec.cols * spec.rows / 2;
  const auto dict = cv::aruco::getPredefinedDictionary(aruco_dictionary_id(spec.dictionary));
  if (dict->bytesList.rows < markers) {
    throw UsageError(spec.dictionary + " has " + std::to_string(dict->bytesList.rows) + " markers; a " +
                     std::to_string(spec.cols) + "x" + std::to_string(spec.rows) + " ChArUco board needs " +
                     std::to_string(markers));
  }
}

std::vector<std::string> expand_image_arguments(const std::vector<std::string>& args, std::istream& list) {
  std::vector<std::string> images;
  for (const auto& a : args) {
    if (a != "-") {
      images.push_back(a);
      continue;
    }
    bool first = true;
    for (std::string line; std::getline(list, line);) {
      if (first && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte-order mark
      first = false;
      if (!line.empty() && line.back() == '\r') line.pop_back();
      // Blank lines (spaces only too) and comments name no photo.
      if (line.find_first_not_of(" \t") != std::string::npos && line[0] != '#') images.push_back(line);
    }
  }
  // The same photo twice would give every point twice in one image, which no stage accepts.
  std::set<std::string> seen;
  for (const auto& image : images) {
    if (!seen.insert(image).second) throw InputError(image, 0, "named twice: give each image once");
  }
  return images;
}

std::string describe(const ImageDetection& d) {
  std::string line = d.image + ": " + (d.found ? "found, " : "not found, ") + std::to_string(d.observations.size()) +
                     " corners";
  if (d.markers > 0) line += ", " + std::to_string(d.markers) + " markers";
  if (d.rejected > 0) line += ", " + std::to_string(d.rejected) + " corners dropped by the refinement";
  if (d.corrected > 0) {
    line += ", " + std::to_string(d.corrected) + " corners from the half window (the full one took in another edge)";
  }
  return line;
}

ImageDetection detect_board(const cv::Mat& grey, const std::string& image_name, const BoardSpec& spec,
                            const BoardDetectOptions& options) {
  CV_Assert(grey.type() == CV_8UC1);
  ImageDetection out;
  out.image = image_name;
  out.width_px = grey.cols;
  out.height_px = grey.rows;
  if (spec.kind == BoardKind::Chessboard) {
    detect_chessboard(grey, spec, options, out);
  } else {
    detect_charuco(grey, spec, options, out);
  }
  return out;
}

std::vector<ImageDetection> detect_boards(const std::vector<std::string>& images, const BoardSpec& spec,
                                          const BoardDetectOptions& options,
                                          const std::function<void(const ImageDetection&)>& on_image,
                                          const BoardImageHook& on_pixels) {
  validate_board(spec);
  std::vector<ImageDetection> results(images.size());
  std::mutex report_mutex;
  geometry::parallel_for(images.size(), options.jobs, [&](std::size_t i) {
    const cv::Mat grey = read_image(images[i], cv::IMREAD_GRAYSCALE, options.max_image_pixels);
    results[i] = detect_board(grey, images[i], spec, options);
    if (on_pixels) on_pixels(grey, results[i]);
    if (on_image) {
      const std::lock_guard<std::mutex> lock(report_mutex);
      on_image(results[i]);
    }
  });
  return results;
}

}  // namespace photomill::detect
