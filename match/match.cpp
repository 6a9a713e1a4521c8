// match: observations and features to verified tracks (contract in match.hpp).
#include "match/match.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <set>
#include <thread>
#include <unordered_map>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/flann.hpp>

#include "formats/camera_for.hpp"
#include "formats/error.hpp"
#include "geometry/parallel.hpp"

namespace photomill::match {

namespace {

struct ImageData {
  const Camera* camera = nullptr;               // its camera, if any is given
  std::vector<Eigen::Vector2d> coded_px;        // as observed
  std::vector<Eigen::Vector2d> coded_ideal;     // undistorted
  std::vector<PointId> coded_ids;
  std::unordered_map<PointId, std::size_t> coded_index;
  const FeatureSet* features = nullptr;
  std::vector<Eigen::Vector2d> feature_ideal;   // undistorted keypoints
  // SIFT gives a blob with several dominant orientations one keypoint per orientation, all at
  // the same position: canonical[k] is the first keypoint at keypoint k's position, so such
  // copies join one track instead of making parallel tracks of the same point.
  std::vector<int> canonical;
  std::unordered_map<int, std::vector<int>> copies;  // canonical -> all keypoints at its position
  const cv::Mat* grey = nullptr;                     // for least-squares matching
  std::vector<std::uint8_t> root_descriptors;        // RootSIFT bytes, with MatchOptions::root_sift
  // The descriptors compared: the file's or the RootSIFT ones.
  const std::uint8_t* descriptor_bytes() const {
    return root_descriptors.empty() ? features->descriptors.data() : root_descriptors.data();
  }
  cv::Mat descriptors;                          // CV_32F, one row per keypoint (kd-tree search only)
  std::unique_ptr<cv::flann::Index> index;      // over `descriptors`
};

// Nearest and second-nearest neighbours of every row of `query` in `index`: best index and the
// ratio of the distances (FLANN's L2 gives squared distances).
struct Nearest {
  std::vector<int> best;
  std::vector<float> ratio;
};
Nearest nearest_two(cv::flann::Index& index, const cv::Mat& query, int checks) {
  Nearest out;
  if (query.rows == 0) return out;
  cv::Mat indices, dists;
  index.knnSearch(query, indices, dists, 2, cv::flann::SearchParams(checks));
  out.best.resize(static_cast<std::size_t>(query.rows));
  out.ratio.resize(static_cast<std::size_t>(query.rows));
  for (int r = 0; r < query.rows; ++r) {
    out.best[static_cast<std::size_t>(r)] = indices.at<int>(r, 0);
    const float d1 = dists.at<float>(r, 0), d2 = dists.at<float>(r, 1);
    out.ratio[static_cast<std::size_t>(r)] = d2 > 0 ? std::sqrt(d1 / d2) : 1.0f;
  }
  return out;
}

struct FeatureMatch {
  int a = 0, b = 0;  // keypoint indices
  double cost = 0;   // the worse of the two distance ratios
};

// Lowe's ratio test in both directions and the mutual check.
std::vector<FeatureMatch> match_descriptors(ImageData& a, ImageData& b, const MatchOptions& o) {
  std::vector<FeatureMatch> out;
  if (a.descriptors.rows < 2 || b.descriptors.rows < 2) return out;
  const Nearest ab = nearest_two(*b.index, a.descriptors, o.flann_checks);
  const Nearest ba = nearest_two(*a.index, b.descriptors, o.flann_checks);
  for (std::size_t i = 0; i < ab.best.size(); ++i) {
    const int j = ab.best[i];
    if (j < 0 || ab.ratio[i] >= o.ratio) continue;
    const auto ju = static_cast<std::size_t>(j);
    const bool mutual = ba.best[ju] == static_cast<int>(i);
    if (o.mutual && (!mutual || ba.ratio[ju] >= o.ratio)) continue;
    out.push_back({static_cast<int>(i), j, std::max(ab.ratio[i], o.mutual ? ba.ratio[ju] : 0.0f)});
  }
  return out;
}

// Squared Euclidean distance of two byte descriptors (SIFT's: 0-255 per value), summed in
// integers: exact, and an integer sum may be reordered, so the compiler vectorises it (a float sum
// it must add in order, one value after the other). Up to 258 values the sum stays below 2^24,
// so as a float it is the same number the float sum of the converted descriptors gave.
std::int32_t squared_distance(const std::uint8_t* a, const std::uint8_t* b, int n) {
  std::int32_t sum = 0;
  for (int k = 0; k < n; ++k) {
    const std::int32_t e = static_cast<std::int32_t>(a[k]) - static_cast<std::int32_t>(b[k]);
    sum += e * e;
  }
  return sum;
}

// Guided matching with a known F: each feature of `a` is compared only with the features of `b`
// within the epipolar band (Sampson distance <= threshold; Hartley & Zisserman sec. 11.9 "guided
// matching"), the ratio test taken among those candidates, in both directions, with the mutual
// check. The band holds ~50 of the ~20 000 features of a photo, so this is exact and much faster
// than kd-tree search over all of them; EpipolarPencil finds the band's features without
// looking at the others. (The order in which candidates are met does not matter: the best two
// distances are the smallest two whatever the order, and a tie for the best fails the ratio test.)
std::vector<FeatureMatch> match_guided(const ImageData& a, const ImageData& b, const Eigen::Matrix3d& F,
                                       const MatchOptions& o) {
  std::vector<FeatureMatch> out;
  const int na = static_cast<int>(a.features->keypoints.size()), nb = static_cast<int>(b.features->keypoints.size());
  if (na < 2 || nb < 2) return out;
  const int dim = a.features->descriptor_dim;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // Best and second-best squared distances per feature, both directions.
  std::vector<float> a1(static_cast<std::size_t>(na), kInf), a2(static_cast<std::size_t>(na), kInf);
  std::vector<float> b1(static_cast<std::size_t>(nb), kInf), b2(static_cast<std::size_t>(nb), kInf);
  std::vector<int> abest(static_cast<std::size_t>(na), -1), bbest(static_cast<std::size_t>(nb), -1);
  const double thr = o.fit.threshold_px;
  // Keeps the best and second-best distance (and who had the best).
  auto keep_two = [](float& best, float& second, int& who, float d, int other) {
    if (d < best) {
      second = best;
      best = d;
      who = other;
    } else if (d < second) {
      second = d;
    }
  };
  // Sampson distance (H&Z eq. 11.9) from F x_a, computed once per feature of a, and the first two
  // components of F^T x_b, once per feature of b (by the pencil):
  //   d^2 = (x_b . F x_a)^2 / ((F x_a)_1^2 + (F x_a)_2^2 + (F^T x_b)_1^2 + (F^T x_b)_2^2).
  const EpipolarPencil pencil(b.feature_ideal, F);
  const double thr2 = thr * thr;
  for (int i = 0; i < na; ++i) {
    const Eigen::Vector2d& xa = a.feature_ideal[static_cast<std::size_t>(i)];
    const Eigen::Vector3d fa = F * xa.homogeneous();
    const double fa2 = fa.head<2>().squaredNorm();
    if (!(fa2 > 0)) continue;
    const std::uint8_t* da = a.descriptor_bytes() + static_cast<std::size_t>(i) * static_cast<std::size_t>(dim);
    pencil.near(fa, thr, [&](std::size_t j) {
      const Eigen::Vector2d& xb = b.feature_ideal[j];
      const double e = xb.x() * fa.x() + xb.y() * fa.y() + fa.z();
      if (e * e > thr2 * (fa2 + pencil.ftb2(j))) return;
      const std::uint8_t* db = b.descriptor_bytes() + j * static_cast<std::size_t>(dim);
      const auto d = static_cast<float>(squared_distance(da, db, dim));
      const int jb = static_cast<int>(j);
      keep_two(a1[static_cast<std::size_t>(i)], a2[static_cast<std::size_t>(i)], abest[static_cast<std::size_t>(i)], d, jb);
      keep_two(b1[j], b2[j], bbest[j], d, i);
    });
  }
  auto ratio = [](float d1, float d2) { return d2 > 0 && d2 < kInf ? std::sqrt(d1 / d2) : 1.0f; };
  for (int i = 0; i < na; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    const int j = abest[iu];
    if (j < 0) continue;
    const float rab = ratio(a1[iu], a2[iu]);
    if (rab >= o.guided_ratio) continue;
    const auto ju = static_cast<std::size_t>(j);
    const float rba = ratio(b1[ju], b2[ju]);
    if (o.mutual && (bbest[ju] != i || rba >= o.guided_ratio)) continue;
    out.push_back({i, j, std::max(rab, o.mutual ? rba : 0.0f)});
  }
  return out;
}

struct PairWork {
  PairReport report;
  std::optional<Eigen::Matrix3d> F;
  std::vector<FeatureMatch> inlier_matches;
};

// The options match cannot work with.
void check_options(const MatchInputs& in, const MatchOptions& o) {
  if (!(o.ratio > 0 && o.ratio <= 1)) throw UsageError("--ratio must be in (0, 1]");
  if (!(o.guided_ratio > 0 && o.guided_ratio <= 1)) throw UsageError("--guided-ratio must be in (0, 1]");
  if (!(o.fit.threshold_px > 0)) throw UsageError("--threshold-px must be positive");
  if (o.feature_track_offset < 0) throw UsageError("--feature-id-offset must be non-negative");
  if (!in.poses.empty() && !in.camera && in.cameras_by_prefix.empty()) {
    throw UsageError("--poses needs --camera (F = K^-T [t]x R K^-1)");
  }
  if (in.camera && !in.cameras_by_prefix.empty()) throw UsageError("give one camera for all photos or one per prefix, not both");
}

// Each image's coded observations, features and (for refinement) grey image; `image_index` maps
// an image name to its index in `data`.
std::vector<ImageData> load_images(const MatchInputs& in, const MatchOptions& o,
                                   const std::unordered_map<std::string, std::size_t>& image_index, std::size_t n) {
  std::vector<ImageData> data(n);
  std::vector<std::string> prefixes;
  for (const auto& [prefix, camera] : in.cameras_by_prefix) prefixes.push_back(prefix);
  for (const auto& [name, i] : image_index) {
    if (in.camera) {
      data[i].camera = &*in.camera;
    } else if (!prefixes.empty()) {
      data[i].camera = &in.cameras_by_prefix[require_rig_prefix(prefixes, name, "match's inputs").camera].second;
    }
  }
  for (const auto& ob : in.observations) {
    ImageData& d = data[image_index.at(ob.image)];
    if (!d.coded_index.emplace(ob.point_id, d.coded_ids.size()).second) {
      throw InputError(ob.image, 0, "point " + std::to_string(ob.point_id) + " observed twice");
    }
    d.coded_ids.push_back(ob.point_id);
    d.coded_px.emplace_back(ob.u_px, ob.v_px);
  }
  int dim = -1;
  for (const auto& fs : in.features) {
    ImageData& d = data[image_index.at(fs.image)];
    if (d.features) throw InputError(fs.image, 0, "features of this image given twice");
    if (!fs.keypoints.empty()) {
      if (dim >= 0 && fs.descriptor_dim != dim) {
        throw InputError(fs.image, 0, "descriptors of " + std::to_string(fs.descriptor_dim) + " values, others have " +
                                          std::to_string(dim));
      }
      dim = fs.descriptor_dim;
    }
    d.features = &fs;
  }
  if (o.refine) {
    if (in.grey_images.size() != in.features.size()) throw std::logic_error("match: refine needs one grey image per feature set");
    for (std::size_t k = 0; k < in.features.size(); ++k) {
      const cv::Mat& g = in.grey_images[k];
      if (g.type() != CV_32FC1) throw std::logic_error("match: grey images must be CV_32FC1");
      const FeatureSet& fs = in.features[k];
      if (g.cols != fs.image_width_px || g.rows != fs.image_height_px) {
        throw InputError(fs.image, 0, "image is " + std::to_string(g.cols) + "x" + std::to_string(g.rows) +
                                          " px but its features file says " + std::to_string(fs.image_width_px) + "x" +
                                          std::to_string(fs.image_height_px));
      }
      data[image_index.at(fs.image)].grey = &g;
    }
  }
  return data;
}

// A pose names its image exactly or, failing that, by file name when only one pose has it (the
// poses of another tool name photos relative to its own folder), as triangulate --known-poses.
// Empty without poses.
std::unordered_map<std::string, const Pose*> poses_by_image(const std::vector<Pose>& poses,
                                                            const std::vector<std::string>& images) {
  std::unordered_map<std::string, const Pose*> pose_of;
  if (poses.empty()) return pose_of;
  std::unordered_map<std::string, const Pose*> exact;
  std::unordered_map<std::string, std::vector<const Pose*>> by_file;
  for (const auto& p : poses) {
    exact[p.image] = &p;
    by_file[std::filesystem::path(p.image).filename().string()].push_back(&p);
  }
  for (const auto& name : images) {
    if (const auto it = exact.find(name); it != exact.end()) {
      pose_of[name] = it->second;
    } else if (const auto f = by_file.find(std::filesystem::path(name).filename().string());
               f != by_file.end() && f->second.size() == 1) {
      pose_of[name] = f->second.front();
    } else {
      throw InputError(name, 0, "no pose for this image in --poses");
    }
  }
  return pose_of;
}

void check_id_collisions(const std::vector<ImageData>& data, const MatchInputs& in, const MatchOptions& o) {
  for (const auto& d : data) {
    for (PointId id : d.coded_ids) {
      if (id >= o.feature_track_offset && !in.features.empty()) {
        throw UsageError("coded point id " + std::to_string(id) + " collides with natural-feature track ids (from " +
                         std::to_string(o.feature_track_offset) + "): raise --feature-id-offset");
      }
    }
  }
}

}  // namespace

// RootSIFT (Arandjelovic & Zisserman 2012): each descriptor v divided by its L1 norm, the square
// root taken of every value (so the result has unit L2 norm), then scaled by 512 and rounded to
// a byte as SIFT's own descriptors are (COLMAP's FeatureDescriptorsToUnsignedByte uses the same
// 512; a value over 255 would need one bin to hold a quarter of the L1 mass, and is clamped).
std::vector<std::uint8_t> root_sift(const std::vector<std::uint8_t>& descriptors, int dim) {
  std::vector<std::uint8_t> out(descriptors.size());
  const auto n = static_cast<std::size_t>(dim);
  for (std::size_t row = 0; row + n <= descriptors.size(); row += n) {
    double l1 = 0;
    for (std::size_t k = 0; k < n; ++k) l1 += descriptors[row + k];
    for (std::size_t k = 0; k < n && l1 > 0; ++k) {
      const double v = 512.0 * std::sqrt(descriptors[row + k] / l1);
      out[row + k] = static_cast<std::uint8_t>(std::min(255.0, std::round(v)));
    }
  }
  return out;
}

namespace {

// Undistorts the coded points and keypoints, finds each keypoint's canonical copy, and indexes the
// descriptors for FLANN's kd-trees unless matching is guided (in parallel over images).
void prepare_images(std::vector<ImageData>& data, const MatchOptions& o, bool guided) {
  // One undistorter per camera (a photo without a camera keeps its pixels).
  std::map<const Camera*, Undistorter> undistorters;
  for (const ImageData& d : data) {
    if (d.camera && !undistorters.count(d.camera)) undistorters.emplace(d.camera, Undistorter(*d.camera));
  }
  const Undistorter none;
  geometry::parallel_for(data.size(), o.jobs, [&](std::size_t i) {
    ImageData& d = data[i];
    const Undistorter& undistort = d.camera ? undistorters.at(d.camera) : none;
    d.coded_ideal = undistort.apply(d.coded_px);
    if (!d.features) return;
    std::vector<Eigen::Vector2d> kp;
    std::map<std::pair<double, double>, int> first_at;
    for (const auto& k : d.features->keypoints) {
      const int index = static_cast<int>(kp.size());
      d.canonical.push_back(first_at.emplace(std::make_pair(k.x_px, k.y_px), index).first->second);
      d.copies[d.canonical.back()].push_back(index);
      kp.emplace_back(k.x_px, k.y_px);
    }
    d.feature_ideal = undistort.apply(kp);
    const int rows = static_cast<int>(d.features->keypoints.size());
    if (o.root_sift) d.root_descriptors = root_sift(d.features->descriptors, d.features->descriptor_dim);
    if (!guided && rows >= 2) {
      cv::Mat(rows, d.features->descriptor_dim, CV_8U, const_cast<std::uint8_t*>(d.descriptor_bytes()))
          .convertTo(d.descriptors, CV_32F);
      // FLANN draws its random trees from OpenCV's thread-local RNG: seed it per image so the
      // trees, hence the matches, do not depend on which thread indexed which image before.
      cv::theRNG() = cv::RNG(0x9E3779B9u + static_cast<std::uint64_t>(i));
      d.index = std::make_unique<cv::flann::Index>(d.descriptors, cv::flann::KDTreeIndexParams(o.flann_trees));
    }
  });
}

using ImagesOfPoint = std::unordered_map<PointId, std::vector<std::size_t>>;  // point id -> images

ImagesOfPoint images_of_points(const std::vector<ImageData>& data) {
  ImagesOfPoint seen_in;
  for (std::size_t i = 0; i < data.size(); ++i) {
    for (PointId id : data[i].coded_ids) seen_in[id].push_back(i);
  }
  return seen_in;
}

// An image pair to look at; `features`: its natural features are matched too.
struct ImagePair {
  std::size_t a = 0, b = 0;
  bool features = false;
};

// Pairs: those sharing coded points (their coded points verified), plus the descriptor pairs
// (feature_pairs: exhaustive, sequence and coded neighbours); with poses and guided matching,
// every pair sharing coded points and every pair of feature images whose optical axes are close
// enough, all matched along the epipolar lines.
std::vector<ImagePair> select_pairs(
    const std::vector<ImageData>& data, const ImagesOfPoint& seen_in, const std::vector<std::string>& images,
    const std::unordered_map<std::string, const Pose*>& pose_of, const MatchOptions& o, bool guided) {
  const std::size_t n = data.size();
  std::vector<std::vector<int>> overlap(n, std::vector<int>(n, 0));
  for (const auto& [id, seen] : seen_in) {
    for (std::size_t x = 0; x < seen.size(); ++x) {
      for (std::size_t y = x + 1; y < seen.size(); ++y) {
        ++overlap[seen[x]][seen[y]];
        ++overlap[seen[y]][seen[x]];
      }
    }
  }
  std::map<std::pair<std::size_t, std::size_t>, bool> pair_set;  // (a, b) -> match its features
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      if (overlap[a][b] > 0) pair_set[{a, b}] = guided;
    }
  }
  if (guided) {
    // Optical axis in the world: the third row of R (cam_from_world), R^T (0, 0, 1).
    const double min_cos = std::cos(o.guided_max_axis_angle_deg * std::numbers::pi / 180);
    std::vector<Eigen::Vector3d> axis(n);
    for (std::size_t i = 0; i < n; ++i) axis[i] = pose_of.at(images[i])->rotation().row(2).transpose();
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) {
        if (data[a].features && data[b].features && axis[a].dot(axis[b]) >= min_cos) pair_set[{a, b}] = true;
      }
    }
  } else {
    std::vector<std::size_t> with_features;
    for (std::size_t i = 0; i < n; ++i) {
      if (data[i].index) with_features.push_back(i);
    }
    for (const auto& [x, y] : feature_pairs(with_features.size(), o, [&](std::size_t p, std::size_t q) {
           return overlap[with_features[p]][with_features[q]];
         })) {
      pair_set[{with_features[x], with_features[y]}] = true;
    }
  }
  std::vector<ImagePair> pairs;
  for (const auto& [ab, features] : pair_set) pairs.push_back({ab.first, ab.second, features});
  return pairs;
}

// Matches and verifies one image pair (a, b): its shared coded points and its feature matches
// against one F, from the two poses (`pose_a`, `pose_b`, both given or neither) or estimated.
PairWork match_pair(ImageData& a, ImageData& b, const Pose* pose_a, const Pose* pose_b, const MatchInputs& in,
                    const MatchOptions& o, bool guided, bool features) {
  PairWork w;
  std::vector<Eigen::Vector2d> pa, pb;
  for (std::size_t i = 0; i < a.coded_ids.size(); ++i) {
    const auto it = b.coded_index.find(a.coded_ids[i]);
    if (it == b.coded_index.end()) continue;
    // (A point where the camera's distortion cannot be inverted is NaN: left out.)
    if (!a.coded_ideal[i].allFinite() || !b.coded_ideal[it->second].allFinite()) continue;
    pa.push_back(a.coded_ideal[i]);
    pb.push_back(b.coded_ideal[it->second]);
  }
  w.report.coded_shared = static_cast<int>(pa.size());
  std::vector<FeatureMatch> matches;
  if (guided) {
    w.F = fundamental_from_poses(a.camera->camera_matrix, b.camera->camera_matrix, *pose_a, *pose_b);
    if (a.features && b.features) matches = match_guided(a, b, *w.F, o);
  } else if (features && a.index && b.index) {
    matches = match_descriptors(a, b, o);
  }
  std::erase_if(matches, [&](const FeatureMatch& m) {
    return !a.feature_ideal[static_cast<std::size_t>(m.a)].allFinite() ||
           !b.feature_ideal[static_cast<std::size_t>(m.b)].allFinite();
  });
  w.report.feature_matches = static_cast<int>(matches.size());
  for (const auto& m : matches) {
    pa.push_back(a.feature_ideal[static_cast<std::size_t>(m.a)]);
    pb.push_back(b.feature_ideal[static_cast<std::size_t>(m.b)]);
  }
  std::vector<bool> inlier(pa.size(), false);
  if (!in.poses.empty()) {
    w.F = fundamental_from_poses(a.camera->camera_matrix, b.camera->camera_matrix, *pose_a, *pose_b);
    w.report.from_poses = true;
    for (std::size_t i = 0; i < pa.size(); ++i) inlier[i] = sampson_distance_px(*w.F, pa[i], pb[i]) <= o.fit.threshold_px;
  } else if (const auto fit = estimate_fundamental(pa, pb, o.fit)) {
    w.F = fit->F;
    inlier = fit->inliers;
  }
  w.report.verified = w.F.has_value();
  if (w.F) {
    for (int i = 0; i < w.report.coded_shared; ++i) w.report.coded_inliers += inlier[static_cast<std::size_t>(i)] ? 1 : 0;
    for (std::size_t m = 0; m < matches.size(); ++m) {
      if (inlier[static_cast<std::size_t>(w.report.coded_shared) + m]) w.inlier_matches.push_back(matches[m]);
    }
    w.report.feature_inliers = static_cast<int>(w.inlier_matches.size());
  }
  // With poses F needs no matches, but a pair whose matches agree with it fewer than
  // --min-inliers times is no verified pair: its feature matches are chance agreements along
  // the epipolar lines. (F still judges its coded points, which carry their ids.)
  if (w.report.from_poses && w.report.coded_inliers + w.report.feature_inliers < o.fit.min_inliers) {
    w.report.verified = false;
    w.inlier_matches.clear();
    w.report.feature_inliers = 0;
  }
  return w;
}

// Pairwise verdict of two observations (image, undistorted position) of one track: the Sampson
// distance to the F of their image pair within the threshold; nullopt when the pair has no F.
class PairVerdicts {
 public:
  PairVerdicts(const std::vector<PairWork>& work, double threshold_px) : threshold_px_(threshold_px) {
    for (const auto& w : work) by_pair_[{w.report.a, w.report.b}] = &w;
  }
  std::optional<bool> operator()(std::size_t ia, const Eigen::Vector2d& xa, std::size_t ib,
                                 const Eigen::Vector2d& xb) const {
    const bool swap = ia > ib;
    const auto it = by_pair_.find(swap ? std::make_pair(ib, ia) : std::make_pair(ia, ib));
    if (it == by_pair_.end() || !it->second->F) return std::nullopt;
    const double d = swap ? sampson_distance_px(*it->second->F, xb, xa) : sampson_distance_px(*it->second->F, xa, xb);
    return d <= threshold_px_;
  }

 private:
  std::map<std::pair<std::size_t, std::size_t>, const PairWork*> by_pair_;
  double threshold_px_;
};

// Coded tracks: group by id, vote; into result.tracks, the observations dropped into result.dropped.
void coded_tracks(const ImagesOfPoint& seen_in, const std::vector<ImageData>& data, const PairVerdicts& agree,
                  const MatchOptions& o, MatchResult& result) {
  std::vector<PointId> coded_ids;
  for (const auto& [id, images] : seen_in) coded_ids.push_back(id);
  std::sort(coded_ids.begin(), coded_ids.end());
  for (PointId id : coded_ids) {
    const auto& images = seen_in.at(id);
    if (images.size() < 2) {
      result.dropped.push_back({result.images[images[0]], id, "seen in one image only"});
      continue;
    }
    auto position = [&](std::size_t k) { return data[images[k]].coded_ideal[data[images[k]].coded_index.at(id)]; };
    std::vector<bool> verified;
    const auto kept = vote_track(
        images.size(), [&](std::size_t x, std::size_t y) { return agree(images[x], position(x), images[y], position(y)); },
        &verified);
    std::vector<std::size_t> final_kept;
    for (std::size_t k = 0; k < images.size(); ++k) {
      const bool is_kept = std::find(kept.begin(), kept.end(), k) != kept.end();
      if (is_kept && (verified[k] || o.keep_unverified)) {
        final_kept.push_back(k);
      } else {
        result.dropped.push_back({result.images[images[k]], id,
                                  is_kept ? "no image pair could verify it" : "inconsistent with the other images of the point"});
      }
    }
    if (final_kept.size() < std::max<std::size_t>(o.min_track_length, 2)) {
      for (std::size_t k : final_kept) {
        result.dropped.push_back({result.images[images[k]], id, "track too short after verification"});
      }
      continue;
    }
    ++result.coded_tracks;
    ++result.track_lengths[final_kept.size()];
    for (std::size_t k : final_kept) {
      const auto& p = data[images[k]].coded_px[data[images[k]].coded_index.at(id)];
      result.tracks.push_back({id, result.images[images[k]], p.x(), p.y()});
    }
  }
}

// Natural-feature tracks: union-find over the verified matches, then the same vote; the tracks
// still at least `min_length` long.
std::vector<std::vector<FeatureRef>> voted_feature_tracks(const std::vector<PairWork>& work,
                                                          const std::vector<ImageData>& data, const PairVerdicts& agree,
                                                          const MatchOptions& o, std::size_t min_length,
                                                          MatchResult& result) {
  std::vector<MatchEdge> edges;
  for (const auto& w : work) {
    const ImageData& a = data[w.report.a];
    const ImageData& b = data[w.report.b];
    for (const auto& m : w.inlier_matches) {
      edges.push_back({{static_cast<int>(w.report.a), a.canonical[static_cast<std::size_t>(m.a)]},
                       {static_cast<int>(w.report.b), b.canonical[static_cast<std::size_t>(m.b)]}, m.cost});
    }
  }
  const auto tracks = build_tracks(std::move(edges), o.min_track_length, &result.feature_unions);
  std::vector<std::vector<FeatureRef>> voted;
  for (const auto& t : tracks) {
    auto pos = [&](std::size_t k) {
      return data[static_cast<std::size_t>(t[k].image)].feature_ideal[static_cast<std::size_t>(t[k].feature)];
    };
    const auto kept = vote_track(t.size(), [&](std::size_t x, std::size_t y) {
      return agree(static_cast<std::size_t>(t[x].image), pos(x), static_cast<std::size_t>(t[y].image), pos(y));
    });
    result.feature_observations_voted_out += t.size() - kept.size();
    if (kept.size() < min_length) continue;
    std::vector<FeatureRef> v;
    for (std::size_t k : kept) v.push_back(t[k]);
    voted.push_back(std::move(v));
  }
  return voted;
}

const Keypoint& keypoint(const std::vector<ImageData>& data, const FeatureRef& f) {
  return data[static_cast<std::size_t>(f.image)].features->keypoints[static_cast<std::size_t>(f.feature)];
}

// Least-squares matching of one track: every observation against the one with the smallest
// feature (finest detail), which stays where SIFT put it and so names the surface point. The
// start is the similarity the two keypoints imply (size ratio, orientation difference); as
// OpenCV's angle sense and a blob's several orientations (copies) leave the rotation open, the
// candidate with the best window correlation starts the alignment.
std::vector<std::optional<Eigen::Vector2d>> refine_track(const std::vector<ImageData>& data,
                                                         const std::vector<FeatureRef>& t, const LsmOptions& lo,
                                                         std::map<std::string, std::size_t>& refused) {
  std::vector<std::optional<Eigen::Vector2d>> out(t.size());
  std::size_t r = 0;
  for (std::size_t j = 1; j < t.size(); ++j) {
    if (keypoint(data, t[j]).size_px < keypoint(data, t[r]).size_px) r = j;
  }
  const ImageData& dr = data[static_cast<std::size_t>(t[r].image)];
  const Keypoint& kr = keypoint(data, t[r]);
  const Eigen::Vector2d ref(kr.x_px, kr.y_px);
  out[r] = ref;
  const int h = half_window_for(kr.size_px, lo);
  for (std::size_t j = 0; j < t.size(); ++j) {
    if (j == r) continue;
    const ImageData& dj = data[static_cast<std::size_t>(t[j].image)];
    const Keypoint& kj = keypoint(data, t[j]);
    const Eigen::Vector2d start(kj.x_px, kj.y_px);
    const double zoom = kr.size_px > 0 && kj.size_px > 0 ? kj.size_px / kr.size_px : 1.0;
    std::vector<double> turns{0.0};
    for (int a : dr.copies.at(t[r].feature)) {
      for (int b : dj.copies.at(t[j].feature)) {
        const double aa = dr.features->keypoints[static_cast<std::size_t>(a)].angle_deg;
        const double ab = dj.features->keypoints[static_cast<std::size_t>(b)].angle_deg;
        if (aa < 0 || ab < 0) continue;
        const double turn = (ab - aa) * std::numbers::pi / 180;
        turns.push_back(turn);
        turns.push_back(-turn);
      }
    }
    Eigen::Matrix2d best_A = zoom * Eigen::Matrix2d::Identity();
    double best = -2;
    for (double turn : turns) {
      const Eigen::Matrix2d A = zoom * Eigen::Rotation2Dd(turn).toRotationMatrix();
      const auto c = window_correlation(*dr.grey, ref, h, *dj.grey, A, start, 2);
      if (c && *c > best) {
        best = *c;
        best_A = A;
      }
    }
    LsmFailure why = LsmFailure::None;
    if (const auto fit = lsm_align(*dr.grey, ref, h, *dj.grey, best_A, start, lo, &why)) {
      out[j] = fit->point_px;
    } else {
      ++refused[to_string(why)];
    }
  }
  return out;
}

// Writes the voted feature tracks into result.tracks, numbered from --feature-id-offset up: each
// observation at its keypoint (with its size) or, with `refined` (one entry per track, from
// refine_track), at its refined position, dropping the observations LSM refused and the tracks
// then shorter than `min_length`.
void write_feature_tracks(const std::vector<std::vector<FeatureRef>>& voted,
                          const std::vector<std::vector<std::optional<Eigen::Vector2d>>>& refined,
                          const std::vector<ImageData>& data, const MatchOptions& o, std::size_t min_length,
                          MatchResult& result) {
  TrackId next_id = o.feature_track_offset;
  for (std::size_t k = 0; k < voted.size(); ++k) {
    const auto& t = voted[k];
    std::size_t length = t.size();
    if (o.refine) {
      length = static_cast<std::size_t>(std::count_if(refined[k].begin(), refined[k].end(), [](const auto& p) { return p.has_value(); }));
      if (length < min_length) {
        ++result.refine_tracks_dropped;
        continue;
      }
    }
    const TrackId id = next_id++;
    ++result.feature_tracks;
    ++result.track_lengths[length];
    for (std::size_t j = 0; j < t.size(); ++j) {
      const Keypoint& kp = keypoint(data, t[j]);
      const std::string& image = result.images[static_cast<std::size_t>(t[j].image)];
      if (o.refine) {
        if (!refined[k][j]) continue;
        ++result.refined_observations;
        result.tracks.push_back({id, image, refined[k][j]->x(), refined[k][j]->y()});
      } else {
        result.tracks.push_back({id, image, kp.x_px, kp.y_px, kp.size_px > 0 ? std::optional<double>(kp.size_px) : std::nullopt});
      }
    }
  }
}

// Natural-feature tracks from the pairs' verified matches, least-squares refined with
// MatchOptions::refine, into `result`.
void feature_tracks(const std::vector<PairWork>& work, const std::vector<ImageData>& data, const PairVerdicts& agree,
                    const MatchOptions& o, const std::function<void(const std::string&)>& say, MatchResult& result) {
  say("building feature tracks");
  const std::size_t min_length = std::max<std::size_t>(o.min_track_length, 2);
  const auto voted = voted_feature_tracks(work, data, agree, o, min_length, result);
  // Positions written per observation: the keypoint's, or the refined one.
  std::vector<std::vector<std::optional<Eigen::Vector2d>>> refined(voted.size());
  if (o.refine) {
    say("least-squares matching of " + std::to_string(voted.size()) + " feature tracks");
    std::vector<std::map<std::string, std::size_t>> refused(voted.size());
    geometry::parallel_for(voted.size(), o.jobs, [&](std::size_t k) {
      refined[k] = refine_track(data, voted[k], *o.refine, refused[k]);
    });
    for (const auto& r : refused) {
      for (const auto& [why, count] : r) result.refine_refused[why] += count;
    }
  }
  write_feature_tracks(voted, refined, data, o, min_length, result);
}

}  // namespace

std::vector<std::pair<std::size_t, std::size_t>> feature_pairs(
    std::size_t n, const MatchOptions& o, const std::function<int(std::size_t, std::size_t)>& coded_overlap) {
  std::set<std::pair<std::size_t, std::size_t>> pairs;
  if (n <= static_cast<std::size_t>(std::max(o.exhaustive_max_images, 0))) {
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) pairs.emplace(a, b);
    }
    return {pairs.begin(), pairs.end()};
  }
  for (std::size_t a = 0; a < n; ++a) {
    for (int d = 1; d <= o.sequence_neighbours && a + static_cast<std::size_t>(d) < n; ++d) {
      pairs.emplace(a, a + static_cast<std::size_t>(d));
    }
    if (o.coded_neighbours <= 0) continue;
    std::vector<std::pair<int, std::size_t>> overlap;
    for (std::size_t b = 0; b < n; ++b) {
      if (b == a) continue;
      const int shared = coded_overlap(a, b);
      if (shared > 0) overlap.emplace_back(-shared, b);
    }
    const auto k = std::min<std::size_t>(overlap.size(), static_cast<std::size_t>(o.coded_neighbours));
    std::partial_sort(overlap.begin(), overlap.begin() + static_cast<std::ptrdiff_t>(k), overlap.end());
    for (std::size_t m = 0; m < k; ++m) pairs.emplace(std::min(a, overlap[m].second), std::max(a, overlap[m].second));
  }
  return {pairs.begin(), pairs.end()};
}

MatchResult match(const MatchInputs& in, const MatchOptions& o, const std::function<void(const std::string&)>& progress) {
  auto say = [&](const std::string& m) {
    if (progress) progress(m);
  };
  check_options(in, o);

  MatchResult result;
  std::unordered_map<std::string, std::size_t> image_index;
  auto image_of = [&](const std::string& name) {
    const auto [it, fresh] = image_index.emplace(name, result.images.size());
    if (fresh) result.images.push_back(name);
    return it->second;
  };
  for (const auto& ob : in.observations) image_of(ob.image);
  for (const auto& fs : in.features) image_of(fs.image);
  const std::size_t n = result.images.size();
  if (n < 2) throw GeometryError("nothing to match: the inputs cover " + std::to_string(n) + " image(s), at least 2 are needed");

  std::vector<ImageData> data = load_images(in, o, image_index, n);
  const auto pose_of = poses_by_image(in.poses, result.images);
  check_id_collisions(data, in, o);

  // With known poses the features are matched along epipolar lines (match_guided), otherwise by
  // kd-tree search over all of them.
  const bool guided = o.guided && !in.poses.empty();
  say("indexing " + std::to_string(in.features.size()) + " feature sets");
  prepare_images(data, o, guided);

  const ImagesOfPoint seen_in = images_of_points(data);
  const auto pairs = select_pairs(data, seen_in, result.images, pose_of, o, guided);

  // Match and verify every pair.
  say("matching " + std::to_string(pairs.size()) + " image pairs");
  std::vector<PairWork> work(pairs.size());
  std::atomic<std::size_t> done{0};
  std::mutex say_mutex;
  geometry::parallel_for(pairs.size(), o.jobs, [&](std::size_t k) {
    const auto [ia, ib, features] = pairs[k];
    const Pose* pose_a = pose_of.empty() ? nullptr : pose_of.at(result.images[ia]);
    const Pose* pose_b = pose_of.empty() ? nullptr : pose_of.at(result.images[ib]);
    work[k] = match_pair(data[ia], data[ib], pose_a, pose_b, in, o, guided, features);
    work[k].report.a = ia;
    work[k].report.b = ib;
    const std::size_t finished = ++done;
    if (progress && (finished % 10 == 0 || finished == pairs.size())) {
      const std::lock_guard<std::mutex> lock(say_mutex);
      say("pairs: " + std::to_string(finished) + "/" + std::to_string(pairs.size()));
    }
  });
  for (const auto& w : work) result.pairs.push_back(w.report);
  const PairVerdicts agree(work, o.fit.threshold_px);

  coded_tracks(seen_in, data, agree, o, result);
  if (!in.features.empty()) feature_tracks(work, data, agree, o, say, result);
  std::stable_sort(result.tracks.begin(), result.tracks.end(), [&](const TrackObservation& x, const TrackObservation& y) {
    if (x.track_id != y.track_id) return x.track_id < y.track_id;
    return image_index.at(x.image) < image_index.at(y.image);
  });
  return result;
}

}  // namespace photomill::match
