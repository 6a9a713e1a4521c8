// pick's job (issue 29): the photos, the camera and poses when the photos are oriented, and the
// observations the user marks, with undo; every change is saved at once (written to a temporary
// name and renamed, formats/tool.hpp), in photomill's observations format, so that the points join
// the markers in match and triangulate. With a camera and poses it also gives, for a point, the
// epipolar curves of its observations in another photo (distortion included: a curve, sampled),
// the position predicted from its triangulation, and each observation's reprojection residual.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "formats/tables.hpp"
#include "geometry/camera_model.hpp"
#include "geometry/rotation.hpp"

namespace photomill::pick {

// How a click becomes an observation.
enum class Refine {
  None,    // the clicked position as it is (at a zoom of z screen pixels per image pixel, within 1/(2z) px)
  Corner,  // the nearest grey-value corner (OpenCV's cornerSubPix: the point where the image
           // gradients in the window are orthogonal to the lines from it), for drawn crosses and
           // the corners of squares
  Blob,    // the grey-value centroid of the dark or bright blob under the click, for drawn dots
           // and round targets
  Match,   // least-squares matching (match's LSM) of the point's neighbourhood in the photo where it
           // was marked first, for natural texture
  Auto     // Corner when the click is coarser than the corner fit (zoom below
           // SessionOptions::auto_corner_below_zoom), None otherwise
};
const char* to_string(Refine r);
std::optional<Refine> parse_refine(const std::string& name);

struct SessionOptions {
  // Corner refinement: window half-width, and the farthest a refined point (corner or match) may
  // move from the click before the click is kept instead (the window held no corner, or another).
  int corner_half_window_px = 5;
  double max_refine_shift_px = 2.0;
  // Refine::Auto: corner refinement below this zoom (screen pixels per image pixel). A click at
  // zoom z is within 1/(2z) px; cornerSubPix on the corner of a dark square (an L-corner, not a
  // saddle) is biased by about 0.2 px (docs/measurements/pick.md): above zoom 4 the click is better.
  double auto_corner_below_zoom = 4;
  // Blob centring: the window a blob must fit in (half-width).
  int blob_half_window_px = 15;
  // Least-squares matching: window half-width (match's LsmOptions do the rest).
  int lsm_half_window_px = 12;
  // Epipolar curves: samples along the ray, spread geometrically over depths from
  // ray_depth_min to ray_depth_max times the distance between the two cameras.
  int epipolar_samples = 2000;
  double ray_depth_min = 0.02;
  double ray_depth_max = 50.0;
  // The id a new point gets when none is marked at or above it: above the ids detect gives marker
  // corners (4 x marker id + corner, under 4 000 for the largest OpenCV dictionary), so that
  // clicked points joined to detect's observations never merge with a marker by accident.
  PointId first_id = 100000;
  // Thumbnails: longest side in pixels.
  int thumbnail_px = 256;
  int threads = 0;  // thumbnails made in parallel; 0 = all cores
};

struct Photo {
  std::string path;     // as given on the command line; also the observations' image name
  int width_px = 0;
  int height_px = 0;
  std::string thumbnail_jpeg;  // made at start
  bool oriented = false;       // a pose exists for it (and a camera was given)
  geometry::PoseBlock cam_from_world{};
};

// What a mark did: where the observation landed, and how the refinement went.
struct MarkResult {
  Observation observation;
  Refine refine = Refine::None;  // the method applied (Auto resolved)
  bool refined = false;      // false: the click was kept (refine None, or refused: see note)
  double shift_px = 0;       // from the click to the refined position
  std::string note;          // why a refinement was refused; empty otherwise
};

// One observation's residual against its point's triangulation (oriented photos only).
struct Residual {
  std::string image;
  double residual_px = 0;
};

struct PointSummary {
  PointId point_id = 0;
  std::vector<Observation> observations;  // in the photos of this job
  std::optional<Eigen::Vector3d> xyz;     // triangulated from >= 2 oriented views (camera units)
  std::string triangulation_note;         // why not, when it could not be
  std::vector<Residual> residuals;
};

// The guidance for marking `point` in `target`: an epipolar curve per observation of it in
// another oriented photo (each a list of polylines: the curve leaves and re-enters the image),
// and the predicted position from its triangulation when it has one.
struct Guide {
  struct Curve {
    std::string from_image;
    std::vector<std::vector<Eigen::Vector2d>> polylines;  // target pixels
  };
  std::vector<Curve> curves;
  std::optional<Eigen::Vector2d> predicted_px;
};

class Session {
public:
  // Reads the photos' sizes and makes their thumbnails; camera and poses are optional (both or
  // neither); observations are loaded from `observations_path` when that file exists (rows for
  // other photos are kept and written back). Throws InputError naming the file for a bad input:
  // a photo that cannot be read, a camera whose size differs from a photo's, a pose for a photo
  // that is not given (a warning) or a photo without a pose (it is shown but not oriented).
  Session(std::vector<std::string> photos, const std::optional<std::string>& camera_path,
          const std::optional<std::string>& poses_path, std::string observations_path, SessionOptions options);

  const std::vector<Photo>& photos() const { return photos_; }
  bool oriented() const { return camera_.has_value(); }
  const std::string& observations_path() const { return observations_path_; }
  const std::vector<Observation>& observations() const { return observations_; }

  // Marks (or moves) `point_id` in photo `photo` at the clicked pixel, refined as asked; saves.
  // `zoom_px`: screen pixels per image pixel where the click was made (for Refine::Auto).
  MarkResult mark(std::size_t photo, PointId point_id, const Eigen::Vector2d& click_px, Refine refine, double zoom_px = 1);
  // Deletes `point_id`'s observation in photo `photo`; false if there was none. Saves.
  bool remove(std::size_t photo, PointId point_id);
  // Undoes the last mark or removal; false if there is nothing to undo. Saves.
  bool undo();
  std::size_t undo_depth() const { return history_.size(); }
  // False after a save failed (a full disk, the folder gone) until one succeeds.
  bool saved() const { return saved_; }
  // Saves again if the last save failed; throws InputError naming the file if it fails again.
  void flush() const {
    if (!saved_) save();
  }

  std::vector<PointSummary> points() const;
  Guide guide(PointId point_id, std::size_t target) const;
  // One more than the largest id in use at or above SessionOptions::first_id (first_id when there
  // is none): a new point never takes the id of one marked before.
  PointId next_free_id() const;

  // The photo's pixels, grey (decoded on first use and kept: refinement needs them).
  const cv::Mat& grey(std::size_t photo) const;

private:
  // The index of the photo whose name (as given) is `image`; nullopt for another photo's row.
  std::optional<std::size_t> photo_index(const std::string& image) const;
  void save() const;
  std::optional<Eigen::Vector3d> triangulate(PointId point_id, std::string* note) const;

  std::vector<Photo> photos_;
  std::optional<geometry::CameraModel> camera_;
  std::string observations_path_;
  SessionOptions options_;
  std::vector<Observation> observations_;           // the file's rows, in order
  std::vector<std::vector<Observation>> history_;   // earlier states, for undo
  mutable std::map<std::size_t, cv::Mat> grey_;     // decoded photos
  mutable bool saved_ = true;                       // the file holds observations_
};

}  // namespace photomill::pick
