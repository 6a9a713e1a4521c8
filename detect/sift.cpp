// SIFT features and the marker mask (contract in sift.hpp).
#include "detect/sift.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "detect/sift_scale_space.hpp"
#include "formats/error.hpp"

namespace photomill::detect {

void validate(const SiftOptions& o) {
  if (o.max_features < 0) throw UsageError("--max-features must be 0 (no cap) or positive");
  if (o.cap_cell_px < 0) throw UsageError("--cap-cell-px must be 0 (strongest in the image) or positive");
  if (o.octave_layers < 1 || o.octave_layers > 10) throw UsageError("--sift-octave-layers must be in 1..10");
  if (!(o.contrast_threshold >= 0) || !std::isfinite(o.contrast_threshold)) {
    throw UsageError("--sift-contrast-threshold must be a non-negative number");
  }
  if (!(o.edge_threshold > 0) || !std::isfinite(o.edge_threshold)) throw UsageError("--sift-edge-threshold must be positive");
  if (!(o.sigma > 0) || !std::isfinite(o.sigma)) throw UsageError("SIFT sigma must be positive");
  if (!std::isfinite(o.position_offset_px)) throw UsageError("SIFT position offset must be finite");
  if (!(o.mask_clearance_per_size >= 0) || !std::isfinite(o.mask_clearance_per_size)) {
    throw UsageError("--mask-clearance-per-size must be a non-negative number");
  }
}

namespace {

// The first max_features keypoints of spread_order(all, cap_cell_px, cap_order).
std::vector<cv::KeyPoint> cap(const std::vector<cv::KeyPoint>& all, const SiftOptions& o) {
  const std::vector<std::size_t> order = spread_order(all, o.cap_cell_px, o.cap_order);
  const std::size_t kept = std::min(order.size(), static_cast<std::size_t>(o.max_features));
  std::vector<cv::KeyPoint> keypoints;
  keypoints.reserve(kept);
  for (std::size_t k = 0; k < kept; ++k) keypoints.push_back(all[order[k]]);
  return keypoints;
}

}  // namespace

FeatureSet detect_sift(const cv::Mat& grey, const std::string& image_name, const SiftOptions& o, const cv::Mat& mask) {
  CV_Assert(grey.type() == CV_8UC1);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == grey.size()));
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  const bool clearance = !mask.empty() && o.mask_clearance_per_size > 0;
  const bool opencv_cap = o.max_features == 0 || (o.cap_cell_px == 0 && o.cap_order == CapOrder::Response);
  // One scale space for finding and describing (sift_scale_space.hpp): cv::SIFT would build it
  // again to describe keypoints chosen after detection.
  const SiftScaleSpace space(grey, o.octave_layers, o.sigma);
  if (!clearance && opencv_cap) {
    // As cv::SIFT::detectAndCompute with nfeatures = max_features: the strongest kept
    // (KeyPointsFilter::retainBest), then the mask.
    keypoints = space.keypoints(o.contrast_threshold, o.edge_threshold);
    if (o.max_features > 0) cv::KeyPointsFilter::retainBest(keypoints, o.max_features);
    if (!mask.empty()) cv::KeyPointsFilter::runByPixelsMask(keypoints, mask);
  } else {
    // All keypoints, with a clearance those too near the mask's blanks dropped, then the cap.
    std::vector<cv::KeyPoint> all = space.keypoints(o.contrast_threshold, o.edge_threshold, mask);
    if (clearance) {
      // Exact Euclidean distance of every allowed pixel to the nearest blanked one (OpenCV's
      // DIST_MASK_PRECISE: Felzenszwalb & Huttenlocher 2012, "Distance transforms of sampled functions").
      cv::Mat clear_px;
      cv::distanceTransform(mask, clear_px, cv::DIST_L2, cv::DIST_MASK_PRECISE);
      std::erase_if(all, [&](const cv::KeyPoint& k) {
        const int x = std::clamp(static_cast<int>(std::lround(k.pt.x)), 0, clear_px.cols - 1);
        const int y = std::clamp(static_cast<int>(std::lround(k.pt.y)), 0, clear_px.rows - 1);
        return clear_px.at<float>(y, x) < o.mask_clearance_per_size * k.size;
      });
    }
    if (o.max_features > 0 && opencv_cap) {
      cv::KeyPointsFilter::retainBest(all, o.max_features);
      keypoints = std::move(all);
    } else {
      keypoints = o.max_features > 0 ? cap(all, o) : std::move(all);
    }
  }
  descriptors = space.descriptors(keypoints);
  FeatureSet fs;
  fs.image = image_name;
  fs.image_width_px = grey.cols;
  fs.image_height_px = grey.rows;
  fs.descriptor_dim = descriptors.empty() ? 128 : descriptors.cols;
  std::vector<std::size_t> order(keypoints.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return keypoints[a].response > keypoints[b].response; });
  fs.keypoints.reserve(order.size());
  fs.descriptors.reserve(order.size() * static_cast<std::size_t>(fs.descriptor_dim));
  for (std::size_t k : order) {
    const cv::KeyPoint& kp = keypoints[k];
    fs.keypoints.push_back({kp.pt.x + o.position_offset_px, kp.pt.y + o.position_offset_px, kp.size, kp.angle,
                            kp.response});
    const auto* row = descriptors.ptr<std::uint8_t>(static_cast<int>(k));
    fs.descriptors.insert(fs.descriptors.end(), row, row + fs.descriptor_dim);
  }
  return fs;
}

std::vector<std::size_t> spread_order(const std::vector<cv::KeyPoint>& keypoints, int cell_px, CapOrder by) {
  std::vector<std::pair<long, long>> cell(keypoints.size());
  for (std::size_t k = 0; k < keypoints.size() && cell_px > 0; ++k) {
    cell[k] = {static_cast<long>(std::floor(keypoints[k].pt.x / cell_px)),
               static_cast<long>(std::floor(keypoints[k].pt.y / cell_px))};
  }
  const auto stronger = [&](std::size_t a, std::size_t b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    if (by == CapOrder::Scale && ka.size != kb.size) return ka.size > kb.size;
    return ka.response > kb.response;
  };
  std::vector<std::size_t> by_cell(keypoints.size());
  std::iota(by_cell.begin(), by_cell.end(), std::size_t{0});
  std::stable_sort(by_cell.begin(), by_cell.end(),
                   [&](std::size_t a, std::size_t b) { return cell[a] != cell[b] ? cell[a] < cell[b] : stronger(a, b); });
  std::vector<std::size_t> rank(keypoints.size());
  for (std::size_t k = 0; k < by_cell.size(); ++k) {
    const bool same_cell = k > 0 && cell[by_cell[k]] == cell[by_cell[k - 1]];
    rank[by_cell[k]] = same_cell ? rank[by_cell[k - 1]] + 1 : 0;
  }
  std::vector<std::size_t> order(keypoints.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return rank[a] != rank[b] ? rank[a] < rank[b] : stronger(a, b); });
  return order;
}

cv::Mat marker_mask(cv::Size size, const std::vector<std::array<Eigen::Vector2d, 4>>& markers, int cells,
                    double margin_cells) {
  cv::Mat mask(size, CV_8UC1, cv::Scalar(255));
  // Growing a marker by m cells on every side scales it about its centre by (cells + 2m) / cells
  // (exact for a parallelogram, close enough under perspective).
  const double scale = (cells + 2 * margin_cells) / cells;
  for (const auto& q : markers) {
    const Eigen::Vector2d c = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    std::vector<cv::Point> poly;
    for (const auto& p : q) {
      const Eigen::Vector2d g = c + scale * (p - c);
      poly.emplace_back(static_cast<int>(std::lround(g.x())), static_cast<int>(std::lround(g.y())));
    }
    cv::fillConvexPoly(mask, poly, cv::Scalar(0));
  }
  return mask;
}

}  // namespace photomill::detect
