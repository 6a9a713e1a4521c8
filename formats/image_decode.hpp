// Reads a photo once (formats/image.hpp's read_image_file: checked, every read error naming the
// file) and decodes those bytes with OpenCV. Header-only: the formats library has no OpenCV; the
// stages that decode photos link opencv_imgcodecs.
#pragma once

#include <climits>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/image.hpp"

namespace photomill {

// The image `path` decoded with cv::imdecode's `flags` (cv::IMREAD_GRAYSCALE, ...); InputError
// naming the file if it cannot be read or decoded, or if its header claims more than `max_pixels`.
inline cv::Mat read_image(const std::string& path, int flags, std::uint64_t max_pixels = kMaxImagePixels) {
  const std::string bytes = read_image_file(path, max_pixels);
  if (bytes.size() > static_cast<std::size_t>(INT_MAX)) throw InputError(path, 0, "not a readable image: too large");
  const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
  cv::Mat img = cv::imdecode(raw, flags);
  if (img.empty()) throw InputError(path, 0, "not a readable image");
  return img;
}

}  // namespace photomill
