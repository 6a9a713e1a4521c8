// SiftScaleSpace against OpenCV 4.6's cv::SIFT on the same images: the same keypoints (position,
// size, orientation, octave, response to float rounding) and the same descriptors (to one unit
// in a rare byte: OpenCV's build sums some loops in SIMD order), with and without a mask, at
// photomill's contrast threshold and OpenCV's default; and descriptors that do not depend on which
// other keypoints are described with them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "detect/sift_scale_space.hpp"

namespace photomill::detect {
namespace {

cv::Mat demo_crop(const std::string& name, cv::Rect roi) {
  const cv::Mat grey = cv::imread(std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/" + name, cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(grey.empty()) << name;
  return grey.empty() ? cv::Mat() : grey(roi).clone();
}

struct Comparison {
  std::size_t opencv = 0, ours = 0;
  std::size_t unlike_keypoints = 0;  // index by index: position, size or angle apart, or another octave
  double max_position_px = 0, max_relative_response = 0;
  std::size_t bytes = 0, bytes_differing = 0;
  int max_byte_difference = 0;
};

// Both keypoint lists come out of KeyPointsFilter::removeDuplicatedSorted (ordered by position,
// size, angle), so the same set is in the same order.
Comparison compare(const cv::Mat& grey, double contrast, const cv::Mat& mask = cv::Mat()) {
  Comparison c;
  const auto sift = cv::SIFT::create(0, 3, contrast, 10, 1.6, CV_8U);
  std::vector<cv::KeyPoint> theirs;
  cv::Mat their_descriptors;
  sift->detectAndCompute(grey, mask, theirs, their_descriptors);
  const SiftScaleSpace space(grey, 3, 1.6);
  const std::vector<cv::KeyPoint> ours = space.keypoints(contrast, 10, mask);
  const cv::Mat our_descriptors = space.descriptors(ours);
  c.opencv = theirs.size();
  c.ours = ours.size();
  for (std::size_t k = 0; k < std::min(theirs.size(), ours.size()); ++k) {
    const cv::KeyPoint& a = theirs[k];
    const cv::KeyPoint& b = ours[k];
    const double position = cv::norm(a.pt - b.pt);
    const double turn = std::abs(std::remainder(static_cast<double>(a.angle - b.angle), 360.0));
    if (position > 1e-3 || std::abs(a.size - b.size) > 1e-3 || turn > 1e-2 || a.octave != b.octave) {
      ++c.unlike_keypoints;
      continue;
    }
    c.max_position_px = std::max(c.max_position_px, position);
    c.max_relative_response = std::max(c.max_relative_response, static_cast<double>(std::abs(a.response - b.response) / a.response));
    for (int q = 0; q < 128; ++q) {
      const int d = std::abs(their_descriptors.at<std::uint8_t>(static_cast<int>(k), q) -
                             our_descriptors.at<std::uint8_t>(static_cast<int>(k), q));
      ++c.bytes;
      c.bytes_differing += d != 0;
      c.max_byte_difference = std::max(c.max_byte_difference, d);
    }
  }
  return c;
}

void expect_same(const Comparison& c) {
  EXPECT_GT(c.opencv, 500u);
  EXPECT_EQ(c.ours, c.opencv);
  EXPECT_EQ(c.unlike_keypoints, 0u);
  EXPECT_LT(c.max_position_px, 1e-3);
  EXPECT_LT(c.max_relative_response, 1e-5);
  EXPECT_LE(c.max_byte_difference, 1);
  EXPECT_LE(static_cast<double>(c.bytes_differing), 1e-4 * static_cast<double>(c.bytes));
}

TEST(SiftScaleSpace, KeypointsAndDescriptorsAreOpenCvs) {
  // A corner of a demo photo: the marker plate, markers and the part's speckle.
  const cv::Mat grey = demo_crop("part_03.jpg", cv::Rect(700, 500, 640, 480));
  expect_same(compare(grey, 0.01));
  expect_same(compare(grey, 0.04));  // OpenCV's default: the first test's threshold is no longer 0
}

TEST(SiftScaleSpace, MaskedAsOpenCvMasks) {
  const cv::Mat grey = demo_crop("part_07.jpg", cv::Rect(400, 300, 700, 520));
  cv::Mat mask(grey.size(), CV_8U, cv::Scalar(255));
  cv::rectangle(mask, cv::Rect(100, 80, 300, 200), cv::Scalar(0), cv::FILLED);
  const Comparison c = compare(grey, 0.01, mask);
  expect_same(c);
  EXPECT_LT(c.opencv, compare(grey, 0.01).opencv);  // the mask took some
}

TEST(SiftScaleSpace, DescriptorsDoNotDependOnTheOtherKeypoints) {
  // descriptors() visits keypoints layer by layer and down the image; a keypoint's descriptor is
  // the same whether it is described alone, with a few, or with all.
  const cv::Mat grey = demo_crop("part_05.jpg", cv::Rect(600, 400, 600, 450));
  const SiftScaleSpace space(grey, 3, 1.6);
  const std::vector<cv::KeyPoint> all = space.keypoints(0.01, 10);
  ASSERT_GT(all.size(), 300u);
  const cv::Mat every = space.descriptors(all);
  std::vector<cv::KeyPoint> some;
  std::vector<int> rows;
  for (std::size_t k = all.size(); k-- > 0;) {  // backwards, every seventh
    if (k % 7 != 0) continue;
    some.push_back(all[k]);
    rows.push_back(static_cast<int>(k));
  }
  const cv::Mat few = space.descriptors(some);
  ASSERT_EQ(few.rows, static_cast<int>(some.size()));
  for (std::size_t q = 0; q < some.size(); ++q) {
    EXPECT_EQ(cv::norm(few.row(static_cast<int>(q)), every.row(rows[q]), cv::NORM_L1), 0.0) << "keypoint " << rows[q];
  }
  EXPECT_EQ(space.descriptors({}).rows, 0);
}

}  // namespace
}  // namespace photomill::detect
