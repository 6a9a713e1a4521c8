// Calibration-board corners in images: chessboards (OpenCV's findChessboardCorners + cornerSubPix)
// and ChArUco boards (ArUco markers + interpolated chessboard corners, refined again on the image).
// Images -> observations (point_id = the board's corner index); a board -> its control points
// (z = 0, mm), so `detect --chessboard 9x6 ... | calib --chessboard 9x6` needs no other file.
#pragma once

#include <cstdint>

#include <functional>
#include <istream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "formats/image.hpp"
#include "formats/tables.hpp"
#include "geometry/board.hpp"

namespace photomill::detect {

// The board's geometry lives in geometry/board.hpp (calib needs it without detect).
using geometry::BoardKind;
using geometry::BoardSpec;
using geometry::board_control_points;
using geometry::board_corner_count;
using geometry::parse_grid;

// Checks a spec (sizes, dictionary name, marker < square, enough markers in the dictionary);
// throws UsageError.
void validate_board(const BoardSpec& spec);

// The names accepted for BoardSpec::dictionary (OpenCV's PREDEFINED_DICTIONARY_NAME), in enum
// order. Throws UsageError for an unknown name.
const std::vector<std::string>& aruco_dictionary_names();
int aruco_dictionary_id(const std::string& name);

struct BoardDetectOptions {
  // Chessboard corner refinement (the settings of OpenCV's calibration sample and of the
  // reference values in ../shared/data/README.md): cornerSubPix with an 11x11 half-window.
  int chessboard_half_window_px = 11;
  // > 0: each chessboard corner is refined again with half that half-window, from the same
  // start; where the two disagree by more than this (px), the large window has taken in another
  // edge (the board's outer edge beside a foreshortened outer row) and the small window's corner
  // is kept (counted in ImageDetection::corrected). 0: OpenCV's corners as they are.
  double chessboard_window_check_px = 0.5;
  int subpix_max_iterations = 30;
  double subpix_epsilon_px = 1e-4;
  // ChArUco: OpenCV 4.6's interpolateCornersCharuco returns corners shifted by +0.5 px in x and y
  // (OpenCV issue 25539: it adds (0.5, 0.5) after its cornerSubPix; measured in boards_test.cpp
  // on rendered boards with known corners). With `charuco_refine` every corner is refined again
  // by cornerSubPix on the image, to the chessboard criteria above, with a half-window as large as
  // the neighbouring markers allow (see refine_charuco in boards.cpp) up to the maximum below.
  // On rendered boards this leaves 0.016-0.036 px RMS against the truth where OpenCV's corners
  // minus 0.5 px leave 0.018-0.059 px (docs/measurements/calib.md).
  bool charuco_refine = true;
  int charuco_max_half_window_px = 20;
  int charuco_min_half_window_px = 2;
  int charuco_min_markers = 2;  // adjacent markers needed to interpolate a corner (OpenCV's)
  int jobs = 0;                 // images processed in parallel; 0 = all cores
  std::uint64_t max_image_pixels = kMaxImagePixels;  // a header claiming more is refused (--max-image-mpx)
};

// What was found in one image.
struct ImageDetection {
  std::string image;                      // as given
  int width_px = 0;
  int height_px = 0;
  bool found = false;                     // board found (chessboard: all corners; ChArUco: >= 1)
  int markers = 0;                        // ChArUco: markers detected
  int rejected = 0;                       // ChArUco: corners dropped by the refinement
  int corrected = 0;                      // chessboard: corners taken from the half window
  std::vector<Observation> observations;  // sorted by point_id
};

// Image arguments as given on a command line, "-" standing for a list of image paths read from
// `list`, one per line (blank lines and lines starting with '#' skipped; CRLF and a UTF-8 BOM
// accepted). Shared by every mode. Throws InputError for an image named twice.
std::vector<std::string> expand_image_arguments(const std::vector<std::string>& args, std::istream& list);

// One line for a person: "left01.jpg: found, 54 corners" (+ markers, dropped corners).
std::string describe(const ImageDetection& detection);

// Detects the board in one grey image (CV_8UC1). Never throws for "no board": found = false.
ImageDetection detect_board(const cv::Mat& grey, const std::string& image_name, const BoardSpec& spec,
                            const BoardDetectOptions& options);

// Called from the worker threads, in parallel (not serialised), with each image as read (grey)
// and its detection: for work on the pixels such as drawings (draw.hpp).
using BoardImageHook = std::function<void(const cv::Mat& grey, const ImageDetection& detection)>;

// Reads and processes every image (in parallel), results in the order of `images`. Calls
// `on_image` (serialised, from worker threads) as each image finishes, for progress reports,
// after `on_pixels`. Throws InputError(path, 0, ...) for an image that cannot be read, or what
// `on_pixels` throws.
std::vector<ImageDetection> detect_boards(const std::vector<std::string>& images, const BoardSpec& spec,
                                          const BoardDetectOptions& options,
                                          const std::function<void(const ImageDetection&)>& on_image = {},
                                          const BoardImageHook& on_pixels = {});

}  // namespace photomill::detect
