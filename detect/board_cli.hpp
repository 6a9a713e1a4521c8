// detect's board modes (--chessboard, --charuco): the run that reads the images and writes the
// corners' observations CSV, or with --print-board the board's control points CSV. Kept apart
// from main.cpp, which only reads the command line.
#pragma once

#include <string>
#include <vector>

#include "detect/boards.hpp"
#include "detect/draw.hpp"

namespace photomill::detect {

// Validates `spec`, detects the board in `image_args` (expanded as expand_image_arguments does,
// '-' reading paths from stdin) and writes the observations to `output` ("-": stdout), with
// `draw.dir` set also one drawing per image; with `print_board`, writes the board's control points
// instead. Throws UsageError for bad arguments, GeometryError when no image shows the board; on
// failure no output file is left behind.
void run_boards(BoardSpec spec, const BoardDetectOptions& options, const std::vector<std::string>& image_args,
                bool print_board, const std::string& output, const DrawOptions& draw);

}  // namespace photomill::detect
