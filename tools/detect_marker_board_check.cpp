// detect_marker_board_check: marker corners on real photos of a ChArUco board, against the board's
// own geometry (tools/marker_board_check.hpp: the chessboard corners, measured apart from the
// markers, place the board in each photo after the lens distortion is removed; a marker corner's
// error is its distance from where the board puts it). Needs no truth beyond the board's layout
// and a calibration (OpenCV's YAML with camera_matrix and distortion_coefficients). Methods, on the
// same photos: photomill's edge fit with the code cells modelled (detect's default), without
// (--edge-ignore-code), and OpenCV's refinements (CORNER_REFINE_SUBPIX, _CONTOUR, _NONE). Prints,
// per photo and over all, per method: markers kept, RMS and largest corner error, the mean error
// along the marker's diagonals (outwards positive: a bias), and the RMS over the markers every
// method kept; and the chessboard corners' own residual (the floor). Data on stdout.
#include <iomanip>
#include <iostream>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "detect/markers.hpp"
#include "formats/error.hpp"
#include "formats/tool.hpp"
#include "tools/marker_board_check.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  using namespace photomill::detect;
  std::vector<std::string> photos;
  std::string camera_path;
  board_check::CharucoBoardSpec spec;
  double gamma = 2.2;
  int degree = EdgeFitOptions{}.degree;
  return tool::run(
      argc, argv,
      {"detect_marker_board_check", "Marker corners on ChArUco board photos against the board's geometry",
       "detect_marker_board_check ../shared/data/opencv-aruco/img_0*.jpg --camera "
       "../shared/data/opencv-aruco/tutorial_camera_charuco.yml"},
      [&](CLI::App& app) {
        app.add_option("photos", photos, "Photos of the ChArUco board")->required();
        app.add_option("--camera", camera_path, "OpenCV YAML with camera_matrix and distortion_coefficients")->required();
        app.add_option("--dictionary", spec.dictionary, "ArUco dictionary of the board")->capture_default_str();
        app.add_option("--squares-x", spec.squares_x, "Board squares along x")->capture_default_str()->check(CLI::Range(2, 100));
        app.add_option("--squares-y", spec.squares_y, "Board squares along y")->capture_default_str()->check(CLI::Range(2, 100));
        app.add_option("--square", spec.square, "Square side (any unit)")->capture_default_str()->check(CLI::PositiveNumber);
        app.add_option("--marker", spec.marker, "Marker side (same unit)")->capture_default_str()->check(CLI::PositiveNumber);
        app.add_option("--edge-degree", degree, "photomill's edge fit: --edge-degree")->capture_default_str()->check(CLI::Range(1, 3));
        app.add_option("--gamma", gamma, "photomill's edge fit: --edge-gamma")->capture_default_str()->check(CLI::Range(0.2, 5.0));
      },
      [&] {
        cv::FileStorage fs(camera_path, cv::FileStorage::READ);
        cv::Mat K, dist;
        if (fs.isOpened()) {
          fs["camera_matrix"] >> K;
          fs["distortion_coefficients"] >> dist;
        }
        if (K.rows != 3 || K.cols != 3) throw InputError(camera_path, 0, "no 3 x 3 camera_matrix");
        std::vector<std::string> names;
        std::vector<MarkerDetectOptions> methods;
        auto add = [&](const std::string& name, CornerRefinement refinement, bool code) {
          MarkerDetectOptions o;
          o.refinement = refinement;
          o.edges.gamma = gamma;
          o.edges.degree = degree;
          o.edges.model_code = code;
          names.push_back(name);
          methods.push_back(o);
        };
        add("photomill edge fit, code modelled", CornerRefinement::Edges, true);
        add("photomill edge fit, --edge-ignore-code", CornerRefinement::Edges, false);
        add("OpenCV CORNER_REFINE_SUBPIX", CornerRefinement::Subpix, true);
        add("OpenCV CORNER_REFINE_CONTOUR", CornerRefinement::Contour, true);
        add("OpenCV CORNER_REFINE_NONE", CornerRefinement::None, true);
        std::vector<board_check::CornerErrors> all(methods.size()), all_common(methods.size());
        board_check::CornerErrors all_floor;
        auto line = [&](const std::string& name, const board_check::CornerErrors& e, const board_check::CornerErrors& common,
                        const std::string& common_label) {
          std::cout << "  " << std::left << std::setw(42) << name << std::right << std::setw(3) << e.markers
                    << " markers, RMS " << e.rms() << " px, max " << e.max << " px, mean outwards " << e.mean_outward()
                    << " px; on " << common_label << ": RMS " << common.rms() << " px\n";
        };
        std::cout << std::fixed << std::setprecision(4);
        for (const auto& photo : photos) {
          const cv::Mat grey = cv::imread(photo, cv::IMREAD_GRAYSCALE);
          if (grey.empty()) throw InputError(photo, 0, "cannot read this image");
          const auto check = board_check::check_charuco_photo(grey, photo, spec, K, dist, methods);
          if (!check.board_found) {
            std::cout << photo << ": fewer than 4 of the board's markers found, skipped\n";
            continue;
          }
          all_floor.merge(check.floor);
          std::cout << photo << ": " << check.floor.count << " chessboard corners about the homography: RMS "
                    << check.floor.rms() << " px, max " << check.floor.max << " px (" << check.half_window_px
                    << " px half-window)\n";
          for (std::size_t m = 0; m < methods.size(); ++m) {
            all[m].merge(check.methods[m]);
            all_common[m].merge(check.methods_common[m]);
            line(names[m], check.methods[m], check.methods_common[m],
                 "the " + std::to_string(check.common_markers) + " markers all kept");
          }
        }
        if (all_floor.count == 0) throw InputError(photos.front(), 0, "no photo showed the board");
        std::cout << "all photos: chessboard corners about their homographies RMS " << all_floor.rms() << " px\n";
        for (std::size_t m = 0; m < methods.size(); ++m) line(names[m], all[m], all_common[m], "the markers all kept");
      });
}
