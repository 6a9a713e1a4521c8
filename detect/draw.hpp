// Drawings for people (detect --draw DIR): what detect found, drawn over each photo, one picture
// per photo. Markers: outline and id, every corner dot with its corner index (colour-coded),
// markers photomill dropped and quadrilaterals OpenCV could not identify in other colours, SIFT
// features as small circles; boards: every corner with its id, rows joined. The photo is shown
// in grey, dimmed, and scaled down to a maximum width; marks and text are drawn at the output
// resolution so they stay readable. Nothing reads the pictures back.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "detect/boards.hpp"
#include "detect/markers.hpp"
#include "formats/features.hpp"

namespace photomill::detect {

struct DrawOptions {
  std::string dir;             // write <dir>/<photo's stem>.<format>; empty: no drawings
  std::string format = "jpg";  // "jpg" (small) or "png" (exact)
  int max_width_px = 1600;     // wider photos are scaled down to this width; 0: full size
  int jpeg_quality = 90;
};

// Throws UsageError for a bad format, width or quality.
void validate(const DrawOptions& options);

// The drawing of one photo's markers and/or features (either may be null), BGR, CV_8UC3.
// `grey`: the photo (CV_8UC1) the detections were made on.
cv::Mat draw_photo(const cv::Mat& grey, const MarkerDetection* markers, const FeatureSet* features,
                   const DrawOptions& options);

// The drawing of one photo's board corners (ids row-major, rows joined), BGR, CV_8UC3.
cv::Mat draw_board(const cv::Mat& grey, const ImageDetection& detection, const BoardSpec& spec,
                   const DrawOptions& options);

// Encodes a drawing as options.format (JPEG at options.jpeg_quality, or PNG).
std::vector<std::uint8_t> encode_drawing(const cv::Mat& bgr, const DrawOptions& options);

// The drawing files of one run: DIR/<photo's stem>.<format> per image, part_05.jpg -> part_05.jpg
// (the folder is created).
// write() may be called from several threads at once. Inside tool::run the files are renamed
// into place only when the whole run succeeded: a failed run leaves the previous drawings.
class DrawingFiles {
public:
  // Throws UsageError if two images share a file name, InputError if the folder cannot be made.
  DrawingFiles(const DrawOptions& options, const std::vector<std::string>& images);
  DrawingFiles(const DrawingFiles&) = delete;
  DrawingFiles& operator=(const DrawingFiles&) = delete;

  // Encodes and writes the drawing of `image` (one of the constructor's images), through a
  // temporary name renamed on success.
  void write(const std::string& image, const cv::Mat& bgr);
  const std::filesystem::path& path_of(const std::string& image) const { return paths_.at(image); }

private:
  DrawOptions options_;
  std::map<std::string, std::filesystem::path> paths_;
};

}  // namespace photomill::detect
