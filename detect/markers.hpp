// ArUco markers in images: OpenCV's detector finds and identifies them, then every corner is
// refined by fitting the marker's four edges (a blurred, pixel-integrated step across a polynomial
// curve, fitted to all pixels of a band along each edge) and intersecting adjacent edges.
// Images -> observations (point_id = marker_id * 4 + corner, corners 0..3 = TL, TR, BR, BL as
// cv::aruco::detectMarkers returns them); markers whose refinement fails are dropped and named.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "formats/tables.hpp"

namespace cv::aruco {
class Dictionary;
}

namespace photomill::detect {

// An ArUco dictionary: one of OpenCV's predefined ones, or one read from OpenCV's YAML dictionary
// format (nmarkers, markersize, optional maxCorrectionBits, marker_0 .. marker_{n-1} as strings of
// markersize^2 bits, row-major, '1' = white; as cv::aruco::Dictionary::readDictionary reads it).
class MarkerDictionary {
public:
  // `name` as aruco_dictionary_names() lists it; throws UsageError for an unknown name.
  static MarkerDictionary predefined(const std::string& name);
  // Throws InputError(path, 0, ...) naming the missing key or the bad marker.
  static MarkerDictionary from_file(const std::string& path);

  const std::string& name() const { return name_; }
  int marker_count() const;
  int bits_per_side() const;          // markersize: 4 for DICT_4X4_*
  int max_correction_bits() const;
  // Marker `id`'s code: bits_per_side() x bits_per_side() CV_8UC1, 1 = white, rows top to bottom
  // with the marker upright (corners TL TR BR BL as detect_markers returns them).
  cv::Mat code(int id) const;
  // The OpenCV dictionary (OpenCV's detector takes it by non-const pointer; it is not modified).
  const std::shared_ptr<cv::aruco::Dictionary>& opencv() const { return dictionary_; }

private:
  std::shared_ptr<cv::aruco::Dictionary> dictionary_;
  std::string name_;
};

// How corners are refined after OpenCV's detection.
enum class CornerRefinement {
  Edges,    // edge-model fit (below); the default
  Subpix,   // OpenCV's CORNER_REFINE_SUBPIX (cornerSubPix on the corner: biased ~0.2 px inwards)
  Contour,  // OpenCV's CORNER_REFINE_CONTOUR
  None,     // OpenCV's polygon corners as they are
};
const std::vector<std::string>& corner_refinement_names();  // "edges", "subpix", "contour", "none"
CornerRefinement corner_refinement_from_name(const std::string& name);

// Edge-model corner refinement. For each edge of the marker's quadrilateral, with t the distance
// along the edge from its first corner (length L), s the signed distance across it (outwards,
// towards the white quiet zone, positive) and tau = t / L - 1/2, every pixel of a band
// |s - f(tau)| <= w (pixels the neighbouring edges reach left out) is fitted by
//   I = a + b R(s - f(tau); sigma),   f(tau) = c_0 + c_1 tau + ... + c_D tau^D,
//   a = a0 + a1 tau + a2 s,  b = b0 + b1 tau + b2 s
// i.e. a straight (D = 1) or curved (D = 2, 3) step edge, blurred by a Gaussian PSF of standard
// deviation sigma and integrated over the pixel's footprint across the edge (R: the step convolved
// with the Gaussian and with the pixel square's projection on the edge normal, a trapezoid; closed
// form in markers.cpp), on a shading that varies linearly along and across the edge (light on a
// curved part). Parameters x = [c_0..c_D, sigma, a0, a1, a2, b0, b1, b2], solved by
// Levenberg-Marquardt (Madsen, Nielsen & Tingleff, "Methods for non-linear least squares
// problems", 2004, sec. 3.2).
// The inner term: the black border is one cell wide, and inside it lie the code cells. Where a
// small or blurred marker's band reaches the border's inner edge, a white code cell there lifts
// the border's dark side, and a step model alone takes that for the edge (on OpenCV's photos, with
// 3-4.5 px cells, the fit then depended on its start by 0.1-0.6 px, docs/measurements/detect.md).
// With the decoded code known, the model is
//   I = a + b [R(s - f) + k (1 - R(s - f + w_b))]
// with w_b the border's width across the edge (from the homography through the corners) and k the
// whiteness of the code cell next to the border at the pixel's place along the edge (0 black,
// 1 white, blurred at the cell's ends). Far from the inner edge (big markers) the term is 0.
// Each corner is the intersection of its two edge curves (Newton's
// method in 2D). Curved edges come from lens distortion (~0.1 px sagitta for a 130 px edge near
// the border at k1 = -0.08) and from markers stuck on a curved part: D starts at 3 and drops while
// the top coefficient is not significant. Two passes: a coarse one around OpenCV's polygon, a fine
// one through the coarse corners. Measured choices and figures: docs/measurements/detect.md.
struct EdgeFitOptions {
  int degree = 3;                 // D at most: 1 straight lines, 2 parabolas, 3 cubics ...
  double degree_significance = 3; // ... lowered while |c_D| is below this many standard errors
  double span = 1.0;              // fraction of each edge, from the corner, fitted for that corner
                                  // (1: whole edges, shared by both corners; 0.5: local fits)
  double window_cells = 0.5;      // band half-width w in marker cells (stays in the black border);
  double band_plateau_px = 2;     // with the code modelled, widened to hold the blurred transition
                                  // and this much level ground beyond it, up to one cell (markers.cpp)
  double min_window_px = 1.5;     // ... but at least
  double max_window_px = 4;       // ... and at most this (the plateaus beyond add little)
  int max_iterations = 30;        // Levenberg-Marquardt iterations per edge and round
  double tolerance_px = 1e-3;     // ... until the curve moves less than this
  double initial_blur_px = 0.7;   // sigma to start from (and for the first corner margins)
  double initial_corner_error_px = 1; // OpenCV's polygon corners are this far off at most: the
                                      // first pass keeps that much further from the corners
  double min_px_per_degree = 4;   // a stretch of L px is fitted with degree <= L / this (>= 1)
  double min_fit_length_px = 3;   // shortest stretch of an edge worth fitting
  double min_contrast = 15;       // b0: white minus black, grey levels
  double max_blur_px = 4;         // sigma
  double max_residual = 0.25;     // RMS fit residual as a fraction of the contrast
  double max_shift_cells = 0.5;   // a corner may move this far from OpenCV's (in cells) ...
  double min_max_shift_px = 2;    // ... or this far in pixels, whichever is larger
  int min_pixels_per_edge = 12;
  // Markers whose cells are at least this wide (px, across each edge) take the quick start: the
  // fine pass starts from the coarse pass's curves and fits once on the band that follows them,
  // and the cold fits' first iterations run on a third of the band (same corners to ~0.01 px on
  // such markers). Smaller markers, whose corners depend on where the fit starts, never take it.
  double quick_start_min_cell_px = 6;
  // The model blurs light, so intensities must be linear in light: grey value v is fitted as
  // 255 (v / 255)^gamma. 1 for linear images (synth's renders, raw data); about 2.2 for sRGB
  // JPEGs, whose midtones otherwise move a blurred edge towards the dark side by roughly 0.8 sigma.
  double gamma = 1;
  // Model the decoded code cells next to the border (the inner term above); false: the inside of
  // the border is taken as black, as before.
  bool model_code = true;
};

struct MarkerDetectOptions {
  CornerRefinement refinement = CornerRefinement::Edges;
  EdgeFitOptions edges;
  // OpenCV's detector: errorCorrectionRate (fraction of the dictionary's correctable bits used).
  double error_correction_rate = 0.6;
  // The smallest of the candidate search's adaptive-threshold windows (then +10 px up to 23),
  // OpenCV's 3 by default. The 3 px window turns JPEG noise and texture into many small contours:
  // on the demo's photos it is three quarters of the search's time, but some small, foreshortened
  // markers are found only with it (docs/detect.md, "Speed").
  int threshold_window_min_px = 3;
};

// A marker OpenCV found but photomill dropped, and why.
struct RejectedMarker {
  int marker_id = 0;
  std::string reason;
  // OpenCV's polygon corners TL TR BR BL, px (for drawings).
  std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                         Eigen::Vector2d::Zero()};
  bool operator==(const RejectedMarker&) const = default;
};

// What was found in one image.
struct MarkerDetection {
  std::string image;
  int width_px = 0;
  int height_px = 0;
  std::vector<int> marker_ids;                        // kept markers, ascending
  std::vector<std::array<Eigen::Vector2d, 4>> corners;  // their corners TL TR BR BL, px
  std::vector<RejectedMarker> rejected;
  // Quadrilaterals OpenCV's detector found but could not identify as a marker of the dictionary
  // (its rejectedImgPoints), px; only for drawings.
  std::vector<std::array<Eigen::Vector2d, 4>> candidates;
  // Every corner of every kept marker, point_id = marker_id * 4 + corner, sorted by point_id.
  std::vector<Observation> observations() const;
};

// Result of refining one marker's corners.
struct EdgeFit {
  bool ok = false;
  std::string failure;                  // why not, when !ok
  std::array<Eigen::Vector2d, 4> corners;
  double blur_px = 0;                   // mean sigma of the four edges
  double band_px = 0;                   // mean half-width of their bands
  double contrast = 0;                  // smallest b0 of the four edges
  double residual = 0;                  // largest RMS residual / contrast
  int iterations = 0;                   // Levenberg-Marquardt iterations of the edge fits, both passes
};

// Refines the corners of one marker (initial corners TL TR BR BL from OpenCV; `cells` = bits per
// side + 2 border cells). Never throws for a bad fit: ok = false with the reason.
// `code`: the marker's decoded cells (MarkerDictionary::code), for the model's inner term; empty:
// the inside of the border is taken as black.
EdgeFit refine_marker_corners(const cv::Mat& grey, const std::array<Eigen::Vector2d, 4>& initial, int cells,
                              const EdgeFitOptions& options, const cv::Mat& code = cv::Mat());

// Detects, identifies and refines the markers of one grey image (CV_8UC1). A marker id seen twice
// in one image is dropped both times (one of them is a wrong decoding).
MarkerDetection detect_markers(const cv::Mat& grey, const std::string& image_name, const MarkerDictionary& dictionary,
                               const MarkerDetectOptions& options);

// The four sides of every marker id in `ids` as scale bars of `side_mm` (corner 0-1, 1-2, 2-3,
// 3-0), for triangulate --scale-bars.
std::vector<ScaleBar> marker_scale_bars(const std::vector<int>& ids, double side_mm);

}  // namespace photomill::detect
