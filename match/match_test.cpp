// match against truth: the demo set's true marker observations with 5 % of the marker ids
// corrupted (every corrupted observation must go), a hand-clicked CSV passing through, natural
// features on a rendered synth scene judged against the exact geometry, and golden CLI cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "detect/markers.hpp"
#include "detect/sift.hpp"
#include "formats/error.hpp"
#include "match/match.hpp"
#include "tools/track_truth.hpp"
#include "tests/run_tool.hpp"
#include "tools/synth/dataset.hpp"
#include "tools/synth/test_scene.hpp"

namespace photomill::match {
namespace {

const std::string kDemo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";

template <typename T, typename Reader>
T read_file(const std::string& path, Reader reader) {
  std::ifstream in(path);
  return reader(in, path);
}

std::vector<Observation> demo_truth() {
  return read_file<std::vector<Observation>>(kDemo + "observations.csv", read_observations);
}
Camera demo_camera() { return read_file<Camera>(kDemo + "camera.yaml", [](std::istream& in, const std::string& s) {
  return read_camera_yaml(in, s);
}); }

// ---------------------------------------------------------------------------------------------
// Wrongly decoded ids. A corruption gives every corner of one marker in one image another id:
// one that is in the scene (the observation then joins a physical point it does not belong to)
// or an unused one; each (true marker, wrong id) pair is used once, so no two corrupted
// observations describe the same physical point under the same wrong id (that would be a
// consistent renaming, invisible to geometry and harmless to triangulation).

struct Corrupted {
  std::vector<Observation> observations;
  std::set<std::pair<std::string, PointId>> wrong;  // (image, corrupted point id)
  std::map<std::pair<std::string, PointId>, PointId> true_id;
};

Corrupted corrupt(const std::vector<Observation>& truth, double share, unsigned seed) {
  std::mt19937 rng(seed);
  std::map<std::string, std::set<int>> present;
  std::set<std::pair<std::string, int>> markers;
  std::set<int> scene_ids;
  for (const auto& o : truth) {
    const int m = static_cast<int>(o.point_id / 4);
    present[o.image].insert(m);
    markers.insert({o.image, m});
    scene_ids.insert(m);
  }
  std::vector<std::pair<std::string, int>> all(markers.begin(), markers.end());
  std::shuffle(all.begin(), all.end(), rng);
  all.resize(static_cast<std::size_t>(std::lround(share * static_cast<double>(all.size()))));
  std::map<std::pair<std::string, int>, int> new_id;
  std::set<std::pair<int, int>> used;  // (true marker, wrong id)
  for (const auto& [image, m] : all) {
    std::vector<int> pool;
    const bool existing = std::uniform_int_distribution<int>(0, 1)(rng) == 1;
    for (int id = 0; id < 100; ++id) {
      if (present[image].count(id) || used.count({m, id})) continue;
      if (existing == (scene_ids.count(id) > 0)) pool.push_back(id);
    }
    if (pool.empty()) {
      for (int id = 0; id < 100; ++id) {
        if (!present[image].count(id) && !used.count({m, id})) pool.push_back(id);
      }
    }
    const int id = pool[std::uniform_int_distribution<std::size_t>(0, pool.size() - 1)(rng)];
    present[image].insert(id);
    used.insert({m, id});
    new_id[{image, m}] = id;
  }
  Corrupted c;
  for (Observation o : truth) {
    const PointId original = o.point_id;
    const auto it = new_id.find({o.image, static_cast<int>(o.point_id / 4)});
    if (it != new_id.end()) {
      o.point_id = static_cast<PointId>(it->second) * 4 + o.point_id % 4;
      c.wrong.insert({o.image, o.point_id});
    }
    c.true_id[{o.image, o.point_id}] = original;
    c.observations.push_back(o);
  }
  return c;
}

struct CorruptionCase {
  unsigned seed;
  bool poses;  // verify with the true poses instead of estimated F
};

void PrintTo(const CorruptionCase& c, std::ostream* os) { *os << "seed " << c.seed << (c.poses ? ", poses" : ""); }

class CorruptedIds : public ::testing::TestWithParam<CorruptionCase> {};

TEST_P(CorruptedIds, EveryWronglyDecodedIdIsDropped) {
  const auto truth = demo_truth();
  const Corrupted c = corrupt(truth, 0.05, GetParam().seed);
  ASSERT_GE(c.wrong.size(), 40u);
  MatchInputs in;
  in.observations = c.observations;
  in.camera = demo_camera();
  if (GetParam().poses) in.poses = read_file<std::vector<Pose>>(kDemo + "poses.csv", read_poses);
  const MatchResult r = match(in, {});
  std::size_t survived = 0, kept_correct = 0;
  for (const auto& t : r.tracks) {
    survived += c.wrong.count({t.image, t.track_id});
    kept_correct += c.wrong.count({t.image, t.track_id}) ? 0 : 1;
  }
  const std::size_t correct = c.observations.size() - c.wrong.size();
  std::cout << "[ match    ] seed " << GetParam().seed << (GetParam().poses ? " (poses)" : "") << ": " << c.wrong.size()
            << " corrupted corners, " << survived << " survived; " << kept_correct << " of " << correct
            << " correct corners kept\n";
  EXPECT_EQ(survived, 0u);
  // The correct observations are kept, except those of markers seen in one image only.
  EXPECT_GE(kept_correct * 100, correct * 97);
}

INSTANTIATE_TEST_SUITE_P(Seeds, CorruptedIds,
                         ::testing::Values(CorruptionCase{1, false}, CorruptionCase{2, false}, CorruptionCase{3, false},
                                           CorruptionCase{4, false}, CorruptionCase{5, false}, CorruptionCase{6, true},
                                           CorruptionCase{7, true}),
                         [](const auto& info) {
                           return "Seed" + std::to_string(info.param.seed) + (info.param.poses ? "Poses" : "");
                         });

TEST(Match, HandClickedPointsPassThrough) {
  // Twelve points (three plate markers) clicked in three images: the tracks are the clicks.
  std::vector<Observation> clicked;
  for (const auto& o : demo_truth()) {
    const bool image = o.image == "part_00.jpg" || o.image == "part_01.jpg" || o.image == "part_02.jpg";
    const int m = static_cast<int>(o.point_id / 4);
    if (image && (m == 0 || m == 5 || m == 9 || m == 12)) clicked.push_back(o);
  }
  ASSERT_GE(clicked.size(), 36u);
  MatchInputs in;
  in.observations = clicked;
  in.camera = demo_camera();
  const MatchResult r = match(in, {});
  EXPECT_EQ(r.tracks.size(), clicked.size());
  EXPECT_TRUE(r.dropped.empty());
  for (const auto& t : r.tracks) {
    const auto it = std::find_if(clicked.begin(), clicked.end(),
                                 [&](const Observation& o) { return o.image == t.image && o.point_id == t.track_id; });
    ASSERT_NE(it, clicked.end());
    EXPECT_EQ(it->u_px, t.u_px);
    EXPECT_EQ(it->v_px, t.v_px);
  }
}

TEST(Match, TooFewClicksToVerifyAreDroppedUnlessKept) {
  std::vector<Observation> clicked;
  for (const auto& o : demo_truth()) {
    if ((o.image == "part_00.jpg" || o.image == "part_01.jpg") && o.point_id < 6) clicked.push_back(o);
  }
  MatchInputs in;
  in.observations = clicked;
  MatchOptions o;
  EXPECT_TRUE(match(in, o).tracks.empty());
  o.keep_unverified = true;
  EXPECT_EQ(match(in, o).tracks.size(), clicked.size());
}

// ---------------------------------------------------------------------------------------------
// Natural features on a rendered scene: six views of the part at 1000 x 750, noise 1 grey level,
// JPEG 90; SIFT away from the markers; tracks judged against the exact surface.

// One synth scene (7 views of 1000 x 750, noise 1, JPEG 90), detected once for every mode below.
struct FeatureScene {
  synth::SynthOptions o;
  synth::PartScene scene;
  std::vector<Pose> poses;
  MatchInputs in;
};

const FeatureScene& feature_scene() {
  static const FeatureScene fs = [] {
    FeatureScene f;
    f.o = synth::test::small_options();
    f.o.camera = synth::test::small_camera(1000, 750, 1200);
    f.o.views.count = 7;
    f.o.render.noise_sigma = 1;
    f.o.speckle_mm = 1.6;
    f.o.seed = 21;
    f.scene = synth::make_part_scene(f.o);
    const synth::PartRayScene rays(f.scene);
    f.poses = synth::part_view_poses(f.o);
    const auto dict = detect::MarkerDictionary::predefined(f.scene.dictionary);
    f.in.camera = f.o.camera;
    int view = 0;
    for (const Pose& pose : f.poses) {
      const cv::Mat image = cv::imdecode(
          synth::encode_image(synth::render(rays, f.o.camera, pose, f.o.render, static_cast<std::uint64_t>(view++)), "jpg", 90),
          cv::IMREAD_GRAYSCALE);
      const auto markers = detect::detect_markers(image, pose.image, dict, {});
      const auto obs = markers.observations();
      f.in.observations.insert(f.in.observations.end(), obs.begin(), obs.end());
      f.in.features.push_back(detect::detect_sift(
          image, pose.image, {}, detect::marker_mask(image.size(), markers.corners, dict.bits_per_side() + 2, 1)));
      cv::Mat grey;
      image.convertTo(grey, CV_32F);
      f.in.grey_images.push_back(grey);
    }
    return f;
  }();
  return fs;
}

struct FeatureMode {
  const char* name;
  bool poses;              // known poses: guided matching
  bool refine;             // least-squares matching
  double median_error_px;  // bound on the tracks' median error against the truth
};

class NaturalFeatures : public ::testing::TestWithParam<FeatureMode> {};

// The bound: >= 2000 verified tracks of length >= 3 with <= 1 % off the true geometry
// (by more than 2 px), in every mode; least-squares matching makes the tracks ~10x more precise.
TEST_P(NaturalFeatures, TracksOnASynthScene) {
  const FeatureMode& m = GetParam();
  const FeatureScene& fs = feature_scene();
  MatchInputs in = fs.in;
  if (m.poses) in.poses = fs.poses;
  MatchOptions opt;
  if (m.refine) opt.refine = LsmOptions{};
  const MatchResult r = match(in, opt);
  const auto judged = truth::judge_tracks(r.tracks, fs.scene, fs.o.camera, fs.poses);
  const auto features3 = truth::summarise(judged, 3, 2.0, opt.feature_track_offset);
  std::vector<double> errors;
  for (const auto& j : judged) {
    if (j.track_id >= opt.feature_track_offset) errors.push_back(j.error_px);
  }
  ASSERT_FALSE(errors.empty());
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
  const double median = errors[errors.size() / 2];
  std::cout << "[ match    ] synth, 7 views of 1000 x 750, " << m.name << ": " << r.feature_tracks << " feature tracks, "
            << features3.tracks << " of length >= 3, " << features3.outliers
            << " of them off the true geometry by more than 2 px (" << features3.outlier_percent()
            << " %), median error " << median << " px; coded tracks " << r.coded_tracks << "\n";
  EXPECT_GE(features3.tracks, 2000u);
  EXPECT_LE(features3.outlier_percent(), 1.0);
  EXPECT_LT(median, m.median_error_px);
  if (m.refine) {
    EXPECT_GT(r.refined_observations, 0u);
    // Refined observations carry no size; unrefined ones carry their feature's.
    for (const auto& t : r.tracks) {
      if (t.track_id >= opt.feature_track_offset) {
        EXPECT_FALSE(t.size_px.has_value());
      }
    }
  } else {
    for (const auto& t : r.tracks) {
      if (t.track_id >= opt.feature_track_offset) {
        EXPECT_TRUE(t.size_px.has_value());
      }
    }
  }
  // Coded tracks (ids below the offset) are all right to 1 px.
  std::size_t coded_wrong = 0;
  for (const auto& j : judged) coded_wrong += j.track_id < opt.feature_track_offset && j.error_px > 1 ? 1 : 0;
  EXPECT_EQ(coded_wrong, 0u);
}

INSTANTIATE_TEST_SUITE_P(Modes, NaturalFeatures,
                         ::testing::Values(FeatureMode{"kdtree", false, false, 0.6},
                                           FeatureMode{"kdtree_lsm", false, true, 0.1},
                                           FeatureMode{"guided_lsm", true, true, 0.1}),
                         [](const auto& info) { return std::string(info.param.name); });

// ---------------------------------------------------------------------------------------------
// Golden CLI cases.

struct GoldenCase {
  std::string name;
  std::vector<std::string> args;  // "{dir}": temp dir; "{demo}": data/demo
  std::string stdin_text;
  int exit_code;
  std::string stderr_has;
};

void PrintTo(const GoldenCase& c, std::ostream* os) { *os << c.name; }

class MatchCli : public ::testing::TestWithParam<GoldenCase> {};

TEST_P(MatchCli, Golden) {
  const GoldenCase& c = GetParam();
  test::TempDir dir;
  std::ofstream(dir.path() / "bad.csv") << "image,point_id,u_px,v_px\na.jpg,1,2,3\na.jpg,2,3\n";
  std::ofstream(dir.path() / "empty.csv") << "image,point_id,u_px,v_px\n";
  std::filesystem::create_directories(dir.path() / "nofeat");
  std::vector<std::string> args;
  for (std::string a : c.args) {
    for (auto [key, value] : {std::pair<std::string, std::string>{"{dir}", dir.path().string()}, {"{demo}", kDemo}}) {
      for (auto at = a.find(key); at != std::string::npos; at = a.find(key)) a.replace(at, key.size(), value);
    }
    args.push_back(a);
  }
  const auto r = test::run_tool("match", args, c.stdin_text);
  EXPECT_EQ(r.exit_code, c.exit_code) << r.err;
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
  if (c.exit_code != 0) {
    EXPECT_TRUE(r.out.empty());
    EXPECT_FALSE(std::filesystem::exists(dir.path() / "out.csv"));
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, MatchCli,
    ::testing::Values(
        GoldenCase{"missing_input", {"{dir}/missing.csv", "-o", "{dir}/out.csv"}, "", 1, "missing.csv"},
        GoldenCase{"malformed_line", {"{dir}/bad.csv", "-o", "{dir}/out.csv"}, "", 1, "bad.csv:3:"},
        GoldenCase{"header_only", {"{dir}/empty.csv", "-o", "{dir}/out.csv"}, "", 1, "empty.csv: no observations"},
        GoldenCase{"poses_without_camera", {"{demo}observations.csv", "--poses", "{demo}poses.csv", "-o", "{dir}/out.csv"}, "", 2,
                   "--camera"},
        GoldenCase{"empty_features_folder", {"--features", "{dir}/nofeat", "-o", "{dir}/out.csv"}, "", 1, "no .feat files"},
        GoldenCase{"bad_ratio", {"{demo}observations.csv", "--ratio", "2"}, "", 2, "--ratio"},
        GoldenCase{"threads_out_of_range", {"{demo}observations.csv", "--threads", "-1"}, "", 2,
                   "--threads: Value -1 not in range 0 to 1024"},
        GoldenCase{"jobs_is_the_old_name_of_threads", {"{demo}observations.csv", "--jobs", "2000"}, "", 2,
                   "--threads: Value 2000 not in range 0 to 1024"},
        GoldenCase{"one_thread", {"{demo}observations.csv", "--camera", "{demo}camera.yaml", "--threads", "1"}, "", 0,
                   "track lengths"},
        GoldenCase{"demo_from_a_file", {"{demo}observations.csv", "--camera", "{demo}camera.yaml"}, "", 0, "track lengths"},
        GoldenCase{"stdin", {"--camera", "{demo}camera.yaml", "-"}, test::read_file(kDemo + "observations.csv"), 0,
                   "coded points: 80 tracks"},
        GoldenCase{"stdin_malformed", {"-"}, "image,point_id,u_px,v_px\na.jpg,x,1,2\n", 1, "<stdin>:2:"}),
    [](const auto& info) { return info.param.name; });

TEST(MatchCli, WritesTracksThatReadBack) {
  test::TempDir dir;
  const auto out = (dir.path() / "tracks.csv").string();
  const auto r = test::run_tool("match", {kDemo + "observations.csv", "--camera", kDemo + "camera.yaml", "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto tracks = read_file<std::vector<TrackObservation>>(out, read_tracks);
  EXPECT_EQ(tracks.size(), demo_truth().size());
  EXPECT_NE(r.err.find("12 images"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace photomill::match
