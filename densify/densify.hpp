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
//   Masks: markers with their quiet zones (detect's observations), the part box (or the sparse
//   cloud's box), the photos' borders.
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
  double spacing_px = 2;
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
  double marker_margin = 0.5;
  // Points outside this box (XMIN, YMIN, ZMIN, XMAX, YMAX, ZMAX, world frame) are refused; by
  // default the sparse cloud's box grown by box_margin of its size on every side.
  std::optional<std::array<double, 6>> box;
  double box_margin = 0.05;
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

struct ReferenceStats {
  std::size_t seeds = 0;
  std::size_t measured = 0;
  std::size_t accepted = 0;
  std::size_t occupied = 0;   // cells already holding an earlier reference's point
  std::array<std::size_t, static_cast<std::size_t>(PatchFailure::Count)> failures{};
  std::size_t outside_box = 0;
  std::vector<int> neighbours;
};

struct DensifyResult {
  // Per point: x y z, nx ny nz (unit normal facing the reference camera), sigma_mm (along the
  // reference ray), views (reference included), ref_image (index into the poses), correlation.
  PointCloud cloud;
  std::vector<ReferenceStats> references;
  std::array<double, 6> box{};
};

using Progress = std::function<void(const std::string&)>;

// Throws InputError when nothing can be measured: no seed in the box (naming the cloud), or no
// accepted patch (naming the poses).
DensifyResult densify(const DensifyInputs& inputs, const DensifyOptions& options, const Progress& progress = {});

}  // namespace photomill::densify
