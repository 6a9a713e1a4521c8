// detect's board modes (see board_cli.hpp).
#include "detect/board_cli.hpp"

#include <optional>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tables.hpp"
#include "formats/tool.hpp"

namespace photomill::detect {

void run_boards(BoardSpec spec, const BoardDetectOptions& options, const std::vector<std::string>& image_args,
                bool print_board, const std::string& output, const DrawOptions& draw) {
  validate_board(spec);
  if (print_board && !draw.dir.empty()) throw UsageError("--draw needs images, not --print-board");
  tool::OutputFile out(output);
  if (print_board) {
    write_control_points(out.stream(), board_control_points(spec));
    out.commit();
    return;
  }
  const auto images = expand_image_arguments(image_args, *tool::open_input("-"));
  if (images.empty()) throw UsageError("no images given");
  std::optional<DrawingFiles> drawings;
  BoardImageHook draw_hook;
  if (!draw.dir.empty()) {
    drawings.emplace(draw, images);
    draw_hook = [&](const cv::Mat& grey, const ImageDetection& r) {
      drawings->write(r.image, draw_board(grey, r, spec, draw));
    };
  }
  const auto results = detect_boards(
      images, spec, options, [](const ImageDetection& r) { log::info(describe(r)); }, draw_hook);
  std::vector<Observation> observations;
  int found = 0;
  for (const auto& r : results) {
    found += r.found ? 1 : 0;
    observations.insert(observations.end(), r.observations.begin(), r.observations.end());
  }
  if (found == 0) throw GeometryError("no board found in any of the " + std::to_string(images.size()) + " images");
  write_observations(out.stream(), observations);
  out.commit();
  log::info("board found in " + std::to_string(found) + " of " + std::to_string(images.size()) + " images, " +
            std::to_string(observations.size()) + " corners");
}

}  // namespace photomill::detect
