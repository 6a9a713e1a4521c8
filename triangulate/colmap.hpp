// COLMAP text model export (cameras.txt, images.txt, points3D.txt, the format of COLMAP's
// src/base/reconstruction.cc ReadText/WriteText, 3.8), so a result opens in COLMAP's GUI.
// Conventions: COLMAP's pixel centre of the top-left pixel is (0.5, 0.5), OpenCV's is (0, 0), so
// principal points and 2D points are written +0.5 px. Poses are cam_from_world with the
// quaternion w first (Hamilton), the same as photomill's. Point ids are the track ids; image ids
// count registered images from 1 in input order; one camera (id 1).
#pragma once

#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "formats/camera.hpp"
#include "formats/tool.hpp"
#include "triangulate/reconstruct.hpp"

namespace photomill::triangulate {

// COLMAP's model name and parameters for the camera: PINHOLE (no distortion), OPENCV
// (fx fy cx cy k1 k2 p1 p2) or FULL_OPENCV (+ k3 k4 k5 k6), principal point +0.5 px.
// Throws InputError(source, 0, ...) if COLMAP cannot represent it (skew, thin-prism or tilt
// coefficients): check_colmap_camera() says so before a long run.
struct ColmapCamera {
  std::string model;
  std::vector<double> params;
};
ColmapCamera to_colmap_camera(const Camera& camera, const std::string& source);
void check_colmap_camera(const Camera& camera, const std::string& source);

// Throws InputError if an image name contains a blank (COLMAP's text format splits on them).
void write_colmap_cameras(std::ostream& out, const Reconstruction& r);
void write_colmap_images(std::ostream& out, const Reconstruction& r);
void write_colmap_points(std::ostream& out, const Reconstruction& r);

// Reads the poses of COLMAP's images.txt (the format written above and by COLMAP 3.8): '#'
// comments, then per image the line IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME (cam_from_world,
// Hamilton, w first) and the next line, its POINTS2D (X Y POINT3D_ID triples, may be empty),
// which is checked for its shape and skipped. Translations are taken as mm (a photomill model
// is in mm; a COLMAP model's scale is whatever its datum made it). The camera id is not used.
// Throws InputError naming the line: not 10 fields, a number that is not one, a quaternion
// that is not a unit one, an image named twice, a POINTS2D line that is not triples.
// lines, if given, receives each pose's line.
std::vector<Pose> read_colmap_images(std::istream& in, const std::string& source,
                                     std::vector<std::size_t>* lines = nullptr);

// The three files in a folder, written under temporary names and renamed by commit() (so a
// failed run leaves no model that looks finished). write() creates the folder if missing.
class ColmapModelFiles {
public:
  explicit ColmapModelFiles(std::string folder);
  ~ColmapModelFiles();
  ColmapModelFiles(const ColmapModelFiles&) = delete;
  ColmapModelFiles& operator=(const ColmapModelFiles&) = delete;
  void write(const Reconstruction& r);
  void commit();

private:
  std::string folder_;
  std::vector<std::unique_ptr<tool::OutputFile>> files_;
};

}  // namespace photomill::triangulate
