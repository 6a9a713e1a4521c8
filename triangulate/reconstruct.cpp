// The reconstruction pipeline (see reconstruct.hpp).
#include "triangulate/reconstruct.hpp"

#include <algorithm>
#include <optional>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

#include <Eigen/Geometry>

#include "formats/camera_for.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/text.hpp"
#include "geometry/parallel.hpp"

namespace photomill::triangulate {
namespace {

// The focal length that turns pixel thresholds into normalised ones: the mean of fx and fy over
// the cameras (their spread only scales a RANSAC threshold).
double mean_focal_px(const Scene& scene) {
  double sum = 0;
  for (const CameraModel& c : scene.cameras) sum += 0.5 * (c.params[kFx] + c.params[kFy]);
  return sum / static_cast<double>(scene.cameras.size());
}

using Clock = std::chrono::steady_clock;

std::string fmt(double v, int precision = 3) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

bool placed(const SceneTrack& t) { return t.at_control || t.state == TrackState::Triangulated; }

// The state of one run: the scene, the options and what the report collects along the way.
class Pipeline {
public:
  Pipeline(const ReconstructInput& input, const ReconstructOptions& options)
      : input_(input), o_(options) {}

  Reconstruction run();

private:
  void check_input();
  void register_from_known();
  void place_control_points();
  bool register_from_control();
  void start_incremental();
  void grow();
  void set_up_rig();
  std::size_t place_rig_frames();
  void report_rig();
  bool register_by_relative_pose(const std::set<std::size_t>& skip);
  void shared_points(std::size_t a, std::size_t b, std::vector<Eigen::Vector2d>& xa,
                     std::vector<Eigen::Vector2d>& xb) const;
  void intermediate_adjustment();
  bool align_to_control();
  void build_scale_constraints();
  void choose_datum();
  void final_adjustment();
  void prune();
  void check_two_view(Reconstruction& r, const std::vector<std::size_t>& views);
  using Sigmas = std::array<double, kObservationClasses>;
  Sigmas robust_sigma_px() const;
  std::vector<double> active_errors(std::vector<std::size_t>* which) const;
  // One adjustment; function_tolerance: a looser stop than --function-tolerance (intermediate ones).
  BundleSummary adjust(const BundleSetup& setup, std::optional<double> function_tolerance = std::nullopt);
  void finish(Reconstruction& r);

  const ReconstructInput& input_;
  const ReconstructOptions& o_;
  Scene scene_;
  Report report_;
  std::vector<std::string> registered_by_;
  BundleSetup setup_;                  // the gauge and datum of the current stage
  std::vector<ScaleConstraint> bars_;  // resolved scale constraints
  std::vector<std::size_t> bar_report_;  // bars_[i] -> report_.scale_bars index
  std::size_t last_ba_registered_ = 0;
  std::set<std::size_t> relative_tried_;  // images once registered from a relative pose (only once)
  BundleSummary last_;
  long long iterations_used_ = 0;  // Ceres iterations of all adjustments so far (the work limit)
};

void Pipeline::check_input() {
  if (scene_.observations.empty()) throw GeometryError(input_.tracks_source + ": no tracks: nothing to triangulate");
  if (scene_.images.size() < 2) {
    throw GeometryError(input_.tracks_source + ": every observation comes from one image ('" + scene_.images[0].name +
                        "'); triangulation needs two or more images that see the same points");
  }
  std::size_t unusable = 0;
  for (const auto& ob : scene_.observations) unusable += ob.usable ? 0 : 1;
  if (unusable > 0) {
    report_.warnings.push_back(std::to_string(unusable) +
                               " observations lie where the camera's distortion cannot be inverted; ignored");
  }
  std::size_t multi = 0;
  for (SceneTrack& t : scene_.tracks) {
    std::set<std::size_t> images;
    for (std::size_t o : t.observations) {
      if (scene_.observations[o].usable) images.insert(scene_.observations[o].image);
    }
    if (images.size() >= 2) {
      ++multi;
    } else if (!t.control_mm) {
      t.state = TrackState::Rejected;
      t.issue = TrackIssue::SeenOnce;
    }
  }
  if (multi == 0) {
    throw GeometryError(input_.tracks_source + ": every track is seen in only one image, so no ray meets another; "
                        "tracks must link the same point across two or more images");
  }
  // All points on a line: then every image shows them on a line (the image of a line is a line),
  // and neither PnP nor the essential matrix has a unique answer.
  bool any_spread = false;
  for (const SceneImage& im : scene_.images) {
    std::vector<Eigen::Vector2d> xy;
    for (std::size_t o : im.observations) {
      if (scene_.observations[o].usable) xy.push_back(scene_.observations[o].xy);
    }
    if (xy.size() >= 3 && !collinear(xy, o_.collinear_tolerance)) any_spread = true;
  }
  if (!any_spread) {
    throw GeometryError(input_.tracks_source + ": all points lie on a line (in every image the observations are "
                        "collinear), so the camera poses are not determined; points must span a plane or a volume");
  }
}

// The rig's frames (ReconstructInput::rig): each photo's frame from its name, the cameras' poses
// in the rig from rig.yaml, the reference frame's rig pose the identity (its photos' known poses
// are the rig's own, so the world is the rig's frame there).
void Pipeline::set_up_rig() {
  if (!input_.rig) return;
  std::vector<std::string> prefixes;
  for (const PrefixCamera& c : input_.cameras) prefixes.push_back(c.prefix);
  SceneRig rig;
  std::map<std::string, std::size_t> frame_index;
  for (SceneImage& im : scene_.images) {
    const std::string frame = require_rig_prefix(prefixes, im.name, input_.tracks_source).frame;
    const auto [it, added] = frame_index.emplace(frame, rig.frames.size());
    if (added) rig.frames.push_back(frame);
    im.frame = static_cast<std::ptrdiff_t>(it->second);
  }
  rig.rig_from_world.assign(rig.frames.size(), PoseBlock{});
  rig.frame_placed.assign(rig.frames.size(), 0);
  setup_.rig_reference_frame = frame_index.at(input_.rig_reference_frame);
  rig.frame_placed[setup_.rig_reference_frame] = 1;
  for (const RigCamera& c : input_.rig->cameras) {
    rig.cam_from_rig.push_back(make_pose(c.cam_from_rig_rotation, c.cam_from_rig_translation_mm));
    setup_.cam_from_rig_sigma.push_back(c.cam_from_rig_sigma);
  }
  setup_.cam_from_rig_given = rig.cam_from_rig;
  scene_.rig = std::move(rig);
}

// Frames not placed yet get the rig's pose from a registered photo of theirs (the one seeing the
// most points): rig_from_world = cam_from_rig^-1 cam_from_world. Every photo of a placed frame is
// then posed by the rig (registering those no PnP reached). Returns the photos newly registered.
std::size_t Pipeline::place_rig_frames() {
  if (!scene_.rig) return 0;
  SceneRig& rig = *scene_.rig;
  std::vector<std::size_t> best(rig.frames.size(), scene_.images.size()), seen(rig.frames.size(), 0);
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    const SceneImage& im = scene_.images[i];
    const auto f = static_cast<std::size_t>(im.frame);
    if (rig.frame_placed[f] || !im.registered) continue;
    std::size_t count = 0;
    for (std::size_t o : im.observations) count += scene_.observations[o].inlier && placed(scene_.tracks[scene_.observations[o].track]) ? 1 : 0;
    if (best[f] == scene_.images.size() || count > seen[f]) best[f] = i, seen[f] = count;
  }
  for (std::size_t f = 0; f < rig.frames.size(); ++f) {
    if (best[f] == scene_.images.size()) continue;
    const SceneImage& im = scene_.images[best[f]];
    rig.rig_from_world[f] = compose(geometry::inverse(rig.cam_from_rig[im.camera]), im.cam_from_world);
    rig.frame_placed[f] = 1;
  }
  std::size_t added = 0;
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    SceneImage& im = scene_.images[i];
    const auto f = static_cast<std::size_t>(im.frame);
    if (!rig.frame_placed[f]) continue;
    im.cam_from_world = compose(rig.cam_from_rig[im.camera], rig.rig_from_world[f]);
    if (!im.registered) {
      im.registered = true;
      registered_by_[i] = "rig";
      ++added;
    }
  }
  return added;
}

// The report's rig: frames placed, and each camera's pose in the rig as adjusted against the
// one given (rotation angle between them, translation difference).
void Pipeline::report_rig() {
  if (!scene_.rig) return;
  const SceneRig& rig = *scene_.rig;
  RigReport rr;
  rr.frames = rig.frames.size();
  for (char p : rig.frame_placed) rr.frames_placed += p ? 1 : 0;
  rr.reference_frame = rig.frames[setup_.rig_reference_frame];
  std::string unplaced;
  std::size_t n_unplaced = 0;
  for (std::size_t f = 0; f < rig.frames.size(); ++f) {
    if (rig.frame_placed[f]) continue;
    if (++n_unplaced <= 5) unplaced += (unplaced.empty() ? "'" : ", '") + rig.frames[f] + "'";
  }
  if (n_unplaced > 0) {
    report_.warnings.push_back(std::to_string(n_unplaced) + " frames of the rig have no pose (" + unplaced +
                               (n_unplaced > 5 ? "..." : "") + "): none of their photos sees enough of the model");
  }
  for (std::size_t k = 0; k < rig.cam_from_rig.size(); ++k) {
    RigCameraReport c;
    c.prefix = input_.cameras[k].prefix;
    c.refined = k > 0 && setup_.cam_from_rig_sigma[k].has_value();
    const PoseBlock& got = rig.cam_from_rig[k];
    const PoseBlock& given = setup_.cam_from_rig_given[k];
    const Eigen::Matrix3d dR = rotation_of(got) * rotation_of(given).transpose();
    c.rotation_change_deg = Eigen::AngleAxisd(dR).angle() * 180 / std::numbers::pi;
    c.translation_change_mm = (geometry::translation_of(got) - geometry::translation_of(given)).norm();
    c.translation_mm = {got[3], got[4], got[5]};
    c.baseline_mm = centre_of(got).norm();
    rr.cameras.push_back(c);
  }
  report_.rig = rr;
}

// The user's poses: each names an image of the tracks, exactly or (failing that) by its file
// name alone when only one image has it (a COLMAP model names images relative to its folder).
void Pipeline::register_from_known() {
  std::map<std::string, std::size_t> by_name;
  std::map<std::string, std::vector<std::size_t>> by_file;
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    by_name[scene_.images[i].name] = i;
    by_file[std::filesystem::path(scene_.images[i].name).filename().string()].push_back(i);
  }
  const std::string& src = input_.known_poses_source;
  std::set<std::size_t> taken;
  for (std::size_t k = 0; k < input_.known_poses.size(); ++k) {
    const Pose& p = input_.known_poses[k];
    const std::size_t line = k < input_.known_pose_lines.size() ? input_.known_pose_lines[k] : 0;
    std::optional<std::size_t> image;
    if (const auto it = by_name.find(p.image); it != by_name.end()) {
      image = it->second;
    } else if (const auto f = by_file.find(std::filesystem::path(p.image).filename().string());
               f != by_file.end() && f->second.size() == 1) {
      image = f->second.front();
    }
    if (!image) {
      throw InputError(src, line, "image '" + p.image + "' is not in the tracks (" + input_.tracks_source +
                                      "): a pose for a photo that was not matched; check the names");
    }
    if (!taken.insert(*image).second) {
      throw InputError(src, line, "a second pose for image '" + scene_.images[*image].name + "'");
    }
    SceneImage& im = scene_.images[*image];
    im.registered = true;
    im.cam_from_world = make_pose(p.rotation(), p.cam_from_world_translation_mm);
    registered_by_[*image] = "known_pose";
    KnownPose known{*image, im.cam_from_world, 0, 0};
    if (o_.pose_sigma_mm && o_.pose_sigma_deg) {
      known.sigma_mm = *o_.pose_sigma_mm;
      known.sigma_rad = *o_.pose_sigma_deg * std::numbers::pi / 180;
    }
    setup_.known_poses.push_back(known);
  }
  report_.known_poses = taken.size();
  if (o_.pose_sigma_mm && o_.pose_sigma_deg) {
    report_.pose_sigma_mm = o_.pose_sigma_mm;
    report_.pose_sigma_deg = o_.pose_sigma_deg;
  }
  if (taken.size() < 2) {
    throw InputError(src, 0, "gives the pose of " + std::to_string(taken.size()) +
                                 " image of the tracks; two or more are needed to triangulate from known poses");
  }
  place_control_points();
}

// Control points are in the world frame of the registered poses: place their tracks there.
void Pipeline::place_control_points() {
  for (SceneTrack& t : scene_.tracks) {
    if (!t.control_mm) continue;
    t.at_control = true;
    t.xyz_mm = *t.control_mm;
    if (t.state == TrackState::Rejected && t.issue == TrackIssue::SeenOnce) t.state = TrackState::Pending;
  }
}

bool Pipeline::register_from_control() {
  std::size_t registered = 0;
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    std::vector<Correspondence> corr;
    std::vector<Eigen::Vector3d> xyz;
    for (std::size_t o : scene_.images[i].observations) {
      const ObservationRef& ob = scene_.observations[o];
      const SceneTrack& t = scene_.tracks[ob.track];
      if (!ob.usable || !t.control_mm) continue;
      corr.push_back({*t.control_mm, ob.xy, ob.uv_px});
      xyz.push_back(*t.control_mm);
    }
    if (corr.size() < o_.control_min_points || collinear(xyz, o_.collinear_tolerance)) continue;
    const auto pose = estimate_absolute_pose(scene_.camera_of(i), corr, o_.ransac, o_.control_min_points, o_.collinear_tolerance);
    if (!pose) continue;
    scene_.images[i].registered = true;
    scene_.images[i].cam_from_world = pose->cam_from_world;
    registered_by_[i] = "control_pnp";
    ++registered;
  }
  if (registered >= 2) {
    place_control_points();
    return true;
  }
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    scene_.images[i].registered = false;
    registered_by_[i].clear();
  }
  return false;
}

// The undistorted observations in images a and b of every track both see usably (and that is not
// rejected), in b's order: the correspondences of a relative pose.
void Pipeline::shared_points(std::size_t a, std::size_t b, std::vector<Eigen::Vector2d>& xa,
                             std::vector<Eigen::Vector2d>& xb) const {
  std::map<std::size_t, std::size_t> in_a;  // track -> its observation in a
  for (std::size_t o : scene_.images[a].observations) {
    if (scene_.observations[o].usable) in_a[scene_.observations[o].track] = o;
  }
  for (std::size_t o : scene_.images[b].observations) {
    const ObservationRef& ob = scene_.observations[o];
    const auto it = in_a.find(ob.track);
    if (!ob.usable || it == in_a.end() || scene_.tracks[ob.track].state == TrackState::Rejected) continue;
    xa.push_back(scene_.observations[it->second].xy);
    xb.push_back(ob.xy);
  }
}

void Pipeline::start_incremental() {
  // Shared usable tracks per image pair.
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> shared;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (scene_.tracks[t].state == TrackState::Rejected) continue;
    std::vector<std::size_t> ims;
    for (std::size_t o : scene_.tracks[t].observations) {
      if (scene_.observations[o].usable) ims.push_back(scene_.observations[o].image);
    }
    std::sort(ims.begin(), ims.end());
    for (std::size_t a = 0; a < ims.size(); ++a) {
      for (std::size_t b = a + 1; b < ims.size(); ++b) ++shared[{ims[a], ims[b]}];
    }
  }
  std::vector<std::pair<std::size_t, std::pair<std::size_t, std::size_t>>> candidates;
  std::size_t most = 0;
  for (const auto& [pair, n] : shared) {
    most = std::max(most, n);
    if (n >= o_.min_shared_tracks) candidates.push_back({n, pair});
  }
  if (candidates.empty()) {
    throw GeometryError("no two images share " + std::to_string(o_.min_shared_tracks) +
                        " or more tracks (the most any pair shares is " + std::to_string(most) +
                        "), so no relative pose can be found; photos must overlap");
  }
  std::stable_sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (candidates.size() > o_.initial_pair_candidates) candidates.resize(o_.initial_pair_candidates);

  const double focal = mean_focal_px(scene_);
  // Each candidate pair, evaluated independently (in parallel): its relative pose, how many of
  // its tracks triangulate with enough angle, and their median angle.
  struct PairResult {
    bool no_baseline = false;     // a rotation alone explains it, or its median angle is too small
    double median_angle = 0;
    std::size_t good = 0;
    PoseBlock pose{};
  };
  std::vector<PairResult> results(candidates.size());
  geometry::parallel_blocks(candidates.size(), o_.threads, 64, [&](std::size_t begin, std::size_t end, int) {
    for (std::size_t c = begin; c < end; ++c) {
      const auto [a, b] = candidates[c].second;
      PairResult& res = results[c];
      std::vector<Eigen::Vector2d> xa, xb;
      shared_points(a, b, xa, xb);
      if (rotation_only_median_residual(xa, xb) * focal < o_.ransac.threshold_px) {
        res.no_baseline = true;
        continue;
      }
      const auto rel = estimate_relative_pose(xa, xb, focal, o_.ransac);
      if (!rel) continue;
      const PoseBlock identity{};
      const PoseBlock* poses[2] = {&identity, &rel->second_from_first};
      std::vector<PointView> views(2);
      for (int v = 0; v < 2; ++v) {
        PointView& pv = views[static_cast<std::size_t>(v)];
        pv.cam_from_world = poses[v];
        pv.R = rotation_of(*poses[v]);
        pv.t = translation_of(*poses[v]);
        pv.centre_mm = centre_of(*poses[v]);
      }
      std::vector<double> angles;
      for (std::size_t k : rel->inliers) {
        views[0].xy = xa[k];
        views[1].xy = xb[k];
        const auto X = triangulate_linear(views);
        if (!X) continue;
        if (!((views[0].R * *X + views[0].t).z() > 0) || !((views[1].R * *X + views[1].t).z() > 0)) continue;
        const double angle = max_intersection_angle_deg(views, *X);
        angles.push_back(angle);
        if (angle >= o_.triangulation.min_angle_deg) ++res.good;
      }
      if (angles.empty()) continue;
      std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(angles.size() / 2), angles.end());
      res.median_angle = angles[angles.size() / 2];
      res.no_baseline = res.median_angle < o_.initial_min_angle_deg;
      res.pose = rel->second_from_first;
    }
  });
  // The best pair: the most well-triangulated tracks, with enough median angle.
  struct Best {
    std::size_t a = 0, b = 0, good = 0;
    PoseBlock pose{};
    double median_angle = 0;
  } best;
  double best_small_angle = 0;  // the largest median angle seen among pairs that failed on it
  std::size_t no_baseline = 0;
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const PairResult& res = results[c];
    if (res.no_baseline) {
      ++no_baseline;
      best_small_angle = std::max(best_small_angle, res.median_angle);
      continue;
    }
    if (res.good >= o_.min_shared_tracks && res.good > best.good) {
      best = {candidates[c].second.first, candidates[c].second.second, res.good, res.pose, res.median_angle};
    }
  }
  if (best.good == 0) {
    if (no_baseline * 2 >= candidates.size()) {
      throw GeometryError("no baseline: in " + std::to_string(no_baseline) + " of the " +
                          std::to_string(candidates.size()) +
                          " image pairs tried a rotation alone explains the image points, or their rays meet at a "
                          "median angle below " + fmt(o_.initial_min_angle_deg) + " deg (largest seen " +
                          fmt(best_small_angle) + " deg); the photos seem taken from one place: move the camera "
                          "between photos");
    }
    throw GeometryError("no image pair gives a consistent relative pose (essential matrix) with " +
                        std::to_string(o_.min_shared_tracks) + " or more well-triangulated tracks");
  }
  scene_.images[best.a].registered = true;
  scene_.images[best.a].cam_from_world = PoseBlock{};
  scene_.images[best.b].registered = true;
  scene_.images[best.b].cam_from_world = best.pose;
  registered_by_[best.a] = registered_by_[best.b] = "initial_pair";
  report_.reference_image = scene_.images[best.a].name;
  // Gauge of the model frame: the first image fixed, and the largest translation coordinate of
  // the second (|t| = 1 now), as COLMAP does.
  int k = 0;
  for (int c = 1; c < 3; ++c) {
    if (std::abs(best.pose[static_cast<std::size_t>(3 + c)]) > std::abs(best.pose[static_cast<std::size_t>(3 + k)])) k = c;
  }
  setup_.fixed_image = best.a;
  setup_.fixed_translation = std::make_pair(best.b, k);
  log::debug("initial pair: " + scene_.images[best.a].name + " + " + scene_.images[best.b].name + ", " +
             std::to_string(best.good) + " tracks, median angle " + fmt(best.median_angle) + " deg");
  triangulate_tracks(scene_, o_.triangulation, o_.threads);
  intermediate_adjustment();
}

void Pipeline::grow() {
  std::set<std::size_t> failed;
  std::size_t next_ba = static_cast<std::size_t>(std::ceil(static_cast<double>(scene_.registered_count()) * o_.global_ba_growth));
  while (true) {
    std::size_t best = scene_.images.size(), best_count = 0;
    for (std::size_t i = 0; i < scene_.images.size(); ++i) {
      if (scene_.images[i].registered || failed.count(i)) continue;
      std::size_t count = 0;
      for (std::size_t o : scene_.images[i].observations) {
        const ObservationRef& ob = scene_.observations[o];
        if (ob.usable && placed(scene_.tracks[ob.track])) ++count;
      }
      if (count > best_count) {
        best = i;
        best_count = count;
      }
    }
    if (best == scene_.images.size() || best_count < o_.pnp_min_inliers) {
      // No image for PnP: one linked to the model by its matches but seeing too few of its points.
      if (!register_by_relative_pose(failed)) break;
      failed.clear();
      triangulate_tracks(scene_, o_.triangulation, o_.threads);
      intermediate_adjustment();
      next_ba = static_cast<std::size_t>(std::ceil(static_cast<double>(scene_.registered_count()) * o_.global_ba_growth));
      continue;
    }
    std::vector<Correspondence> corr;
    for (std::size_t o : scene_.images[best].observations) {
      const ObservationRef& ob = scene_.observations[o];
      if (ob.usable && placed(scene_.tracks[ob.track])) corr.push_back({scene_.tracks[ob.track].xyz_mm, ob.xy, ob.uv_px});
    }
    const auto pose = estimate_absolute_pose(scene_.camera_of(best), corr, o_.ransac, o_.pnp_min_inliers, o_.collinear_tolerance);
    if (!pose) {
      failed.insert(best);
      continue;
    }
    failed.clear();
    scene_.images[best].registered = true;
    scene_.images[best].cam_from_world = pose->cam_from_world;
    registered_by_[best] = "pnp";
    log::debug(scene_.images[best].name + ": registered by PnP, " + std::to_string(pose->inliers.size()) + " of " +
               std::to_string(corr.size()) + " points");
    triangulate_tracks(scene_, o_.triangulation, o_.threads);
    if (scene_.registered_count() >= next_ba) {
      intermediate_adjustment();
      next_ba = static_cast<std::size_t>(std::ceil(static_cast<double>(scene_.registered_count()) * o_.global_ba_growth));
    }
  }
  if (scene_.registered_count() != last_ba_registered_) intermediate_adjustment();
}

// Registration of an image u from its relative pose to a registered image r, for an image that
// sees too few triangulated points for PnP but shares many tracks with r (a ring of photos whose
// tracks mostly span two of them). The essential matrix of their shared tracks gives u's
// rotation and the direction of its baseline from r (5 of the 6 unknowns, from many points):
//   x_u ~ R_rel (R_r X + t_r) + s t_rel,   |t_rel| = 1,
// and every triangulated point X that u sees gives the length s: with a = R_rel (R_r X + t_r),
// b = t_rel and the bearing x = (x_u, 1), x x (a + s b) = 0 in least squares,
//   s = -((x x a) . (x x b)) / |x x b|^2.
// The median over the points is kept if relative_min_scale_points of them reproject within the
// RANSAC threshold. Pairs are tried from the most shared tracks down.
bool Pipeline::register_by_relative_pose(const std::set<std::size_t>& skip) {
  if (o_.relative_min_scale_points == 0) return false;
  const double focal = mean_focal_px(scene_);
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> shared;  // (unregistered, registered)
  for (const SceneTrack& t : scene_.tracks) {
    if (t.state == TrackState::Rejected) continue;
    std::vector<std::size_t> in, out;
    for (std::size_t o : t.observations) {
      const ObservationRef& ob = scene_.observations[o];
      if (!ob.usable) continue;
      (scene_.images[ob.image].registered ? in : out).push_back(ob.image);
    }
    for (std::size_t u : out) {
      for (std::size_t r : in) ++shared[{u, r}];
    }
  }
  std::vector<std::pair<std::size_t, std::pair<std::size_t, std::size_t>>> candidates;
  for (const auto& [pair, n] : shared) {
    if (n >= o_.min_shared_tracks && !skip.count(pair.first) && !relative_tried_.count(pair.first)) {
      candidates.push_back({n, pair});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  for (const auto& [n, pair] : candidates) {
    const auto [u, r] = pair;
    std::vector<Eigen::Vector2d> xr, xu;
    shared_points(r, u, xr, xu);
    if (rotation_only_median_residual(xr, xu) * focal < o_.ransac.threshold_px) continue;
    const auto rel = estimate_relative_pose(xr, xu, focal, o_.ransac);
    if (!rel || rel->inliers.size() < o_.min_shared_tracks) continue;
    const Eigen::Matrix3d R_rel = rotation_of(rel->second_from_first);
    const Eigen::Vector3d b = translation_of(rel->second_from_first);
    const PoseBlock& pose_r = scene_.images[r].cam_from_world;
    std::vector<double> scales;
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector2d>> points;  // (X, uv_px) seen in u
    for (std::size_t o : scene_.images[u].observations) {
      const ObservationRef& ob = scene_.observations[o];
      if (!ob.usable || !placed(scene_.tracks[ob.track])) continue;
      const Eigen::Vector3d& X = scene_.tracks[ob.track].xyz_mm;
      const Eigen::Vector3d a = R_rel * (rotation_of(pose_r) * X + translation_of(pose_r));
      const Eigen::Vector3d x(ob.xy.x(), ob.xy.y(), 1);
      const Eigen::Vector3d xb = x.cross(b);
      if (!(xb.squaredNorm() > 1e-12)) continue;
      scales.push_back(-x.cross(a).dot(xb) / xb.squaredNorm());
      points.push_back({X, ob.uv_px});
    }
    if (scales.size() < o_.relative_min_scale_points) continue;
    std::vector<double> sorted = scales;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double s = sorted[sorted.size() / 2];
    if (!(s > 0)) continue;
    const Eigen::Matrix3d R_u = R_rel * rotation_of(pose_r);
    const PoseBlock pose_u = make_pose(R_u, R_rel * translation_of(pose_r) + s * b);
    std::size_t agree = 0;
    for (const auto& [X, uv] : points) {
      double proj[2];
      if (project(shape_of(scene_.camera_of(u)), scene_.camera_of(u).params.data(), pose_u.data(), X.data(), proj) &&
          (Eigen::Vector2d(proj[0], proj[1]) - uv).norm() <= o_.ransac.threshold_px) {
        ++agree;
      }
    }
    if (agree < o_.relative_min_scale_points) continue;
    scene_.images[u].registered = true;
    scene_.images[u].cam_from_world = pose_u;
    registered_by_[u] = "relative_pose";
    relative_tried_.insert(u);  // should the adjustment drop it again, it is not tried twice
    log::debug(scene_.images[u].name + ": registered from its relative pose to " + scene_.images[r].name + " (" +
               std::to_string(rel->inliers.size()) + " of " + std::to_string(xr.size()) + " shared tracks), baseline " +
               "length from " + std::to_string(agree) + " of " + std::to_string(points.size()) + " points");
    return true;
  }
  return false;
}

BundleSummary Pipeline::adjust(const BundleSetup& setup, std::optional<double> function_tolerance) {
  // The work limit: each adjustment may take what is left of --max-total-iterations.
  const long long left = o_.max_total_iterations - iterations_used_;
  const auto over = [&] {
    return GeometryError("the bundle adjustments need more than " + std::to_string(o_.max_total_iterations) +
                         " Ceres iterations in all, the work limit --max-total-iterations: raise it for a job this large");
  };
  if (left <= 0) throw over();
  BundleOptions bundle = o_.bundle;
  if (function_tolerance) bundle.function_tolerance = std::max(bundle.function_tolerance, *function_tolerance);
  bundle.max_iterations = static_cast<int>(std::min<long long>(bundle.max_iterations, left));
  last_ = bundle_adjust(scene_, setup, bundle);
  iterations_used_ += std::max(last_.iterations, 1);
  // Cut short by the limit (not by --max-iterations): the result would be less converged than asked.
  if (bundle.max_iterations < o_.bundle.max_iterations && last_.iterations >= bundle.max_iterations) throw over();
  ++report_.adjustments;
  report_.adjustment_seconds += last_.seconds;
  report_.solver = last_.solver;
  report_.threads = last_.threads;
  log::debug("bundle adjustment: " + std::to_string(last_.images) + " images, " + std::to_string(last_.points) +
             " points, " + std::to_string(last_.iterations) + " iterations, " + fmt(last_.seconds) + " s (" +
             last_.timing + "), " + last_.message);
  return last_;
}

void Pipeline::intermediate_adjustment() {
  BundleSetup s = setup_;
  s.observation_sigma_px.fill(o_.observation_sigma_px.value_or(1.0));
  s.scale_bars.clear();
  adjust(s, o_.intermediate_function_tolerance);
  last_ba_registered_ = scene_.registered_count();
  // Gross outliers only; the final adjustment removes the rest.
  for (std::size_t o = 0; o < scene_.observations.size(); ++o) {
    ObservationRef& ob = scene_.observations[o];
    if (!ob.usable || !ob.inlier || !scene_.images[ob.image].registered) continue;
    if (!placed(scene_.tracks[ob.track])) continue;
    const double e = reprojection_error_px(scene_, o);
    if (e > o_.outliers.max_px) {
      ob.inlier = false;
      ob.removed_round = -1;
      ob.removed_residual_px = e;
    }
  }
  prune();
  triangulate_tracks(scene_, o_.triangulation, o_.threads);
}

// Umeyama (1991), "Least-squares estimation of transformation parameters between two point
// patterns": the similarity X_world = s R X_model + T minimising sum |X_world - (s R X_model + T)|^2
// over the control points reconstructed in the model frame (Eigen::umeyama).
bool Pipeline::align_to_control() {
  std::vector<std::size_t> ids;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (scene_.tracks[t].control_mm && scene_.tracks[t].state == TrackState::Triangulated) ids.push_back(t);
  }
  std::vector<Eigen::Vector3d> world;
  for (std::size_t t : ids) world.push_back(*scene_.tracks[t].control_mm);
  if (ids.size() < 3 || collinear(world, o_.collinear_tolerance)) {
    report_.warnings.push_back("control points ignored: fewer than 3 of them (not on a line) were reconstructed");
    return false;
  }
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(ids.size())), dst(3, static_cast<Eigen::Index>(ids.size()));
  for (std::size_t k = 0; k < ids.size(); ++k) {
    src.col(static_cast<Eigen::Index>(k)) = scene_.tracks[ids[k]].xyz_mm;
    dst.col(static_cast<Eigen::Index>(k)) = world[k];
  }
  const Eigen::Matrix4d M = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3d sR = M.topLeftCorner<3, 3>();
  const double s = std::cbrt(sR.determinant());
  const Eigen::Matrix3d R = sR / s;
  const Eigen::Vector3d T = M.topRightCorner<3, 1>();
  // x_cam = Rc X + tc with X = R^T (X' - T) / s; scaling the camera frame by s keeps the image:
  // Rc' = Rc R^T, tc' = s tc - Rc' T.
  for (SceneImage& im : scene_.images) {
    if (!im.registered) continue;
    const Eigen::Matrix3d Rc = rotation_of(im.cam_from_world) * R.transpose();
    im.cam_from_world = make_pose(Rc, s * translation_of(im.cam_from_world) - Rc * T);
  }
  for (SceneTrack& t : scene_.tracks) t.xyz_mm = s * R * t.xyz_mm + T;
  double sum = 0;
  for (std::size_t t : ids) sum += (scene_.tracks[t].xyz_mm - *scene_.tracks[t].control_mm).squaredNorm();
  log::debug("aligned to " + std::to_string(ids.size()) + " control points, RMS " +
             fmt(std::sqrt(sum / static_cast<double>(ids.size()))) + " mm");
  place_control_points();
  setup_.fixed_image.reset();
  setup_.fixed_translation.reset();
  return true;
}

void Pipeline::build_scale_constraints() {
  for (const ScaleBar& b : input_.scale_bars) {
    ScaleBarReport r{b.point_a, b.point_b, "file", b.distance_mm, b.sigma_mm.value_or(o_.scale.default_bar_sigma_mm)};
    const auto a = scene_.find_track(b.point_a), c = scene_.find_track(b.point_b);
    if (a && c) {
      bars_.push_back({*a, *c, b.distance_mm, r.sigma_mm});
      bar_report_.push_back(report_.scale_bars.size());
    }
    report_.scale_bars.push_back(r);
  }
  if (!o_.scale.marker_side_mm) return;
  const double side = *o_.scale.marker_side_mm;
  std::set<std::int64_t> markers;
  for (const SceneTrack& t : scene_.tracks) {
    const std::int64_t m = t.id / 4;
    for (const auto& [lo, hi] : o_.scale.marker_ids) {
      if (m >= lo && m <= hi) markers.insert(m);
    }
  }
  struct Side {
    std::size_t a, b;
    PointId ida, idb;
  };
  std::vector<Side> sides;
  for (std::int64_t m : markers) {
    for (int c = 0; c < 4; ++c) {
      const PointId ida = m * 4 + c, idb = m * 4 + (c + 1) % 4;
      const auto a = scene_.find_track(ida), b = scene_.find_track(idb);
      if (a && b && placed(scene_.tracks[*a]) && placed(scene_.tracks[*b])) sides.push_back({*a, *b, ida, idb});
    }
  }
  if (sides.empty()) {
    report_.warnings.push_back("--marker-side-mm given but no two adjacent marker corners were reconstructed");
    return;
  }
  // Consistency: measured lengths relative to their median (the model's scale is arbitrary here).
  std::vector<double> lengths;
  for (const Side& s : sides) lengths.push_back((scene_.tracks[s.a].xyz_mm - scene_.tracks[s.b].xyz_mm).norm());
  std::vector<double> sorted = lengths;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  std::size_t excluded = 0;
  for (std::size_t k = 0; k < sides.size(); ++k) {
    ScaleBarReport r{sides[k].ida, sides[k].idb, "marker_side", side, o_.scale.marker_side_sigma_mm};
    if (std::abs(lengths[k] / median - 1) <= o_.scale.marker_side_tolerance) {
      bars_.push_back({sides[k].a, sides[k].b, side, o_.scale.marker_side_sigma_mm});
      bar_report_.push_back(report_.scale_bars.size());
    } else {
      ++excluded;
    }
    report_.scale_bars.push_back(r);
  }
  if (excluded > 0) {
    report_.warnings.push_back(std::to_string(excluded) + " marker sides differ from the median side by more than " +
                               fmt(100 * o_.scale.marker_side_tolerance) +
                               " % and are not used as scale bars (markers of another size?)");
  }
}

void Pipeline::choose_datum() {
  build_scale_constraints();
  bool control = false;
  for (const SceneTrack& t : scene_.tracks) control = control || t.at_control;
  bool from_file = false, from_marker = false;
  for (std::size_t k = 0; k < bars_.size(); ++k) {
    const ScaleConstraint& b = bars_[k];
    if (!placed(scene_.tracks[b.track_a]) || !placed(scene_.tracks[b.track_b])) continue;
    (report_.scale_bars[bar_report_[k]].origin == "file" ? from_file : from_marker) = true;
  }
  if (!setup_.known_poses.empty()) {
    // The poses give the frame and the scale; control points and scale bars add to them.
    report_.datum = control ? "known_poses+control_points" : "known_poses";
    report_.reference_image.reset();
  } else if (control) {
    report_.datum = "control_points";
    report_.reference_image.reset();
  } else if (from_file || from_marker) {
    report_.datum = from_file && from_marker ? "scale_bars+marker_side" : from_file ? "scale_bars" : "marker_side";
    // Start the adjustment at about the right scale (the constraints inside it do the rest).
    std::vector<double> ratios;
    for (const ScaleConstraint& b : bars_) {
      if (!placed(scene_.tracks[b.track_a]) || !placed(scene_.tracks[b.track_b])) continue;
      const double d = (scene_.tracks[b.track_a].xyz_mm - scene_.tracks[b.track_b].xyz_mm).norm();
      if (d > 0) ratios.push_back(b.distance_mm / d);
    }
    std::nth_element(ratios.begin(), ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2), ratios.end());
    const double s = ratios[ratios.size() / 2];
    for (SceneImage& im : scene_.images) {
      for (int k = 3; k < 6; ++k) im.cam_from_world[static_cast<std::size_t>(k)] *= s;
    }
    for (SceneTrack& t : scene_.tracks) t.xyz_mm *= s;
    setup_.fixed_translation.reset();  // the scale bars fix the scale
  } else if (o_.scale.allow_arbitrary_scale) {
    report_.datum = "arbitrary_scale";
    report_.warnings.push_back("no control points or scale bars: the scale is arbitrary (first baseline = 1), not mm");
  } else {
    throw GeometryError("none of the given control points or scale bars could be reconstructed, so the scale is "
                        "unknown; check their ids against the tracks, or allow an arbitrary scale with --arbitrary-scale");
  }
  setup_.scale_bars = bars_;
}

std::vector<double> Pipeline::active_errors(std::vector<std::size_t>* which) const {
  std::vector<double> errors;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    const auto act = scene_.active_observations(t);
    if (!in_adjustment(scene_, t, act.size())) continue;
    for (std::size_t o : act) {
      errors.push_back(reprojection_error_px(scene_, o));
      if (which) which->push_back(o);
    }
  }
  return errors;
}

// Robust per-axis noise estimate of each observation class: for 2D Gaussian residuals of sigma
// per axis, |r| is Rayleigh distributed with median sigma sqrt(2 ln 2); corrected for the degrees
// of freedom the adjustment absorbed:
//   sigma_hat = median|r| / sqrt(2 ln 2) * sqrt(m / (m - n)),
// m = 2 x observations, n = 6 x images + 3 x points (over all classes), with each |r| divided by
// its observation's relative sigma first (feature size). A class without observations keeps
// sigma 1.
Pipeline::Sigmas Pipeline::robust_sigma_px() const {
  std::vector<std::size_t> which;
  const std::vector<double> e = active_errors(&which);
  std::array<std::vector<double>, kObservationClasses> by_class;
  for (std::size_t k = 0; k < e.size(); ++k) {
    const ObservationRef& ob = scene_.observations[which[k]];
    by_class[static_cast<std::size_t>(ob.cls)].push_back(e[k] / ob.rel_sigma);
  }
  std::size_t points = 0;
  for (const SceneTrack& t : scene_.tracks) points += t.state == TrackState::Triangulated ? 1 : 0;
  const double m = 2.0 * static_cast<double>(e.size());
  const double n = 6.0 * static_cast<double>(scene_.registered_count()) + 3.0 * static_cast<double>(points);
  const double dof = m > n ? std::sqrt(m / (m - n)) : 1.0;
  Sigmas sigma;
  for (std::size_t c = 0; c < kObservationClasses; ++c) {
    auto& v = by_class[c];
    if (v.empty()) {
      sigma[c] = 1;
      continue;
    }
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    sigma[c] = std::max(v[v.size() / 2] / std::sqrt(2 * std::numbers::ln2) * dof, 1e-9);
  }
  return sigma;
}

// Tracks left with too few inlier observations leave the adjustment; images left with too few
// observations lose their pose.
void Pipeline::prune() {
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    SceneTrack& track = scene_.tracks[t];
    if (track.state != TrackState::Triangulated || track.at_control) continue;
    if (scene_.active_observations(t).size() < 2) {
      track.state = TrackState::Pending;
      track.issue = TrackIssue::TooFewInliers;
    }
  }
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    SceneImage& im = scene_.images[i];
    if (!im.registered) continue;
    std::size_t n = 0;
    for (std::size_t o : im.observations) {
      const ObservationRef& ob = scene_.observations[o];
      n += ob.usable && ob.inlier && placed(scene_.tracks[ob.track]) ? 1 : 0;
    }
    if (n < o_.outliers.min_image_observations && setup_.fixed_image != i) {
      im.registered = false;
      registered_by_[i].clear();
      report_.warnings.push_back(im.name + ": pose dropped, only " + std::to_string(n) + " inlier observations left");
    }
  }
}

void Pipeline::final_adjustment() {
  const bool estimate = !o_.observation_sigma_px.has_value();
  Sigmas sigma{};
  if (estimate) {
    sigma = robust_sigma_px();
  } else {
    sigma.fill(*o_.observation_sigma_px);
  }
  {
    const auto e = active_errors(nullptr);
    double sum = 0;
    for (double v : e) sum += v * v;
    report_.initial_rms_px = e.empty() ? 0 : std::sqrt(sum / static_cast<double>(e.size()));
  }
  // The adjustments of the outlier rounds stop at the intermediate tolerance (their residuals
  // only sort inliers from outliers); the last adjustment, with the outliers out, runs to
  // --function-tolerance.
  for (int round = 1;; ++round) {
    setup_.observation_sigma_px = sigma;
    const bool last = round > o_.outliers.rounds;
    adjust(setup_, last ? std::nullopt : std::optional<double>(o_.intermediate_function_tolerance));
    if (last) break;
    const Sigmas sigma_hat = robust_sigma_px();
    Sigmas threshold{};
    bool sigma_changed = false;
    for (std::size_t c = 0; c < kObservationClasses; ++c) {
      threshold[c] = std::clamp(o_.outliers.sigmas * sigma_hat[c], o_.outliers.min_px, o_.outliers.max_px);
      sigma_changed = sigma_changed || (estimate && std::abs(sigma_hat[c] / sigma[c] - 1) > 0.05);
    }
    std::vector<std::size_t> which;
    const std::vector<double> errors = active_errors(&which);
    std::size_t removed = 0;
    for (std::size_t k = 0; k < errors.size(); ++k) {
      ObservationRef& ob = scene_.observations[which[k]];
      if (errors[k] <= threshold[static_cast<std::size_t>(ob.cls)] * ob.rel_sigma) continue;
      ob.inlier = false;
      ob.removed_round = round;
      ob.removed_residual_px = errors[k];
      ++removed;
    }
    prune();
    if (estimate) sigma = sigma_hat;
    log::debug("outlier round " + std::to_string(round) + ": thresholds " + fmt(threshold[0]) + " / " +
               fmt(threshold[1]) + " px (coded / natural), removed " + std::to_string(removed) + ", sigma " +
               fmt(sigma[0]) + " / " + fmt(sigma[1]) + " px");
    if (removed == 0 && !sigma_changed) {
      adjust(setup_);  // the same observations and sigmas, to the final tolerance
      break;
    }
  }
  report_.observation_sigma_estimated = estimate;
  report_.final_iterations = last_.iterations;
  report_.total_iterations = static_cast<int>(iterations_used_);
}

// Two-view points against their neighbours seen in three or more views (two_view.hpp), after
// the final adjustment: each removed one leaves the result (in_result 0), is counted in
// tracks_dropped and listed in the report, and one warning gives the count and the options.
// The adjustment is not run again: a wrong two-view match reprojects well (that is why it needs
// this check), so it pulled no camera.
void Pipeline::check_two_view(Reconstruction& r, const std::vector<std::size_t>& views) {
  TwoViewReport& tr = report_.two_view;
  const TwoViewOptions& o = o_.two_view;
  tr.enabled = o.enabled;
  tr.neighbours = o.neighbours;
  tr.reach = o.reach;
  tr.sigmas = o.sigmas;
  // Without a scale a length in mm means nothing: the tolerance is not applied (0) and the
  // sigma test alone judges; the report's tolerance_mm says 0 and the warning says why.
  const bool arbitrary = report_.datum == "arbitrary_scale";
  tr.tolerance_mm = arbitrary ? 0.0 : o.tolerance_mm;
  std::vector<CheckedPoint> pts(scene_.tracks.size());
  // Scale-bar ends took part as bars: judged as control points are (references, never removed).
  std::vector<char> bar_end(scene_.tracks.size(), 0);
  for (const ScaleConstraint& b : bars_) bar_end[b.track_a] = bar_end[b.track_b] = 1;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;  // views 0: neither checked nor a reference
    pts[t].xyz_mm = scene_.tracks[t].xyz_mm;
    pts[t].views = views[t];
    pts[t].control = scene_.tracks[t].at_control || bar_end[t];
    if (r.covariance_mm2[t].allFinite()) pts[t].covariance_mm2 = r.covariance_mm2[t];
  }
  TwoViewOptions opts = o;
  opts.threads = o_.threads;
  opts.tolerance_mm = tr.tolerance_mm;
  const TwoViewCheck c = check_two_view_points(pts, opts);
  tr.ran = c.ran;
  tr.reference_points = c.reference_points;
  tr.spacing_mm = c.spacing_mm;
  tr.checked = c.checked;
  tr.removed_unsupported = c.unsupported;
  tr.removed_off_neighbours = c.off_neighbours;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    const TwoViewVerdict v = c.verdict[t];
    if (v != TwoViewVerdict::Unsupported && v != TwoViewVerdict::OffNeighbours) continue;
    r.in_result[t] = 0;
    const std::string reason = v == TwoViewVerdict::Unsupported ? "unsupported" : "off_neighbours";
    ++report_.tracks_dropped["two_view_" + reason];
    const Eigen::Vector3d& x = scene_.tracks[t].xyz_mm;
    tr.removed.push_back({scene_.tracks[t].id, {x.x(), x.y(), x.z()}, reason, c.distance_mm[t], c.allowed_mm[t]});
  }
  if (!tr.removed.empty()) {
    // Without a scale the lengths are in the model's unit (the first baseline = 1).
    report_.warnings.push_back(
        std::to_string(tr.removed.size()) + " of " + std::to_string(c.checked) + " two-view points removed (" +
        std::to_string(c.unsupported) + " with no point seen in three views within " + fmt(o.reach * c.spacing_mm) +
        (arbitrary ? " units of the arbitrary scale" : " mm") + " (--two-view-reach), " +
        std::to_string(c.off_neighbours) + " off their neighbours' surface by more than --two-view-sigmas " +
        fmt(o.sigmas) + " sigma" +
        (arbitrary ? " (--two-view-tolerance-mm not applied: the scale is arbitrary)"
                   : " and --two-view-tolerance-mm " + fmt(o.tolerance_mm)) +
        "); --no-two-view-check keeps them");
  }
}

void Pipeline::finish(Reconstruction& r) {
  Report& rep = report_;
  r.in_result.assign(scene_.tracks.size(), 0);
  std::vector<std::size_t> views(scene_.tracks.size(), 0);
  std::size_t unknown_points = 0;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    const std::size_t act = scene_.active_observations(t).size();
    if (!in_adjustment(scene_, t, act)) {
      const SceneTrack& track = scene_.tracks[t];
      const TrackIssue issue = track.issue == TrackIssue::None ? TrackIssue::NotRegistered : track.issue;
      ++rep.tracks_dropped[to_string(issue)];
      continue;
    }
    r.in_result[t] = 1;
    views[t] = act;
    unknown_points += scene_.tracks[t].at_control ? 0 : 1;
  }
  if (unknown_points == 0) {
    std::size_t worst = 0;
    std::string reason = "none";
    for (const auto& [why, k] : rep.tracks_dropped) {
      if (k > worst) {
        worst = k;
        reason = why;
      }
    }
    std::string hint;
    if (reason == "small_angle") hint = " (no baseline: the photos seem taken from one place; move the camera between photos)";
    throw GeometryError("no track could be triangulated; most failed with '" + reason + "'" + hint);
  }
  // The points' uncertainty (from the final adjustment, which every point above took part in),
  // then the two-view check that uses it.
  CovarianceOptions co = o_.covariance;
  co.threads = o_.threads;
  const PointUncertainty u = point_uncertainty(scene_, setup_, o_.bundle, co);
  r.sigma_mm = u.sigma_mm;
  r.covariance_mm2 = u.covariance_mm2;
  // A point whose covariance is not finite is not determined by the adjustment (its rays are
  // parallel to rounding: two views left once an outlier is gone, at a vanishing angle). Its
  // position is meaningless, so it leaves the result, counted and named in a warning (issue 23:
  // on the Middlebury temple such a point made the PLY writer fail in some runs).
  std::size_t undetermined = 0;
  TrackId example = 0;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (!r.in_result[t] || scene_.tracks[t].at_control || std::isfinite(r.sigma_mm[t])) continue;
    r.in_result[t] = 0;
    ++rep.tracks_dropped["undetermined"];
    if (undetermined++ == 0) example = scene_.tracks[t].id;
  }
  if (undetermined > 0) {
    report_.warnings.push_back(std::to_string(undetermined) + " point(s) left out (track " + std::to_string(example) +
                               (undetermined > 1 ? " and others" : "") +
                               "): the adjustment does not determine them (their covariance is not finite: the rays "
                               "left after outlier removal are parallel)");
  }
  rep.sigma_method = to_string(u.method);
  rep.variance_factor = u.variance_factor;
  check_two_view(r, views);

  std::vector<double> sq(scene_.images.size(), 0);
  std::vector<std::size_t> n(scene_.images.size(), 0);
  double total = 0;
  std::size_t count = 0;
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    const auto act = scene_.active_observations(t);
    for (std::size_t o : act) {
      const double e = reprojection_error_px(scene_, o);
      const std::size_t i = scene_.observations[o].image;
      sq[i] += e * e;
      ++n[i];
      total += e * e;
      ++count;
    }
  }
  rep.points = static_cast<std::size_t>(std::count(r.in_result.begin(), r.in_result.end(), 1));
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    for (std::size_t o : scene_.active_observations(t)) {
      const ObservationClass c = scene_.observations[o].cls;
      ClassReport& cr = rep.observation_classes[to_string(c)];
      cr.sigma_px = setup_.observation_sigma_px[static_cast<std::size_t>(c)];
      ++cr.observations;
    }
  }
  rep.observations_used = count;
  rep.final_rms_px = count ? std::sqrt(total / static_cast<double>(count)) : 0;
  rep.images = scene_.images.size();
  rep.registered_images = scene_.registered_count();
  rep.tracks = scene_.tracks.size();
  for (const ObservationRef& ob : scene_.observations) {
    if (ob.usable && !ob.inlier) {
      rep.removed.push_back({scene_.tracks[ob.track].id, scene_.images[ob.image].name, ob.removed_residual_px, ob.removed_round});
    }
  }
  for (std::size_t i = 0; i < scene_.images.size(); ++i) {
    ImageReport ir;
    ir.image = scene_.images[i].name;
    ir.registered = scene_.images[i].registered;
    ir.registered_by = registered_by_[i];
    ir.observations = n[i];
    ir.rms_px = n[i] ? std::sqrt(sq[i] / static_cast<double>(n[i])) : 0;
    rep.per_image.push_back(ir);
    if (!ir.registered) rep.warnings.push_back(ir.image + ": no pose (too few observations of reconstructed points)");
  }
  for (std::size_t k = 0; k < bars_.size(); ++k) {
    ScaleBarReport& br = rep.scale_bars[bar_report_[k]];
    const ScaleConstraint& b = bars_[k];
    br.used = r.in_result[b.track_a] && r.in_result[b.track_b];
    if (br.used) br.measured_mm = (scene_.tracks[b.track_a].xyz_mm - scene_.tracks[b.track_b].xyz_mm).norm();
  }
  for (std::size_t t = 0; t < scene_.tracks.size(); ++t) {
    const SceneTrack& track = scene_.tracks[t];
    if (!track.at_control || !r.in_result[t]) continue;
    ControlReport cr;
    cr.point_id = track.id;
    cr.fixed = !track.control_sigma_mm;
    cr.sigma_mm = track.control_sigma_mm.value_or(0);
    cr.residual_mm = (track.xyz_mm - *track.control_mm).norm();
    cr.observations = scene_.active_observations(t).size();
    rep.control_points.push_back(cr);
  }
  rep.loss = to_string(o_.bundle.loss);
  rep.loss_scale_px = o_.bundle.loss_scale_px;
  rep.refine_intrinsics = to_string(o_.bundle.refine_intrinsics);
  if (rep.threads == 0) rep.threads = geometry::thread_count(o_.threads);  // no adjustment ran
  for (std::size_t k = 0; k < scene_.cameras.size(); ++k) {
    r.cameras.push_back(to_camera(scene_.cameras[k], input_.cameras.empty() ? input_.camera : input_.cameras[k].camera));
  }
  r.camera = r.cameras.front();
  if (o_.bundle.refine_intrinsics != IntrinsicsRefinement::None) {
    auto values = [](const Camera& c) {
      std::vector<double> v{c.fx(), c.fy(), c.cx(), c.cy()};
      v.insert(v.end(), c.distortion.begin(), c.distortion.end());
      return v;
    };
    if (r.cameras.size() == 1) rep.refined_camera = values(r.camera);
    for (std::size_t k = 0; k < r.cameras.size() && r.cameras.size() > 1; ++k) {
      rep.refined_cameras.push_back({input_.cameras[k].prefix, values(r.cameras[k])});
    }
  }
}

Reconstruction Pipeline::run() {
  const auto start = Clock::now();
  auto lap = [last = Clock::now()](const std::string& what) mutable {
    const auto now = Clock::now();
    log::debug(what + ": " + fmt(std::chrono::duration<double>(now - last).count()) + " s");
    last = now;
  };
  std::vector<CameraModel> cameras;
  std::vector<std::string> prefixes;
  if (input_.cameras.empty()) {
    cameras.push_back(to_camera_model(input_.camera, input_.camera_source));
  } else {
    for (const PrefixCamera& c : input_.cameras) {
      cameras.push_back(to_camera_model(c.camera, c.source));
      prefixes.push_back(c.prefix);
    }
  }
  if (input_.known_poses.empty() && input_.control_points.empty() && input_.scale_bars.empty() &&
      !o_.scale.marker_side_mm && !o_.scale.allow_arbitrary_scale) {
    throw UsageError("no datum: give control points (--control-points), scale bars (--scale-bars), the marker side "
                     "(--marker-side-mm) or known poses (--known-poses), or accept an arbitrary scale with "
                     "--arbitrary-scale");
  }
  scene_ = build_scene(
      input_.tracks, cameras,
      [&](const std::string& image) -> std::size_t {
        return prefixes.empty() ? 0 : require_rig_prefix(prefixes, image, input_.tracks_source).camera;
      },
      input_.control_points, o_.coded_id_limit, o_.weight_by_feature_size);
  registered_by_.assign(scene_.images.size(), "");
  check_input();
  set_up_rig();

  lap("indexing and undistorting the observations");
  std::optional<log::Step> step;
  step.emplace("orienting " + std::to_string(scene_.images.size()) + " images and triangulating " +
               std::to_string(scene_.tracks.size()) + " tracks");
  if (!input_.known_poses.empty()) {
    register_from_known();
    report_.pose_initialisation = "known_poses";
    log::debug(std::to_string(scene_.registered_count()) + " images registered from known poses");
    triangulate_tracks(scene_, o_.triangulation, o_.threads);
    grow();
    // With a rig: frames placed by their registered photos, their other photos by the rig, and
    // on with PnP from what those add, until nothing changes; then every adjustment holds the
    // frames to the rig.
    if (scene_.rig) {
      while (place_rig_frames() > 0) {
        triangulate_tracks(scene_, o_.triangulation, o_.threads);
        grow();
      }
      setup_.use_rig = true;
      intermediate_adjustment();
    }
  } else if (register_from_control()) {
    report_.pose_initialisation = "control_pnp";
    log::debug(std::to_string(scene_.registered_count()) + " images registered from control points");
    triangulate_tracks(scene_, o_.triangulation, o_.threads);
    grow();
  } else {
    report_.pose_initialisation = "incremental";
    start_incremental();
    lap("initial pair");
    grow();
    bool any_control = false;
    for (const SceneTrack& t : scene_.tracks) any_control = any_control || t.control_mm.has_value();
    if (any_control && align_to_control()) {
      report_.pose_initialisation = "incremental+control_alignment";
      triangulate_tracks(scene_, o_.triangulation, o_.threads);
    }
  }
  lap("poses and points");
  step.reset();
  choose_datum();
  step.emplace("final bundle adjustment of " + std::to_string(scene_.registered_count()) + " images");
  final_adjustment();
  report_rig();
  lap("final adjustment");

  Reconstruction r;
  step.emplace("uncertainty of every point and statistics");
  finish(r);
  step.reset();
  lap("statistics and uncertainty");
  r.setup = setup_;
  r.scene = std::move(scene_);
  report_.total_seconds = std::chrono::duration<double>(Clock::now() - start).count();
  r.report = std::move(report_);
  return r;
}

}  // namespace

Reconstruction reconstruct(const ReconstructInput& input, const ReconstructOptions& options) {
  Pipeline p(input, options);
  return p.run();
}

PointCloud make_point_cloud(const Reconstruction& r) {
  PointCloud cloud;
  std::vector<double> ids, views, rms, sigma, control;
  bool ids_fit_uint32 = true;
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    if (!r.in_result[t]) continue;
    const SceneTrack& track = r.scene.tracks[t];
    const auto act = r.scene.active_observations(t);
    double sum = 0;
    for (std::size_t o : act) {
      const double e = reprojection_error_px(r.scene, o);
      sum += e * e;
    }
    cloud.points_mm.push_back(track.xyz_mm);
    ids.push_back(static_cast<double>(track.id));
    ids_fit_uint32 = ids_fit_uint32 && track.id <= std::numeric_limits<std::uint32_t>::max();
    views.push_back(static_cast<double>(act.size()));
    // Stored as float in the PLY: round here so the value is exactly representable.
    rms.push_back(static_cast<float>(act.empty() ? 0 : std::sqrt(sum / static_cast<double>(act.size()))));
    sigma.push_back(r.sigma_mm[t]);
    control.push_back(track.at_control ? 1 : 0);
  }
  // Track ids beyond 32 bits are written as doubles (exact up to 2^53). The names carry the
  // "scalar_" prefix that makes CloudCompare load them as scalar fields (it shows them without
  // it); photomill's readers find them by either name (PointCloud::find).
  cloud.properties = {{"scalar_track_id", ids_fit_uint32 ? PlyScalar::UInt32 : PlyScalar::Float64, ids},
                      {"scalar_views", PlyScalar::UInt32, views},
                      {"scalar_reproj_rms_px", PlyScalar::Float32, rms},
                      {"scalar_sigma_mm", PlyScalar::Float64, sigma},
                      {"scalar_control", PlyScalar::UInt8, control}};
  // Without any datum the unit is the first baseline, not mm: the PLY header says so.
  if (r.report.datum == "arbitrary_scale") cloud.units = "arbitrary";
  return cloud;
}

std::vector<Pose> registered_poses(const Reconstruction& r) {
  std::vector<Pose> poses;
  for (const SceneImage& im : r.scene.images) {
    if (im.registered) poses.push_back(to_pose(im.name, im.cam_from_world));
  }
  return poses;
}

}  // namespace photomill::triangulate
