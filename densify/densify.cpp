#include "densify/densify.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <queue>
#include <set>

#include <opencv2/imgproc.hpp>

#include "formats/error.hpp"
#include "geometry/parallel.hpp"

namespace photomill::densify {
namespace {

// The least angle between two rays of a marker corner for it to be placed in space (degrees).
constexpr double kMarkerMinAngleDeg = 2;

enum class CellState : unsigned char { Empty, Done, Occupied };

struct Cell {
  CellState state = CellState::Empty;
  unsigned char attempts = 0;
  bool expanded = false;      // an Occupied cell's plane was proposed to its neighbours
  float correlation = 0;
  Eigen::Vector3d plane = Eigen::Vector3d::Zero();  // reference frame
};

struct Candidate {
  double priority;
  int cell;
  Eigen::Vector3d plane;
  bool operator<(const Candidate& o) const { return priority < o.priority; }
};

// One accepted point, world frame.
struct DensePoint : SurfaceSample {
  double sigma;
  int views;
  int ref;
  double correlation;
  double reprojection_px;
  bool marker_corner = false;
  double window_mm = 0;  // the matched window's half-width at the point's depth (0: a sparse point)
};

// The plane n . X = 1 in the frame of the camera (R, t) through world point P with world normal N:
// X_w = R^T (X_c - t), so N . R^T (X_c - t) = N . P, i.e. (R N) . X_c = N . P + (R N) . t.
std::optional<Eigen::Vector3d> plane_in_camera(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                               const Eigen::Vector3d& P, const Eigen::Vector3d& N) {
  const Eigen::Vector3d Nc = R * N;
  const double d = N.dot(P) + Nc.dot(t);
  if (!(std::abs(d) > 1e-12)) return std::nullopt;
  return Nc / d;
}

bool in_box(const std::array<double, 6>& b, const Eigen::Vector3d& p) {
  return p.x() >= b[0] && p.y() >= b[1] && p.z() >= b[2] && p.x() <= b[3] && p.y() <= b[4] && p.z() <= b[5];
}

// A marker's four corners in one photo (pixels, corner order).
using Quad = std::array<Eigen::Vector2d, 4>;

// The markers each photo's observations show whole: marker id -> its corners.
std::map<PointId, Quad> observed_quads(const std::vector<const Observation*>& obs) {
  std::map<PointId, std::array<const Observation*, 4>> corners;
  for (const Observation* o : obs) {
    if (o->point_id < 0 || o->point_id >= kFirstClickedId) continue;
    corners[o->point_id / 4][static_cast<std::size_t>(o->point_id % 4)] = o;
  }
  std::map<PointId, Quad> quads;
  for (const auto& [id, q] : corners) {
    if (!q[0] || !q[1] || !q[2] || !q[3]) continue;
    Quad& out = quads[id];
    for (std::size_t k = 0; k < 4; ++k) out[k] = Eigen::Vector2d(q[k]->u_px, q[k]->v_px);
  }
  return quads;
}

// Where the marker masks of a photo are 0: each quad grown by `margin` of its side about its
// centre.
cv::Mat marker_mask(const std::vector<Quad>& quads, int width, int height, double margin) {
  cv::Mat mask(height, width, CV_8U, cv::Scalar(255));
  for (const Quad& q : quads) {
    const Eigen::Vector2d c = (q[0] + q[1] + q[2] + q[3]) / 4;
    std::vector<cv::Point> poly;
    for (const Eigen::Vector2d& corner : q) {
      const Eigen::Vector2d p = c + (corner - c) * (1 + 2 * margin);
      poly.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
    cv::fillConvexPoly(mask, poly, cv::Scalar(0));
  }
  return mask;
}

// Whether all four corners of `marker` (point ids marker * 4 + 0..3) are in `corners`.
bool whole_marker(const std::map<PointId, Eigen::Vector3d>& corners, PointId marker) {
  for (PointId c = 0; c < 4; ++c) {
    if (!corners.count(marker * 4 + c)) return false;
  }
  return true;
}

// The marker corners in space, from their observations in the photos: the point nearest to all
// of a corner's rays in the least-squares sense, X = (sum P_i)^-1 sum P_i c_i with
// P_i = I - d_i d_i^T (d_i the unit ray from centre c_i; Hartley & Zisserman 2003, 12.2's
// mid-point method generalised to n rays). A corner seen in fewer than two photos, or whose rays
// meet at less than min_angle_deg, is left out.
std::map<PointId, Eigen::Vector3d> marker_corners_in_space(const std::vector<std::vector<const Observation*>>& obs_of,
                                                            const std::vector<PatchView>& views,
                                                            const geometry::CameraModel& cam, double min_angle_deg) {
  struct Rays {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> dirs;
  };
  std::map<PointId, Rays> rays;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const Eigen::Matrix3d Rt = views[i].rotation.transpose();
    const Eigen::Vector3d c = -Rt * views[i].translation_mm;
    for (const Observation* o : obs_of[i]) {
      if (o->point_id < 0 || o->point_id >= kFirstClickedId) continue;
      const auto xy = geometry::undistort(cam, Eigen::Vector2d(o->u_px, o->v_px));
      if (!xy) continue;
      const Eigen::Vector3d d = (Rt * Eigen::Vector3d(xy->x(), xy->y(), 1)).normalized();
      const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - d * d.transpose();
      Rays& r = rays[o->point_id];
      r.A += P;
      r.b += P * c;
      r.dirs.push_back(d);
    }
  }
  std::map<PointId, Eigen::Vector3d> out;
  const double cos_min = std::cos(min_angle_deg * M_PI / 180);
  for (const auto& [id, r] : rays) {
    bool wide = false;
    for (std::size_t a = 0; a < r.dirs.size() && !wide; ++a) {
      for (std::size_t b = a + 1; b < r.dirs.size() && !wide; ++b) wide = r.dirs[a].dot(r.dirs[b]) < cos_min;
    }
    if (wide) out[id] = r.A.ldlt().solve(r.b);
  }
  return out;
}

// The sparse cloud's coded targets' tracks (ids below kCodedIdLimit, finite): id -> row.
std::map<PointId, std::size_t> coded_rows(const PointCloud& sparse) {
  std::map<PointId, std::size_t> rows;
  const PointProperty* track = sparse.find("track_id");
  if (!track) return rows;
  for (std::size_t i = 0; i < sparse.points_mm.size(); ++i) {
    const double id = track->values[i];
    if (id >= 0 && id < kCodedIdLimit && sparse.points_mm[i].allFinite()) rows[static_cast<PointId>(id)] = i;
  }
  return rows;
}

// The sparse cloud's marker corners (its coded targets' tracks) inside the box, as points of the
// dense cloud. The markers are masked in every photo, so the dense points leave a hole at each;
// their corners, measured by the bundle adjustment from detect's sub-pixel corners, hold the
// fitted surface across it.
// Normal: the marker's plane (the cross product of its diagonals, Hartley & Zisserman 2003, 2.2)
// when its four corners are there, else the direction to the cameras; turned to face the
// cameras' mean centre. sigma_mm, views and reprojection_px come from the sparse cloud when it
// has them; ref_image is the first photo that observed the corner.
std::vector<DensePoint> marker_corner_points(const PointCloud& sparse, const std::array<double, 6>& box,
                                             const std::vector<Eigen::Vector3d>& centres,
                                             const std::vector<std::vector<const Observation*>>& obs_of) {
  std::vector<DensePoint> out;
  const PointProperty* sigma = sparse.find("sigma_mm");
  const PointProperty* views = sparse.find("views");
  const PointProperty* reprojection = sparse.find("reproj_rms_px");
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  for (const auto& c : centres) eye += c / static_cast<double>(centres.size());
  std::map<PointId, Eigen::Vector3d> corner;
  const std::map<PointId, std::size_t> row = coded_rows(sparse);
  for (const auto& [id, i] : row) corner[id] = sparse.points_mm[i];
  std::map<PointId, int> first_photo;
  for (std::size_t v = 0; v < obs_of.size(); ++v) {
    for (const Observation* o : obs_of[v]) {
      if (corner.count(o->point_id) && !first_photo.count(o->point_id)) first_photo[o->point_id] = static_cast<int>(v);
    }
  }
  for (const auto& [id, X] : corner) {
    if (!in_box(box, X)) continue;
    const PointId m = id / 4 * 4;
    Eigen::Vector3d n = (eye - X).normalized();
    if (whole_marker(corner, id / 4)) {
      const Eigen::Vector3d plane = (corner[m + 2] - corner[m]).cross(corner[m + 3] - corner[m + 1]);
      if (plane.norm() > 0) n = plane.dot(eye - X) >= 0 ? plane.normalized() : Eigen::Vector3d(-plane.normalized());
    }
    if (!n.allFinite()) continue;
    const std::size_t r = row.at(id);
    DensePoint p;
    p.xyz = X;
    p.normal = n;
    p.sigma = sigma ? sigma->values[r] : 0;
    p.views = views ? static_cast<int>(std::min(255.0, views->values[r])) : 0;
    p.ref = first_photo.count(id) ? first_photo[id] : 0;
    p.correlation = 1;
    p.reprojection_px = reprojection ? reprojection->values[r] : 0;
    p.marker_corner = true;
    out.push_back(p);
  }
  return out;
}

// The markers' corners in space for the printed squares' measurement: the sparse cloud's
// (bundle-adjusted from detect's sub-pixel corners) where it has all four of a marker's,
// else those placed from the photos' rays (marker_corners_in_space).
std::map<PointId, Eigen::Vector3d> best_marker_corners(const PointCloud& sparse,
                                                       const std::map<PointId, Eigen::Vector3d>& from_rays) {
  std::map<PointId, Eigen::Vector3d> adjusted;
  for (const auto& [id, i] : coded_rows(sparse)) adjusted[id] = sparse.points_mm[i];
  std::map<PointId, Eigen::Vector3d> out;
  std::set<PointId> markers;
  for (const auto& [id, X] : adjusted) markers.insert(id / 4);
  for (const auto& [id, X] : from_rays) markers.insert(id / 4);
  for (PointId m : markers) {
    const auto* src = whole_marker(adjusted, m) ? &adjusted : whole_marker(from_rays, m) ? &from_rays : nullptr;
    if (!src) continue;
    for (PointId c = 0; c < 4; ++c) out[m * 4 + c] = src->at(m * 4 + c);
  }
  return out;
}

// The surface under a marker's printed square, predicted in the marker's frame (origin its
// centre, axes e1, e2 in its plane, n its normal) as a height h(a, b) = c0 + c1 a + c2 b + c3 a^2
// + c4 a b + c5 b^2 fitted by least squares to its four corners (weight kCornerWeight each) and
// the dense points around it (weight 1; marker_frame); dense points off the first fit by more
// than reject_sides marker sides are dropped and the fit repeated once.
struct MarkerFrame {
  Eigen::Vector3d centre, e1, e2, n;
  double side = 0;
  Eigen::Matrix<double, 6, 1> h = Eigen::Matrix<double, 6, 1>::Zero();
  static Eigen::Matrix<double, 6, 1> basis(double a, double b) {
    Eigen::Matrix<double, 6, 1> r;
    r << 1, a, b, a * a, a * b, b * b;
    return r;
  }
  Eigen::Vector2d local(const Eigen::Vector3d& X) const { return {(X - centre).dot(e1), (X - centre).dot(e2)}; }
  double height(double a, double b) const { return basis(a, b).dot(h); }
  // How far X lies above the predicted surface, along n.
  double off(const Eigen::Vector3d& X) const {
    const Eigen::Vector2d ab = local(X);
    return (X - centre).dot(n) - height(ab.x(), ab.y());
  }
  Eigen::Vector3d point(double a, double b) const { return centre + a * e1 + b * e2 + height(a, b) * n; }
  Eigen::Vector3d normal(double a, double b) const {
    const double ha = h[1] + 2 * h[3] * a + h[4] * b, hb = h[2] + h[4] * a + 2 * h[5] * b;
    return (n - ha * e1 - hb * e2).normalized();
  }
};

// A corner weighs as much as this many dense points in the prediction (it is measured from
// detect's sub-pixel corners, the dense points from texture).
constexpr double kCornerWeight = 10;
// Dense points within this many marker sides of its centre (in its plane) enter the prediction.
constexpr double kPredictionRadiusSides = 1.6;
// ... at least this many of them.
constexpr std::size_t kPredictionMinPoints = 30;

std::optional<MarkerFrame> marker_frame(const std::array<Eigen::Vector3d, 4>& corner, const Eigen::Vector3d& eye,
                                        const std::vector<Eigen::Vector3d>& dense, double reject_sides) {
  MarkerFrame f;
  f.centre = (corner[0] + corner[1] + corner[2] + corner[3]) / 4;
  const Eigen::Vector3d plane = (corner[2] - corner[0]).cross(corner[3] - corner[1]);
  if (!(plane.norm() > 0)) return std::nullopt;
  f.n = plane.dot(eye - f.centre) >= 0 ? plane.normalized() : Eigen::Vector3d(-plane.normalized());
  f.e1 = (corner[1] - corner[0]).normalized();
  f.e1 = (f.e1 - f.e1.dot(f.n) * f.n).normalized();
  f.e2 = f.n.cross(f.e1);
  for (int k = 0; k < 4; ++k) f.side += (corner[(k + 1) % 4] - corner[k]).norm() / 4;
  if (!f.e2.allFinite() || !(f.side > 0)) return std::nullopt;
  std::vector<std::pair<Eigen::Vector3d, double>> data;
  for (const auto& c : corner) data.emplace_back(c, kCornerWeight);
  for (const auto& X : dense) {
    const Eigen::Vector2d ab = f.local(X);
    if (ab.norm() <= kPredictionRadiusSides * f.side && std::abs((X - f.centre).dot(f.n)) < f.side) data.emplace_back(X, 1);
  }
  if (data.size() < 4 + kPredictionMinPoints) return std::nullopt;
  for (int round = 0; round < 2; ++round) {
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    std::size_t used = 0;
    for (const auto& [X, w] : data) {
      if (round == 1 && w == 1 && std::abs(f.off(X)) > reject_sides * f.side) continue;
      const Eigen::Vector2d ab = f.local(X) / f.side;
      const Eigen::Matrix<double, 6, 1> q = MarkerFrame::basis(ab.x(), ab.y());
      A += w * q * q.transpose();
      b += w * q * ((X - f.centre).dot(f.n));
      used += w == 1;
    }
    if (used < kPredictionMinPoints) return std::nullopt;
    const Eigen::Matrix<double, 6, 1> c = A.ldlt().solve(b);
    if (!c.allFinite()) return std::nullopt;
    // Back from side-scaled coordinates.
    const double s = f.side;
    f.h << c[0], c[1] / s, c[2] / s, c[3] / (s * s), c[4] / (s * s), c[5] / (s * s);
  }
  return f;
}

// The largest window a marker's square is measured with (half-width, px).
constexpr int kSquareMaxHalfWindowPx = 40;
// Radius of the neighbourhood a marker square's point is compared with, in marker sides.
constexpr double kSquareNeighbourSides = 0.1;
// Fewest neighbours a marker square's point must have to be kept.
constexpr std::size_t kSquareMinNeighbours = 5;
// A point further than this many robust standard deviations from its neighbours is dropped.
constexpr double kSquareRejectSigmas = 3;

// Drops the points measured on a marker's square that disagree with their neighbours: each
// point's height above the predicted surface (MarkerFrame::off) against the median of its
// neighbours' within kSquareNeighbourSides, compared with the robust spread of these
// differences over the square (1.4826 times their median absolute value: the standard
// deviation of a normal distribution; Rousseeuw & Croux 1993). The prediction's own error is
// smooth and cancels between neighbours; a window that locked onto the wrong cell does not.
template <class Point>
void reject_unlike_neighbours(const MarkerFrame& frame, std::vector<Point>* points) {
  const std::size_t n = points->size();
  std::vector<Eigen::Vector2d> ab(n);
  std::vector<double> off(n), diff(n, INFINITY);
  for (std::size_t i = 0; i < n; ++i) {
    ab[i] = frame.local((*points)[i].xyz);
    off[i] = frame.off((*points)[i].xyz);
  }
  const double r2 = std::pow(kSquareNeighbourSides * frame.side, 2);
  std::vector<double> near;
  for (std::size_t i = 0; i < n; ++i) {
    near.clear();
    for (std::size_t j = 0; j < n; ++j) {
      if (j != i && (ab[j] - ab[i]).squaredNorm() <= r2) near.push_back(off[j]);
    }
    if (near.size() < kSquareMinNeighbours) continue;
    std::nth_element(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(near.size() / 2), near.end());
    diff[i] = off[i] - near[near.size() / 2];
  }
  std::vector<double> abs_diff;
  for (double d : diff) {
    if (std::isfinite(d)) abs_diff.push_back(std::abs(d));
  }
  if (abs_diff.empty()) {
    points->clear();
    return;
  }
  std::nth_element(abs_diff.begin(), abs_diff.begin() + static_cast<std::ptrdiff_t>(abs_diff.size() / 2), abs_diff.end());
  const double limit = kSquareRejectSigmas * 1.4826 * abs_diff[abs_diff.size() / 2];
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(std::abs(diff[i]) <= limit)) continue;
    if (kept != i) (*points)[kept] = std::move((*points)[i]);
    ++kept;
  }
  points->resize(kept);
}

// The dense point of an accepted patch measured in reference photo `ref` (pose R, t; world
// X = R^T (x_ref - t)), whose cell is `spacing_px` wide.
DensePoint measured_point(const PatchResult& r, int ref, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double spacing_px,
                          double fx) {
  DensePoint dp;
  dp.xyz = R.transpose() * (r.point_ref - t);
  dp.normal = R.transpose() * (-r.plane.normalized());
  dp.footprint = spacing_px * r.point_ref.z() / fx;
  dp.seen_by = {ref};
  dp.seen_by.insert(dp.seen_by.end(), r.views.begin(), r.views.end());
  dp.sigma = r.sigma_along_ray;
  dp.views = static_cast<int>(r.views.size()) + 1;
  dp.ref = ref;
  dp.correlation = r.correlation;
  dp.reprojection_px = r.reprojection_px;
  dp.window_mm = r.half_window_px * r.point_ref.z() / fx;
  return dp;
}

// A value as a Float32 property holds it (write_ply refuses a value its type cannot store). Not
// inlined: GCC 12.2 at -O3 vectorised the round trip of two adjacent fields (a point's correlation
// and reprojection error) into one that kept the doubles, and write_ply refused them.
[[gnu::noinline]] double f32(double v) { return static_cast<double>(static_cast<float>(v)); }

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / M_PI;
}

}  // namespace

std::vector<int> free_space_violations(const std::vector<SurfaceSample>& pts, const std::vector<PatchView>& views,
                                       const geometry::CameraModel& cam, double gap_footprints, int threads) {
  threads = geometry::thread_count(threads);
  std::vector<int> count(pts.size(), 0);
  std::vector<Eigen::Vector3d> centres;
  for (const PatchView& v : views) centres.push_back(-v.rotation.transpose() * v.translation_mm);
  const double fx = cam.params[geometry::kFx];
  const geometry::ModelShape shape = geometry::shape_of(cam);
  constexpr double bucket_px = 4;
  const int bw = static_cast<int>(std::ceil(cam.width_px / bucket_px)) + 1;
  const int bh = static_cast<int>(std::ceil(cam.height_px / bucket_px)) + 1;
  struct Proj {
    double u = 0, v = 0, z = 0;
    bool ok = false;
  };
  std::vector<Proj> proj(pts.size());
  for (std::size_t j = 0; j < views.size(); ++j) {
    const Eigen::Matrix3d& R = views[j].rotation;
    const Eigen::Vector3d& t = views[j].translation_mm;
    const Eigen::Vector3d& C = centres[j];
    geometry::parallel_for(pts.size(), threads, [&](std::size_t i) {
      Proj& q = proj[i];
      const Eigen::Vector3d Xc = R * pts[i].xyz + t;
      q.ok = Xc.z() > 0;
      if (!q.ok) return;
      geometry::distort_to_pixel(shape, cam.params.data(), Xc.x() / Xc.z(), Xc.y() / Xc.z(), &q.u, &q.v);
      q.z = Xc.z();
      q.ok = q.u >= 0 && q.v >= 0 && q.u < cam.width_px && q.v < cam.height_px;
    });
    // The points view j matched, by bucket (counting sort).
    std::vector<int> start(static_cast<std::size_t>(bw) * bh + 1, 0);
    auto bucket = [&](const Proj& q) {
      return static_cast<int>(q.v / bucket_px) * bw + static_cast<int>(q.u / bucket_px);
    };
    std::vector<std::size_t> matched;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!proj[i].ok) continue;
      if (std::find(pts[i].seen_by.begin(), pts[i].seen_by.end(), static_cast<int>(j)) == pts[i].seen_by.end()) continue;
      matched.push_back(i);
      ++start[static_cast<std::size_t>(bucket(proj[i])) + 1];
    }
    for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
    std::vector<std::size_t> order(matched.size());
    {
      std::vector<int> fill(start.begin(), start.end() - 1);
      for (std::size_t i : matched) order[static_cast<std::size_t>(fill[static_cast<std::size_t>(bucket(proj[i]))]++)] = i;
    }
    geometry::parallel_for(pts.size(), threads, [&](std::size_t i) {
      const Proj& p = proj[i];
      if (!p.ok) return;
      const SurfaceSample& P = pts[i];
      const double reach_px = P.footprint * fx / p.z + 1;
      const int bx0 = std::max(0, static_cast<int>((p.u - reach_px) / bucket_px));
      const int bx1 = std::min(bw - 1, static_cast<int>((p.u + reach_px) / bucket_px));
      const int by0 = std::max(0, static_cast<int>((p.v - reach_px) / bucket_px));
      const int by1 = std::min(bh - 1, static_cast<int>((p.v + reach_px) / bucket_px));
      const double np = P.normal.dot(P.xyz - C);
      const double gap = gap_footprints * P.footprint;
      for (int by = by0; by <= by1; ++by) {
        for (int bx = bx0; bx <= bx1; ++bx) {
          const std::size_t b = static_cast<std::size_t>(by) * bw + bx;
          for (int k = start[b]; k < start[b + 1]; ++k) {
            const std::size_t qi = order[static_cast<std::size_t>(k)];
            if (qi == i || !(proj[qi].z > p.z)) continue;
            const Eigen::Vector3d d = pts[qi].xyz - C;
            const double nd = P.normal.dot(d);
            if (!(std::abs(nd) > 1e-12)) continue;
            const double s = np / nd;
            if (!(s > 0 && s < 1)) continue;
            if ((1 - s) * d.norm() <= gap) continue;
            if ((C + s * d - P.xyz).squaredNorm() > P.footprint * P.footprint) continue;
            ++count[i];
          }
        }
      }
    });
  }
  return count;
}


DensifyResult densify(const DensifyInputs& in, const DensifyOptions& o, const Progress& progress) {
  const std::size_t n_views = in.poses.size();
  if (in.photos.size() != n_views) throw std::logic_error("densify: one photo per pose");
  const geometry::CameraModel& cam = in.camera;
  DensifyResult result;
  result.references.resize(n_views);

  std::vector<PatchView> views(n_views);
  std::vector<Eigen::Vector3d> centres(n_views);
  for (std::size_t i = 0; i < n_views; ++i) {
    views[i].grey = in.photos[i];
    views[i].rotation = in.poses[i].rotation();
    views[i].translation_mm = in.poses[i].cam_from_world_translation_mm;
    centres[i] = in.poses[i].centre_mm();
  }

  // The box: given, or the sparse cloud's grown by box_margin.
  std::vector<Eigen::Vector3d> sparse;
  if (o.box) {
    result.box = *o.box;
    for (const auto& p : in.sparse.points_mm) {
      if (p.allFinite() && in_box(result.box, p)) sparse.push_back(p);
    }
  } else {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
    for (const auto& p : in.sparse.points_mm) {
      if (!p.allFinite()) continue;
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      sparse.push_back(p);
    }
    const Eigen::Vector3d grow = (hi - lo) * o.box_margin;
    result.box = {lo.x() - grow.x(), lo.y() - grow.y(), lo.z() - grow.z(), hi.x() + grow.x(), hi.y() + grow.y(), hi.z() + grow.z()};
  }
  if (sparse.empty()) {
    throw InputError(in.cloud_source, 0, "no point of the sparse cloud lies inside the box: nothing to seed the growth from");
  }
  // The scene's centre (median per axis) decides each reference's neighbour views.
  Eigen::Vector3d centre;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> v;
    v.reserve(sparse.size());
    for (const auto& p : sparse) v.push_back(p[a]);
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    centre[a] = v[v.size() / 2];
  }

  // Masks per photo.
  std::vector<std::vector<const Observation*>> obs_of(n_views);
  {
    std::map<std::string, std::size_t> index;
    for (std::size_t i = 0; i < n_views; ++i) index[in.poses[i].image] = i;
    for (const auto& ob : in.observations) {
      if (const auto it = index.find(ob.image); it != index.end()) obs_of[it->second].push_back(&ob);
    }
  }

  // The markers each photo shows, masked: those its observations show whole, and every other
  // marker whose corners are known in space (seen in other photos) projected into it. A marker
  // the detector missed in one photo (too oblique, blurred, partly hidden) would otherwise be
  // measured there as surface: a printed square lying flat on the part, not the part.
  std::vector<std::vector<Quad>> quads_of(n_views);
  std::vector<std::map<PointId, Quad>> detected_quads(n_views);  // the markers detect found whole in each photo
  const auto corners_from_rays = marker_corners_in_space(obs_of, views, cam, kMarkerMinAngleDeg);
  {
    const auto& corners = corners_from_rays;
    std::set<PointId> markers;
    for (const auto& [id, X] : corners) {
      if (whole_marker(corners, id / 4)) markers.insert(id / 4);
    }
    const double* k = cam.params.data();
    const geometry::ModelShape shape = geometry::shape_of(cam);
    for (std::size_t i = 0; i < n_views; ++i) {
      std::map<PointId, Quad> quads = observed_quads(obs_of[i]);
      detected_quads[i] = quads;
      for (PointId m : markers) {
        if (quads.count(m)) continue;
        Quad q;
        bool in_front = true;
        for (int c = 0; c < 4 && in_front; ++c) {
          const Eigen::Vector3d Xc = views[i].rotation * corners.at(m * 4 + c) + views[i].translation_mm;
          in_front = Xc.z() > 0;
          if (in_front) geometry::distort_to_pixel(shape, k, Xc.x() / Xc.z(), Xc.y() / Xc.z(), &q[c].x(), &q[c].y());
        }
        if (in_front) {
          quads[m] = q;
          ++result.markers_projected;
        }
      }
      for (const auto& [m, q] : quads) quads_of[i].push_back(q);
    }
  }

  const PatchMatcher matcher(cam, o.patch);
  const double s = o.spacing_px;
  const int threads = geometry::thread_count(o.threads);
  std::vector<DensePoint> points;

  for (std::size_t ref = 0; ref < n_views; ++ref) {
    ReferenceStats& st = result.references[ref];
    const cv::Mat& f = views[ref].grey;
    const Eigen::Matrix3d& R = views[ref].rotation;
    const Eigen::Vector3d& t = views[ref].translation_mm;
    // Neighbours: nearest first by the angle at the scene's centre, within the angle range.
    {
      std::vector<std::pair<double, int>> by_angle;
      for (std::size_t j = 0; j < n_views; ++j) {
        if (j == ref) continue;
        const double a = angle_deg(centres[ref] - centre, centres[j] - centre);
        if (a >= o.min_angle_deg && a <= o.max_angle_deg) by_angle.emplace_back(a, static_cast<int>(j));
      }
      std::sort(by_angle.begin(), by_angle.end());
      for (const auto& [a, j] : by_angle) {
        if (static_cast<int>(st.neighbours.size()) < o.max_views) st.neighbours.push_back(j);
      }
    }
    if (static_cast<int>(st.neighbours.size()) < o.patch.min_views - 1) {
      if (progress) progress("photo " + in.poses[ref].image + ": too few neighbour views, not a reference");
      continue;
    }
    const cv::Mat mask = marker_mask(quads_of[ref], f.cols, f.rows, o.marker_margin);
    const int gw = static_cast<int>(f.cols / s), gh = static_cast<int>(f.rows / s);
    std::vector<Cell> cells(static_cast<std::size_t>(gw) * gh);
    auto cell_centre = [&](int c) {
      return Eigen::Vector2i(static_cast<int>(std::lround((c % gw + 0.5) * s - 0.5)), static_cast<int>(std::lround((c / gw + 0.5) * s - 0.5)));
    };
    auto cell_of = [&](const Eigen::Vector2d& px) -> int {
      const int cx = static_cast<int>(std::floor((px.x() + 0.5) / s)), cy = static_cast<int>(std::floor((px.y() + 0.5) / s));
      if (cx < 0 || cy < 0 || cx >= gw || cy >= gh) return -1;
      return cy * gw + cx;
    };
    auto project = [&](const Eigen::Vector3d& X, Eigen::Vector3d* Xc) -> std::optional<Eigen::Vector2d> {
      *Xc = R * X + t;
      if (!(Xc->z() > 0)) return std::nullopt;
      double u, v;
      geometry::distort_to_pixel(geometry::shape_of(cam), cam.params.data(), Xc->x() / Xc->z(), Xc->y() / Xc->z(), &u, &v);
      return Eigen::Vector2d(u, v);
    };
    // Cells holding a point of an earlier reference (facing this camera).
    for (const DensePoint& p : points) {
      Eigen::Vector3d Xc;
      const auto px = project(p.xyz, &Xc);
      if (!px) continue;
      if (!(p.normal.dot(centres[ref] - p.xyz) > 0)) continue;
      const int c = cell_of(*px);
      if (c < 0 || cells[c].state != CellState::Empty) continue;
      const auto plane = plane_in_camera(R, t, p.xyz, p.normal);
      if (!plane) continue;
      cells[c].state = CellState::Occupied;
      cells[c].plane = *plane;
      cells[c].correlation = static_cast<float>(p.correlation);
      ++st.occupied;
    }
    // Seeds: the sparse points seen in this photo, each with the plane facing the camera.
    const int tiles_x = (gw + o.tile_cells - 1) / o.tile_cells, tiles_y = (gh + o.tile_cells - 1) / o.tile_cells;
    auto tile_of = [&](int c) { return (c / gw) / o.tile_cells * tiles_x + (c % gw) / o.tile_cells; };
    std::vector<std::vector<Candidate>> seeds(static_cast<std::size_t>(tiles_x) * tiles_y);
    for (const auto& X : sparse) {
      Eigen::Vector3d Xc;
      const auto px = project(X, &Xc);
      if (!px) continue;
      const int c = cell_of(*px);
      if (c < 0) continue;
      seeds[tile_of(c)].push_back({-1.0, c, Xc / Xc.squaredNorm()});
      ++st.seeds;
    }

    // Grows the cells of one tile from its candidates; returns the tile's accepted points.
    struct TileOut {
      std::vector<DensePoint> points;
      ReferenceStats stats;
    };
    auto grow = [&](int tile, std::vector<Candidate> start, TileOut* out) {
      const int tx0 = (tile % tiles_x) * o.tile_cells, ty0 = (tile / tiles_x) * o.tile_cells;
      const int tx1 = std::min(gw, tx0 + o.tile_cells), ty1 = std::min(gh, ty0 + o.tile_cells);
      std::priority_queue<Candidate> queue(std::less<Candidate>(), std::move(start));
      auto propose = [&](int c, const Eigen::Vector3d& plane, double priority) {
        const int cx = c % gw, cy = c / gw;
        const int nb[4][2] = {{cx - 1, cy}, {cx + 1, cy}, {cx, cy - 1}, {cx, cy + 1}};
        for (const auto& q : nb) {
          if (q[0] < tx0 || q[1] < ty0 || q[0] >= tx1 || q[1] >= ty1) continue;
          const int nc = q[1] * gw + q[0];
          if (cells[nc].state == CellState::Done || cells[nc].attempts >= o.max_attempts) continue;
          queue.push({priority, nc, plane});
        }
      };
      PatchResult r;
      while (!queue.empty()) {
        const Candidate cand = queue.top();
        queue.pop();
        Cell& cell = cells[cand.cell];
        if (cell.state == CellState::Done || cell.attempts >= o.max_attempts) continue;
        const Eigen::Vector2i px = cell_centre(cand.cell);
        if (cell.state == CellState::Occupied) {
          if (!cell.expanded) {
            cell.expanded = true;
            propose(cand.cell, cell.plane, cell.correlation);
          }
          // Measured again only if the candidate lies well in front of the earlier point (which
          // the reference may not see).
          const auto ray = geometry::undistort(cam, px.cast<double>());
          if (!ray) continue;
          const Eigen::Vector3d r(ray->x(), ray->y(), 1);
          if (!(cand.plane.dot(r) > cell.plane.dot(r) * 1.02)) continue;
        }
        if (mask.at<unsigned char>(px.y(), px.x()) == 0) {
          cell.attempts = static_cast<unsigned char>(o.max_attempts);
          continue;
        }
        ++cell.attempts;
        ++out->stats.measured;
        const PatchFailure why = matcher.measure(views, static_cast<int>(ref), px, cand.plane, st.neighbours, &r);
        if (why != PatchFailure::None) {
          ++out->stats.failures[static_cast<std::size_t>(why)];
          // A window across a crease: the faces on either side (its quadrants' planes) are
          // proposed to the neighbours, after every plane of an accepted patch, so that the
          // growth carries on past the crease (from a wall's top onto its face).
          if (why == PatchFailure::Bent) {
            for (const Eigen::Vector3d& plane : r.bend_planes) propose(cand.cell, plane, r.correlation - 1);
          }
          continue;
        }
        const Eigen::Vector3d X = R.transpose() * (r.point_ref - t);
        if (!in_box(result.box, X)) {
          ++out->stats.outside_box;
          cell.attempts = static_cast<unsigned char>(o.max_attempts);
          continue;
        }
        cell.state = CellState::Done;
        cell.plane = r.plane;
        cell.correlation = static_cast<float>(r.correlation);
        ++out->stats.accepted;
        out->points.push_back(measured_point(r, static_cast<int>(ref), R, t, s, cam.params[geometry::kFx]));
        propose(cand.cell, r.plane, r.correlation);
      }
    };
    const int n_tiles = tiles_x * tiles_y;
    std::vector<TileOut> outs(static_cast<std::size_t>(n_tiles));
    geometry::parallel_for(static_cast<std::size_t>(n_tiles), threads,
                           [&](std::size_t k) { grow(static_cast<int>(k), std::move(seeds[k]), &outs[k]); });
    // Second pass: each empty cell beside a measured cell of another tile starts from its plane.
    std::vector<std::vector<Candidate>> border(static_cast<std::size_t>(n_tiles));
    for (int c = 0; c < gw * gh; ++c) {
      if (cells[c].state == CellState::Done || cells[c].attempts >= o.max_attempts) continue;
      const int cx = c % gw, cy = c / gw;
      const int nb[4][2] = {{cx - 1, cy}, {cx + 1, cy}, {cx, cy - 1}, {cx, cy + 1}};
      for (const auto& q : nb) {
        if (q[0] < 0 || q[1] < 0 || q[0] >= gw || q[1] >= gh) continue;
        const int nc = q[1] * gw + q[0];
        if (tile_of(nc) == tile_of(c) || cells[nc].state == CellState::Empty) continue;
        border[tile_of(c)].push_back({cells[nc].correlation, c, cells[nc].plane});
      }
    }
    std::vector<TileOut> outs2(static_cast<std::size_t>(n_tiles));
    geometry::parallel_for(static_cast<std::size_t>(n_tiles), threads, [&](std::size_t k) {
      if (!border[k].empty()) grow(static_cast<int>(k), std::move(border[k]), &outs2[k]);
    });
    for (auto* pass : {&outs, &outs2}) {
      for (TileOut& to : *pass) {
        points.insert(points.end(), to.points.begin(), to.points.end());
        st.measured += to.stats.measured;
        st.accepted += to.stats.accepted;
        st.outside_box += to.stats.outside_box;
        for (std::size_t k = 0; k < st.failures.size(); ++k) st.failures[k] += to.stats.failures[k];
      }
    }
    if (progress) {
      progress("reference " + std::to_string(ref + 1) + " of " + std::to_string(n_views) + " (" + in.poses[ref].image +
               "): " + std::to_string(st.accepted) + " points of " + std::to_string(st.measured) + " patches measured, " +
               std::to_string(points.size()) + " in all");
    }
  }
  // The markers' printed squares, measured rather than grown into: their cells repeat every few
  // pixels, and growth reaching a square from the part can lock a window one cell off. Each
  // marker whose four corners are known (best_marker_corners) is measured from the
  // marker_square_views photos that detected it most squarely: every cell inside its square in
  // that photo starts from the surface predicted under it (MarkerFrame, from its corners and the
  // dense points around it), and its point is kept only within marker_square_tolerance sides of
  // that prediction along the marker's normal (a window one cell off lands the point a cell's
  // width or more from it along the ray).
  auto measure_marker_squares = [&]() {
    // The window: marker_square_window of the marker's side in the reference photo, at least the
    // growth's (a window of one or two cells of the pattern often sees one edge only).
    const auto half_window = [&](const Quad& q) {
      double side = 0;
      for (std::size_t e = 0; e < 4; ++e) side += (q[(e + 1) % 4] - q[e]).norm() / 4;
      return std::clamp(static_cast<int>(std::lround(o.marker_square_window * side)), o.patch.half_window_px,
                        std::max(o.patch.half_window_px, kSquareMaxHalfWindowPx));
    };
    std::map<int, PatchMatcher> matchers;
    for (const auto& quads : detected_quads) {
      for (const auto& [m, q] : quads) {
        const int h = half_window(q);
        if (matchers.count(h)) continue;
        PatchOptions po = o.patch;
        po.half_window_px = h;
        matchers.emplace(h, PatchMatcher(cam, po));
      }
    }
    const auto corners = best_marker_corners(in.sparse, corners_from_rays);
    Eigen::Vector3d eye = Eigen::Vector3d::Zero();
    for (const auto& c : centres) eye += c / static_cast<double>(n_views);
    std::vector<PointId> markers;
    for (const auto& [id, X] : corners) {
      if (id % 4 == 0) markers.push_back(id / 4);
    }
    std::vector<Eigen::Vector3d> dense;
    dense.reserve(points.size());
    for (const DensePoint& p : points) dense.push_back(p.xyz);
    std::vector<std::vector<DensePoint>> outs(markers.size());
    std::atomic<std::size_t> measured{0}, unpredicted{0};
    geometry::parallel_for(markers.size(), threads, [&](std::size_t k) {
      const PointId m = markers[k];
      std::array<Eigen::Vector3d, 4> c;
      for (PointId i = 0; i < 4; ++i) c[static_cast<std::size_t>(i)] = corners.at(m * 4 + i);
      if (!in_box(result.box, (c[0] + c[1] + c[2] + c[3]) / 4)) return;
      const auto frame = marker_frame(c, eye, dense, o.marker_square_tolerance);
      if (!frame) {
        ++unpredicted;
        return;
      }
      std::vector<std::pair<double, std::size_t>> refs;
      for (std::size_t i = 0; i < n_views; ++i) {
        if (!detected_quads[i].count(m)) continue;
        if (static_cast<int>(result.references[i].neighbours.size()) < o.patch.min_views - 1) continue;
        refs.emplace_back(-frame->n.dot((centres[i] - frame->centre).normalized()), i);
      }
      std::sort(refs.begin(), refs.end());
      if (refs.size() > static_cast<std::size_t>(o.marker_square_views)) refs.resize(static_cast<std::size_t>(o.marker_square_views));
      if (!refs.empty()) ++measured;
      PatchResult r;
      for (const auto& [unused, ref] : refs) {
        const Quad& q = detected_quads[ref].at(m);
        const PatchMatcher& sq_matcher = matchers.at(half_window(q));
        const Eigen::Matrix3d& R = views[ref].rotation;
        const Eigen::Vector3d& t = views[ref].translation_mm;
        const int cols = views[ref].grey.cols, rows = views[ref].grey.rows;
        const int gw = static_cast<int>(cols / s), gh = static_cast<int>(rows / s);
        double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
        for (const auto& v : q) {
          x0 = std::min(x0, v.x()), x1 = std::max(x1, v.x()), y0 = std::min(y0, v.y()), y1 = std::max(y1, v.y());
        }
        // Inside the (convex) quad: on the same side of its four edges.
        const auto inside = [&](const Eigen::Vector2d& p) {
          int pos = 0, neg = 0;
          for (std::size_t e = 0; e < 4; ++e) {
            const Eigen::Vector2d a = q[e], b = q[(e + 1) % 4];
            const double z = (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x();
            pos += z > 0, neg += z < 0;
          }
          return pos == 0 || neg == 0;
        };
        const int cx0 = std::max(0, static_cast<int>(std::floor(x0 / s))), cx1 = std::min(gw - 1, static_cast<int>(std::ceil(x1 / s)));
        const int cy0 = std::max(0, static_cast<int>(std::floor(y0 / s))), cy1 = std::min(gh - 1, static_cast<int>(std::ceil(y1 / s)));
        for (int cy = cy0; cy <= cy1; ++cy) {
          for (int cx = cx0; cx <= cx1; ++cx) {
            const Eigen::Vector2i px(static_cast<int>(std::lround((cx + 0.5) * s - 0.5)), static_cast<int>(std::lround((cy + 0.5) * s - 0.5)));
            if (!inside(px.cast<double>())) continue;
            const auto ray = geometry::undistort(cam, px.cast<double>());
            if (!ray) continue;
            // Where the pixel's ray meets the predicted surface: meet its tangent plane, a few times.
            const Eigen::Vector3d d = R.transpose() * Eigen::Vector3d(ray->x(), ray->y(), 1);
            const Eigen::Vector3d& C = centres[ref];
            Eigen::Vector3d X = frame->centre, N = frame->n;
            for (int it = 0; it < 4; ++it) {
              const double along = N.dot(X - C) / N.dot(d);
              if (!(along > 0) || !std::isfinite(along)) break;
              const Eigen::Vector2d ab = frame->local(C + along * d);
              X = frame->point(ab.x(), ab.y());
              N = frame->normal(ab.x(), ab.y());
            }
            const auto plane = plane_in_camera(R, t, X, N);
            if (!plane) continue;
            if (sq_matcher.measure(views, static_cast<int>(ref), px, *plane, result.references[ref].neighbours, &r) != PatchFailure::None) continue;
            DensePoint dp = measured_point(r, static_cast<int>(ref), R, t, s, cam.params[geometry::kFx]);
            if (!in_box(result.box, dp.xyz) || std::abs(frame->off(dp.xyz)) > o.marker_square_tolerance * frame->side) continue;
            outs[k].push_back(std::move(dp));
          }
        }
      }
      reject_unlike_neighbours(*frame, &outs[k]);
    });
    for (auto& out : outs) {
      result.marker_square_points += out.size();
      points.insert(points.end(), out.begin(), out.end());
    }
    result.marker_squares_measured = measured;
    result.marker_squares_unpredicted = unpredicted;
    if (progress) {
      progress("markers' printed squares: " + std::to_string(result.marker_square_points) + " points on " +
               std::to_string(result.marker_squares_measured) + " markers (" + std::to_string(result.marker_squares_unpredicted) +
               " in the box with too few points around them to predict the surface under them: not measured)");
    }
  };
  if (o.marker_squares && !points.empty()) measure_marker_squares();
  if (o.free_space_min_violations > 0 && !points.empty()) {
    const std::vector<int> violations = free_space_violations(std::vector<SurfaceSample>(points.begin(), points.end()), views, cam,
                                                              o.free_space_gap_footprints, threads);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (violations[i] >= o.free_space_min_violations) {
        ++result.references[static_cast<std::size_t>(points[i].ref)].free_space;
        ++result.free_space_removed;
        continue;
      }
      if (kept != i) points[kept] = std::move(points[i]);
      ++kept;
    }
    points.resize(kept);
    if (progress) {
      progress("free-space check: " + std::to_string(result.free_space_removed) +
               " points removed (in front of a surface a view saw behind them)");
    }
  }
  if (points.empty()) {
    if (result.free_space_removed > 0) {
      throw InputError(in.poses_source, 0,
                       "the free-space check removed all " + std::to_string(result.free_space_removed) +
                           " points (each lies in front of a surface a view saw behind it): the poses may not fit "
                           "the photos; --free-space-min-violations 0 turns the check off");
    }
    throw InputError(in.poses_source, 0,
                     "no patch was accepted in any photo: the photos may not match their poses or camera, or the "
                     "surface has no texture (see the refusals above with -v)");
  }

  if (o.marker_corners) {
    const auto corners = marker_corner_points(in.sparse, result.box, centres, obs_of);
    result.marker_corners = corners.size();
    points.insert(points.end(), corners.begin(), corners.end());
  }

  PointCloud& cloud = result.cloud;
  cloud.units = in.sparse.units;
  cloud.points_mm.reserve(points.size());
  for (const char* name : {"nx", "ny", "nz"}) cloud.add_property(name, PlyScalar::Float32);
  cloud.add_property("scalar_sigma_mm", PlyScalar::Float32);
  cloud.add_property("scalar_views", PlyScalar::UInt8);
  cloud.add_property("scalar_ref_image", PlyScalar::UInt16);
  cloud.add_property("scalar_correlation", PlyScalar::Float32);
  cloud.add_property("scalar_reprojection_px", PlyScalar::Float32);
  cloud.add_property("scalar_marker_corner", PlyScalar::UInt8);
  cloud.add_property("scalar_window_mm", PlyScalar::Float32);
  for (auto& p : cloud.properties) p.values.reserve(points.size());
  for (const DensePoint& p : points) {
    cloud.points_mm.push_back(p.xyz);
    const double vals[10] = {f32(p.normal.x()), f32(p.normal.y()), f32(p.normal.z()), f32(p.sigma), static_cast<double>(p.views),
                             static_cast<double>(p.ref), f32(p.correlation), f32(p.reprojection_px),
                             p.marker_corner ? 1.0 : 0.0, f32(p.window_mm)};
    for (std::size_t k = 0; k < 10; ++k) cloud.properties[k].values.push_back(vals[k]);
  }
  return result;
}

}  // namespace photomill::densify
