// Parallel marker and feature detection over photos (contract in photos.hpp).
#include "detect/photos.hpp"

#include <algorithm>
#include <mutex>

#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/image_decode.hpp"
#include "geometry/parallel.hpp"

namespace photomill::detect {

void validate(const PhotoOptions& o) {
  if (!o.dictionary && !o.sift) throw UsageError("nothing to detect: give a marker dictionary or ask for features");
  if (o.mask_markers && !o.dictionary) throw UsageError("--mask-markers needs markers to mask (--aruco or --aruco-dict-file)");
  if (!(o.mask_margin_cells >= 0) || o.mask_margin_cells > 100) throw UsageError("--mask-margin-cells must be in 0..100");
  if (o.sift) validate(*o.sift);
  if (o.sift && o.sift->mask_clearance_per_size > 0 && !o.mask_markers) {
    throw UsageError("--mask-clearance-per-size keeps features clear of the marker mask: it needs --mask-markers");
  }
  if (o.jobs < 0) throw UsageError("--threads must be 0 (all cores) or positive");
}

void detect_photos(const std::vector<std::string>& images, const PhotoOptions& options,
                   const std::function<void(PhotoResult&&)>& on_result, const PhotoImageHook& on_image) {
  validate(options);
  std::mutex mutex;
  bool failed = false;  // guarded by mutex: results still in flight after a failure are not delivered
  auto detect_one = [&](std::size_t i) {
    const cv::Mat grey = read_image(images[i], cv::IMREAD_GRAYSCALE, options.max_image_pixels);
    PhotoResult r;
    r.index = i;
    if (options.dictionary) r.markers = detect_markers(grey, images[i], *options.dictionary, options.markers);
    if (options.sift) {
      cv::Mat mask;
      if (options.mask_markers) {
        mask = marker_mask(grey.size(), r.markers->corners, options.dictionary->bits_per_side() + 2,
                           options.mask_margin_cells);
      }
      r.features = detect_sift(grey, images[i], *options.sift, mask);
    }
    if (on_image) on_image(grey, r);
    const std::lock_guard<std::mutex> lock(mutex);
    if (!failed) on_result(std::move(r));
  };
  // Images are handed out in order and none after a failure: the error rethrown is the earliest
  // failing image's, whatever the threads' timing.
  geometry::parallel_for(images.size(), options.jobs, [&](std::size_t i) {
    try {
      detect_one(i);
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex);
      failed = true;
      throw;
    }
  });
}

}  // namespace photomill::detect
