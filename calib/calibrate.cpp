// calib's pipeline: views from observations, method choice, calibration with outlier-view
// rejection, uncertainties and geometry warnings (see calibrate.hpp).
#include "calib/calibrate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <unordered_map>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/init.hpp"
#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/image_decode.hpp"
#include "geometry/linear_algebra.hpp"

namespace photomill::calib {
namespace {

std::string fmt(double v, int precision = 3) {
  std::ostringstream s;
  s.precision(precision);
  s << std::fixed << v;
  return s.str();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Eigen::Matrix3d rotation_of(const std::array<double, kPose>& pose) {
  const Eigen::Vector3d r(pose[0], pose[1], pose[2]);
  const double a = r.norm();
  return a < 1e-15 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, r / a).toRotationMatrix();
}

// Groups observations by image (in order of first appearance) and pairs them with control points.
std::vector<View> make_views(const std::vector<Observation>& observations, const std::vector<ControlPoint>& control,
                             std::size_t& unmatched) {
  std::unordered_map<PointId, Eigen::Vector3d> xyz;
  for (const auto& c : control) xyz.emplace(c.point_id, c.xyz_mm);
  std::vector<View> views;
  std::map<std::string, std::size_t> index;
  unmatched = 0;
  for (const auto& o : observations) {
    const auto it = xyz.find(o.point_id);
    if (it == xyz.end()) {
      ++unmatched;
      continue;
    }
    auto [pos, inserted] = index.emplace(o.image, views.size());
    if (inserted) views.push_back(View{o.image, {}, {}, {}});
    View& v = views[pos->second];
    v.ids.push_back(o.point_id);
    v.world_mm.push_back(it->second);
    v.observed_px.emplace_back(o.u_px, o.v_px);
  }
  return views;
}

// A rigid transform taking coplanar points onto z = 0 (identity when they already are there).
Eigen::Isometry3d plane_from_world(const std::vector<View>& views) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> pts;
  bool all_zero = true;
  for (const auto& v : views) {
    for (const auto& p : v.world_mm) {
      pts.push_back(p);
      all_zero = all_zero && p.z() == 0;
    }
  }
  if (all_zero || pts.size() < 3) return T;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  Eigen::MatrixXd A(pts.size(), 3);
  for (std::size_t i = 0; i < pts.size(); ++i) A.row(static_cast<Eigen::Index>(i)) = (pts[i] - c).transpose();
  Eigen::Matrix3d B = geometry::svd(A, Eigen::ComputeThinV).V;
  if (B.determinant() < 0) B.col(2) *= -1;
  T.linear() = B.transpose();
  T.translation() = -B.transpose() * c;
  return T;
}

// Do the board points of a view span two dimensions (not all on one line)?
bool spans_plane(const View& v) {
  std::vector<Eigen::Vector3d> p = v.world_mm;
  for (auto& q : p) q.z() = 0;
  if (p.size() < 3) return false;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& q : p) c += q;
  c /= static_cast<double>(p.size());
  Eigen::MatrixXd A(p.size(), 2);
  for (std::size_t i = 0; i < p.size(); ++i) A.row(static_cast<Eigen::Index>(i)) = (p[i] - c).head<2>().transpose();
  const Eigen::Vector2d s = geometry::singular_values(A);
  return s(0) > 0 && s(1) / s(0) > 1e-3;
}

struct Solved {
  Parameters params;
  RefineStats stats;
};

Solved solve(const std::vector<View>& views, Method method, Optimizer optimizer, cv::Size size,
             const CalibOptions& o, std::vector<std::string>& notes) {
  Solved s;
  if (optimizer == Optimizer::OpenCv && method == Method::Planar) {
    s.stats = refine_opencv(views, o.model, o.lm, size, false, s.params);
  } else {
    s.params = method == Method::Planar ? initial_from_plane(views, o.model, size)
                                        : initial_from_dlt(views, o.model, size, o.dlt_min_flatness, &notes);
    switch (optimizer) {
      case Optimizer::OpenCv: s.stats = refine_opencv(views, o.model, o.lm, size, true, s.params); break;
      case Optimizer::Simplex: s.stats = refine_simplex(views, o.model, o.simplex, size, s.params); break;
      default: s.stats = refine_lm(views, o.model, o.lm, s.params); break;
    }
  }
  const auto& k = s.params.intrinsics;
  bool finite = std::isfinite(s.stats.final_rms_px);
  for (double v : k) finite = finite && std::isfinite(v);
  for (double v : s.params.distortion) finite = finite && std::isfinite(v);
  if (!finite || !(k[0] > 0) || !(k[1] > 0)) {
    throw GeometryError("the calibration diverged (focal length " + fmt(k[0]) +
                        " px): the views do not constrain the camera; add views at different angles");
  }
  return s;
}

Camera to_camera(const Parameters& p, cv::Size size, const ModelOptions& model, double rms_px) {
  Camera c;
  c.image_width_px = size.width;
  c.image_height_px = size.height;
  c.camera_matrix = camera_matrix(p);
  c.distortion.assign(p.distortion.begin(), p.distortion.begin() + (model.rational ? 8 : 5));
  c.avg_reprojection_error_px = rms_px;
  return c;
}

double view_rms(const std::vector<Eigen::Vector2d>& r) {
  double s = 0;
  for (const auto& e : r) s += e.squaredNorm();
  return r.empty() ? 0.0 : std::sqrt(s / static_cast<double>(r.size()));
}

// Pose of a view that was left out, with the final camera: PnP with distortion.
std::array<double, kPose> pose_with_camera(const View& v, const Parameters& p, const ModelOptions& model) {
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (std::size_t i = 0; i < v.world_mm.size(); ++i) {
    obj.emplace_back(v.world_mm[i].x(), v.world_mm[i].y(), v.world_mm[i].z());
    img.emplace_back(v.observed_px[i].x(), v.observed_px[i].y());
  }
  const double fy = model.fix_aspect_ratio ? p.intrinsics[0] : p.intrinsics[1];
  const cv::Matx33d K(p.intrinsics[0], 0, p.intrinsics[2], 0, fy, p.intrinsics[3], 0, 0, 1);
  const std::vector<double> d(p.distortion.begin(), p.distortion.end());
  cv::Vec3d r;
  cv::Vec3d t;
  try {
    cv::solvePnP(obj, img, K, d, r, t, false, cv::SOLVEPNP_SQPNP);
    cv::solvePnP(obj, img, K, d, r, t, true, cv::SOLVEPNP_ITERATIVE);
  } catch (const cv::Exception& e) {
    throw GeometryError(v.image + ": no camera pose fits its control points (" + e.err + ")");
  }
  return {r[0], r[1], r[2], t[0], t[1], t[2]};
}

Pose to_pose(const std::string& image, const std::array<double, kPose>& pose, const Eigen::Isometry3d& plane_from_world) {
  // x_cam = R X_plane + t and X_plane = A X_world + b  =>  x_cam = (R A) X_world + (R b + t).
  const Eigen::Matrix3d R = rotation_of(pose) * plane_from_world.linear();
  const Eigen::Vector3d t = rotation_of(pose) * plane_from_world.translation() + Eigen::Vector3d(pose[3], pose[4], pose[5]);
  Pose out;
  out.image = image;
  out.cam_from_world_rotation = Eigen::Quaterniond(R).normalized();
  out.cam_from_world_translation_mm = t;
  return out;
}

double coverage(const std::vector<View>& views, cv::Size size) {
  std::vector<cv::Point2f> pts;
  for (const auto& v : views) {
    for (const auto& p : v.observed_px) pts.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
  if (pts.size() < 3) return 0;
  std::vector<cv::Point2f> hull;
  cv::convexHull(pts, hull);
  return cv::contourArea(hull) / (static_cast<double>(size.width) * size.height);
}

// "k3 = 1.79 +- 1.02": a camera parameter by its report name, with its standard deviation.
std::string parameter_with_sigma(const CalibResult& r, const std::string& name) {
  const auto& u = r.uncertainty;
  const auto& c = r.camera;
  for (int i = 0; i < kIntrinsics; ++i) {
    if (intrinsic_names()[i] != name) continue;
    const double value[kIntrinsics] = {c.fx(), c.fy(), c.cx(), c.cy()};
    return name + " = " + fmt(value[i], 2) + " +- " + fmt(u.intrinsics_sigma[i], 2) + " px";
  }
  for (std::size_t i = 0; i < c.distortion.size() && i < static_cast<std::size_t>(kDistortion); ++i) {
    if (distortion_names()[i] == name) return name + " = " + fmt(c.distortion[i], 3) + " +- " + fmt(u.distortion_sigma[i], 3);
  }
  return name;
}

// `normals`: the board normal of every kept view in its camera frame (boards only).
void add_geometry_warnings(const CalibOptions& o, cv::Size size, Method method, const std::vector<View>& used,
                           const std::vector<Eigen::Vector3d>& normals, CalibResult& r) {
  auto& w = r.warnings;
  const int n = static_cast<int>(used.size());
  if (n < o.min_views) {
    w.push_back("only " + std::to_string(n) + " view" + (n == 1 ? "" : "s") + " used: " +
                (method == Method::Planar
                     ? "Zhang's method needs 3 or more views of a plane to fix all intrinsics"
                     : "intrinsics and distortion are weakly separated from the poses") +
                "; add views from other directions");
  }
  if (method == Method::Planar) {
    double max_tilt = 0;
    double max_between = 0;
    for (const auto& v : r.views) {
      if (!v.rejected) max_tilt = std::max(max_tilt, v.tilt_deg);
    }
    for (std::size_t i = 0; i < normals.size(); ++i) {
      for (std::size_t j = i + 1; j < normals.size(); ++j) {
        const double c = std::clamp(normals[i].dot(normals[j]), -1.0, 1.0);
        max_between = std::max(max_between, std::acos(c) * 180 / std::numbers::pi);
      }
    }
    if (max_tilt < o.min_tilt_deg) {
      w.push_back("all views are nearly fronto-parallel (largest tilt " + fmt(max_tilt, 1) +
                  " deg): focal length and principal point are poorly constrained; tilt the board 20-45 deg");
    } else if (n > 1 && max_between < o.min_tilt_deg) {
      w.push_back("every view sees the board at the same orientation (normals within " + fmt(max_between, 1) +
                  " deg): planes parallel to each other do not constrain the intrinsics (Zhang 2000, degenerate configurations)");
    }
  }
  const auto& u = r.uncertainty;
  if (!u.undetermined.empty()) {
    std::string names;
    for (const auto& s : u.undetermined) names += (names.empty() ? "" : ", ") + s;
    w.push_back("the data do not determine " + names + "; fix them (e.g. --fix-principal-point, --fix-k3) or add views");
  }
  const double diag = std::hypot(size.width, size.height);
  const double pp_sigma = std::max(u.intrinsics_sigma[2], u.intrinsics_sigma[3]);
  if (!o.model.fix_principal_point && pp_sigma > o.max_principal_point_sigma * diag) {
    w.push_back("principal point unobservable: sigma cx = " + fmt(u.intrinsics_sigma[2], 1) + " px, sigma cy = " +
                fmt(u.intrinsics_sigma[3], 1) + " px; add views tilted about both axes, or --fix-principal-point");
  }
  const double f_rel = u.intrinsics_sigma[0] / r.camera.fx();
  if (f_rel > o.max_focal_sigma) {
    w.push_back("focal length poorly determined: sigma fx = " + fmt(100 * f_rel, 2) + " %");
  }
  if (!std::isfinite(u.projection_sigma_corners_px)) {
    w.push_back("the fitted distortion folds over before the image corners (no ray projects there): the points cover " +
                fmt(100 * r.coverage, 0) + " % of the image; add photos with the board in the corners and along the edges" +
                (!o.model.fix_k3 ? ", or --fix-k3" : ""));
  } else if (u.projection_sigma_corners_px > o.max_corner_sigma_px) {
    w.push_back("the camera is uncertain towards the image corners: a ray there projects with sigma " +
                fmt(u.projection_sigma_corners_px, 2) + " px (" + fmt(u.projection_sigma_centre_px, 2) +
                " px at the centre, " + fmt(u.projection_sigma_edges_px, 2) + " px at the edges), mostly from " +
                parameter_with_sigma(r, u.corner_sigma_parameter) + " (" + fmt(u.corner_sigma_parameter_px, 2) +
                " px there); the points cover " +
                fmt(100 * r.coverage, 0) + " % of the image: add photos with the board in the corners and along the edges" +
                (u.corner_sigma_parameter == "k3" && !o.model.fix_k3 ? ", or --fix-k3" : ""));
  }
  if (r.coverage < o.min_coverage) {
    w.push_back("the points cover only " + fmt(100 * r.coverage, 0) +
                " % of the image: distortion is extrapolated towards the edges; add views with the board near the borders");
  }
  if (!r.stats.converged) w.push_back("the optimiser did not converge: " + r.stats.message);
}

}  // namespace

std::string to_string(Method m) {
  switch (m) {
    case Method::Planar: return "planar";
    case Method::Dlt: return "dlt";
    default: return "auto";
  }
}

std::string to_string(Optimizer o) {
  switch (o) {
    case Optimizer::OpenCv: return "opencv";
    case Optimizer::Lm: return "lm";
    case Optimizer::Simplex: return "simplex";
    default: return "auto";
  }
}

CalibResult calibrate(const std::vector<Observation>& observations, const std::vector<ControlPoint>& control,
                      cv::Size size, const CalibOptions& o) {
  if (size.width <= 0 || size.height <= 0) throw UsageError("the image size must be positive");
  CalibResult r;
  std::vector<View> all = make_views(observations, control, r.unmatched_observations);
  if (all.empty()) {
    throw GeometryError("no observation refers to a control point (" + std::to_string(observations.size()) +
                        " observations, " + std::to_string(control.size()) + " control points): check the point ids");
  }
  // Method: coplanar control points make a board.
  std::vector<Eigen::Vector3d> used_points;
  for (const auto& v : all) used_points.insert(used_points.end(), v.world_mm.begin(), v.world_mm.end());
  const double flat = flatness(used_points);
  r.method = o.method == Method::Auto ? (flat < o.coplanar_tolerance ? Method::Planar : Method::Dlt) : o.method;
  if (r.method == Method::Planar && flat >= o.coplanar_tolerance) {
    throw GeometryError("the control points are not coplanar (flatness " + fmt(flat, 4) +
                        "): the planar method needs a board; use --method dlt");
  }
  r.optimizer = o.optimizer == Optimizer::Auto ? (r.method == Method::Planar ? Optimizer::OpenCv : Optimizer::Lm)
                                               : o.optimizer;
  const Eigen::Isometry3d to_plane =
      r.method == Method::Planar ? plane_from_world(all) : Eigen::Isometry3d::Identity();
  // Views with too few points (or, on a board, all on one line) are skipped.
  std::vector<View> views;
  for (auto& v : all) {
    for (auto& p : v.world_mm) p = to_plane * p;
    const bool enough = static_cast<int>(v.ids.size()) >= std::max(o.min_points_per_view, 4);
    if (!enough || (r.method == Method::Planar && !spans_plane(v))) {
      r.skipped_views.push_back(v.image + " (" + std::to_string(v.ids.size()) + " points" +
                                (enough ? ", all on one line" : "") + ")");
    } else {
      views.push_back(std::move(v));
    }
  }
  if (views.empty()) {
    throw GeometryError("no view has the " + std::to_string(std::max(o.min_points_per_view, 4)) +
                        " control points a view needs (" + std::to_string(all.size()) + " views seen)");
  }
  // Calibrate; reject the worst view while it is an outlier; recalibrate.
  std::vector<bool> rejected(views.size(), false);
  std::vector<std::string> reasons(views.size());
  std::vector<double> first_rms(views.size(), 0);
  Solved s;
  std::vector<std::size_t> active;
  for (bool first = true;; first = false) {
    active.clear();
    std::vector<View> used;
    for (std::size_t i = 0; i < views.size(); ++i) {
      if (!rejected[i]) {
        active.push_back(i);
        used.push_back(views[i]);
      }
    }
    std::vector<std::string> notes;
    s = solve(used, r.method, r.optimizer, size, o, notes);
    if (first) r.warnings.insert(r.warnings.end(), notes.begin(), notes.end());
    std::vector<double> rms(active.size());
    for (std::size_t k = 0; k < active.size(); ++k) rms[k] = view_rms(view_residuals(used[k], s.params, k, o.model));
    if (first) {
      for (std::size_t k = 0; k < active.size(); ++k) first_rms[active[k]] = rms[k];
      r.rms_all_views_px = s.stats.final_rms_px;
      r.camera_all_views = to_camera(s.params, size, o.model, r.rms_all_views_px);
    }
    const auto worst = static_cast<std::size_t>(std::max_element(rms.begin(), rms.end()) - rms.begin());
    const double med = median(rms);
    const double limit = std::max(o.reject_factor * med, o.reject_min_px);
    if (o.reject_factor <= 0 || static_cast<int>(active.size()) <= o.min_views || rms[worst] <= limit) break;
    rejected[active[worst]] = true;
    reasons[active[worst]] = "RMS " + fmt(rms[worst]) + " px > " + fmt(o.reject_factor, 1) + " x median " + fmt(med) +
                             " px (and > " + fmt(o.reject_min_px, 2) + " px)";
  }
  // Reports for every view: kept views with their refined pose, rejected views by PnP.
  std::vector<View> used;
  Parameters all_params = s.params;
  all_params.poses.clear();
  for (std::size_t i = 0, k = 0; i < views.size(); ++i) {
    all_params.poses.push_back(rejected[i] ? pose_with_camera(views[i], s.params, o.model) : s.params.poses[k++]);
    if (!rejected[i]) used.push_back(views[i]);
  }
  std::vector<Eigen::Vector3d> normals;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const auto res = view_residuals(views[i], all_params, i, o.model);
    ViewReport v;
    v.image = views[i].image;
    v.points = static_cast<int>(views[i].ids.size());
    v.rms_px = view_rms(res);
    for (const auto& e : res) v.max_px = std::max(v.max_px, e.norm());
    v.first_rms_px = first_rms[i];
    v.rejected = rejected[i];
    v.reason = reasons[i];
    const Eigen::Vector3d normal = rotation_of(all_params.poses[i]).col(2);  // board z axis, camera frame
    v.tilt_deg = r.method == Method::Planar ? std::acos(std::clamp(std::abs(normal.z()), 0.0, 1.0)) * 180 / std::numbers::pi
                                            : std::numeric_limits<double>::quiet_NaN();
    if (!rejected[i]) normals.push_back(normal);
    v.cam_from_world = to_pose(views[i].image, all_params.poses[i], to_plane);
    r.views.push_back(v);
    for (std::size_t j = 0; j < res.size(); ++j) {
      r.residuals.push_back({views[i].image, views[i].ids[j], views[i].observed_px[j], res[j], rejected[i]});
    }
  }
  r.stats = s.stats;
  r.rms_px = s.stats.final_rms_px;
  r.points_used = point_count(used);
  r.coverage = coverage(used, size);
  r.uncertainty = estimate_uncertainty(used, o.model, s.params, size.width, size.height);
  r.camera = to_camera(s.params, size, o.model, r.rms_px);
  add_geometry_warnings(o, size, r.method, used, normals, r);
  return r;
}

std::optional<cv::Size> image_size_from_files(const std::vector<Observation>& observations) {
  std::optional<cv::Size> size;
  std::string first;
  std::map<std::string, bool> seen;
  for (const auto& o : observations) {
    if (!seen.emplace(o.image, true).second) continue;
    // Images that are not here (the observations came from elsewhere): the size must be given.
    // Images that are here but broken: say which and why (no OpenCV warning on stderr).
    if (!image_file_exists(o.image)) return std::nullopt;
    const cv::Mat img = read_image(o.image, cv::IMREAD_UNCHANGED);
    if (!size) {
      size = img.size();
      first = o.image;
    } else if (img.size() != *size) {
      throw InputError(o.image, 0, "is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) + ", but " +
                                       first + " is " + std::to_string(size->width) + "x" +
                                       std::to_string(size->height) + ": one calibration needs one image size");
    }
  }
  return size;
}

}  // namespace photomill::calib
