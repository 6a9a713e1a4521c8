// The Middlebury temple (../shared/data/middlebury-temple: 16 real views on a ring, ground-truth
// K, R, t) through detect, match and triangulate with the true cameras held fixed
// (--known-poses), against COLMAP 3.8's point_triangulator given the same cameras
// (../shared/data/README.md: 1 427 points, reprojection median 0.189 px, 99.0 % inside the
// published bounding box). Issue #23's bound: at least as many points, median <= 0.14 px, at
// least 99 % inside the box. The median is over the observations the model keeps, read from
// its COLMAP export as COLMAP's own figure is. And the same tracks without the cameras.
// Every stage with its default options.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "formats/tables.hpp"
#include "tests/option_check.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::triangulate {
namespace {

namespace fs = std::filesystem;
using photomill::test::run_tool;
using photomill::test::TempDir;

const fs::path kTemple = fs::path(PHOTOMILL_SHARED_DIR) / "data" / "middlebury-temple";

struct TrueCamera {
  std::string image;
  Eigen::Matrix3d K, R;
  Eigen::Vector3d t_mm;
};

// templeSR_par.txt: a count, then per image "name k11..k33 r11..r33 t1 t2 t3" (metres).
std::vector<TrueCamera> read_par(const fs::path& path) {
  std::ifstream in(path);
  std::size_t n = 0;
  in >> n;
  std::vector<TrueCamera> cams(n);
  for (TrueCamera& c : cams) {
    in >> c.image;
    for (int i = 0; i < 9; ++i) in >> c.K(i / 3, i % 3);
    for (int i = 0; i < 9; ++i) in >> c.R(i / 3, i % 3);
    for (int i = 0; i < 3; ++i) in >> c.t_mm[i];
    c.t_mm *= 1000;
  }
  return cams;
}

// COLMAP text model: each kept observation's reprojection error with the PINHOLE camera and the
// image's pose (COLMAP's +0.5 px convention on both the camera and the points).
std::vector<double> model_errors_px(const fs::path& dir) {
  std::ifstream cams(dir / "cameras.txt");
  std::string line;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  while (std::getline(cams, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    std::string id, model, w, h;
    s >> id >> model >> w >> h >> fx >> fy >> cx >> cy;
  }
  struct Image {
    Eigen::Quaterniond q;
    Eigen::Vector3d t;
    std::vector<Eigen::Vector2d> xy;
  };
  std::map<long, Image> images;
  std::ifstream im(dir / "images.txt");
  while (std::getline(im, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    long id = 0, cam = 0;
    double qw, qx, qy, qz;
    Image img;
    std::string name;
    s >> id >> qw >> qx >> qy >> qz >> img.t.x() >> img.t.y() >> img.t.z() >> cam >> name;
    img.q = Eigen::Quaterniond(qw, qx, qy, qz);
    std::getline(im, line);
    std::istringstream p(line);
    double x, y;
    long pid;
    while (p >> x >> y >> pid) img.xy.push_back({x, y});
    images[id] = img;
  }
  std::vector<double> errors;
  std::ifstream pts(dir / "points3D.txt");
  while (std::getline(pts, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    long id;
    Eigen::Vector3d X;
    int r, g, b;
    double err;
    s >> id >> X.x() >> X.y() >> X.z() >> r >> g >> b >> err;
    long image, idx;
    while (s >> image >> idx) {
      const Image& img = images.at(image);
      const Eigen::Vector3d c = img.q.normalized() * X + img.t;
      const Eigen::Vector2d uv(fx * c.x() / c.z() + cx, fy * c.y() / c.z() + cy);
      errors.push_back((uv - img.xy.at(static_cast<std::size_t>(idx))).norm());
    }
  }
  return errors;
}

// The true cameras as camera.yaml and a poses CSV (named by file name only: the tracks name the
// photos by their paths), and detect + match with their defaults (features only: the temple has
// no markers). Made once per test process.
struct TempleRun {
  TempDir dir;
  std::vector<TrueCamera> cams;
  std::string error;  // why it could not run, if it could not
  fs::path d() const { return dir.path(); }
  TempleRun() {
    const fs::path par = kTemple / "templeSR_par.txt";
    if (!fs::exists(par)) {
      error = "shared data not found: " + par.string();
      return;
    }
    cams = read_par(par);
    std::ofstream y(d() / "camera.yaml");
    y.precision(17);
    const Eigen::Matrix3d& K = cams.at(0).K;
    y << "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n"
         "   cols: 3\n   dt: d\n   data: [ " << K(0, 0) << ", 0., " << K(0, 2) << ", 0., " << K(1, 1) << ", " << K(1, 2)
      << ", 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n"
         "   data: [ 0., 0., 0., 0., 0. ]\n";
    y.close();
    std::ofstream p(d() / "poses.csv");
    p.precision(17);
    p << "image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm\n";
    for (const TrueCamera& c : cams) {
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(c.R, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Eigen::Quaterniond q(Eigen::Matrix3d(svd.matrixU() * svd.matrixV().transpose()));
      p << c.image << "," << q.w() << "," << q.x() << "," << q.y() << "," << q.z() << "," << c.t_mm.x() << ","
        << c.t_mm.y() << "," << c.t_mm.z() << "\n";
    }
    p.close();
    std::vector<std::string> detect{"-q", "--features", (d() / "feat").string()};
    for (const TrueCamera& c : cams) detect.push_back((kTemple / c.image).string());
    const auto det = run_tool("detect", detect);
    if (det.exit_code != 0) {
      error = "detect: " + det.err;
      return;
    }
    const auto mat = run_tool("match", {"-q", "--features", (d() / "feat").string(), "--camera",
                                        (d() / "camera.yaml").string(), "-o", (d() / "tracks.csv").string()});
    if (mat.exit_code != 0) error = "match: " + mat.err;
  }
};
const TempleRun& temple() {
  static const TempleRun run;
  return run;
}

TEST(Temple, TrueCamerasHeldFixedGiveMorePointsThanColmapAtALowerError) {
  const TempleRun& t = temple();
  if (t.error.rfind("shared data", 0) == 0) GTEST_SKIP() << t.error;
  ASSERT_EQ(t.error, "");
  ASSERT_EQ(t.cams.size(), 16u);
  const fs::path d = t.d();
  const auto tri = run_tool("triangulate", {"-q", (d / "tracks.csv").string(), "-c", (d / "camera.yaml").string(),
                                            "--known-poses", (d / "poses.csv").string(), "--colmap",
                                            (d / "model").string(), "--report", (d / "report.json").string(), "-o",
                                            (d / "cloud.ply").string(), "--ply-encoding", "ascii"});
  ASSERT_EQ(tri.exit_code, 0) << tri.err;
  const std::string report = photomill::test::read_file(d / "report.json");
  EXPECT_EQ(photomill::test::json_number(report, "registered_images"), 16);

  std::vector<double> e = model_errors_px(d / "model");
  ASSERT_FALSE(e.empty());
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  const double median = e[e.size() / 2];

  // The points, against the published tight bounding box (metres).
  std::ifstream ply(d / "cloud.ply");
  std::string line;
  while (std::getline(ply, line) && line != "end_header") {
  }
  const Eigen::Vector3d lo(-73.568, 21.728, -12.445), hi(28.855, 181.892, 62.736);
  std::size_t points = 0, inside = 0;
  while (std::getline(ply, line)) {
    std::istringstream s(line);
    Eigen::Vector3d X;
    if (!(s >> X.x() >> X.y() >> X.z())) continue;
    ++points;
    inside += (X.array() >= lo.array()).all() && (X.array() <= hi.array()).all() ? 1 : 0;
  }
  const double fraction = static_cast<double>(inside) / static_cast<double>(std::max<std::size_t>(points, 1));
  std::cout << "temple, true cameras fixed: " << points << " points, reprojection median " << median << " px over "
            << e.size() << " observations, " << 100 * fraction << " % inside the bounding box "
            << "(COLMAP 3.8 point_triangulator: 1427 points, 0.189 px, 99.0 %)\n";
  EXPECT_GE(points, 1427u);
  EXPECT_LE(median, 0.14);
  EXPECT_GE(fraction, 0.99);
}

// templeSR0001 and templeSR0011 have the same true pose in templeSR_par.txt. A track seen in both
// and in templeSR0010 (the one guided matching made, 1000816) keeps two parallel rays once the
// third observation is removed as an outlier: its covariance is infinite. That point made the PLY
// writer refuse ("'scalar_sigma_mm' holds a value its type cannot store", exit 1) in some runs
// with --refine-intrinsics all; it must leave the result with a warning instead. With these
// (unguided) tracks the pipeline drops the added track before the covariance, for its angle, so
// this case checks the outcome (exit 0, no non-finite value in the cloud), not which of the two
// checks removed it; the run prints which.
TEST(Temple, APointOnParallelRaysLeavesTheResultWithAWarning) {
  const TempleRun& t = temple();
  if (t.error.rfind("shared data", 0) == 0) GTEST_SKIP() << t.error;
  ASSERT_EQ(t.error, "");
  const fs::path d = t.d();
  std::string tracks = photomill::test::read_file(d / "tracks.csv");
  const auto stamp_end = tracks.find('\n');
  if (tracks.rfind("#", 0) == 0) tracks.erase(0, stamp_end + 1);  // the row count changes
  const std::string dir = kTemple.string() + "/";
  tracks += "99999999," + dir + "templeSR0001.png,444.9950866699219,318.7215576171875\n";
  tracks += "99999999," + dir + "templeSR0010.png,447.75691877244043,303.26630173609936\n";
  tracks += "99999999," + dir + "templeSR0011.png,444.9812065140768,318.59972358297244\n";
  {
    std::ofstream f(d / "tracks_parallel.csv");
    f << tracks;
  }
  const auto tri = run_tool("triangulate", {(d / "tracks_parallel.csv").string(), "-c", (d / "camera.yaml").string(),
                                            "--known-poses", (d / "poses.csv").string(), "--refine-intrinsics", "all",
                                            "-o", (d / "parallel.ply").string(), "--ply-encoding", "ascii"});
  ASSERT_EQ(tri.exit_code, 0) << tri.err;
  std::ifstream ply(d / "parallel.ply");
  std::string line;
  while (std::getline(ply, line) && line != "end_header") {
  }
  while (std::getline(ply, line)) {
    EXPECT_EQ(line.find("nan"), std::string::npos) << line;
    EXPECT_EQ(line.find("inf"), std::string::npos) << line;
  }
  // Left out as undetermined, or before that for its angle: either way named on stderr or absent.
  const bool undetermined = tri.err.find("left out (track 99999999") != std::string::npos;
  std::cout << "the parallel-ray track: " << (undetermined ? "left out as undetermined" : "dropped earlier") << "\n";
}

// No markers, no poses, the true K: at least 15 of the 16 views oriented, their centres within
// 1 mm RMS of the truth after the similarity that best maps them onto it (Umeyama 1991; the
// scale is arbitrary). COLMAP 3.8's mapper: 13 of 16 (2.5 mm with its intrinsics refined,
// 1.25 mm held fixed; scripts/bench-temple.sh).
TEST(Temple, OrientedWithoutMarkersOrPoses) {
  const TempleRun& t = temple();
  if (t.error.rfind("shared data", 0) == 0) GTEST_SKIP() << t.error;
  ASSERT_EQ(t.error, "");
  const fs::path d = t.d();
  const auto tri = run_tool("triangulate", {"-q", (d / "tracks.csv").string(), "-c", (d / "camera.yaml").string(),
                                            "--arbitrary-scale", "--poses", (d / "estimated.csv").string(), "-o",
                                            (d / "free.ply").string()});
  ASSERT_EQ(tri.exit_code, 0) << tri.err;
  std::map<std::string, Eigen::Vector3d> truth;
  for (const TrueCamera& c : t.cams) truth[c.image] = -c.R.transpose() * c.t_mm;
  std::vector<Eigen::Vector3d> est, tru;
  std::ifstream in(d / "estimated.csv");
  for (const Pose& p : read_poses(in, (d / "estimated.csv").string())) {
    est.push_back(p.centre_mm());
    tru.push_back(truth.at(fs::path(p.image).filename().string()));
  }
  ASSERT_GE(est.size(), 3u);
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(est.size())), dst(3, static_cast<Eigen::Index>(est.size()));
  for (std::size_t k = 0; k < est.size(); ++k) {
    src.col(static_cast<Eigen::Index>(k)) = est[k];
    dst.col(static_cast<Eigen::Index>(k)) = tru[k];
  }
  const Eigen::Matrix4d M = Eigen::umeyama(src, dst, true);
  double sum = 0;
  for (Eigen::Index k = 0; k < src.cols(); ++k) {
    sum += ((M.topLeftCorner<3, 3>() * src.col(k) + M.topRightCorner<3, 1>()) - dst.col(k)).squaredNorm();
  }
  const double rms = std::sqrt(sum / static_cast<double>(src.cols()));
  std::cout << "temple, no markers, no poses: " << est.size() << " of 16 views oriented, camera centres " << rms
            << " mm RMS after a similarity (COLMAP 3.8 mapper: 13 of 16, 2.5 mm)\n";
  EXPECT_GE(est.size(), 15u);
  EXPECT_LE(rms, 1.0);
}

}  // namespace
}  // namespace photomill::triangulate
