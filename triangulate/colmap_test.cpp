// The COLMAP text export: camera models and the +0.5 px pixel convention, the cross-references
// between images.txt and points3D.txt, and, when COLMAP is installed, COLMAP 3.8 reading the
// model back (model_converter) and evaluating it (bundle_adjuster's initial cost must equal our
// final RMS, which it only does if poses, points, intrinsics and the pixel offset all agree).
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"
#include "triangulate/colmap.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

namespace fs = std::filesystem;

Camera camera_with(std::vector<double> distortion, double skew = 0) {
  Camera c;
  c.image_width_px = 2000;
  c.image_height_px = 1500;
  c.camera_matrix << 2400, skew, 999.5, 0, 2400.5, 749.25, 0, 0, 1;
  c.distortion = std::move(distortion);
  return c;
}

struct CameraCase {
  std::vector<double> distortion;
  const char* model;        // empty: not representable
  std::size_t params;
};

class ColmapCameras : public ::testing::TestWithParam<CameraCase> {};

TEST_P(ColmapCameras, ModelAndPixelConvention) {
  const CameraCase& c = GetParam();
  const Camera cam = camera_with(c.distortion);
  if (std::string(c.model).empty()) {
    EXPECT_THROW(to_colmap_camera(cam, "cam.yaml"), InputError);
    return;
  }
  const ColmapCamera cc = to_colmap_camera(cam, "cam.yaml");
  EXPECT_EQ(cc.model, c.model);
  ASSERT_EQ(cc.params.size(), c.params);
  EXPECT_EQ(cc.params[0], 2400);
  EXPECT_EQ(cc.params[1], 2400.5);
  EXPECT_EQ(cc.params[2], 999.5 + 0.5);  // COLMAP: centre of the top-left pixel at (0.5, 0.5)
  EXPECT_EQ(cc.params[3], 749.25 + 0.5);
  for (std::size_t i = 4; i < cc.params.size(); ++i) {
    EXPECT_EQ(cc.params[i], i - 4 < c.distortion.size() ? c.distortion[i - 4] : 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Triangulate, ColmapCameras,
    ::testing::Values(CameraCase{{}, "PINHOLE", 4}, CameraCase{{0, 0, 0, 0, 0}, "PINHOLE", 4},
                      CameraCase{{-0.1, 0.05, 0.001, -0.002}, "OPENCV", 8},
                      CameraCase{{-0.1, 0.05, 0.001, -0.002, 0}, "OPENCV", 8},
                      CameraCase{{-0.1, 0.05, 0.001, -0.002, 0.01}, "FULL_OPENCV", 12},
                      CameraCase{{-0.1, 0.05, 0.001, -0.002, 0.01, 0.1, 0.02, 0.003}, "FULL_OPENCV", 12},
                      CameraCase{{-0.1, 0.05, 0.001, -0.002, 0.01, 0, 0, 0, 0.001, 0, 0, 0}, "", 0}));

TEST(ColmapCamera, SkewIsRefused) { EXPECT_THROW(to_colmap_camera(camera_with({}, 0.5), "cam.yaml"), InputError); }

Reconstruction reconstruction() {
  test::SceneOptions so;
  so.part_id_offset = 0;  // a point id 0 must be accepted too
  so.plate_points_x = 6;
  const test::SceneTruth truth = test::make_scene(so);
  ReconstructInput in;
  in.tracks = truth.tracks;
  in.camera = truth.camera;
  in.scale_bars = {{truth.part_points[0].point_id, truth.part_points[5].point_id,
                    (truth.part_points[0].xyz_mm - truth.part_points[5].xyz_mm).norm(), 0.001}};
  return reconstruct(in, {});
}

struct Image2D {
  std::vector<Eigen::Vector2d> xy;
  std::vector<long long> point_ids;
  Pose pose;
};

TEST(ColmapExport, ImagesAndPointsReferToEachOther) {
  const Reconstruction r = reconstruction();
  std::ostringstream images, points;
  write_colmap_images(images, r);
  write_colmap_points(points, r);

  std::map<long long, Image2D> by_id;
  std::istringstream in(images.str());
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream head(line);
    long long id = 0, camera = 0;
    Image2D im;
    double qw, qx, qy, qz;
    head >> id >> qw >> qx >> qy >> qz >> im.pose.cam_from_world_translation_mm.x() >>
        im.pose.cam_from_world_translation_mm.y() >> im.pose.cam_from_world_translation_mm.z() >> camera >> im.pose.image;
    im.pose.cam_from_world_rotation = Eigen::Quaterniond(qw, qx, qy, qz);
    EXPECT_EQ(camera, 1);
    std::getline(in, line);
    std::istringstream pts(line);
    double x, y;
    long long pid;
    while (pts >> x >> y >> pid) {
      im.xy.emplace_back(x, y);
      im.point_ids.push_back(pid);
    }
    by_id[id] = im;
  }
  ASSERT_EQ(by_id.size(), r.report.registered_images);
  const auto poses = registered_poses(r);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Pose& p = by_id.at(static_cast<long long>(k + 1)).pose;
    EXPECT_EQ(p.image, poses[k].image);
    EXPECT_LT((p.centre_mm() - poses[k].centre_mm()).norm(), 1e-9);
  }

  const CameraModel model = to_camera_model(r.camera, "camera");
  std::istringstream pin(points.str());
  std::size_t n = 0;
  bool saw_zero = false;
  while (std::getline(pin, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    long long id;
    Eigen::Vector3d X;
    int red, green, blue;
    double error;
    s >> id >> X.x() >> X.y() >> X.z() >> red >> green >> blue >> error;
    saw_zero = saw_zero || id == 0;
    long long image_id;
    std::size_t index;
    double sum = 0;
    int views = 0;
    while (s >> image_id >> index) {
      const Image2D& im = by_id.at(image_id);
      ASSERT_LT(index, im.point_ids.size());
      EXPECT_EQ(im.point_ids[index], id);
      // Back to OpenCV's convention, the point projects where COLMAP's 2D point says.
      PoseBlock pose = make_pose(im.pose.rotation(), im.pose.cam_from_world_translation_mm);
      const auto uv = project_point(model, pose.data(), X);
      ASSERT_TRUE(uv.has_value());
      sum += (*uv - (im.xy[index] - Eigen::Vector2d(0.5, 0.5))).norm();
      ++views;
    }
    ASSERT_GE(views, 2);
    EXPECT_NEAR(error, sum / views, 1e-6);
    EXPECT_LT(error, 0.5);
    ++n;
  }
  EXPECT_EQ(n, r.report.points);
  EXPECT_TRUE(saw_zero);
}

std::string find_colmap() {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const fs::path p = fs::path(dir) / "colmap";
    if (!dir.empty() && fs::exists(p)) return p.string();
  }
  return "";
}

TEST(ColmapExport, Colmap38ReadsAndEvaluatesIt) {
  const std::string colmap = find_colmap();
  if (colmap.empty()) GTEST_SKIP() << "COLMAP not installed: the export is checked against the documented format only";
  const Reconstruction r = reconstruction();
  photomill::test::TempDir dir;
  const std::string model = (dir.path() / "model").string();
  ColmapModelFiles files(model);
  files.write(r);
  files.commit();

  const std::string converted = (dir.path() / "converted").string();
  fs::create_directories(converted);
  const auto conv = photomill::test::run_tool(colmap, {"model_converter", "--input_path", model, "--output_path", converted,
                                                       "--output_type", "TXT"});
  ASSERT_EQ(conv.exit_code, 0) << conv.out << conv.err;
  const std::string back = photomill::test::read_file(fs::path(converted) / "points3D.txt");
  EXPECT_NE(back.find("# Number of points: " + std::to_string(r.report.points) + ","), std::string::npos) << back.substr(0, 300);

  const std::string adjusted = (dir.path() / "adjusted").string();
  fs::create_directories(adjusted);
  const auto ba = photomill::test::run_tool(
      colmap, {"bundle_adjuster", "--input_path", model, "--output_path", adjusted, "--BundleAdjustment.max_num_iterations", "1",
               "--BundleAdjustment.refine_focal_length", "0", "--BundleAdjustment.refine_principal_point", "0",
               "--BundleAdjustment.refine_extra_params", "0"});
  ASSERT_EQ(ba.exit_code, 0) << ba.out << ba.err;
  std::smatch m;
  const std::string text = ba.out + ba.err;
  ASSERT_TRUE(std::regex_search(text, m, std::regex(R"(Initial cost\s*:\s*([0-9.eE+-]+)\s*\[px\])"))) << text;
  // COLMAP prints sqrt(cost / residuals) with cost = 1/2 sum |r|^2 and two residuals per
  // observation: half the RMS of |r|.
  const double colmap_rms = 2 * std::stod(m[1].str());
  EXPECT_NEAR(colmap_rms, r.report.final_rms_px, 1e-5 + 1e-4 * r.report.final_rms_px);
}

}  // namespace
}  // namespace photomill::triangulate
