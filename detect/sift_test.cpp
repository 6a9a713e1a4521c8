// SIFT features: keypoint positions against Gaussian blobs at known sub-pixel centres (OpenCV
// 4.6 reports them 1/4 px off, opencv/opencv#23123; detect_sift takes that out), the cap, the
// order, the marker mask, and the features file round trip.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <random>
#include <sstream>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "detect/huge_pages.hpp"
#include "detect/sift.hpp"
#include "formats/error.hpp"

namespace photomill::detect {
namespace {

// 20 x 20 Gaussian blobs of standard deviation `sigma_px` on a 1000 x 1000 image, each at a
// random sub-pixel centre (OpenCV's pixel convention: the value of pixel (x, y) is the blob
// evaluated at (x, y)).
struct Blobs {
  cv::Mat image;
  std::vector<Eigen::Vector2d> centres;
};

Blobs make_blobs(double sigma_px, unsigned seed) {
  Blobs b;
  cv::Mat img(1000, 1000, CV_32F, cv::Scalar(40));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int gy = 0; gy < 20; ++gy) {
    for (int gx = 0; gx < 20; ++gx) {
      const Eigen::Vector2d c(25 + gx * 48 + u(rng), 25 + gy * 48 + u(rng));
      b.centres.push_back(c);
      for (int y = static_cast<int>(c.y()) - 20; y <= static_cast<int>(c.y()) + 20; ++y) {
        for (int x = static_cast<int>(c.x()) - 20; x <= static_cast<int>(c.x()) + 20; ++x) {
          const double r2 = (Eigen::Vector2d(x, y) - c).squaredNorm();
          img.at<float>(y, x) += static_cast<float>(180 * std::exp(-r2 / (2 * sigma_px * sigma_px)));
        }
      }
    }
  }
  img.convertTo(b.image, CV_8U);
  return b;
}

// Mean keypoint - centre over the blobs whose nearest keypoint is within 1.5 px.
Eigen::Vector2d mean_offset(const std::vector<Eigen::Vector2d>& keypoints, const std::vector<Eigen::Vector2d>& centres,
                            int* matched) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  *matched = 0;
  for (const auto& c : centres) {
    const Eigen::Vector2d* best = nullptr;
    for (const auto& k : keypoints) {
      if (!best || (k - c).norm() < (*best - c).norm()) best = &k;
    }
    if (best && (*best - c).norm() < 1.5) {
      sum += *best - c;
      ++*matched;
    }
  }
  return *matched ? Eigen::Vector2d(sum / *matched) : sum;
}

class SiftPositions : public ::testing::TestWithParam<double> {};

TEST_P(SiftPositions, KeypointsSitOnTheBlobCentres) {
  const Blobs b = make_blobs(GetParam(), 3);
  // OpenCV's own coordinates, for the record and to show the correction is needed.
  std::vector<cv::KeyPoint> raw;
  cv::SIFT::create()->detect(b.image, raw);
  std::vector<Eigen::Vector2d> raw_xy;
  for (const auto& k : raw) raw_xy.emplace_back(k.pt.x, k.pt.y);
  int matched = 0;
  const Eigen::Vector2d raw_offset = mean_offset(raw_xy, b.centres, &matched);
  const FeatureSet fs = detect_sift(b.image, "blobs", {});
  std::vector<Eigen::Vector2d> xy;
  for (const auto& k : fs.keypoints) xy.emplace_back(k.x_px, k.y_px);
  const Eigen::Vector2d offset = mean_offset(xy, b.centres, &matched);
  std::cout << "[ sift     ] blobs of sigma " << GetParam() << " px: OpenCV's keypoints are off by (" << raw_offset.x() << ", "
            << raw_offset.y() << ") px on average, detect_sift's by (" << offset.x() << ", " << offset.y() << ") px\n";
  EXPECT_GE(matched, 380);
  EXPECT_GT(raw_offset.minCoeff(), 0.15);
  EXPECT_LT(offset.cwiseAbs().maxCoeff(), 0.05);
}

INSTANTIATE_TEST_SUITE_P(Blobs, SiftPositions, ::testing::Values(2.0, 3.0));

cv::Mat texture(unsigned seed) {
  cv::Mat img(480, 640, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 2.0);
  cv::normalize(img, img, 0, 255, cv::NORM_MINMAX);
  return img;
}

TEST(Sift, CapKeepsTheStrongestInOrder) {
  const cv::Mat img = texture(5);
  SiftOptions o;
  o.max_features = 0;
  const FeatureSet all = detect_sift(img, "t", o);
  o.max_features = 100;
  const FeatureSet capped = detect_sift(img, "t", o);
  ASSERT_GT(all.keypoints.size(), 300u);
  EXPECT_LE(capped.keypoints.size(), 100u);
  EXPECT_GE(capped.keypoints.size(), 95u);
  EXPECT_EQ(capped.descriptors.size(), capped.keypoints.size() * 128);
  for (std::size_t k = 1; k < capped.keypoints.size(); ++k) {
    EXPECT_GE(capped.keypoints[k - 1].response, capped.keypoints[k].response);
  }
  // The capped set is the strongest of all.
  EXPECT_GE(capped.keypoints.back().response, all.keypoints[150].response);
}

TEST(Sift, MaskedMarkersGetNoFeatures) {
  const cv::Mat img = texture(9);
  const std::vector<std::array<Eigen::Vector2d, 4>> markers{
      {Eigen::Vector2d(100, 100), {220, 110}, {210, 230}, {95, 215}},
      {Eigen::Vector2d(400, 300), {480, 300}, {480, 380}, {400, 380}}};
  const int cells = 6;
  const double margin = 1;
  const cv::Mat mask = marker_mask(img.size(), markers, cells, margin);
  EXPECT_EQ(mask.at<std::uint8_t>(160, 160), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(340, 440), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(390, 440), 0);    // within one cell (13.3 px) of the second marker
  EXPECT_EQ(mask.at<std::uint8_t>(397, 440), 255);  // beyond it
  const FeatureSet fs = detect_sift(img, "t", {}, mask);
  ASSERT_GT(fs.keypoints.size(), 100u);
  // OpenCV tests the mask at its own (1/4 px shifted) position: allow the pixel next door.
  cv::Mat allowed;
  cv::dilate(mask, allowed, cv::Mat::ones(3, 3, CV_8U));
  for (const auto& k : fs.keypoints) {
    const int x = static_cast<int>(std::lround(k.x_px)), y = static_cast<int>(std::lround(k.y_px));
    EXPECT_EQ(allowed.at<std::uint8_t>(y, x), 255) << k.x_px << " " << k.y_px;
  }
}

// With a clearance, no kept keypoint's neighbourhood (clearance x size) reaches the mask's blanks,
// and the keypoints far from them are the ones OpenCV's position-only mask keeps; parameterized
// over the cap (none, by strength, spread over cells): each path applies it.
class SiftClearance : public ::testing::TestWithParam<std::pair<int, int>> {};

TEST_P(SiftClearance, NoFeatureReachesTheMask) {
  const cv::Mat img = texture(9);
  const std::vector<std::array<Eigen::Vector2d, 4>> markers{
      {Eigen::Vector2d(100, 100), {220, 110}, {210, 230}, {95, 215}},
      {Eigen::Vector2d(400, 300), {480, 300}, {480, 380}, {400, 380}}};
  const cv::Mat mask = marker_mask(img.size(), markers, 6, 1);
  cv::Mat clear_px;
  cv::distanceTransform(mask, clear_px, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const auto clearance = [&](const Keypoint& k) {
    return clear_px.at<float>(static_cast<int>(std::lround(k.y_px)), static_cast<int>(std::lround(k.x_px)));
  };
  SiftOptions o;
  o.max_features = 0;
  const FeatureSet plain = detect_sift(img, "t", o, mask);  // all of them, position-only mask
  o.max_features = GetParam().first;
  o.cap_cell_px = GetParam().second;
  o.mask_clearance_per_size = 1;
  const FeatureSet cleared = detect_sift(img, "t", o, mask);
  ASSERT_GT(cleared.keypoints.size(), 50u);
  EXPECT_EQ(cleared.descriptors.size(), cleared.keypoints.size() * 128);
  std::size_t near = 0;
  for (const auto& k : plain.keypoints) near += clearance(k) < k.size_px;
  EXPECT_GT(near, 5u) << "the texture should put some keypoints beside the markers";
  // 0.5 px for the quarter-pixel shift and the rounding of the position.
  for (const auto& k : cleared.keypoints) EXPECT_GE(clearance(k) + 0.75, k.size_px) << k.x_px << " " << k.y_px;
  if (o.max_features == 0) {  // no cap: exactly the plain set without the near ones
    std::size_t far = 0;
    for (const auto& k : plain.keypoints) far += clearance(k) >= k.size_px + 0.75;
    EXPECT_GE(cleared.keypoints.size(), far);
    EXPECT_LE(cleared.keypoints.size(), plain.keypoints.size() - near + 2);
  }
}

INSTANTIATE_TEST_SUITE_P(Caps, SiftClearance,
                         ::testing::Values(std::pair{0, 0}, std::pair{200, 0}, std::pair{200, 64}));

TEST(Sift, FeatureSetsRoundTripThroughTheFileFormat) {
  const FeatureSet fs = detect_sift(texture(2), "dir/img.png", {});
  std::stringstream s;
  write_features(s, fs);
  const FeatureSet back = read_features(s, "mem");
  EXPECT_EQ(back.keypoints.size(), fs.keypoints.size());
  EXPECT_EQ(back.descriptors, fs.descriptors);
  EXPECT_EQ(back.image, "dir/img.png");
  for (std::size_t k = 0; k < fs.keypoints.size(); ++k) EXPECT_EQ(back.keypoints[k], fs.keypoints[k]);
}

TEST(Sift, OptionsAreChecked) {
  SiftOptions o;
  o.max_features = -1;
  EXPECT_THROW(validate(o), UsageError);
  o = {};
  o.edge_threshold = 0;
  EXPECT_THROW(validate(o), UsageError);
  o = {};
  o.cap_cell_px = -1;
  EXPECT_THROW(validate(o), UsageError);
  o = {};
  o.mask_clearance_per_size = -0.5;
  EXPECT_THROW(validate(o), UsageError);
}

// The cap by scale keeps the largest keypoints of all those found (ties by response), each with
// its descriptor, and spread over cells keeps each cell's largest first.
TEST(Sift, ScaleCapKeepsTheLargest) {
  const cv::Mat img = texture(4);
  SiftOptions o;
  o.max_features = 0;
  const FeatureSet all = detect_sift(img, "t", o);
  ASSERT_GT(all.keypoints.size(), 400u);
  std::vector<double> sizes;
  for (const auto& k : all.keypoints) sizes.push_back(k.size_px);
  std::sort(sizes.begin(), sizes.end(), std::greater<>());
  o.max_features = 100;
  o.cap_order = CapOrder::Scale;
  const FeatureSet largest = detect_sift(img, "t", o);
  ASSERT_EQ(largest.keypoints.size(), 100u);
  EXPECT_EQ(largest.descriptors.size(), 100u * 128);
  for (const auto& k : largest.keypoints) EXPECT_GE(k.size_px, sizes[99]);
  o.cap_order = CapOrder::Response;
  const FeatureSet strongest = detect_sift(img, "t", o);
  std::size_t small = 0;
  for (const auto& k : strongest.keypoints) small += k.size_px < sizes[99] ? 1 : 0;
  EXPECT_GT(small, 50u) << "the strongest keypoints should mostly be smaller ones";
  const auto kp = [](float x, float size, float response) { return cv::KeyPoint(x, 10.f, size, -1.f, response); };
  const std::vector<cv::KeyPoint> k{kp(10, 3, 0.9f), kp(20, 8, 0.1f), kp(30, 8, 0.2f), kp(150, 4, 0.5f)};
  EXPECT_EQ(spread_order(k, 0, CapOrder::Scale), (std::vector<std::size_t>{2, 1, 3, 0}));
  EXPECT_EQ(spread_order(k, 100, CapOrder::Scale), (std::vector<std::size_t>{2, 3, 1, 0}));
}

// Three cells of 100 px: the first with four strong keypoints, the others with weaker ones.
TEST(Sift, SpreadOrderTakesEachCellsStrongestFirst) {
  const auto kp = [](float x, float y, float response) { return cv::KeyPoint(x, y, 3.f, -1.f, response); };
  const std::vector<cv::KeyPoint> k{kp(10, 10, 0.9f),  kp(20, 10, 0.8f),  kp(30, 10, 0.7f), kp(40, 10, 0.6f),
                                    kp(150, 10, 0.2f), kp(160, 10, 0.3f), kp(10, 150, 0.1f)};
  EXPECT_EQ(spread_order(k, 100), (std::vector<std::size_t>{0, 5, 6, 1, 4, 2, 3}));
  // One cell over everything: plain decreasing response.
  EXPECT_EQ(spread_order(k, 1000), (std::vector<std::size_t>{0, 1, 2, 3, 5, 4, 6}));
}

// The left half at full contrast, the right half at a fifth (a shadowed flank): the cap kept by
// strength alone leaves the dim half almost bare, spread over cells it keeps about half there.
TEST(Sift, SpreadCapKeepsFeaturesInTheShadow) {
  cv::Mat img = texture(11);
  cv::Mat right = img(cv::Rect(img.cols / 2, 0, img.cols / 2, img.rows));
  right.convertTo(right, -1, 0.2, 100);
  SiftOptions o;
  o.contrast_threshold = 0.01;
  o.max_features = 300;
  const auto share_right = [&](const FeatureSet& fs) {
    std::size_t n = 0;
    for (const auto& k : fs.keypoints) n += k.x_px >= img.cols / 2 + 8 ? 1 : 0;
    return static_cast<double>(n) / static_cast<double>(fs.keypoints.size());
  };
  const FeatureSet strongest = detect_sift(img, "t", o);
  o.cap_cell_px = 64;
  const FeatureSet spread = detect_sift(img, "t", o);
  ASSERT_EQ(strongest.keypoints.size(), 300u);
  ASSERT_EQ(spread.keypoints.size(), 300u);
  EXPECT_EQ(spread.descriptors.size(), 300u * 128);
  std::cout << "[ sift     ] share of features in the dim half: strongest " << share_right(strongest) << ", spread "
            << share_right(spread) << "\n";
  EXPECT_LT(share_right(strongest), 0.1);
  EXPECT_GT(share_right(spread), 0.35);
  // Kept in spread order: responses decrease within every cell.
  std::map<std::pair<int, int>, float> last;
  for (const auto& k : spread.keypoints) {
    const std::pair<int, int> cell(static_cast<int>((k.x_px + 0.25) / 64), static_cast<int>((k.y_px + 0.25) / 64));
    if (last.count(cell)) {
      EXPECT_LE(k.response, last[cell]);
    }
    last[cell] = k.response;
  }
}

// Large images in huge pages: a large Mat starts on a 2 MiB boundary and holds what is written;
// a small one still comes from OpenCV's allocator; a freed block is reused for the same size;
// SIFT finds the same features either way.
// (Installs the allocator for the rest of this test program.)
TEST(HugePages, SameFeaturesAndAlignedLargeImages) {
  cv::Mat big_texture;
  cv::resize(texture(5), big_texture, cv::Size(), 2, 2, cv::INTER_CUBIC);  // its doubled octave: MBs
  SiftOptions o;
  o.max_features = 500;
  o.cap_order = CapOrder::Scale;
  const FeatureSet before = detect_sift(big_texture, "t", o);
  use_huge_pages_for_large_images(std::size_t{1} << 20);
  use_huge_pages_for_large_images();  // idempotent
  cv::Mat large(2000, 1000, CV_32F, cv::Scalar(1.5f));
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(large.data) % (std::uintptr_t{2} << 20), 0u);
  large.at<float>(1999, 999) = 7;
  EXPECT_EQ(cv::sum(large)[0], 1.5 * 2000 * 1000 - 1.5 + 7);
  cv::Mat view = large(cv::Rect(10, 10, 100, 100)).clone();  // 40 kB: OpenCV's own allocator
  EXPECT_EQ(view.at<float>(0, 0), 1.5f);
  const uchar* block = large.data;
  large.release();
  // The freed block is kept and handed to the next array of its size, as it was written (not
  // cleared); one of another size gets a block of its own.
  cv::Mat again(2000, 1000, CV_32F);
  EXPECT_EQ(again.data, block);
  EXPECT_EQ(again.at<float>(1999, 999), 7.0f);
  cv::Mat other(3000, 1000, CV_32F);
  EXPECT_NE(other.data, block);
  again.release();
  other.release();
  // SIFT's pyramids in reused blocks (the second run's are the first's) give the same features.
  for (int run = 0; run < 2; ++run) {
    const FeatureSet after = detect_sift(big_texture, "t", o);
    ASSERT_EQ(after.keypoints.size(), before.keypoints.size());
    EXPECT_EQ(after.descriptors, before.descriptors);
    for (std::size_t k = 0; k < after.keypoints.size(); ++k) EXPECT_EQ(after.keypoints[k], before.keypoints[k]);
  }
}

}  // namespace
}  // namespace photomill::detect
