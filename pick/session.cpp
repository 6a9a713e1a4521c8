#include "pick/session.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <limits>
#include <set>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/camera.hpp"
#include "formats/error.hpp"
#include "formats/image_decode.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "geometry/parallel.hpp"
#include "match/lsm.hpp"
#include "pick/http.hpp"
#include "triangulate/triangulation.hpp"

namespace photomill::pick {
namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxUndo = 10000;  // states kept for undo (a few MB at most)

const char* status_note(triangulate::TriangulationStatus s) {
  using S = triangulate::TriangulationStatus;
  switch (s) {
    case S::Ok: return "";
    case S::TooFewViews: return "fewer than two oriented views";
    case S::Degenerate: return "the rays are parallel";
    case S::SmallAngle: return "the rays meet at less than 1.5 degrees: the depth is not measured";
    case S::BehindCamera: return "the rays meet behind a camera: the marks are not the same point";
    case S::LargeError: return "the rays do not meet";
  }
  return "";
}

// The centre of the blob under `click` in `g` (CV_32F): the window of half-width h around it is
// split at the mid-grey between its darkest and brightest pixels; the blob is the connected region
// on the click's side of that level that holds the pixel nearest the click, grown by one pixel
// (its anti-aliased rim); its centre is the centroid of those pixels weighted by their contrast
// with the background level, |I - background|, which moves with the sub-pixel position of the rim
// (the grey-value weighted centroid of target measurement, Luhmann et al., "Close-Range
// Photogrammetry and 3D Imaging", 2nd ed., sec. 5.4.2.3). nullopt, with *why, when the window
// holds no blob or the blob touches its border (larger than the window).
std::optional<Eigen::Vector2d> blob_centre(const cv::Mat& g, const Eigen::Vector2d& click, int h, std::string* why) {
  const int cx = static_cast<int>(std::lround(click.x())), cy = static_cast<int>(std::lround(click.y()));
  if (cx - h < 0 || cy - h < 0 || cx + h >= g.cols || cy + h >= g.rows) {
    *why = "too close to the border for blob centring";
    return std::nullopt;
  }
  const cv::Mat w = g(cv::Rect(cx - h, cy - h, 2 * h + 1, 2 * h + 1));
  double lo = 0, hi = 0;
  cv::minMaxLoc(w, &lo, &hi);
  if (hi - lo < 10) {
    *why = "no edge within " + std::to_string(h) + " px of the click: no blob there, or one larger than the window (--blob-half-window-px)";
    return std::nullopt;
  }
  const double level = 0.5 * (lo + hi);
  const bool dark = w.at<float>(h, h) < level;
  cv::Mat side = dark ? (w < level) : (w > level);  // 8-bit mask, 255 on the click's side
  cv::Mat labels;
  cv::connectedComponents(side, labels, 8, CV_32S);
  const int blob = labels.at<int>(h, h);
  cv::Mat mask = labels == blob;
  cv::dilate(mask, mask, cv::Mat());
  const double background = dark ? hi : lo;
  double sum = 0, su = 0, sv = 0;
  for (int r = 0; r < w.rows; ++r) {
    for (int c = 0; c < w.cols; ++c) {
      if (!mask.at<unsigned char>(r, c)) continue;
      if (r == 0 || c == 0 || r == w.rows - 1 || c == w.cols - 1) {
        *why = "the blob is larger than the window (" + std::to_string(2 * h + 1) + " px)";
        return std::nullopt;
      }
      const double weight = std::abs(w.at<float>(r, c) - background);
      sum += weight;
      su += weight * c;
      sv += weight * r;
    }
  }
  return Eigen::Vector2d(cx - h + su / sum, cy - h + sv / sum);
}

}  // namespace

const char* to_string(Refine r) {
  switch (r) {
    case Refine::None: return "none";
    case Refine::Corner: return "corner";
    case Refine::Blob: return "blob";
    case Refine::Match: return "match";
    case Refine::Auto: return "auto";
  }
  return "none";
}

std::optional<Refine> parse_refine(const std::string& name) {
  if (name == "none") return Refine::None;
  if (name == "corner") return Refine::Corner;
  if (name == "blob") return Refine::Blob;
  if (name == "match") return Refine::Match;
  if (name == "auto") return Refine::Auto;
  return std::nullopt;
}

Session::Session(std::vector<std::string> photos, const std::optional<std::string>& camera_path,
                 const std::optional<std::string>& poses_path, std::string observations_path, SessionOptions options)
    : observations_path_(std::move(observations_path)), options_(options) {
  if (photos.empty()) throw UsageError("give at least one photo");
  if (camera_path.has_value() != poses_path.has_value()) {
    throw UsageError("--camera and --poses go together (both orient the photos, or neither)");
  }
  {
    std::set<std::string> seen;
    for (const auto& p : photos) {
      if (p.empty()) throw UsageError("a photo name is empty");
      if (!seen.insert(p).second) throw UsageError("photo " + p + " is given twice");
    }
  }
  photos_.resize(photos.size());
  // Each photo read once: its size and its thumbnail (the page shows these first).
  log::info("reading " + std::to_string(photos.size()) + " photos and making their thumbnails");
  std::vector<std::exception_ptr> errors(photos.size());
  geometry::parallel_for(photos.size(), geometry::thread_count(options_.threads), [&](std::size_t i) {
    try {
      const cv::Mat colour = read_image(photos[i], cv::IMREAD_COLOR);
      Photo& p = photos_[i];
      p.path = photos[i];
      p.width_px = colour.cols;
      p.height_px = colour.rows;
      const double scale = static_cast<double>(options_.thumbnail_px) / std::max(colour.cols, colour.rows);
      cv::Mat small;
      if (scale < 1) {
        cv::resize(colour, small, cv::Size(), scale, scale, cv::INTER_AREA);
      } else {
        small = colour;
      }
      std::vector<unsigned char> jpeg;
      cv::imencode(".jpg", small, jpeg, {cv::IMWRITE_JPEG_QUALITY, 85});
      p.thumbnail_jpeg.assign(jpeg.begin(), jpeg.end());
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }

  if (camera_path) {
    auto in = tool::open_input(*camera_path);
    const Camera camera = read_camera_yaml(*in, tool::source_name(*camera_path));
    validate_camera(camera, tool::source_name(*camera_path));
    camera_ = geometry::to_camera_model(camera, tool::source_name(*camera_path));
    for (const auto& p : photos_) {
      if (p.width_px != camera_->width_px || p.height_px != camera_->height_px) {
        throw InputError(tool::source_name(*camera_path), 0,
                         "the camera is " + std::to_string(camera_->width_px) + " x " + std::to_string(camera_->height_px) +
                             " px but photo " + p.path + " is " + std::to_string(p.width_px) + " x " +
                             std::to_string(p.height_px) + " px");
      }
    }
    auto pin = tool::open_input(*poses_path);
    const std::vector<Pose> poses = read_poses(*pin, tool::source_name(*poses_path));
    // A photo's pose: the one of its name as given, else the only one of its file name (as match
    // and triangulate pair them: poses.csv may name part_00.jpg for ../photos/part_00.jpg).
    std::map<std::string, const Pose*> by_image;
    std::map<std::string, std::vector<const Pose*>> by_file;
    for (const auto& pose : poses) {
      by_image[pose.image] = &pose;
      by_file[fs::path(pose.image).filename().string()].push_back(&pose);
    }
    std::size_t oriented = 0;
    for (auto& p : photos_) {
      const Pose* pose = nullptr;
      if (const auto it = by_image.find(p.path); it != by_image.end()) {
        pose = it->second;
      } else if (const auto f = by_file.find(fs::path(p.path).filename().string()); f != by_file.end() && f->second.size() == 1) {
        pose = f->second.front();
      }
      if (!pose) continue;
      p.oriented = true;
      p.cam_from_world = geometry::make_pose(pose->rotation(), pose->cam_from_world_translation_mm);
      ++oriented;
    }
    if (oriented == 0) {
      throw InputError(tool::source_name(*poses_path), 0,
                       "no pose for any of the photos (the poses' image names must be the photos' names as given, e.g. " +
                           photos_.front().path + ")");
    }
    if (oriented < photos_.size()) {
      log::warn(std::to_string(photos_.size() - oriented) + " of " + std::to_string(photos_.size()) +
                " photos have no pose in " + tool::source_name(*poses_path) + ": they get no epipolar guidance");
    }
  }

  // The file is rewritten after every mark: a folder that cannot take it is said now, not at the
  // first click.
  {
    const fs::path folder = fs::path(observations_path_).parent_path().empty() ? fs::path(".") : fs::path(observations_path_).parent_path();
    std::error_code ec;
    if (!fs::is_directory(folder, ec)) throw InputError(observations_path_, 0, "its folder " + folder.string() + " does not exist");
    if (::access(folder.c_str(), W_OK) != 0) throw InputError(observations_path_, 0, "cannot write in " + folder.string() + ": " + std::strerror(errno));
  }
  if (fs::exists(observations_path_)) {
    auto in = tool::open_input(observations_path_);
    observations_ = read_observations(*in, tool::source_name(observations_path_));
    log::info("loaded " + std::to_string(observations_.size()) + " observations from " + observations_path_);
  }
}

std::optional<std::size_t> Session::photo_index(const std::string& image) const {
  for (std::size_t i = 0; i < photos_.size(); ++i) {
    if (photos_[i].path == image) return i;
  }
  return std::nullopt;
}

const cv::Mat& Session::grey(std::size_t photo) const {
  auto it = grey_.find(photo);
  if (it == grey_.end()) {
    cv::Mat g8 = read_image(photos_.at(photo).path, cv::IMREAD_GRAYSCALE), g;
    g8.convertTo(g, CV_32F);
    it = grey_.emplace(photo, std::move(g)).first;
  }
  return it->second;
}

MarkResult Session::mark(std::size_t photo, PointId point_id, const Eigen::Vector2d& click_px, Refine refine,
                         double zoom_px) {
  if (refine == Refine::Auto) refine = zoom_px < options_.auto_corner_below_zoom ? Refine::Corner : Refine::None;
  const Photo& p = photos_.at(photo);
  if (!(click_px.x() >= -0.5 && click_px.y() >= -0.5 && click_px.x() <= p.width_px - 0.5 &&
        click_px.y() <= p.height_px - 0.5)) {
    throw RequestError("(" + std::to_string(click_px.x()) + ", " + std::to_string(click_px.y()) +
                     ") px is outside photo " + p.path);
  }
  MarkResult r;
  r.refine = refine;
  Eigen::Vector2d at = click_px;
  if (refine == Refine::Corner) {
    const cv::Mat& g = grey(photo);
    const int h = options_.corner_half_window_px;
    if (click_px.x() < h + 1 || click_px.y() < h + 1 || click_px.x() > g.cols - h - 2 || click_px.y() > g.rows - h - 2) {
      r.note = "too close to the border for corner refinement";
    } else {
      std::vector<cv::Point2f> corner{cv::Point2f(static_cast<float>(click_px.x()), static_cast<float>(click_px.y()))};
      cv::cornerSubPix(g, corner, cv::Size(h, h), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
      at = {corner[0].x, corner[0].y};
    }
  } else if (refine == Refine::Blob) {
    std::string why;
    if (const auto c = blob_centre(grey(photo), click_px, options_.blob_half_window_px, &why)) {
      at = *c;
    } else {
      r.note = why;
    }
  } else if (refine == Refine::Match) {
    const Observation* reference = nullptr;
    std::size_t reference_photo = 0;
    for (const auto& o : observations_) {
      if (o.point_id != point_id || o.image == p.path) continue;
      const auto index = photo_index(o.image);
      if (!index) continue;
      reference = &o;
      reference_photo = *index;
      break;
    }
    if (!reference) {
      r.note = "no other photo has this point yet: nothing to match (the click is kept)";
    } else {
      match::LsmOptions lo;
      lo.max_shift_px = options_.max_refine_shift_px;
      // The start: the rotation and scale of the reference window that correlates best at the
      // click (the two photos may be turned by any angle about their axes, and LSM converges only
      // from within some 20 degrees), over 15-degree steps and three scales.
      const cv::Mat& f = grey(reference_photo);
      const cv::Mat& g = grey(photo);
      const Eigen::Vector2d ref(reference->u_px, reference->v_px);
      Eigen::Matrix2d start = Eigen::Matrix2d::Identity();
      double best = -2;
      for (int step = 0; step < 24; ++step) {
        const double a = step * 15.0 * M_PI / 180.0;
        for (const double scale : {0.8, 1.0, 1.25}) {
          Eigen::Matrix2d A;
          A << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
          A *= scale;
          const auto c = match::window_correlation(f, ref, options_.lsm_half_window_px, g, A, click_px, 2);
          if (c && *c > best) {
            best = *c;
            start = A;
          }
        }
      }
      match::LsmFailure why = match::LsmFailure::None;
      const auto m = match::lsm_align(f, ref, options_.lsm_half_window_px, g, start, click_px, lo, &why);
      if (m) {
        at = m->point_px;
      } else {
        r.note = std::string("least-squares matching with ") + reference->image + " refused: " + match::to_string(why);
      }
    }
  }
  r.shift_px = (at - click_px).norm();
  if (refine != Refine::None && r.note.empty()) {
    // (A blob holds the click by construction: its centre is where the user pointed, however far.)
    if (!std::isfinite(at.x()) || !std::isfinite(at.y()) || (refine != Refine::Blob && r.shift_px > options_.max_refine_shift_px)) {
      r.note = "the refined point moved " + std::to_string(r.shift_px) + " px (more than " +
               std::to_string(options_.max_refine_shift_px) + "): the click is kept";
      at = click_px;
      r.shift_px = 0;
    } else {
      r.refined = true;
    }
  }
  history_.push_back(observations_);
  if (history_.size() > kMaxUndo) history_.erase(history_.begin());
  r.observation = {p.path, point_id, at.x(), at.y()};
  const auto it = std::find_if(observations_.begin(), observations_.end(),
                               [&](const Observation& o) { return o.image == p.path && o.point_id == point_id; });
  if (it != observations_.end()) {
    *it = r.observation;
  } else {
    observations_.push_back(r.observation);
  }
  save();
  return r;
}

bool Session::remove(std::size_t photo, PointId point_id) {
  const std::string& image = photos_.at(photo).path;
  const auto it = std::find_if(observations_.begin(), observations_.end(),
                               [&](const Observation& o) { return o.image == image && o.point_id == point_id; });
  if (it == observations_.end()) return false;
  history_.push_back(observations_);
  observations_.erase(observations_.begin() + (it - observations_.begin()));
  save();
  return true;
}

bool Session::undo() {
  if (history_.empty()) return false;
  observations_ = std::move(history_.back());
  history_.pop_back();
  save();
  return true;
}

void Session::save() const {
  saved_ = false;
  tool::OutputFile out(observations_path_);
  write_observations(out.stream(), observations_);
  out.commit();
  tool::publish_committed();
  saved_ = true;
}

PointId Session::next_free_id() const {
  PointId next = options_.first_id;
  for (const auto& o : observations_) {
    if (o.point_id >= options_.first_id) next = std::max(next, o.point_id + 1);
  }
  return next;
}

std::optional<Eigen::Vector3d> Session::triangulate(PointId point_id, std::string* note) const {
  if (!camera_) {
    *note = "the photos are not oriented (no --camera and --poses)";
    return std::nullopt;
  }
  std::vector<triangulate::PointView> views;
  for (const auto& o : observations_) {
    if (o.point_id != point_id) continue;
    const auto index = photo_index(o.image);
    if (!index || !photos_[*index].oriented) continue;
    const auto it = photos_.begin() + static_cast<std::ptrdiff_t>(*index);
    const auto xy = geometry::undistort(*camera_, {o.u_px, o.v_px});
    if (!xy) continue;
    triangulate::PointView v;
    v.cam_from_world = &it->cam_from_world;
    v.R = geometry::rotation_of(it->cam_from_world);
    v.t = geometry::translation_of(it->cam_from_world);
    v.centre_mm = geometry::centre_of(it->cam_from_world);
    v.xy = *xy;
    v.uv_px = {o.u_px, o.v_px};
    views.push_back(v);
  }
  if (views.size() < 2) {
    *note = "fewer than two oriented views";
    return std::nullopt;
  }
  triangulate::TriangulationOptions to;
  to.max_reproj_px = std::numeric_limits<double>::infinity();  // every mark stays: its residual is shown instead
  const auto e = triangulate::triangulate_point(*camera_, views, to);
  if (e.status != triangulate::TriangulationStatus::Ok) {
    *note = status_note(e.status);
    return std::nullopt;
  }
  return e.xyz_mm;
}

std::vector<PointSummary> Session::points() const {
  std::map<PointId, PointSummary> by_id;
  std::set<std::string> names;
  for (const auto& p : photos_) names.insert(p.path);
  for (const auto& o : observations_) {
    if (!names.count(o.image)) continue;
    auto& s = by_id[o.point_id];
    s.point_id = o.point_id;
    s.observations.push_back(o);
  }
  std::vector<PointSummary> out;
  for (auto& [id, s] : by_id) {
    s.xyz = triangulate(id, &s.triangulation_note);
    if (s.xyz) {
      for (const auto& o : s.observations) {
        const auto index = photo_index(o.image);
        if (!index || !photos_[*index].oriented) continue;
        const auto it = photos_.begin() + static_cast<std::ptrdiff_t>(*index);
        const auto uv = geometry::project_point(*camera_, it->cam_from_world.data(), *s.xyz);
        if (uv) s.residuals.push_back({o.image, (*uv - Eigen::Vector2d(o.u_px, o.v_px)).norm()});
      }
    }
    out.push_back(std::move(s));
  }
  return out;
}

Guide Session::guide(PointId point_id, std::size_t target) const {
  Guide g;
  const Photo& t = photos_.at(target);
  if (!camera_ || !t.oriented) return g;
  const double margin = 0.05 * std::max(t.width_px, t.height_px);
  const auto inside = [&](const Eigen::Vector2d& uv) {
    return uv.x() >= -margin && uv.y() >= -margin && uv.x() <= t.width_px + margin && uv.y() <= t.height_px + margin;
  };
  const Eigen::Vector3d target_centre = geometry::centre_of(t.cam_from_world);
  for (const auto& o : observations_) {
    if (o.point_id != point_id || o.image == t.path) continue;
    const auto index = photo_index(o.image);
    if (!index || !photos_[*index].oriented) continue;
    const auto it = photos_.begin() + static_cast<std::ptrdiff_t>(*index);
    const auto xy = geometry::undistort(*camera_, {o.u_px, o.v_px});
    if (!xy) continue;
    // The ray X(s) = C + s d of the observation (d: the unit direction R^T (x, y, 1)), sampled at
    // depths s spread geometrically over [min, max] x the baseline, each sample projected into
    // the target with the full camera model.
    const Eigen::Vector3d centre = geometry::centre_of(it->cam_from_world);
    const Eigen::Vector3d d = (geometry::rotation_of(it->cam_from_world).transpose() * Eigen::Vector3d(xy->x(), xy->y(), 1)).normalized();
    const double baseline = (centre - target_centre).norm();
    if (!(baseline > 0)) continue;
    Guide::Curve curve;
    curve.from_image = o.image;
    std::vector<Eigen::Vector2d> line;
    const int n = std::max(2, options_.epipolar_samples);
    const double ratio = options_.ray_depth_max / options_.ray_depth_min;
    for (int i = 0; i < n; ++i) {
      const double s = baseline * options_.ray_depth_min * std::pow(ratio, static_cast<double>(i) / (n - 1));
      const auto uv = geometry::project_point(*camera_, t.cam_from_world.data(), centre + s * d);
      if (uv && inside(*uv)) {
        line.push_back(*uv);
      } else if (!line.empty()) {
        if (line.size() >= 2) curve.polylines.push_back(std::move(line));
        line.clear();
      }
    }
    if (line.size() >= 2) curve.polylines.push_back(std::move(line));
    if (!curve.polylines.empty()) g.curves.push_back(std::move(curve));
  }
  std::string note;
  if (const auto X = triangulate(point_id, &note)) {
    g.predicted_px = geometry::project_point(*camera_, t.cam_from_world.data(), *X);
  }
  return g;
}

}  // namespace photomill::pick
