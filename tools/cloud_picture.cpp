// cloud_picture: a picture of a point cloud seen from one of its photos' cameras, beside the photo
// (docs/measurements/densify.md: the dense cloud of the Middlebury temple). Each point is drawn
// as a square of --splat-px pixels, nearest first (a z-buffer), its grey from its normal lit from
// the camera's upper left (Lambert: 40 + 215 max(0, n . l), the normal turned towards the camera,
// l = (-0.5, -0.5, -1) normalised in the camera's frame), or mid-grey without normals.
// Points behind the camera or outside the photo are left out.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "formats/camera.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/point_cloud.hpp"
#include "formats/tables.hpp"
#include "formats/tool.hpp"
#include "geometry/camera_model.hpp"

using namespace photomill;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  std::string cloud_path, camera_path, poses_path, image, image_dir, output;
  int splat_px = 2;
  return tool::run(
      argc, argv,
      {"cloud_picture", "a point cloud seen from one of its photos' cameras, beside the photo (PNG)",
       "cloud_picture dense.ply --camera camera.yaml --poses poses.csv --image templeSR0001.png -o temple.png"},
      [&](CLI::App& app) {
        app.add_option("cloud", cloud_path, "Point cloud PLY (with nx ny nz for shading)")->required();
        app.add_option("--camera", camera_path, "The photos' camera.yaml")->required();
        app.add_option("--poses", poses_path, "The photos' poses CSV")->required();
        app.add_option("--image", image, "The photo whose camera looks (its file name in the poses)")->required();
        app.add_option("--image-dir", image_dir, "Read the photo from this folder");
        app.add_option("--splat-px", splat_px, "Each point's square, px")->check(tool::finite_in(1, 20))->capture_default_str();
        app.add_option("-o,--output", output, "PNG file")->required();
      },
      [&] {
        const Camera camera = read_camera_yaml(*tool::open_input(camera_path), tool::source_name(camera_path));
        validate_camera(camera, tool::source_name(camera_path));
        const geometry::CameraModel cam = geometry::to_camera_model(camera, tool::source_name(camera_path));
        const std::vector<Pose> poses = read_poses(*tool::open_input(poses_path), tool::source_name(poses_path));
        const auto pose = std::find_if(poses.begin(), poses.end(),
                                       [&](const Pose& p) { return fs::path(p.image).filename() == fs::path(image).filename(); });
        if (pose == poses.end()) throw InputError(tool::source_name(poses_path), 0, "no pose of photo " + image);
        const std::string photo_path =
            image_dir.empty() ? pose->image : (fs::path(image_dir) / fs::path(pose->image).filename()).string();
        const cv::Mat photo = cv::imread(photo_path, cv::IMREAD_COLOR);
        if (photo.empty()) throw InputError(photo_path, 0, "cannot read the photo");
        if (photo.cols != cam.width_px || photo.rows != cam.height_px) {
          throw InputError(photo_path, 0,
                           "the photo is " + std::to_string(photo.cols) + " x " + std::to_string(photo.rows) + " px, the camera " +
                               std::to_string(cam.width_px) + " x " + std::to_string(cam.height_px) + ": another camera's photo?");
        }
        const PointCloud cloud = read_ply(*tool::open_input(cloud_path), tool::source_name(cloud_path));
        const PointProperty* nx = cloud.find("nx");
        const PointProperty* ny = cloud.find("ny");
        const PointProperty* nz = cloud.find("nz");
        const bool shaded = nx && ny && nz;

        const Eigen::Matrix3d R = pose->rotation();
        const Eigen::Vector3d t = pose->cam_from_world_translation_mm;
        const Eigen::Vector3d light = Eigen::Vector3d(-0.5, -0.5, -1).normalized();
        cv::Mat picture(photo.rows, photo.cols, CV_8UC3, cv::Scalar(0, 0, 0));
        cv::Mat depth(photo.rows, photo.cols, CV_64F, cv::Scalar(std::numeric_limits<double>::infinity()));
        std::size_t drawn = 0;
        for (std::size_t i = 0; i < cloud.points_mm.size(); ++i) {
          const Eigen::Vector3d& X = cloud.points_mm[i];
          const Eigen::Vector3d Xc = R * X + t;
          if (!(Xc.z() > 0)) continue;
          double u, v;
          geometry::distort_to_pixel(geometry::shape_of(cam), cam.params.data(), Xc.x() / Xc.z(), Xc.y() / Xc.z(), &u, &v);
          const int x0 = static_cast<int>(std::lround(u)) - splat_px / 2, y0 = static_cast<int>(std::lround(v)) - splat_px / 2;
          if (x0 + splat_px <= 0 || y0 + splat_px <= 0 || x0 >= photo.cols || y0 >= photo.rows) continue;
          unsigned char grey = 128;
          if (shaded) {
            Eigen::Vector3d n = R * Eigen::Vector3d(nx->values[i], ny->values[i], nz->values[i]).normalized();
            if (n.dot(Xc) > 0) n = -n;
            const double c = std::max(0.0, n.dot(light));
            grey = static_cast<unsigned char>(std::lround(40 + 215 * c));
          }
          bool any = false;
          for (int y = std::max(0, y0); y < std::min(photo.rows, y0 + splat_px); ++y) {
            for (int x = std::max(0, x0); x < std::min(photo.cols, x0 + splat_px); ++x) {
              if (!(Xc.z() < depth.at<double>(y, x))) continue;
              depth.at<double>(y, x) = Xc.z();
              picture.at<cv::Vec3b>(y, x) = cv::Vec3b(grey, grey, grey);
              any = true;
            }
          }
          drawn += any ? 1 : 0;
        }
        if (drawn == 0) {
          throw InputError(tool::source_name(cloud_path), 0,
                           "no point lies in front of " + image + "'s camera and inside the photo: a cloud of another run?");
        }
        cv::Mat both;
        cv::hconcat(photo, picture, both);
        std::vector<unsigned char> png;
        if (!cv::imencode(".png", both, png)) throw InputError(output, 0, "cannot encode the picture");
        tool::OutputFile out(output);
        out.stream().write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
        out.commit();
        log::info(std::to_string(drawn) + " of " + std::to_string(cloud.points_mm.size()) + " points drawn from " + image);
      });
}
