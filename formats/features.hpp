// Natural-feature files (detect -> match): keypoints and their descriptors for one image, as
// text. Header lines "photomill-features v1", "image NAME", "size W H", "count N", "dim D", then
// N lines "x_px y_px size_px angle_deg response d_0 ... d_{D-1}" with descriptors as integers
// 0..255 (SIFT's descriptor as OpenCV computes it, rounded).
#pragma once

#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

namespace photomill {

struct Keypoint {
  double x_px = 0;      // OpenCV pixel convention
  double y_px = 0;
  double size_px = 0;   // diameter of the meaningful neighbourhood
  double angle_deg = 0; // orientation, [0, 360), or -1 if none
  double response = 0;
  bool operator==(const Keypoint&) const = default;
};

struct FeatureSet {
  std::string image;
  int image_width_px = 0;
  int image_height_px = 0;
  int descriptor_dim = 128;
  std::vector<Keypoint> keypoints;
  std::vector<std::uint8_t> descriptors;  // keypoints.size() * descriptor_dim, row-major
  // The run of detect that wrote the file (its stamp, formats/run.hpp): read, not written (the
  // writer stamps the current run's); empty if the file has none.
  std::string run_id;
  bool operator==(const FeatureSet&) const = default;
};

struct FeatureLimits {
  int max_descriptor_dim = 1024;
  std::size_t max_line_bytes = 1 << 16;
};

FeatureSet read_features(std::istream& in, const std::string& source, FeatureLimits limits = {});
void write_features(std::ostream& out, const FeatureSet& features);

}  // namespace photomill
