// match: correspondences between images. Coded points (markers, board corners, hand-clicked
// points: observations CSV) are grouped by point id; natural features (SIFT .feat files) are
// matched by descriptor with Lowe's ratio test and a mutual check. Every image pair's
// correspondences are verified together against one fundamental matrix (from known poses, or
// estimated by USAC/MAGSAC++ from the pair's coded points and feature matches), tracks are built
// by union-find, and each track's observations vote pairwise so that a wrongly decoded id or a
// chained mismatch is dropped, not triangulated. Tracks of coded points keep their point id;
// natural-feature tracks are numbered from `feature_track_offset` up.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "formats/camera.hpp"
#include "formats/features.hpp"
#include "formats/tables.hpp"
#include "match/epipolar.hpp"
#include "match/lsm.hpp"
#include "match/tracks.hpp"

namespace photomill::match {

struct MatchOptions {
  // Geometric verification of every pair (threshold on the Sampson distance, px, measured in
  // undistorted pixels when a camera is given).
  RobustFitOptions fit;
  // Coded observations that no image pair could check (the pair had fewer than 8
  // correspondences and no poses were given) are dropped unless this is set.
  bool keep_unverified = false;
  // Natural features.
  double ratio = 0.8;        // Lowe 2004: best distance < ratio * second best (both directions)
  bool mutual = true;        // keep a match only if each feature is the other's best
  int flann_trees = 4;       // randomised kd-trees (FLANN, Muja & Lowe 2009)
  int flann_checks = 32;     // leaves visited per query (64: ~3 % more tracks, twice the time)
  // Compare RootSIFT descriptors (Arandjelovic & Zisserman 2012, "Three things everyone should
  // know to improve object retrieval": the square root of the L1-normalised descriptor, so that
  // Euclidean distance becomes the Hellinger kernel's), as COLMAP does by default.
  bool root_sift = false;
  // With known poses: compare each feature only with those near its epipolar line (guided
  // matching), instead of kd-tree search over all features.
  bool guided = true;
  // The ratio test of guided matching, among the band's candidates only (a stricter bound than
  // `ratio`: the band holds ~50 candidates, not the whole photo; on the demo 0.6 gives as many
  // tracks as the kd-tree search at 0.8, 0.7 and 0.8 mostly more wrong ones).
  double guided_ratio = 0.6;
  // With known poses, the pairs matched along their epipolar lines: every pair whose optical
  // axes are at most this far apart (views of one side of a part overlap; views from opposite
  // sides do not), besides every pair that shares coded points.
  double guided_max_axis_angle_deg = 75;
  std::size_t min_track_length = 2;
  TrackId feature_track_offset = 1'000'000;
  // Which pairs are matched by descriptor: all pairs up to `exhaustive_max_images` images;
  // beyond, each image with its `sequence_neighbours` successors in input order and with the
  // `coded_neighbours` images that share most coded points with it.
  int exhaustive_max_images = 30;
  int sequence_neighbours = 3;
  int coded_neighbours = 5;
  int jobs = 0;  // pairs matched in parallel; 0 = all cores
  // Least-squares matching of every natural-feature observation against the track's reference
  // observation (the one with the smallest feature): needs MatchInputs::grey_images. Observations
  // it cannot align are dropped. Without it, observations carry their feature's size instead.
  std::optional<LsmOptions> refine;
};

struct MatchInputs {
  std::vector<Observation> observations;  // coded points (may be empty)
  std::vector<FeatureSet> features;       // natural features, one set per image (may be empty)
  std::optional<Camera> camera;           // undistort before epipolar checks
  // Or a camera per photo: the photos whose names (or file names, for a prefix without '/') start
  // with the prefix (formats/camera.hpp, match_rig_prefix). Every photo must have one.
  std::vector<std::pair<std::string, Camera>> cameras_by_prefix;
  std::vector<Pose> poses;                // known poses: F from them (needs camera)
  // For MatchOptions::refine: the image of each feature set (same order as `features`),
  // single-channel CV_32F.
  std::vector<cv::Mat> grey_images;
};

// One image pair that was looked at.
struct PairReport {
  std::size_t a = 0, b = 0;      // indices into MatchResult::images
  int coded_shared = 0;          // coded points seen in both
  int coded_inliers = 0;         // ... consistent with F
  int feature_matches = 0;       // after the ratio test and the mutual check
  int feature_inliers = 0;       // ... consistent with F
  bool verified = false;         // F known (poses) or estimated with enough inliers
  bool from_poses = false;
};

struct DroppedObservation {
  std::string image;
  PointId point_id = 0;
  std::string reason;
};

struct MatchResult {
  std::vector<std::string> images;               // in order of first appearance in the inputs
  std::vector<TrackObservation> tracks;          // sorted by track id, then image order
  std::vector<PairReport> pairs;
  std::vector<DroppedObservation> dropped;       // coded observations left out, with why
  std::map<std::size_t, std::size_t> track_lengths;  // length -> number of tracks
  std::size_t coded_tracks = 0;
  std::size_t feature_tracks = 0;
  UnionStats feature_unions;                     // natural-feature union-find
  std::size_t feature_observations_voted_out = 0;
  // Least-squares matching (MatchOptions::refine): observations refined, and those refused by reason.
  std::size_t refined_observations = 0;
  std::map<std::string, std::size_t> refine_refused;
  std::size_t refine_tracks_dropped = 0;  // fell below the minimum length
};

// RootSIFT bytes of `descriptors` (rows of `dim` bytes): 512 sqrt(v / |v|_1), rounded, at most
// 255; an all-zero row stays zero.
std::vector<std::uint8_t> root_sift(const std::vector<std::uint8_t>& descriptors, int dim);

// Throws InputError for inconsistent inputs (features of one image twice, a pose missing for an
// image, descriptors of different lengths), UsageError for bad options or an id collision with
// `feature_track_offset`, GeometryError if nothing can be matched (fewer than two images).
MatchResult match(const MatchInputs& inputs, const MatchOptions& options,
                  const std::function<void(const std::string&)>& progress = {});

// The image pairs matched by descriptor for `n` images (see MatchOptions), a < b, sorted.
// `coded_overlap(a, b)`: coded points shared by the two images.
std::vector<std::pair<std::size_t, std::size_t>> feature_pairs(
    std::size_t n, const MatchOptions& options, const std::function<int(std::size_t, std::size_t)>& coded_overlap);

}  // namespace photomill::match
