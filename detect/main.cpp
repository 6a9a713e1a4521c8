// detect: images -> observations CSV (image,point_id,u_px,v_px) of calibration-board corners, or
// with --print-board the board's control points CSV (run in board_cli.hpp); or ArUco marker
// corners and/or SIFT feature files (options and run in photo_cli.hpp). One mode per run.
// Per-image results go to stderr.
#include <cstdint>
#include <string>
#include <tuple>
#include <vector>

#include "detect/board_cli.hpp"
#include "detect/boards.hpp"
#include "detect/huge_pages.hpp"
#include "detect/photo_cli.hpp"
#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"

using namespace photomill;

int main(int argc, char** argv) {
  std::vector<std::string> images;
  std::string output = "-";
  std::string chessboard;
  std::string charuco;
  bool print_board = false;
  bool raw_charuco = false;
  double max_image_mpx = static_cast<double>(kMaxImagePixels) / 1e6;
  detect::BoardSpec spec;
  detect::BoardDetectOptions options;
  detect::PhotoCli photo;  // --aruco, --aruco-dict-file, --features, --draw (detect/photo_cli.hpp)
  detect::use_huge_pages_for_large_images();  // SIFT's pyramids: fewer page faults and TLB misses
  return tool::run(
      argc, argv,
      {"detect", "find board corners, ArUco markers or SIFT features in images; write observations CSV",
       "detect --chessboard 9x6 left*.jpg | calib --chessboard 9x6 --square-mm 25 > cam.yaml"},
      [&](CLI::App& app) {
        app.add_option("images", images, "Images; '-' reads image paths from stdin, one per line");
        app.add_option("-o,--output", output, "Output CSV (default: stdout)");
        auto* cb = app.add_option("--chessboard", chessboard, "Chessboard with COLSxROWS inner corners (9x6)")
                       ->group("Boards");
        auto* ch = app.add_option("--charuco", charuco, "ChArUco board with COLSxROWS squares (5x7)")->group("Boards");
        cb->excludes(ch);
        app.add_option("--square-mm", spec.square_mm, "Side of a board square, mm (control points; ChArUco)")
            ->group("Boards")->capture_default_str()->check(tool::positive_up_to(10000.0));
        app.add_option("--marker-mm", spec.marker_mm, "Side of a marker, mm (ChArUco; with --scale-bars-out)")
            ->group("Boards")->check(tool::positive_up_to(10000.0));
        detect::add_photo_options(app, photo);
        app.add_option("--dict", spec.dictionary, "ChArUco: ArUco dictionary")
            ->group("Boards")->capture_default_str()
            ->check(CLI::IsMember(detect::aruco_dictionary_names()));
        app.add_flag("--print-board", print_board, "Write the board's control points CSV (z = 0, mm) instead")
            ->group("Boards");
        app.add_flag("--no-charuco-refine", raw_charuco,
                     "Keep OpenCV 4.6's interpolated ChArUco corners (shifted by ~0.5 px) unrefined")
            ->group("Boards");
        app.add_option("--charuco-max-window", options.charuco_max_half_window_px,
                       "ChArUco: largest cornerSubPix half-window, px")
            ->group("Boards")->capture_default_str()->check(CLI::Range(2, 50));
        app.add_option("--chessboard-window-check", options.chessboard_window_check_px,
                       "Chessboard: refine each corner with half the window too and keep that one where they differ "
                       "by more than this, px (the full window took in another edge); 0 = OpenCV's corners")
            ->group("Boards")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--max-image-mpx", max_image_mpx,
                       "Pixel limit: a photo whose header claims more megapixels is refused before it is decoded")
            ->capture_default_str()->check(tool::positive_up_to(10000));
        app.add_option("-j,--threads,--jobs", options.jobs, "Images processed in parallel (0: all cores; --jobs: the old name)")
            ->capture_default_str()->check(CLI::Range(0, 1024));
      },
      [&] {
        options.charuco_refine = !raw_charuco;
        options.max_image_pixels = photo.options.max_image_pixels = static_cast<std::uint64_t>(max_image_mpx * 1e6);
        if (!chessboard.empty()) {
          std::tie(spec.cols, spec.rows) = detect::parse_grid(chessboard, "--chessboard");
          spec.kind = detect::BoardKind::Chessboard;
        } else if (!charuco.empty()) {
          std::tie(spec.cols, spec.rows) = detect::parse_grid(charuco, "--charuco");
          spec.kind = detect::BoardKind::Charuco;
        } else if (detect::photo_mode(photo)) {
          photo.marker_mm = spec.marker_mm;
          photo.options.jobs = options.jobs;
          return detect::run_photos(photo, detect::expand_image_arguments(images, *tool::open_input("-")), output);
        } else {
          throw UsageError("say what to detect: --chessboard COLSxROWS, --charuco COLSxROWS, --aruco DICT, "
                           "--aruco-dict-file FILE or --features DIR");
        }
        detect::run_boards(spec, options, images, print_board, output, photo.draw);
      });
}
