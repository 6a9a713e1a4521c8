// One photo's SIFT scale space (Lowe 2004, "Distinctive image features from scale-invariant
// keypoints", IJCV 60(2)), built once and used both to find the keypoints and to describe the ones
// a cap keeps. OpenCV 4.6's cv::SIFT builds it twice when keypoints are chosen between detection
// and description (detect, then compute on the kept ones), and that second build of a 2x
// upsampled photo's Gaussian pyramid was a fifth of detect's time on the demo
// (docs/measurements/detect.md, session 61).
//
// The conventions are OpenCV 4.6's (modules/features2d/src/sift.simd.hpp), so that keypoints and
// descriptors are interchangeable with cv::SIFT's and every figure measured with those stays
// valid: the photo doubled in size by bilinear interpolation as the first octave (assumed blur
// 0.5 px, so 1 px doubled), s + 3 Gaussian layers per octave, each octave's base the previous
// one's layer s taken at every other pixel; extrema of the difference of Gaussians against their
// 26 neighbours, refined by the quadratic fit (Lowe eq. 3, at most 5 moves), the contrast test
// |D(x)| s >= contrast_threshold and the edge test tr^2 r < (r + 1)^2 det; orientations from a
// 36-bin histogram of gradients in a Gaussian window of 1.5 sigma (radius 4.5 sigma), smoothed
// by (1 4 6 4 1)/16, every peak within 80 % of the highest, parabola-interpolated; descriptors
// of 4 x 4 cells of 8 orientations over a window of 3 sigma per cell, trilinear votes, clipped at
// 0.2 of the norm, renormalised and scaled by 512 into bytes. sift_scale_space_test.cpp checks
// the keypoints and descriptors against cv::SIFT's on photos.
#pragma once

#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/types.hpp>

namespace photomill::detect {

class SiftScaleSpace {
 public:
  // Builds the Gaussian pyramid of `grey` (CV_8UC1) doubled in size: octaves down to a side of
  // about 8 px, `octave_layers` + 3 layers each, the first blurred to `sigma`.
  SiftScaleSpace(const cv::Mat& grey, int octave_layers, double sigma);

  // Every keypoint (as cv::SIFT::detect with nfeatures 0 gives them: duplicates removed, sorted
  // as KeyPointsFilter::removeDuplicatedSorted leaves them, in the photo's coordinates, octave
  // packed as OpenCV packs it), then those on a zero of `mask` (if given) dropped.
  std::vector<cv::KeyPoint> keypoints(double contrast_threshold, double edge_threshold,
                                      const cv::Mat& mask = cv::Mat()) const;

  // The 128-byte descriptors (CV_8U, a row per keypoint) of keypoints from keypoints().
  cv::Mat descriptors(const std::vector<cv::KeyPoint>& keypoints) const;

 private:
  int layers_;
  double sigma_;
  int octaves_ = 0;
  std::vector<cv::Mat> gauss_;  // octave o, layer i at o * (layers_ + 3) + i; octave 0 is the doubled photo
};

}  // namespace photomill::detect
