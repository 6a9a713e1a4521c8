// Natural features for match: SIFT keypoints and descriptors (Lowe 2004, as OpenCV 4.6's
// cv::SIFT computes them) of one grey image, optionally masked away from the markers, capped at
// N (the strongest or the largest), as a FeatureSet (formats/features.hpp, "photomill-features v1").
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "formats/features.hpp"

namespace photomill::detect {

// Which keypoints the cap keeps first.
//   Response: the strongest (OpenCV's nfeatures, KeyPointsFilter::retainBest).
//   Scale: the largest (coarse octaves first, ties by response). A large keypoint's window is
//   described from more of the scene and survives a wider baseline and a change of distance;
//   the finest ones are the most numerous and the least repeatable. COLMAP keeps whole octaves
//   from the coarsest down for the same reason (SiftExtractionOptions::max_num_features). On the
//   Sceaux castle's 11 photos, 11 000 kept by scale gave 3x the verified matches of 8 000 by
//   response (docs/measurements/detect.md).
enum class CapOrder { Response, Scale };

struct SiftOptions {
  int max_features = 8000;          // keypoints kept per image (in cap_order); 0: all
  CapOrder cap_order = CapOrder::Response;
  // 0: the cap keeps the image's strongest keypoints. > 0: the cap is spread over square cells
  // of this side (px): every cell's strongest first, then every cell's second, ... (see
  // spread_order), so dim or shadowed parts of a photo keep features beside bright ones.
  int cap_cell_px = 0;
  // With a mask: also drop keypoints nearer to a blanked pixel than this many times their size
  // (OpenCV's keypoint diameter), so no feature's neighbourhood reaches into what the mask blanks.
  // 0: only the keypoint's own position is tested (OpenCV's mask). Why: a feature just outside a
  // marker's mask is described, and least-squares matched, mostly by the marker's straight black
  // border, along which it can slide (the aperture problem); on the demo such two-view points sat
  // in the quiet zones up to 0.1 mm off, with no neighbours to outvote them (docs/measurements/detect.md).
  double mask_clearance_per_size = 0;
  int octave_layers = 3;            // Lowe's s: scales sampled per octave
  // OpenCV's measure, divided by s (OpenCV's default 0.04; Lowe's 0.03 is 0.09 here, COLMAP's
  // 0.0067 peak threshold 0.02). 0.01 keeps the weakly textured and shadowed surfaces that a
  // part of plaster or cast metal has (docs/measurements/detect.md).
  double contrast_threshold = 0.01;
  double edge_threshold = 10;       // Lowe's r: principal-curvature ratio limit
  double sigma = 1.6;               // Lowe's sigma of the first octave
  // OpenCV 4.6 reports keypoints in the coordinates of its 2x upsampled first octave halved,
  // without the half-pixel term of the upsampling: a keypoint at x' there is x'/2 - 1/4 in the
  // image (resize maps dst x' to src (x' + 1/2)/2 - 1/2), not x'/2 (opencv/opencv#23123). This
  // offset is added to x and y of every keypoint; sift_test.cpp measures OpenCV's +0.25 px on
  // Gaussian blobs at known positions. 0 keeps OpenCV's coordinates.
  double position_offset_px = -0.25;
};

// Validates the options; throws UsageError.
void validate(const SiftOptions& options);

// The order in which the cap keeps keypoints when it is spread over cells of `cell_px`: sorted by
// (rank within the keypoint's cell by decreasing key, then decreasing key), the key the response
// or, with CapOrder::Scale, the size (ties by response). cell_px 0: one cell. The first
// N of this order are, for any N, as even a cover of the image as the cells allow: no cell gets
// its (k+1)-th keypoint before every cell that has k has given its k-th. (The idea of selecting
// features over a grid rather than by global strength: ORB-SLAM's per-cell FAST thresholds,
// Mur-Artal et al. 2015; Brown et al. 2005's adaptive non-maximal suppression.)
std::vector<std::size_t> spread_order(const std::vector<cv::KeyPoint>& keypoints, int cell_px,
                                      CapOrder order = CapOrder::Response);

// SIFT on one grey image (CV_8UC1). `mask` (CV_8UC1, same size, or empty): keypoints only where
// it is non-zero (and, with mask_clearance_per_size, clear of its zeros by that much). Keypoints sorted by decreasing response; descriptors as OpenCV's CV_8U SIFT.
FeatureSet detect_sift(const cv::Mat& grey, const std::string& image_name, const SiftOptions& options,
                       const cv::Mat& mask = cv::Mat());

// A mask (255 = features allowed) that blanks every marker quadrilateral grown by `margin_cells`
// marker cells on every side (its quiet zone), `cells` = bits per side + 2.
cv::Mat marker_mask(cv::Size size, const std::vector<std::array<Eigen::Vector2d, 4>>& markers, int cells,
                    double margin_cells);

}  // namespace photomill::detect
