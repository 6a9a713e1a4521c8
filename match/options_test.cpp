// One case per match option of the verification, the feature matching, the pair selection and
// least-squares matching (issue 22): the option parses and has its documented effect
// (docs/match.md, --help) on the summary on stderr or the tracks; a value out of its range exits 2
// naming the option. Inputs: the demo's marker observations (12 photos), and markers and SIFT
// features that detect finds in crops of three of the demo's photos.
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "formats/camera.hpp"
#include "formats/tables.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::match {
namespace {

using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

const std::string kDemo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";

// Three 560 x 420 px crops of the demo's photos part_00..02.jpg around the middle of the part (the
// camera's principal point moved with them), and what detect finds in them: markers (obs.csv)
// and SIFT features (feat/). Made once per test process, in a temporary folder where match runs.
struct Detected {
  TempDir dir;
  ToolResult r;
  Detected() {
    for (const char* name : {"part_00.jpg", "part_01.jpg", "part_02.jpg"}) {
      const cv::Mat photo = cv::imread(kDemo + name, cv::IMREAD_GRAYSCALE);
      cv::imwrite((dir.path() / name).string(), photo(cv::Rect(740, 450, 560, 420)), {cv::IMWRITE_JPEG_QUALITY, 95});
    }
    std::ifstream in(kDemo + "camera.yaml");
    Camera camera = read_camera_yaml(in, "camera.yaml");
    camera.image_width_px = 560;
    camera.image_height_px = 420;
    camera.camera_matrix(0, 2) -= 740;
    camera.camera_matrix(1, 2) -= 450;
    std::ofstream out(dir.path() / "camera.yaml");
    write_camera_yaml(out, camera);
    out.close();
    r = run_tool("detect", {"--aruco", "DICT_4X4_100", "--features", "feat", "--mask-markers", "--max-features", "800", "part_00.jpg", "part_01.jpg",
                            "part_02.jpg", "-o", "obs.csv"},
                 "", dir.path());
  }
};
const Detected& detected() {
  static const Detected d;
  return d;
}

struct Outcome {
  ToolResult r;
  std::vector<TrackObservation> tracks;
};

// match with `args` in the folder of the crops; "{demo}" is data/demo/.
Outcome match(std::vector<std::string> args) {
  bool crops = false;
  for (std::string& a : args) {
    for (auto at = a.find("{demo}"); at != std::string::npos; at = a.find("{demo}")) a.replace(at, 6, kDemo);
    crops = crops || a == "obs.csv" || a == "feat";
  }
  TempDir elsewhere;
  std::filesystem::path cwd = elsewhere.path();
  if (crops) {
    const Detected& d = detected();
    EXPECT_EQ(d.r.exit_code, 0) << d.r.err;
    cwd = d.dir.path();
  }
  Outcome run{run_tool("match", args, "", cwd), {}};
  if (run.r.exit_code == 0) {
    std::istringstream out(run.r.out);
    run.tracks = read_tracks(out, "stdout");
  }
  return run;
}

// The whole number just before `what` in the summary (-1 when absent): e.g. " verified".
long number_before(const std::string& err, const std::string& what) {
  const std::size_t at = err.find(what);
  if (at == std::string::npos) return -1;
  std::size_t b = at;
  while (b > 0 && std::isdigit(static_cast<unsigned char>(err[b - 1]))) --b;
  return b == at ? -1 : std::atol(err.c_str() + b);
}
// The whole number just after `what`.
long number_after(const std::string& err, const std::string& what) {
  const std::size_t at = err.find(what);
  return at == std::string::npos ? -1 : std::atol(err.c_str() + at + what.size());
}

long verified(const Outcome& r) { return number_before(r.r.err, " verified"); }
long pairs(const Outcome& r) { return number_before(r.r.err, " pairs looked at"); }
long feature_matches(const Outcome& r) { return number_before(r.r.err, " verified matches"); }
long feature_tracks(const Outcome& r) { return number_after(r.r.err, "natural features: "); }
long lsm_kept(const Outcome& r) { return number_after(r.r.err, "least-squares matching: "); }
long lsm_refused(const Outcome& r) {
  const std::size_t at = r.r.err.find("least-squares matching: ");
  return at == std::string::npos ? -1 : number_before(r.r.err.substr(at), " refused");
}

// The coded points of all 12 demo photos, undistorted by the demo camera.
std::vector<std::string> coded(std::vector<std::string> args) {
  args.insert(args.end(), {"{demo}observations.csv", "--camera", "{demo}camera.yaml"});
  return args;
}
// Markers and features of three photos.
std::vector<std::string> features(std::vector<std::string> args) {
  args.insert(args.end(), {"obs.csv", "--features", "feat", "--camera", "camera.yaml"});
  return args;
}
// Features alone (no coded points), without least-squares matching: the pairs matched by descriptor.
std::vector<std::string> features_only(std::vector<std::string> args) {
  args.insert(args.end(), {"--features", "feat", "--camera", "camera.yaml", "--refine", "none"});
  return args;
}

const Outcome& plain_coded() {
  static const Outcome run = match(coded({}));
  return run;
}
const Outcome& plain_features() {
  static const Outcome run = match(features({}));
  return run;
}

struct OptionCase {
  const char* name;
  std::vector<std::string> args;
  int exit_code;
  std::string stderr_has;
  std::function<void(const Outcome&)> check;
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class MatchOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(MatchOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = match(c.args);
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

OptionCase bad(const char* name, std::vector<std::string> args, std::string option) {
  return {name, coded(std::move(args)), 2, std::move(option), nullptr};
}

INSTANTIATE_TEST_SUITE_P(
    Options, MatchOption,
    ::testing::Values(
        // Verification of the coded points
        // (on detect's markers and features: the demo's observations.csv is exact, every threshold passes it)
        // (A run that verifies no pair has no track: exit 1 naming why, not a header-only file.)
        OptionCase{"threshold_px", features({"--refine", "none", "--threshold-px", "0.001"}), 1, "no tracks: no point is seen in two of the 3 images",
                   [](const Outcome& r) {
                     const Outcome plain = match(features({"--refine", "none"}));
                     EXPECT_LT(verified(r), verified(plain)) << r.r.err << plain.r.err;
                   }},
        bad("threshold_px_zero", {"--threshold-px", "0"}, "--threshold-px"),
        OptionCase{"ransac_confidence", coded({"--ransac-confidence", "0.6"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(verified(r), verified(plain_coded())); }},
        bad("ransac_confidence_0_4", {"--ransac-confidence", "0.4"}, "--ransac-confidence"),
        OptionCase{"ransac_iterations", coded({"--ransac-iterations", "10"}), 0, "",
                   [](const Outcome& r) { EXPECT_GT(verified(r), 0); }},
        bad("ransac_iterations_5", {"--ransac-iterations", "5"}, "--ransac-iterations"),
        OptionCase{"min_inliers", coded({"--min-inliers", "1000"}), 1, "no tracks: no point is seen in two of the 12 images",
                   [](const Outcome& r) {
                     // No pair has 1000 coded points in common: none is verified, nothing is kept.
                     EXPECT_EQ(verified(r), 0) << r.r.err;
                     EXPECT_TRUE(r.tracks.empty());
                     EXPECT_GT(verified(plain_coded()), 0);
                   }},
        bad("min_inliers_7", {"--min-inliers", "7"}, "--min-inliers"),
        OptionCase{"min_inlier_ratio", features({"--refine", "none", "--min-inlier-ratio", "1"}), 1, "no tracks: no point is seen in two of the 3 images",
                   [](const Outcome& r) {
                     // No pair of photos has only inliers among its feature matches.
                     const Outcome plain = match(features({"--refine", "none"}));
                     EXPECT_LT(verified(r), verified(plain)) << r.r.err << plain.r.err;
                   }},
        bad("min_inlier_ratio_1_5", {"--min-inlier-ratio", "1.5"}, "--min-inlier-ratio"),
        OptionCase{"keep_unverified", coded({"--min-inliers", "1000", "--keep-unverified"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(verified(r), 0);
                     EXPECT_EQ(r.tracks.size(), plain_coded().tracks.size());
                   }},
        // Natural features
        OptionCase{"no_mutual", features({"--no-mutual"}), 0, "",
                   [](const Outcome& r) {
                     ASSERT_GT(feature_matches(plain_features()), 0) << plain_features().r.err;
                     EXPECT_GT(feature_matches(r), feature_matches(plain_features())) << r.r.err;
                   }},
        // RootSIFT: other distances, so other matches (kd-tree and guided search alike).
        OptionCase{"root_sift", features({"--root-sift"}), 0, "",
                   [](const Outcome& r) {
                     ASSERT_GT(feature_matches(r), 0) << r.r.err;
                     EXPECT_NE(feature_matches(r), feature_matches(plain_features())) << r.r.err;
                     const Outcome guided = match(features({"--poses", "{demo}poses.csv", "--root-sift"}));
                     const Outcome plain_guided = match(features({"--poses", "{demo}poses.csv"}));
                     EXPECT_GT(feature_tracks(guided), 0) << guided.r.err;
                     EXPECT_NE(guided.r.out, plain_guided.r.out);
                   }},
        OptionCase{"guided_ratio", features({"--poses", "{demo}poses.csv", "--guided-ratio", "0.3"}), 0, "",
                   [](const Outcome& r) {
                     const Outcome wide = match(features({"--poses", "{demo}poses.csv"}));
                     EXPECT_LT(feature_tracks(r), feature_tracks(wide)) << r.r.err << wide.r.err;
                   }},
        bad("guided_ratio_0_05", {"--guided-ratio", "0.05"}, "--guided-ratio"),
        OptionCase{"no_guided", features({"--poses", "{demo}poses.csv", "--no-guided", "--guided-ratio", "0.3"}), 0, "",
                   [](const Outcome& r) {
                     // Matched by kd-tree, not along the epipolar lines: --guided-ratio no longer applies.
                     const Outcome kd = match(features({"--poses", "{demo}poses.csv", "--no-guided"}));
                     const Outcome guided = match(features({"--poses", "{demo}poses.csv", "--guided-ratio", "0.3"}));
                     EXPECT_EQ(r.r.out, kd.r.out);
                     EXPECT_NE(r.r.out, guided.r.out);
                     EXPECT_GT(feature_tracks(r), 0) << r.r.err;
                   }},
        // With poses and no markers every pair of overlapping views is matched along its epipolar
        // lines (before: only the pairs sharing coded points, so none, and "no tracks").
        OptionCase{"guided_max_axis_angle_deg", features_only({"--poses", "{demo}poses.csv"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(pairs(r), 3) << r.r.err;
                     EXPECT_GT(feature_tracks(r), 0) << r.r.err;
                     const Outcome none = match(features_only({"--poses", "{demo}poses.csv", "--guided-max-axis-angle-deg", "0"}));
                     EXPECT_EQ(none.r.exit_code, 1) << none.r.err;
                     EXPECT_NE(none.r.err.find("no tracks"), std::string::npos) << none.r.err;
                   }},
        bad("guided_max_axis_angle_deg_negative", {"--guided-max-axis-angle-deg", "-1"}, "--guided-max-axis-angle-deg"),
        // With poses a pair needs --min-inliers matches along F to count as verified.
        OptionCase{"min_inliers_with_poses", features({"--poses", "{demo}poses.csv", "--min-inliers", "100000"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(verified(r), 0) << r.r.err;
                     EXPECT_LE(feature_tracks(r), 0) << r.r.err;  // -1: no natural-feature line at all
                     EXPECT_GT(feature_tracks(match(features({"--poses", "{demo}poses.csv"}))), 0);
                   }},
        OptionCase{"exhaustive_max_images", features_only({"--exhaustive-max-images", "2", "--sequence-neighbours", "1"}), 0, "",
                   [](const Outcome& r) {
                     // Three images, more than 2: each with its next one only (2 pairs of the 3).
                     EXPECT_EQ(pairs(r), 2) << r.r.err;
                     EXPECT_EQ(pairs(match(features_only({}))), 3);
                   }},
        bad("exhaustive_max_images_negative", {"--exhaustive-max-images", "-1"}, "--exhaustive-max-images"),
        OptionCase{"sequence_neighbours", features_only({"--exhaustive-max-images", "0", "--sequence-neighbours", "2",
                                                         "--coded-neighbours", "0"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(pairs(r), 3) << r.r.err; }},
        bad("sequence_neighbours_1001", {"--sequence-neighbours", "1001"}, "--sequence-neighbours"),
        OptionCase{"coded_neighbours", features({"--refine", "none", "--exhaustive-max-images", "0", "--sequence-neighbours",
                                                 "0", "--coded-neighbours", "2"}), 0, "",
                   [](const Outcome& r) {
                     // Each image matched by descriptor with the 2 sharing most markers: all three pairs.
                     const Outcome none = match(features({"--refine", "none", "--exhaustive-max-images", "0",
                                                      "--sequence-neighbours", "0", "--coded-neighbours", "0"}));
                     EXPECT_GT(feature_tracks(r), 0) << r.r.err;
                     EXPECT_LE(feature_tracks(none), 0) << none.r.err;
                   }},
        bad("coded_neighbours_negative", {"--coded-neighbours", "-1"}, "--coded-neighbours"),
        OptionCase{"feature_id_offset", features({"--refine", "none", "--feature-id-offset", "5000000"}), 0, "ids from 5000000",
                   [](const Outcome& r) {
                     std::size_t natural = 0;
                     for (const auto& t : r.tracks) natural += t.track_id >= 5000000 ? 1 : 0;
                     EXPECT_GT(natural, 0u);
                   }},
        bad("feature_id_offset_negative", {"--feature-id-offset", "-1"}, "--feature-id-offset"),
        OptionCase{"flann_checks", features({"--refine", "none", "--flann-checks", "1"}), 0, "",
                   [](const Outcome& r) {
                     // One kd-tree leaf per query finds fewer of the true nearest neighbours.
                     const Outcome plain = match(features({"--refine", "none"}));
                     EXPECT_LT(feature_matches(r), feature_matches(plain)) << r.r.err << plain.r.err;
                   }},
        bad("flann_checks_zero", {"--flann-checks", "0"}, "--flann-checks"),
        OptionCase{"min_track_length", features({"--refine", "none", "--min-track-length", "3"}), 0, "",
                   [](const Outcome& r) {
                     // Every natural-feature track spans all three photos; with the default 2 some span two.
                     std::map<TrackId, int> images;
                     for (const auto& t : r.tracks) ++images[t.track_id];
                     std::size_t natural = 0;
                     for (const auto& [id, n] : images) {
                       if (id < 1000000) continue;
                       ++natural;
                       EXPECT_GE(n, 3) << "track " << id;
                     }
                     EXPECT_GT(natural, 0u) << r.r.err;
                     const Outcome plain = match(features({"--refine", "none"}));
                     EXPECT_LT(feature_tracks(r), feature_tracks(plain)) << r.r.err << plain.r.err;
                   }},
        bad("min_track_length_1", {"--min-track-length", "1"}, "--min-track-length"),
        // Least-squares matching (the default --refine lsm)
        OptionCase{"lsm_window_per_size", features({"--lsm-window-per-size", "0.1"}), 0, "",
                   [](const Outcome& r) { EXPECT_NE(lsm_kept(r), lsm_kept(plain_features())) << r.r.err; }},
        bad("lsm_window_per_size_20", {"--lsm-window-per-size", "20"}, "--lsm-window-per-size"),
        OptionCase{"lsm_min_half_window_px", features({"--lsm-min-half-window-px", "30", "--lsm-max-half-window-px", "30"}), 0,
                   "", [](const Outcome& r) { EXPECT_NE(lsm_kept(r), lsm_kept(plain_features())) << r.r.err; }},
        OptionCase{"lsm_min_half_window_above_max", features({"--lsm-min-half-window-px", "20", "--lsm-max-half-window-px", "10"}),
                   2, "--lsm-min-half-window-px", nullptr},
        bad("lsm_min_half_window_px_1", {"--lsm-min-half-window-px", "1"}, "--lsm-min-half-window-px"),
        OptionCase{"lsm_max_half_window_px", features({"--lsm-min-half-window-px", "2", "--lsm-max-half-window-px", "3"}), 0,
                   "", [](const Outcome& r) { EXPECT_NE(lsm_kept(r), lsm_kept(plain_features())) << r.r.err; }},
        bad("lsm_max_half_window_px_101", {"--lsm-max-half-window-px", "101"}, "--lsm-max-half-window-px"),
        OptionCase{"lsm_max_shift_px", features({"--lsm-max-shift-px", "0.01"}), 0, "",
                   [](const Outcome& r) { EXPECT_GT(lsm_refused(r), lsm_refused(plain_features())) << r.r.err; }},
        bad("lsm_max_shift_px_zero", {"--lsm-max-shift-px", "0"}, "--lsm-max-shift-px"),
        OptionCase{"lsm_min_correlation", features({"--lsm-min-correlation", "0.999"}), 0, "",
                   [](const Outcome& r) { EXPECT_GT(lsm_refused(r), lsm_refused(plain_features())) << r.r.err; }},
        bad("lsm_min_correlation_2", {"--lsm-min-correlation", "2"}, "--lsm-min-correlation"),
        OptionCase{"lsm_quadratic", features({"--lsm-quadratic"}), 0, "",
                   [](const Outcome& r) {
                     // Second-order window terms: other sub-pixel positions (and other windows refused).
                     ASSERT_GT(lsm_kept(r), 0) << r.r.err;
                     EXPECT_NE(r.r.out, plain_features().r.out);
                   }},
        // --preset features: --flann-checks 16 and --lsm-quadratic; an option given wins.
        OptionCase{"preset_features", features({"--preset", "features"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(r.r.out, match(features({"--flann-checks", "16", "--lsm-quadratic"})).r.out);
                     EXPECT_NE(r.r.out, plain_features().r.out);
                     EXPECT_EQ(match(features({"--flann-checks", "32", "--preset", "features"})).r.out,
                               match(features({"--lsm-quadratic"})).r.out);
                   }},
        bad("preset_unknown", {"--preset", "fast"}, "--preset"),
        // The .feat files name the photos in the crops' folder: read from another folder, they are missing.
        OptionCase{"image_dir", features({"--image-dir", "no-such-folder"}), 1, "no-such-folder", nullptr},
        OptionCase{"image_dir_same", features({"--image-dir", "."}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(r.r.out, plain_features().r.out); }},
        // A camera per photo by name prefix (issue 23): the demo's 12 photos split between two
        // prefixes, both with the demo camera, match as with --camera.
        OptionCase{"camera_for",
                   {"{demo}observations.csv", "--camera-for", "part_0={demo}camera.yaml", "--camera-for",
                    "part_1={demo}camera.yaml"},
                   0, "",
                   [](const Outcome& r) {
                     EXPECT_EQ(r.tracks, plain_coded().tracks);
                     EXPECT_EQ(r.r.err.find("no --camera"), std::string::npos) << r.r.err;
                   }},
        OptionCase{"camera_for_missing_photo", {"{demo}observations.csv", "--camera-for", "part_0={demo}camera.yaml"}, 1,
                   "observations.csv: image 'part_10.jpg' starts with none of the cameras' prefixes ('part_0'): give its camera",
                   nullptr},
        OptionCase{"camera_for_syntax", {"{demo}observations.csv", "--camera-for", "{demo}camera.yaml"}, 2,
                   "expected PREFIX=FILE", nullptr},
        OptionCase{"camera_for_and_camera", coded({"--camera-for", "part_={demo}camera.yaml"}), 2, "excludes", nullptr},
        // --rig: the cameras of a rig.yaml by prefix; a stereo rig's (left, right) fits no demo photo.
        OptionCase{"rig",
                   {"{demo}observations.csv", "--rig",
                    std::string(PHOTOMILL_SOURCE_DIR) + "/tests/fuzz/corpus/rig_yaml/valid-stereo-rig.yaml"},
                   1, "starts with none of the cameras' prefixes ('left', 'right')", nullptr}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill::match
