// One case per detect option of the marker edge fit, the SIFT features, the mask and the ChArUco
// refinement (issue 22): the option parses and has its documented effect (docs/detect.md, --help)
// on the observations or the features written; a value out of its range exits 2 naming the option.
// Inputs: a 450 x 500 px crop of the demo's part photo part_00.jpg with four ArUco DICT_4X4_100
// markers and the part's speckle (a crop keeps SIFT quick), and the board photo board_00.jpg.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "formats/features.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::detect {
namespace {

using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

const std::string kDemo = std::string(PHOTOMILL_SOURCE_DIR) + "/data/demo/";
const std::string kBoard = kDemo + "board_00.jpg";
const std::string kRight05 = std::string(PHOTOMILL_SHARED_DIR) + "/data/opencv-chessboard/right05.jpg";

// The crop, written once (lossless) into a temporary folder.
struct Crop {
  TempDir dir;
  std::string path = (dir.path() / "part.png").string();
  Crop() {
    const cv::Mat photo = cv::imread(kDemo + "part_00.jpg", cv::IMREAD_GRAYSCALE);
    cv::imwrite(path, photo(cv::Rect(820, 440, 450, 500)).clone());
  }
};
const std::string& part() {
  static const Crop crop;
  return crop.path;
}

struct Outcome {
  ToolResult r;
  std::vector<Observation> observations;  // stdout
  std::size_t features = 0;               // keypoints in the .feat file (with "{feat}")
  double mean_size_px = 0;                // their mean size
};

// detect with `args`; "{feat}" becomes a temporary features folder.
Outcome detect(std::vector<std::string> args) {
  TempDir dir;
  bool feat = false;
  for (std::string& a : args) {
    if (a == "{feat}") a = (dir.path() / "feat").string(), feat = true;
  }
  Outcome run{run_tool("detect", args), {}, 0};
  if (run.r.exit_code == 0 && !run.r.out.empty()) {
    std::istringstream out(run.r.out);
    run.observations = read_observations(out, "stdout");
  }
  if (feat && run.r.exit_code == 0) {
    std::ifstream in(dir.path() / "feat" / "part.png.feat");
    const FeatureSet fs = read_features(in, "part.png.feat");
    run.features = fs.keypoints.size();
    for (const auto& k : fs.keypoints) run.mean_size_px += k.size_px / static_cast<double>(run.features);
  }
  return run;
}

std::vector<std::string> markers(std::vector<std::string> args) {
  args.insert(args.end(), {"--aruco", "DICT_4X4_100", part()});
  return args;
}
std::vector<std::string> sift(std::vector<std::string> args) {
  args.insert(args.end(), {"--features", "{feat}", "--max-features", "0", part()});
  return args;
}
std::vector<std::string> board(std::vector<std::string> args) {
  args.insert(args.end(), {"--charuco", "7x5", "--square-mm", "30", "--marker-mm", "22", "--dict", "DICT_5X5_100", kBoard});
  return args;
}

const Outcome& plain_markers() {
  static const Outcome run = detect(markers({}));
  return run;
}
const Outcome& plain_sift() {
  static const Outcome run = detect(sift({}));
  return run;
}

// Largest corner shift between two runs' observations of the same points.
double max_shift(const std::vector<Observation>& a, const std::vector<Observation>& b) {
  double m = 0;
  std::size_t matched = 0;
  for (const auto& x : a) {
    for (const auto& y : b) {
      if (x.point_id == y.point_id && x.image == y.image) {
        m = std::max(m, std::hypot(x.u_px - y.u_px, x.v_px - y.v_px));
        ++matched;
      }
    }
  }
  EXPECT_GT(matched, 0u);
  return m;
}

// The same markers as the plain run, with corners moved (the option changed the edge fit).
void moves_corners(const Outcome& r) {
  ASSERT_GT(plain_markers().observations.size(), 0u);
  EXPECT_EQ(r.observations.size(), plain_markers().observations.size());
  EXPECT_GT(max_shift(r.observations, plain_markers().observations), 1e-4);
}

struct OptionCase {
  const char* name;
  std::vector<std::string> args;
  int exit_code;
  std::string stderr_has;
  std::function<void(const Outcome&)> check;
};

void PrintTo(const OptionCase& c, std::ostream* os) { *os << c.name; }

class DetectOption : public ::testing::TestWithParam<OptionCase> {};

TEST_P(DetectOption, ParsesAndHasItsEffect) {
  const OptionCase& c = GetParam();
  const Outcome run = detect(c.args);
  ASSERT_EQ(run.r.exit_code, c.exit_code) << run.r.err;
  if (!c.stderr_has.empty()) {
    EXPECT_NE(run.r.err.find(c.stderr_has), std::string::npos) << run.r.err;
  }
  if (c.check) c.check(run);
}

OptionCase bad(const char* name, std::vector<std::string> args, std::string option) {
  return {name, markers(std::move(args)), 2, std::move(option), nullptr};
}

INSTANTIATE_TEST_SUITE_P(
    Options, DetectOption,
    ::testing::Values(
        // Markers: corner refinement and the edge fit (the default --corner-refine edges).
        // Issue #25: the pixel limit, checked from the header before decoding (a 16000 x 16000
        // header is refused by default: docs/errors.md); lowered below the photo it refuses it.
        OptionCase{"max_image_mpx", markers({"--max-image-mpx", "0.1"}), 1, "its header claims 450x500 pixels (0.225 Mpx), more than the 0.1 Mpx a photo may have", nullptr},
        OptionCase{"max_image_mpx_raised", markers({"--max-image-mpx", "300"}), 0, "",
                   [](const Outcome& r) { EXPECT_EQ(r.observations.size(), plain_markers().observations.size()); }},
        bad("max_image_mpx_nan", {"--max-image-mpx", "nan"}, "--max-image-mpx"),
        OptionCase{"corner_refine", markers({"--corner-refine", "subpix"}), 0, "", moves_corners},
        bad("corner_refine_bad", {"--corner-refine", "lines"}, "--corner-refine"),
        OptionCase{"edge_degree", markers({"--edge-degree", "1"}), 0, "", moves_corners},
        bad("edge_degree_4", {"--edge-degree", "4"}, "--edge-degree"),
        OptionCase{"edge_span", markers({"--edge-span", "0.4"}), 0, "", moves_corners},
        bad("edge_span_0_1", {"--edge-span", "0.1"}, "--edge-span"),
        OptionCase{"edge_max_window_px", markers({"--edge-max-window-px", "1.5"}), 0, "", moves_corners},
        bad("edge_max_window_px_0_5", {"--edge-max-window-px", "0.5"}, "--edge-max-window-px"),
        OptionCase{"edge_min_contrast", markers({"--edge-min-contrast", "250"}), 0, "is below 250",
                   // No printed marker in the photo has 250 grey levels between black and white.
                   [](const Outcome& r) { EXPECT_LT(r.observations.size(), plain_markers().observations.size()); }},
        bad("edge_min_contrast_300", {"--edge-min-contrast", "300"}, "--edge-min-contrast"),
        OptionCase{"edge_max_blur_px", markers({"--edge-max-blur-px", "0.1"}), 0, "px too large",
                   [](const Outcome& r) { EXPECT_LT(r.observations.size(), plain_markers().observations.size()); }},
        bad("edge_max_blur_px_zero", {"--edge-max-blur-px", "0"}, "--edge-max-blur-px"),
        OptionCase{"edge_gamma", markers({"--edge-gamma", "2.2"}), 0, "", moves_corners},
        bad("edge_gamma_6", {"--edge-gamma", "6"}, "--edge-gamma"),
        // The crop's part markers have 8-9 px cells: without the code their bands stay half a
        // cell wide, with it (the default) the first pass widens them (markers.hpp), so their
        // corners move a little.
        OptionCase{"edge_ignore_code", markers({"--edge-ignore-code"}), 0, "", moves_corners},
        // Without the quick start (1000 px: no marker has such cells) every edge takes both fine
        // rounds from scratch: the same markers, their corners within ~0.05 px of the quick ones
        // but not identical.
        OptionCase{"edge_quick_min_cell_px", markers({"--edge-quick-min-cell-px", "1000"}), 0, "",
                   [](const Outcome& r) {
                     ASSERT_EQ(r.observations.size(), plain_markers().observations.size());
                     const double shift = max_shift(r.observations, plain_markers().observations);
                     EXPECT_GT(shift, 1e-4);
                     EXPECT_LT(shift, 0.05);
                   }},
        bad("edge_quick_min_cell_px_nan", {"--edge-quick-min-cell-px", "nan"}, "--edge-quick-min-cell-px"),
        // Windows 13 and 23 px instead of OpenCV's 3, 13 and 23: on the test photo the same markers,
        // the edge fit started from other polygons (within its tolerance of the same corners).
        OptionCase{"threshold_window_min_px", markers({"--threshold-window-min-px", "13"}), 0, "",
                   [](const Outcome& r) {
                     ASSERT_EQ(r.observations.size(), plain_markers().observations.size());
                     EXPECT_LT(max_shift(r.observations, plain_markers().observations), 0.05);
                   }},
        OptionCase{"threshold_window_min_px_0", markers({"--threshold-window-min-px", "0"}), 2, "--threshold-window-min-px", nullptr},
        OptionCase{"aruco_error_correction", markers({"--aruco-error-correction", "0"}), 0, "",
                   [](const Outcome& r) {
                     // The demo's markers are read without error: no correction finds them all the same.
                     EXPECT_EQ(r.observations.size(), plain_markers().observations.size());
                   }},
        bad("aruco_error_correction_1_5", {"--aruco-error-correction", "1.5"}, "--aruco-error-correction"),
        // SIFT features
        OptionCase{"sift_edge_threshold", sift({"--sift-edge-threshold", "2"}), 0, "",
                   [](const Outcome& r) {
                     ASSERT_GT(plain_sift().features, 0u);
                     EXPECT_LT(r.features, plain_sift().features);
                   }},
        bad("sift_edge_threshold_0_5", {"--sift-edge-threshold", "0.5"}, "--sift-edge-threshold"),
        OptionCase{"sift_contrast_threshold", sift({"--sift-contrast-threshold", "0.08"}), 0, "",
                   [](const Outcome& r) {
                     // A higher threshold than the default 0.01 drops the faint features.
                     ASSERT_GT(plain_sift().features, 0u);
                     EXPECT_LT(r.features, plain_sift().features);
                   }},
        bad("sift_contrast_threshold_2", {"--sift-contrast-threshold", "2"}, "--sift-contrast-threshold"),
        // --preset features: the four feature options of the measured chain, an option given wins.
        OptionCase{"preset_features", {"--aruco", "DICT_4X4_100", "--features", "{feat}", "--preset", "features", part()}, 0, "",
                   [](const Outcome& r) {
                     const Outcome spelt = detect({"--aruco", "DICT_4X4_100", "--features", "{feat}", "--mask-markers",
                                                   "--mask-clearance-per-size", "1", "--max-features", "20000",
                                                   "--cap-cell-px", "64", part()});
                     const Outcome plain = detect({"--aruco", "DICT_4X4_100", "--features", "{feat}", part()});
                     EXPECT_EQ(r.features, spelt.features);
                     EXPECT_NE(r.features, plain.features);
                     const Outcome capped = detect({"--aruco", "DICT_4X4_100", "--features", "{feat}", "--preset", "features",
                                                    "--max-features", "50", part()});
                     EXPECT_EQ(capped.features, 50u);
                   }},
        bad("preset_unknown", {"--preset", "fast"}, "--preset"),
        // --cap-order scale: the cap keeps the largest features, not the strongest.
        OptionCase{"cap_order", {"--features", "{feat}", "--max-features", "50", "--cap-order", "scale", part()}, 0, "",
                   [](const Outcome& r) {
                     const Outcome strongest = detect({"--features", "{feat}", "--max-features", "50", part()});
                     EXPECT_EQ(r.features, 50u);
                     EXPECT_EQ(strongest.features, 50u);
                     EXPECT_GT(r.mean_size_px, 1.5 * strongest.mean_size_px) << strongest.mean_size_px;
                   }},
        bad("cap_order_unknown", {"--features", "{feat}", "--cap-order", "size", part()}, "--cap-order"),
        OptionCase{"sift_octave_layers", sift({"--sift-octave-layers", "1"}), 0, "",
                   [](const Outcome& r) {
                     EXPECT_GT(r.features, 0u);
                     EXPECT_NE(r.features, plain_sift().features);
                   }},
        bad("sift_octave_layers_11", {"--sift-octave-layers", "11"}, "--sift-octave-layers"),
        OptionCase{"mask_margin_cells", sift({"--aruco", "DICT_4X4_100", "--mask-markers", "--mask-margin-cells", "6"}), 0, "",
                   [](const Outcome& r) {
                     const Outcome narrow = detect(sift({"--aruco", "DICT_4X4_100", "--mask-markers", "--mask-margin-cells", "0"}));
                     ASSERT_EQ(narrow.r.exit_code, 0) << narrow.r.err;
                     EXPECT_LT(r.features, narrow.features);
                   }},
        bad("mask_margin_cells_negative", {"--mask-margin-cells", "-1"}, "--mask-margin-cells"),
        // ChArUco
        OptionCase{"charuco_max_window", board({"--charuco-max-window", "2"}), 0, "",
                   [](const Outcome& r) {
                     const Outcome wide = detect(board({}));
                     ASSERT_EQ(wide.r.exit_code, 0) << wide.r.err;
                     EXPECT_EQ(r.observations.size(), wide.observations.size());
                     EXPECT_GT(max_shift(r.observations, wide.observations), 1e-4);
                   }},
        OptionCase{"charuco_max_window_1", board({"--charuco-max-window", "1"}), 2, "--charuco-max-window", nullptr},
        // Chessboard: OpenCV's corners without the window check; right05's corner 45 is then the
        // one cornerSubPix pulls 4 px towards the board's edge (boards_test.cpp).
        OptionCase{"chessboard_window_check", {"--chessboard", "9x6", "--chessboard-window-check", "0", kRight05}, 0, "",
                   [](const Outcome& r) {
                     const Outcome checked = detect({"--chessboard", "9x6", kRight05});
                     ASSERT_EQ(checked.r.exit_code, 0) << checked.r.err;
                     ASSERT_EQ(r.observations.size(), 54u);
                     ASSERT_EQ(checked.observations.size(), 54u);
                     EXPECT_GT(checked.observations[45].v_px - r.observations[45].v_px, 3.0);
                   }},
        OptionCase{"chessboard_window_check_negative", {"--chessboard", "9x6", "--chessboard-window-check", "-1", kRight05}, 2,
                   "--chessboard-window-check", nullptr}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill::detect
