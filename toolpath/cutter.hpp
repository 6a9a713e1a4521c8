// Steps 4 and 7 of the paper's section 5 (cutter contact -> cutter location) for a ball end on a
// 3-axis mill, with gouge detection and drop-cutter lifting: the ball is placed tangent to the
// surface at the CC point, then raised until it touches the surface nowhere deeper (the highest
// contact of the ball with the surface around it), so the tool never cuts into the part.
#pragma once

#include <limits>
#include <vector>

#include <Eigen/Core>

#include "formats/surface.hpp"
#include "toolpath/iso_passes.hpp"

namespace photomill::toolpath {

struct CutterOptions {
  double tool_radius_mm = 3;      // R: ball radius
  double stock_mm = 0;            // a: allowance left on the surface (the ball runs on the offset)
  double gouge_tol_mm = 0.0005;   // a lift or dip deeper than this counts as a gouge
  bool lift = true;               // false: report gouges but keep the tangent position
  // Spacing of the surface samples the drop cutter searches before refining contacts exactly.
  double sample_mm = 0.5;
};

// Step 4: the ball centre for a CC point p with upward unit normal n: c = p + (R + a) n, and the
// tool tip (what CL data stores): tip = c - R z. (With a = 0, the ball touches p.)
Eigen::Vector3d ball_centre(const Eigen::Vector3d& cc, const Eigen::Vector3d& normal, double tool_radius_mm,
                            double stock_mm);
inline Eigen::Vector3d tip_from_centre(const Eigen::Vector3d& centre, double tool_radius_mm) {
  return centre - Eigen::Vector3d(0, 0, tool_radius_mm);
}

// Drop cutter against one B-spline surface: the lowest height of a ball of radius r, at a given
// horizontal position, at which it does not cut into the surface:
//   c_z(x, y) = max over surface points q with |q_xy - (x, y)| < r of  q_z + sqrt(r^2 - |q_xy - (x, y)|^2)
// (a 3-axis ball touches the surface from above; OpenCAMLib's "drop cutter" for a sphere). The
// maximum is searched on a grid of surface samples bucketed by (x, y) (the acceleration
// structure), then refined on the exact surface by Newton's method from every sample that is a
// local maximum within `margin = s^2 / r` of the best value (s = sample spacing: twice the
// sampling error of a ball on a plane, so a contact between samples is not missed).
class DropCutter {
public:
  DropCutter(const BSplineSurface& surface, double ball_radius_mm, double sample_mm);

  struct Contact {
    double centre_z = -std::numeric_limits<double>::infinity();  // lowest safe centre height
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();                // (u, v) of the touching point
    Eigen::Vector3d point = Eigen::Vector3d::Zero();             // the touching surface point
    bool hit = false;                                            // the ball is over the surface
  };
  // `known`: an already known contact (the CC point of a tangent ball, with centre_z its exact
  // height), used as the reference; samples in its basin that do not rise above it are skipped.
  // `hints`: (u, v) where contacts are expected (those of nearby balls); refined first, so their
  // basins need no search from the samples.
  Contact drop(const Eigen::Vector2d& xy, const Contact* known = nullptr,
               const std::vector<Eigen::Vector2d>& hints = {}) const;

  double ball_radius_mm() const { return r_; }
  double sample_spacing_mm() const { return spacing_; }
  // Highest and lowest surface sample (mm), for safe heights and previews.
  double top_z() const { return top_z_; }
  double bottom_z() const { return bottom_z_; }
  // Horizontal bounding box of the samples.
  Eigen::Vector2d min_xy() const { return min_xy_; }
  Eigen::Vector2d max_xy() const { return max_xy_; }

private:
  double g_at(int i, int j, const Eigen::Vector2d& xy) const;
  Contact refine(const Eigen::Vector2d& xy, const Eigen::Vector2d& uv0) const;

  const BSplineSurface* surface_;
  double r_;
  double spacing_ = 0;
  int ni_ = 0, nj_ = 0;                 // samples along u and v
  std::vector<Eigen::Vector3d> pts_;    // sample (i, j) at i * nj_ + j
  std::vector<Eigen::Vector2d> uvs_;
  // Buckets of side r_ over the samples' bounding box; CSR layout.
  Eigen::Vector2d min_xy_, max_xy_;
  int bx_ = 0, by_ = 0;
  std::vector<int> bucket_start_;
  std::vector<int> bucket_items_;
  double top_z_ = 0, bottom_z_ = 0;
};

// A CC point converted to a CL point (step 4 / step 7).
struct CutterLocation {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();         // CC parameters
  Eigen::Vector3d cc = Eigen::Vector3d::Zero();         // cutter contact point, mm
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();    // unit surface normal at cc, upwards
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();     // ball centre the tool moves through
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();        // tool tip = centre - R z (the CL point)
  // How far the tangent ball cut into the surface elsewhere: the drop cutter's centre height
  // minus that of c = cc + (R + a) n. Zero where the ball touches only at cc.
  double gouge_depth_mm = 0;
  Eigen::Vector3d contact = Eigen::Vector3d::Zero();    // the highest contact (== cc without gouge)
  Eigen::Vector2d contact_uv = Eigen::Vector2d::Zero(); // its (u, v)
  double concave_radius_mm = std::numeric_limits<double>::infinity();  // 1 / largest concave curvature
  bool gouge = false;   // gouge_depth_mm > gouge tolerance, or concave_radius_mm < R + a
  bool lifted = false;  // the centre was raised by gouge_depth_mm
};

CutterLocation cc_to_cl(const PassFrame& frame, const DropCutter& drop, const CutterOptions& options);

}  // namespace photomill::toolpath
