// Markers and natural features over many photos: each image is read once, its markers found and
// refined (markers.hpp), then its SIFT features computed away from them (sift.hpp); images are
// processed in parallel and handed to the caller one by one as they finish.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "detect/markers.hpp"
#include "detect/sift.hpp"
#include "formats/features.hpp"
#include "formats/image.hpp"

namespace photomill::detect {

struct PhotoOptions {
  std::optional<MarkerDictionary> dictionary;  // find markers (with `markers`) when set
  MarkerDetectOptions markers;
  std::optional<SiftOptions> sift;             // compute SIFT features when set
  bool mask_markers = false;                   // SIFT: not on markers nor their quiet zones
  double mask_margin_cells = 1;                // ... grown by this many cells
  int jobs = 0;                                // images in parallel; 0 = all cores
  std::uint64_t max_image_pixels = kMaxImagePixels;  // a header claiming more is refused (--max-image-mpx)
};

struct PhotoResult {
  std::size_t index = 0;                   // position in the image list
  std::optional<MarkerDetection> markers;  // when a dictionary was given
  std::optional<FeatureSet> features;      // when SIFT was asked for
};

// Throws UsageError for inconsistent options (masking without a dictionary, bad SIFT options).
void validate(const PhotoOptions& options);

// Called from the worker threads, in parallel (not serialised), with each image as read (grey)
// and its result, before `on_result`: for work on the pixels such as drawings (draw.hpp).
using PhotoImageHook = std::function<void(const cv::Mat& grey, const PhotoResult& result)>;

// Processes every image (in parallel) and calls `on_result` once per image, serialised, in the
// order they finish. Throws InputError(path, 0, "not a readable image") for an image that cannot
// be read, or what `on_image` or `on_result` throws; the other workers stop at their next image.
void detect_photos(const std::vector<std::string>& images, const PhotoOptions& options,
                   const std::function<void(PhotoResult&&)>& on_result, const PhotoImageHook& on_image = {});

}  // namespace photomill::detect
