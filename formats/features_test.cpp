// Feature files: round trip and malformed input.
#include "formats/features.hpp"

#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "formats/run.hpp"

namespace photomill {
namespace {

FeatureSet sample_features() {
  FeatureSet f;
  f.image = "photos/part 01.jpg";
  f.image_width_px = 2000;
  f.image_height_px = 1500;
  f.descriptor_dim = 4;
  f.keypoints = {{10.25, 20.5, 3.1, 45.0, 0.02}, {1999.0, 0.0, 12.0, -1.0, 1e-5}};
  f.descriptors = {0, 255, 12, 7, 1, 2, 3, 4};
  return f;
}

TEST(Features, RoundTrip) {
  std::stringstream s;
  write_features(s, sample_features());
  FeatureSet r = read_features(s, "f.feat");
  EXPECT_EQ(r.run_id, run_id()) << "the writer stamps this process's run";
  r.run_id.clear();
  EXPECT_EQ(r, sample_features());
}

TEST(Features, EmptySetRoundTrips) {
  FeatureSet f = sample_features();
  f.keypoints.clear();
  f.descriptors.clear();
  std::stringstream s;
  write_features(s, f);
  FeatureSet r = read_features(s, "f.feat");
  r.run_id.clear();
  EXPECT_EQ(r, f);
}

std::string error_after_replacing(const std::string& from, const std::string& to) {
  std::stringstream s;
  write_features(s, sample_features());
  std::string text = s.str();
  text.replace(text.find(from), from.size(), to);
  std::istringstream in(text);
  try {
    read_features(in, "f.feat");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Features, MalformedInputIsNamed) {
  EXPECT_NE(error_after_replacing("count 2", "count 3").find("f.feat:9: truncated"), std::string::npos);
  EXPECT_NE(error_after_replacing("count 2", "count 1").find("more features than 'count' says"), std::string::npos);
  EXPECT_NE(error_after_replacing("0 255 12 7", "0 256 12 7").find("f.feat:8: descriptor value must be an integer in 0..255"), std::string::npos);
  EXPECT_NE(error_after_replacing("0 255 12 7", "0 255 12").find("f.feat:8: expected 9 values, got 8"), std::string::npos);
  EXPECT_NE(error_after_replacing("dim 4", "dim 100000").find("f.feat:6: dim must be an integer in 1..1024"), std::string::npos);
  EXPECT_NE(error_after_replacing("photomill-features v1", "features").find("f.feat:1: not a photomill features file"), std::string::npos);
  EXPECT_NE(error_after_replacing("10.25", "nan").find("f.feat:8: x_px is not a finite number"), std::string::npos);
}

}  // namespace
}  // namespace photomill
