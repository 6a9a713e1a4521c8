// Parallel marker and feature detection over photos (contract in photos.hpp).
#include "detect/photos.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/image.hpp"

namespace photomill::detect {

void validate(const PhotoOptions& o) {
  if (!o.dictionary && !o.sift) throw UsageError("nothing to detect: give a marker dictionary or ask for features");
  if (o.mask_markers && !o.dictionary) throw UsageError("--mask-markers needs markers to mask (--aruco or --aruco-dict-file)");
  if (!(o.mask_margin_cells >= 0) || o.mask_margin_cells > 100) throw UsageError("--mask-margin-cells must be in 0..100");
  if (o.sift) validate(*o.sift);
  if (o.sift && o.sift->mask_clearance_per_size > 0 && !o.mask_markers) {
    throw UsageError("--mask-clearance-per-size keeps features clear of the marker mask: it needs --mask-markers");
  }
  if (o.jobs < 0) throw UsageError("--jobs must be 0 (all cores) or positive");
}

void detect_photos(const std::vector<std::string>& images, const PhotoOptions& options,
                   const std::function<void(PhotoResult&&)>& on_result, const PhotoImageHook& on_image) {
  validate(options);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex mutex;
  std::exception_ptr error;
  std::size_t error_index = images.size();
  auto worker = [&] {
    for (std::size_t i = next++; i < images.size() && !stop; i = next++) {
      try {
        check_image_file(images[i]);
        const cv::Mat grey = cv::imread(images[i], cv::IMREAD_GRAYSCALE);
        if (grey.empty()) throw InputError(images[i], 0, "not a readable image");
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
        if (!stop) on_result(std::move(r));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        // Report the error of the earliest image, whatever the threads' timing.
        if (i < error_index) {
          error = std::current_exception();
          error_index = i;
        }
        stop = true;
      }
    }
  };
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const std::size_t jobs = std::min<std::size_t>(options.jobs > 0 ? static_cast<std::size_t>(options.jobs) : cores,
                                                 std::max<std::size_t>(1, images.size()));
  {
    std::vector<std::jthread> threads;
    for (std::size_t t = 1; t < jobs; ++t) threads.emplace_back(worker);
    worker();
  }  // joins
  if (error) std::rethrow_exception(error);
}

}  // namespace photomill::detect
