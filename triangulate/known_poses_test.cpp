// Known poses (triangulate --known-poses): held fixed they stay exactly as given and place the
// points; as priors they move by what the photos say; images without one are added by PnP in
// their frame; the poses triangulate writes read back in (photomill's CSV and COLMAP's
// images.txt); a pose that names no image of the tracks, or a malformed file, is an error with
// its file and line.
#include <cmath>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "triangulate/cli.hpp"
#include "triangulate/colmap.hpp"
#include "triangulate/reconstruct.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

using test::SceneOptions;
using test::SceneTruth;

ReconstructInput known_input(const SceneTruth& truth, std::vector<Pose> poses) {
  ReconstructInput in;
  in.tracks = truth.tracks;
  in.camera = truth.camera;
  in.known_poses = std::move(poses);
  for (std::size_t k = 0; k < in.known_poses.size(); ++k) in.known_pose_lines.push_back(k + 2);
  in.known_poses_source = "poses.csv";
  return in;
}

const Pose* find_pose(const std::vector<Pose>& poses, const std::string& image) {
  for (const Pose& p : poses) {
    if (p.image == image) return &p;
  }
  return nullptr;
}

double rotation_deg(const Pose& a, const Pose& b) {
  return Eigen::AngleAxisd(a.rotation() * b.rotation().transpose()).angle() * 180 / M_PI;
}

// The truth's poses moved by about `mm` and `deg` (Gaussian per axis), reproducibly.
std::vector<Pose> perturbed(const std::vector<Pose>& poses, double mm, double deg, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, 1);
  std::vector<Pose> out;
  for (const Pose& p : poses) {
    const Eigen::Vector3d c = p.centre_mm() + mm * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Vector3d w = deg * M_PI / 180 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Matrix3d R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix() * p.rotation();
    Pose q;
    q.image = p.image;
    q.cam_from_world_rotation = Eigen::Quaterniond(R);
    q.cam_from_world_translation_mm = -R * c;
    out.push_back(q);
  }
  return out;
}

double centre_rms_mm(const std::vector<Pose>& a, const std::vector<Pose>& truth) {
  double sum = 0;
  std::size_t n = 0;
  for (const Pose& p : a) {
    const Pose* t = find_pose(truth, p.image);
    if (!t) continue;
    sum += (p.centre_mm() - t->centre_mm()).squaredNorm();
    ++n;
  }
  return n ? std::sqrt(sum / static_cast<double>(n)) : INFINITY;
}

TEST(KnownPoses, HeldFixedStayAsGivenAndPlaceThePoints) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  const Reconstruction r = reconstruct(known_input(truth, truth.poses), ReconstructOptions{});
  EXPECT_EQ(r.report.datum, "known_poses");
  EXPECT_EQ(r.report.pose_initialisation, "known_poses");
  const std::vector<Pose> out = registered_poses(r);
  ASSERT_EQ(out.size(), truth.poses.size());
  for (const Pose& p : out) {
    const Pose* t = find_pose(truth.poses, p.image);
    ASSERT_NE(t, nullptr) << p.image;
    EXPECT_LT((p.centre_mm() - t->centre_mm()).norm(), 1e-9) << p.image;
    EXPECT_LT(rotation_deg(p, *t), 1e-9) << p.image;
  }
  for (const ImageReport& ir : r.report.per_image) EXPECT_EQ(ir.registered_by, "known_pose") << ir.image;
  // No datum but the poses: the points are in their frame and scale, without an alignment.
  const test::Accuracy a = test::evaluate(r, truth, false);
  EXPECT_EQ(a.part_points, truth.part_points.size());
  EXPECT_LT(a.part_rms_mm, 0.01);
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    if (r.in_result[t]) {
      EXPECT_TRUE(std::isfinite(r.sigma_mm[t]) && r.sigma_mm[t] > 0) << r.scene.tracks[t].id;
    }
  }
}

TEST(KnownPoses, FixedMeansFixedEvenWhenTheyAreWrong) {
  // Poses 0.1 mm and 0.01 deg off, held fixed: they stay where they were given (the user said
  // so); the photos disagree, which the reprojection error shows.
  const SceneTruth truth = test::make_scene(SceneOptions{});
  const std::vector<Pose> given = perturbed(truth.poses, 0.1, 0.01, 7);
  const Reconstruction r = reconstruct(known_input(truth, given), ReconstructOptions{});
  EXPECT_LT(std::abs(centre_rms_mm(registered_poses(r), given)), 1e-9);
  EXPECT_GT(r.report.final_rms_px, 0.2);  // the truth's noise is 0.05 px
}

TEST(KnownPoses, PriorsMoveThePosesByWhatThePhotosSay) {
  SceneOptions so;
  const SceneTruth truth = test::make_scene(so);
  const std::vector<Pose> given = perturbed(truth.poses, 0.5, 0.05, 7);
  ReconstructOptions o;
  o.pose_sigma_mm = 0.5;
  o.pose_sigma_deg = 0.05;
  ReconstructInput in = known_input(truth, given);
  in.control_points = truth.plate_points;  // the frame of the truth, so the centres compare
  const Reconstruction r = reconstruct(in, o);
  EXPECT_EQ(r.report.datum, "known_poses+control_points");
  const double before = centre_rms_mm(given, truth.poses);
  const double after = centre_rms_mm(registered_poses(r), truth.poses);
  EXPECT_GT(before, 0.5);
  EXPECT_LT(after, 0.1 * before) << "given " << before << " mm, adjusted " << after << " mm";
  EXPECT_LT(r.report.final_rms_px, 0.1);
}

TEST(KnownPoses, PriorsAloneAreTheDatum) {
  // Without control points the priors fix frame and scale: the result is within a fraction of
  // the pose sigma of the truth, and every point has a finite uncertainty.
  const SceneTruth truth = test::make_scene(SceneOptions{});
  ReconstructOptions o;
  o.pose_sigma_mm = 0.2;
  o.pose_sigma_deg = 0.02;
  const Reconstruction r = reconstruct(known_input(truth, perturbed(truth.poses, 0.2, 0.02, 3)), o);
  EXPECT_EQ(r.report.datum, "known_poses");
  EXPECT_LT(centre_rms_mm(registered_poses(r), truth.poses), 0.2);
  EXPECT_EQ(r.report.sigma_method, "full_covariance");
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    if (r.in_result[t]) {
      EXPECT_TRUE(std::isfinite(r.sigma_mm[t]) && r.sigma_mm[t] > 0) << r.scene.tracks[t].id;
    }
  }
}

TEST(KnownPoses, ImagesWithoutOneAreAddedByPnpInTheirFrame) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  std::vector<Pose> half;
  for (std::size_t k = 0; k < truth.poses.size(); k += 2) half.push_back(truth.poses[k]);
  const Reconstruction r = reconstruct(known_input(truth, half), ReconstructOptions{});
  const std::vector<Pose> out = registered_poses(r);
  ASSERT_EQ(out.size(), truth.poses.size());
  std::size_t by_pnp = 0;
  for (const ImageReport& ir : r.report.per_image) by_pnp += ir.registered_by == "pnp" ? 1 : 0;
  EXPECT_EQ(by_pnp, truth.poses.size() - half.size());
  EXPECT_LT(centre_rms_mm(out, truth.poses), 0.05);
}

TEST(KnownPoses, NamesMatchByFileNameWhenTheFoldersDiffer) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  std::vector<Pose> poses = truth.poses;
  for (Pose& p : poses) p.image = "elsewhere/photos/" + p.image;
  const Reconstruction r = reconstruct(known_input(truth, poses), ReconstructOptions{});
  EXPECT_EQ(registered_poses(r).size(), truth.poses.size());
}

TEST(KnownPoses, APoseForAnImageNotInTheTracksIsNamedWithItsLine) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  std::vector<Pose> poses = truth.poses;
  poses[3].image = "not_matched.png";
  try {
    reconstruct(known_input(truth, poses), ReconstructOptions{});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "poses.csv");
    EXPECT_EQ(e.line(), 5u);
    EXPECT_NE(std::string(e.what()).find("'not_matched.png' is not in the tracks"), std::string::npos) << e.what();
  }
}

TEST(KnownPoses, OneKnownPoseIsNotEnough) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  EXPECT_THROW(reconstruct(known_input(truth, {truth.poses[0]}), ReconstructOptions{}), InputError);
}

TEST(KnownPoses, ThePosesWrittenReadBackIn) {
  const SceneTruth truth = test::make_scene(SceneOptions{});
  ReconstructInput in = known_input(truth, {});
  in.control_points = truth.plate_points;
  const Reconstruction first = reconstruct(in, ReconstructOptions{});
  const std::vector<Pose> written = registered_poses(first);
  std::ostringstream csv;
  write_poses(csv, written);
  std::ostringstream colmap;
  write_colmap_images(colmap, first);
  for (const std::string& text : {csv.str(), colmap.str()}) {
    std::istringstream s(text);
    std::vector<std::size_t> lines;
    const std::vector<Pose> back = read_known_poses(s, "poses", &lines);
    ASSERT_EQ(back.size(), written.size());
    ASSERT_EQ(lines.size(), written.size());
    for (std::size_t k = 0; k < back.size(); ++k) {
      EXPECT_EQ(back[k].image, written[k].image);
      EXPECT_LT((back[k].centre_mm() - written[k].centre_mm()).norm(), 1e-9);
      EXPECT_LT(rotation_deg(back[k], written[k]), 1e-9);
    }
    ReconstructInput again = known_input(truth, back);
    const Reconstruction second = reconstruct(again, ReconstructOptions{});
    EXPECT_LT(centre_rms_mm(registered_poses(second), written), 1e-9);
    EXPECT_LT(test::evaluate(second, truth, false).part_rms_mm, 0.01);
  }
}

struct BadColmap {
  const char* text;
  std::size_t line;
  const char* message;
};

class ColmapImagesMalformed : public ::testing::TestWithParam<BadColmap> {};

TEST_P(ColmapImagesMalformed, NamesTheLine) {
  const BadColmap& c = GetParam();
  std::istringstream in(c.text);
  try {
    read_colmap_images(in, "images.txt");
    FAIL() << "accepted: " << c.text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "images.txt");
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Triangulate, ColmapImagesMalformed,
    ::testing::Values(
        BadColmap{"# c\n1 1 0 0 0 0 0 500 1\n\n", 2, "10 fields"},
        BadColmap{"1 1 0 0 0 0 0 500 1 a.png\n\n2 1 0 0 0 nan 0 500 1 b.png\n", 3, "TX 'nan'"},
        BadColmap{"1 0.9 0 0 0 0 0 500 1 a.png\n\n", 1, "not a unit quaternion"},
        BadColmap{"1 1 0 0 0 0 0 500 1 a.png\n\n2 1 0 0 0 0 0 500 1 a.png\n\n", 3, "two poses"},
        BadColmap{"1 1 0 0 0 0 0 500 1 a.png\n\n1 1 0 0 0 0 0 500 1 b.png\n\n", 3, "appears twice"},
        // The POINTS2D line of a.png was dropped: b.png's line stands in its place.
        BadColmap{"1 1 0 0 0 0 0 500 1 a.png\n2 1 0 0 0 0 0 500 1 b.png\n\n", 2, "POINTS2D line of image 'a.png'"},
        BadColmap{"x 1 0 0 0 0 0 500 1 a.png\n", 1, "IMAGE_ID 'x'"},
        BadColmap{"1 1 0 0 0 0 0 500 c a.png\n", 1, "CAMERA_ID 'c'"}));

TEST(ColmapImages, ReadsCommentsEmptyPointLinesAndAMissingLastOne) {
  std::istringstream in(
      "# Image list with two lines of data per image:\n"
      "1 1 0 0 0 1.5 -2 480 1 a.png\n"
      "\n"
      "7 0.70710678118654757 0.70710678118654757 0 0 0 0 500 3 sub/b.png\n"
      "10.5 20.25 -1 11 12 4\n"
      "8 1 0 0 0 0 0 1 1 c.png\n");
  std::vector<std::size_t> lines;
  const std::vector<Pose> p = read_colmap_images(in, "images.txt", &lines);
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[1].image, "sub/b.png");
  EXPECT_EQ(p[0].cam_from_world_translation_mm, Eigen::Vector3d(1.5, -2, 480));
  EXPECT_EQ(lines, (std::vector<std::size_t>{2, 4, 6}));
}

TEST(KnownPosesFile, ACsvThatIsNotAPosesTableIsNamedAsOne) {
  std::istringstream in("track_id,image,u_px,v_px\n1,a.png,1,2\n");
  try {
    read_known_poses(in, "tracks.csv", nullptr);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "tracks.csv");
    EXPECT_EQ(e.line(), 1u);
  }
}

}  // namespace
}  // namespace photomill::triangulate
