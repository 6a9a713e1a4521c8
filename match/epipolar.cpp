// Epipolar geometry for match (formulas and sources in epipolar.hpp).
#include "match/epipolar.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>

namespace photomill::match {

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& t) {
  Eigen::Matrix3d m;
  m << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return m;
}

}  // namespace

Eigen::Matrix3d fundamental_from_poses(const Eigen::Matrix3d& K, const Pose& a, const Pose& b) {
  return fundamental_from_poses(K, K, a, b);
}

Eigen::Matrix3d fundamental_from_poses(const Eigen::Matrix3d& K_a, const Eigen::Matrix3d& K_b, const Pose& a,
                                       const Pose& b) {
  const Eigen::Matrix3d Ra = a.rotation(), Rb = b.rotation();
  const Eigen::Matrix3d R = Rb * Ra.transpose();
  const Eigen::Vector3d t = b.cam_from_world_translation_mm - R * a.cam_from_world_translation_mm;
  return K_b.inverse().transpose() * skew(t) * R * K_a.inverse();
}

EpipolarPencil::EpipolarPencil(const std::vector<Eigen::Vector2d>& pts, const Eigen::Matrix3d& F) {
  constexpr double kPi = 3.14159265358979323846;
  // e: F^T e = 0, the right singular vector of F^T of the smallest singular value.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F.transpose(), Eigen::ComputeFullV);
  e_ = svd.matrixV().col(2).normalized();
  // l1, l2: an orthonormal basis of the plane orthogonal to e.
  l1_ = e_.unitOrthogonal();
  l2_ = e_.cross(l1_).normalized();
  ftb2_.assign(pts.size(), 0.0);
  struct Point {
    double rho, phi, e_dot_x;
    int index;
  };
  std::vector<Point> ps;
  ps.reserve(pts.size());
  for (std::size_t k = 0; k < pts.size(); ++k) {
    if (!pts[k].allFinite()) continue;
    const Eigen::Vector3d x = pts[k].homogeneous();
    ftb2_[k] = (F.transpose() * x).head<2>().squaredNorm();
    const double p = l1_.dot(x), q = l2_.dot(x);
    double phi = std::atan2(-p, q);
    if (phi < 0) phi += kPi;
    if (phi >= kPi) phi -= kPi;
    ps.push_back({std::hypot(p, q), phi, std::abs(e_.dot(x)), static_cast<int>(k)});
  }
  if (ps.empty()) return;
  // Bands of rho, from the largest down, each a factor 2 wide; the last (up to 24) takes the rest.
  std::sort(ps.begin(), ps.end(), [](const Point& a, const Point& b) { return a.rho > b.rho; });
  entries_.reserve(ps.size());
  std::size_t at = 0;
  double top = ps.front().rho;
  for (int b = 0; at < ps.size(); ++b) {
    const double bottom = b == 23 ? -1.0 : 0.5 * top;
    Band band;
    band.begin = entries_.size();
    band.min_rho = ps[at].rho;
    for (; at < ps.size() && ps[at].rho > bottom; ++at) {
      band.min_rho = ps[at].rho;
      band.max_ftb2 = std::max(band.max_ftb2, ftb2_[static_cast<std::size_t>(ps[at].index)]);
      band.max_e_dot_x = std::max(band.max_e_dot_x, ps[at].e_dot_x);
      entries_.push_back({ps[at].phi, ps[at].index});
    }
    band.end = entries_.size();
    std::sort(entries_.begin() + static_cast<std::ptrdiff_t>(band.begin), entries_.end(),
              [](const Entry& a, const Entry& b) { return a.phi < b.phi || (a.phi == b.phi && a.index < b.index); });
    if (band.end > band.begin) bands_.push_back(band);
    top = bottom;
  }
}

double sampson_distance_px(const Eigen::Matrix3d& F, const Eigen::Vector2d& xa, const Eigen::Vector2d& xb) {
  const Eigen::Vector3d a = xa.homogeneous(), b = xb.homogeneous();
  const Eigen::Vector3d Fa = F * a, Ftb = F.transpose() * b;
  const double denominator = Fa.head<2>().squaredNorm() + Ftb.head<2>().squaredNorm();
  if (!(denominator > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(b.dot(Fa)) / std::sqrt(denominator);
}

namespace {

std::vector<cv::Point2d> to_cv(const std::vector<Eigen::Vector2d>& v) {
  std::vector<cv::Point2d> out;
  out.reserve(v.size());
  for (const auto& p : v) out.emplace_back(p.x(), p.y());
  return out;
}

std::optional<Eigen::Matrix3d> to_eigen(const cv::Mat& m) {
  if (m.rows != 3 || m.cols != 3 || m.type() != CV_64F) return std::nullopt;  // none, or several (7-point)
  Eigen::Matrix3d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = m.at<double>(r, c);
  }
  return out.allFinite() ? std::optional<Eigen::Matrix3d>(out) : std::nullopt;
}

int count_inliers(const Eigen::Matrix3d& F, const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b,
                  double threshold) {
  int n = 0;
  for (std::size_t k = 0; k < a.size(); ++k) n += sampson_distance_px(F, a[k], b[k]) <= threshold ? 1 : 0;
  return n;
}

// Plane and parallax (Hartley & Zisserman sec. 13.3; the DEGENSAC idea of Chum, Werner & Matas,
// "Two-view geometry estimation unaffected by a dominant plane", CVPR 2005). When most
// correspondences lie on one plane (the plate around a part), RANSAC on F tends to return one of
// the family F = [e']x H that all fit the plane, with a wrong epipole e' that rejects the points
// off the plane. Here H is fitted to the dominant plane; every correspondence off it gives a line
// l' = (H x) x x' through the true epipole, so two of them give e' = l1' x l2' and F = [e']x H.
// Pairs of off-plane correspondences are drawn (deterministically) and the F with the most inliers
// wins.
std::optional<Eigen::Matrix3d> plane_and_parallax(const std::vector<Eigen::Vector2d>& a,
                                                  const std::vector<Eigen::Vector2d>& b, const RobustFitOptions& o,
                                                  int to_beat) {
  cv::Mat H_cv;
  try {
    H_cv = cv::findHomography(to_cv(a), to_cv(b), cv::USAC_MAGSAC, o.threshold_px, cv::noArray(), o.max_iterations,
                              o.confidence);
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  const auto H = to_eigen(H_cv);
  if (!H) return std::nullopt;
  std::vector<Eigen::Vector3d> lines;  // parallax lines of the correspondences clearly off the plane
  int on_plane = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const Eigen::Vector3d hx = *H * a[k].homogeneous();
    const double transfer = (hx.hnormalized() - b[k]).norm();
    if (transfer <= o.threshold_px) ++on_plane;
    if (transfer > 3 * o.threshold_px) lines.push_back(hx.cross(b[k].homogeneous()).normalized());
  }
  // No dominant plane, or no parallax to place the epipole: nothing to gain here.
  if (on_plane < o.min_inliers || lines.size() < 2) return std::nullopt;
  std::uint64_t state = 0x9E3779B97F4A7C15ull;  // SplitMix64: the same draws on every run
  auto draw = [&](std::size_t n) {
    state += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = state;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return static_cast<std::size_t>((z ^ (z >> 31)) % n);
  };
  std::optional<Eigen::Matrix3d> best;
  int best_count = to_beat;
  const std::size_t samples = std::min<std::size_t>(500, lines.size() * (lines.size() - 1) / 2);
  for (std::size_t s = 0; s < samples; ++s) {
    const std::size_t i = draw(lines.size());
    std::size_t j = draw(lines.size() - 1);
    if (j >= i) ++j;
    const Eigen::Vector3d e = lines[i].cross(lines[j]);
    if (!(e.norm() > 1e-12)) continue;
    Eigen::Matrix3d ex;
    ex << 0, -e.z(), e.y(), e.z(), 0, -e.x(), -e.y(), e.x(), 0;
    const Eigen::Matrix3d F = ex * *H;
    const int count = count_inliers(F, a, b, o.threshold_px);
    if (count > best_count) {
      best_count = count;
      best = F;
    }
  }
  return best;
}

}  // namespace

std::optional<RobustFit> estimate_fundamental(const std::vector<Eigen::Vector2d>& a,
                                              const std::vector<Eigen::Vector2d>& b, const RobustFitOptions& o) {
  if (a.size() != b.size() || a.size() < 8) return std::nullopt;
  std::optional<Eigen::Matrix3d> F;
  try {
    F = to_eigen(cv::findFundamentalMat(to_cv(a), to_cv(b), cv::USAC_MAGSAC, o.threshold_px, o.confidence,
                                        o.max_iterations));
  } catch (const cv::Exception&) {
    return std::nullopt;  // OpenCV refuses degenerate input (all points equal, ...)
  }
  int count = F ? count_inliers(*F, a, b, o.threshold_px) : 0;
  if (const auto pp = plane_and_parallax(a, b, o, count)) {
    F = pp;
    count = count_inliers(*F, a, b, o.threshold_px);
  }
  if (!F) return std::nullopt;
  // Least squares on the inliers (normalised 8-point algorithm, H&Z alg. 11.1), kept if it
  // explains at least as many correspondences.
  for (int round = 0; round < 3; ++round) {
    std::vector<Eigen::Vector2d> ia, ib;
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (sampson_distance_px(*F, a[k], b[k]) > o.threshold_px) continue;
      ia.push_back(a[k]);
      ib.push_back(b[k]);
    }
    if (ia.size() < 8) break;
    std::optional<Eigen::Matrix3d> refined;
    try {
      refined = to_eigen(cv::findFundamentalMat(to_cv(ia), to_cv(ib), cv::FM_8POINT));
    } catch (const cv::Exception&) {
      break;
    }
    if (!refined) break;
    const int refined_count = count_inliers(*refined, a, b, o.threshold_px);
    if (refined_count < count) break;
    const bool same = refined_count == count;
    F = refined;
    count = refined_count;
    if (same) break;
  }
  RobustFit fit;
  fit.F = *F;
  fit.inliers.resize(a.size());
  for (std::size_t k = 0; k < a.size(); ++k) fit.inliers[k] = sampson_distance_px(fit.F, a[k], b[k]) <= o.threshold_px;
  fit.inlier_count = count;
  if (fit.inlier_count < o.min_inliers || fit.inlier_count < o.min_inlier_ratio * static_cast<double>(a.size())) {
    return std::nullopt;
  }
  return fit;
}

Undistorter::Undistorter(const std::optional<Camera>& camera) {
  if (camera) camera_ = geometry::to_camera_model(*camera, "camera");
}

std::vector<Eigen::Vector2d> Undistorter::apply(const std::vector<Eigen::Vector2d>& pixels) const {
  if (!camera_) return pixels;
  std::vector<Eigen::Vector2d> result;
  result.reserve(pixels.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const auto& p : pixels) result.push_back(geometry::undistort_to_ideal_pixel(*camera_, p).value_or(Eigen::Vector2d(nan, nan)));
  return result;
}

}  // namespace photomill::match
