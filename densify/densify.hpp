// densify: a dense point cloud from oriented photos (issue 28), by multi-image least-squares
// matching of small planar patches (densify/patch.hpp) grown from the sparse cloud's points.
//
// Method (after D'Apuzzo 2003, "Surface measurement and tracking of human body parts from
// multi station video sequences", ETH dissertation: region growing of multi-photo least-squares
// matches from seed points; and Furukawa & Ponce 2010, PMVS: expansion of patches into
// neighbouring image cells, best first, with photo-consistency filtering):
//   For each photo in turn as the reference, its pixels are divided into cells of spacing_px.
//   Seeds are the sparse points seen in it (a plane facing the camera through each). A seed or
//   a candidate is measured by PatchMatcher against the reference's neighbour views; an accepted
//   patch proposes its plane to its four neighbouring cells, best correlation first, until no
//   cell is left to try. Cells already holding a point of an earlier reference are not measured
//   again (their plane still grows), so each surface element is measured about once.
//   Cells are grown tile by tile in parallel; a second pass carries growth across tile borders.
//   Masks: markers with their quiet zones (detect's observations; a marker missed in a photo
//   projected into it from the others), the part box (or the sparse
//   cloud's box), the photos' borders.
//   The markers' printed squares are then measured apart, each cell from the surface its
//   corners and the dense points around it predict, with a window scaled to the marker
//   (measure_marker_squares in densify.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "densify/patch.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "geometry/camera_model.hpp"

namespace photomill::densify {

struct DensifyOptions {
  PatchOptions patch;
  // One point per cell of this many pixels in the reference photo.
  double spacing_px = 1.8;
  // Views matched with each reference: the nearest ones by the angle between their rays at the
  // scene's centre, from min_angle_deg (a shorter baseline measures depth poorly) to
  // max_angle_deg (a wider one sees another face of the texture).
  int max_views = 4;
  double min_angle_deg = 8;
  double max_angle_deg = 50;
  // A cell is measured at most this many times (from different neighbours' planes).
  int max_attempts = 2;
  // Marker masks: the marker's quad (from its four corners in the photo) grown by this fraction
  // of its side on every side (the quiet zone).
  double marker_margin = 0.34;
  // The sparse cloud's marker corners inside the box are written with the dense points (flagged
  // marker_corner): they hold the fitted surface across the masked markers.
  bool marker_corners = true;
  // The markers' printed squares are measured (densify.cpp, measure_marker_squares) from the
  // marker_square_views photos that see each most squarely, each cell starting from the surface
  // predicted under the marker, with a window of half-width marker_square_window of the marker's
  // side in the photo (at least patch.half_window_px); a point off that prediction by more than
  // marker_square_tolerance marker sides is refused.
  bool marker_squares = true;
  int marker_square_views = 2;
  double marker_square_window = 0.4;
  double marker_square_tolerance = 0.03;
  // Points outside this box (XMIN, YMIN, ZMIN, XMAX, YMAX, ZMAX, world frame) are refused; by
  // default the sparse cloud's box grown by box_margin of its size on every side.
  std::optional<std::array<double, 6>> box;
  double box_margin = 0.05;
  // The free-space check (densify.cpp, free_space_violations): a point is removed when it lies at
  // least this many times in front of a point a view matched behind it, more than
  // free_space_gap_footprints of its cell's width before it (0: no check).
  int free_space_min_violations = 1;
  double free_space_gap_footprints = 2;
  // Tiles of this many cells a side are grown in parallel.
  int tile_cells = 64;
  int threads = 0;  // 0: every core
};

struct DensifyInputs {
  geometry::CameraModel camera;
  std::vector<Pose> poses;          // one per photo, in this order
  std::vector<cv::Mat> photos;      // grey CV_32F, one per pose
  PointCloud sparse;                // seeds and the default box
  std::vector<Observation> observations;  // marker corners (point ids below kFirstClickedId)
  std::string cloud_source = "cloud";     // names for the errors
  std::string poses_source = "poses";
};

// Marker corners have point id marker_id * 4 + corner; pick's clicked points start here.
constexpr PointId kFirstClickedId = 100000;
// The sparse cloud's tracks below this id are coded targets (marker corners, board corners),
// the others natural features and clicked points (docs/formats.md, Tracks).
constexpr PointId kCodedIdLimit = 4096;

struct ReferenceStats {
  std::size_t seeds = 0;
  std::size_t measured = 0;
  std::size_t accepted = 0;
  std::size_t occupied = 0;   // cells already holding an earlier reference's point
  std::array<std::size_t, static_cast<std::size_t>(PatchFailure::Count)> failures{};
  std::size_t outside_box = 0;
  std::size_t free_space = 0;  // its points removed by the free-space check
  std::vector<int> neighbours;
};

struct DensifyResult {
  // Per point: x y z, nx ny nz (unit normal facing the reference camera), sigma_mm (along the
  // reference ray), views (reference included), ref_image (index into the poses), correlation,
  // reprojection_px, marker_corner (1: a marker corner of the sparse cloud, not measured here).
  PointCloud cloud;
  std::vector<ReferenceStats> references;
  std::array<double, 6> box{};
  std::size_t free_space_removed = 0;
  // Markers masked in a photo whose observations do not show them whole: their corners, placed
  // in space from the other photos, projected into it (one count per marker and photo).
  std::size_t markers_projected = 0;
  std::size_t marker_corners = 0;  // the sparse cloud's marker corners written (marker_corner 1)
  std::size_t marker_square_points = 0;      // points measured on the markers' printed squares
  std::size_t marker_squares_measured = 0;   // markers whose squares were measured
  std::size_t marker_squares_unpredicted = 0;  // markers in the box left out: too few points around them
};

using Progress = std::function<void(const std::string&)>;

// A measured point as the free-space check sees it (world frame).
struct SurfaceSample {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
  double footprint = 0;        // the patch's radius: its cell's width at its depth in the reference
  std::vector<int> seen_by;    // the views (indices into `views`) it was matched in
};

// The free-space check (after Furukawa & Ponce 2010, PMVS sec. 3.4, the visibility filter, and
// Merrell et al. 2007, "Real-time visibility-based fusion of depth maps", free-space
// violations): view j saw point Q (Q was matched in it), so nothing opaque lies on the ray from
// j's centre C to Q. A point P whose patch (the disc of radius footprint_P about P in P's plane)
// that ray crosses more than gap before Q therefore cannot be there. The crossing is
// X = C + s (Q - C) with
//   s = N_P . (P - C) / N_P . (Q - C),  a violation when 0 < s < 1, |X - P| <= footprint_P and
//   (1 - s) |Q - C| > gap_footprints footprint_P.
// Such points are the "foreground fattening" at depth edges: a window centred just past a wall's
// rim still matches on the top's texture and puts the centre's point in the air beyond the rim,
// in front of the wall's face that the views on that side see. Q is looked up among the points
// view j matched, bucketed by their pixel in j; the disc projects within footprint_P fx / z_j(P)
// px of P's pixel (+1 px for the lens). Returns, per point, the number of (view, Q) violations.
std::vector<int> free_space_violations(const std::vector<SurfaceSample>& points, const std::vector<PatchView>& views,
                                       const geometry::CameraModel& camera, double gap_footprints, int threads = 0);

// Throws InputError when nothing can be measured: no seed in the box (naming the cloud), or no
// accepted patch (naming the poses).
DensifyResult densify(const DensifyInputs& inputs, const DensifyOptions& options, const Progress& progress = {});

}  // namespace photomill::densify
