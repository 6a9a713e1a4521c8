// targets: the layouts (sheet.cpp), the PDF and SVG writers (render.cpp), and the printed targets
// themselves: each sheet is rendered by poppler's pdftoppm at a known DPI and photomill's detect
// must find every marker, its corners (scaled by the DPI) within 0.05 mm of the control points
// CSV after a 2D rigid fit (rotation and translation, no scale: the scale is the DPI's).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include <Eigen/Dense>

#include "formats/error.hpp"
#include "formats/tables.hpp"
#include "targets/render.hpp"
#include "targets/sheet.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::targets {
namespace {

using test::run_tool;

TEST(Paper, NamesAndSizes) {
  EXPECT_EQ(paper_size_mm("A4"), Eigen::Vector2d(210, 297));
  EXPECT_EQ(paper_size_mm("letter"), Eigen::Vector2d(215.9, 279.4));
  EXPECT_EQ(paper_size_mm("300x200"), Eigen::Vector2d(300, 200));
  EXPECT_THROW(paper_size_mm("A9"), UsageError);
  EXPECT_THROW(paper_size_mm("10x10"), UsageError);
  EXPECT_THROW(paper_size_mm("x200"), UsageError);
}

// Every object offset of the cross-reference table points at its "N 0 obj"; startxref at "xref";
// the page is A4 in points (72 per inch).
TEST(Pdf, CrossReferenceTableAndPageSizeAreExact) {
  const TargetSheet t = charuco_sheet({}, {});
  std::ostringstream s;
  write_pdf(s, t.sheet);
  const std::string pdf = s.str();
  ASSERT_EQ(pdf.rfind("%PDF-1.4\n", 0), 0u);
  const auto sx = pdf.rfind("startxref\n");
  ASSERT_NE(sx, std::string::npos);
  const std::size_t xref = std::stoul(pdf.substr(sx + 10));
  ASSERT_EQ(pdf.compare(xref, 5, "xref\n"), 0);
  std::istringstream table(pdf.substr(xref + 5));
  int first = 0, count = 0;
  table >> first >> count;
  ASSERT_EQ(count, 7);
  std::string off, gen, kind;
  table >> off >> gen >> kind;
  EXPECT_EQ(kind, "f");
  for (int i = 1; i < count; ++i) {
    table >> off >> gen >> kind;
    EXPECT_EQ(kind, "n");
    const std::string expect = std::to_string(i) + " 0 obj\n";
    EXPECT_EQ(pdf.compare(std::stoul(off), expect.size(), expect), 0) << "object " << i;
  }
  // Landscape A4 (the 7x5 board is wider than high): 297 x 210 mm = 841.8898 x 595.2756 pt.
  EXPECT_NE(pdf.find("/MediaBox [0 0 841.8898 595.2756]"), std::string::npos);
  const std::regex length("/Length ([0-9]+) >>\nstream\n");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(pdf, m, length));
  const std::size_t begin = static_cast<std::size_t>(m.position(0) + m.length(0));
  EXPECT_EQ(pdf.compare(begin + std::stoul(m[1]), 9, "endstream"), 0);
}

TEST(Svg, SizeInMillimetresAndEscapedText) {
  PageOptions page;
  page.command = "targets plate --x \"a<b&c\"";
  const TargetSheet t = plate_sheet({}, page);
  std::ostringstream s;
  write_svg(s, t.sheet);
  EXPECT_NE(s.str().find("width=\"297mm\" height=\"210mm\" viewBox=\"0 0 297 210\""), std::string::npos);
  EXPECT_NE(s.str().find("&quot;a&lt;b&amp;c&quot;"), std::string::npos);
  EXPECT_EQ(s.str().find("a<b"), std::string::npos);
}

// The plate's control points: four per marker, ids x 4 + corner, corner 0 top-left then
// clockwise, the frame centred on the ring, every marker inside the printable area.
TEST(Plate, ControlPointsFollowTheMarkerCorners) {
  PlateTarget p;
  p.marker_mm = 20;
  p.first_id = 3;
  const TargetSheet t = plate_sheet(p, {});
  ASSERT_GE(t.marker_ids.size(), 8u);
  ASSERT_EQ(t.control_points.size(), 4 * t.marker_ids.size());
  EXPECT_EQ(t.marker_ids.front(), 3);
  std::map<PointId, Eigen::Vector3d> xyz;
  for (const auto& c : t.control_points) xyz[c.point_id] = c.xyz_mm;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const int id : t.marker_ids) {
    const auto& c0 = xyz.at(4 * id);
    EXPECT_NEAR((xyz.at(4 * id + 1) - c0 - Eigen::Vector3d(20, 0, 0)).norm(), 0, 1e-9);
    EXPECT_NEAR((xyz.at(4 * id + 2) - c0 - Eigen::Vector3d(20, -20, 0)).norm(), 0, 1e-9);
    EXPECT_NEAR((xyz.at(4 * id + 3) - c0 - Eigen::Vector3d(0, -20, 0)).norm(), 0, 1e-9);
    for (int c = 0; c < 4; ++c) {
      lo = lo.cwiseMin(xyz.at(4 * id + c));
      hi = hi.cwiseMax(xyz.at(4 * id + c));
    }
  }
  EXPECT_NEAR((lo + hi).norm(), 0, 1e-9) << "the ring is centred on the origin";
  EXPECT_LE(hi.x() - lo.x(), t.sheet.width_mm - 2 * 8 + 1e-9);
  // Ring: marker 1 is right of marker 0 on the top row, the last one below marker 0.
  EXPECT_GT(xyz.at(4 * 4).x(), xyz.at(4 * 3).x());
  EXPECT_NEAR(xyz.at(4 * 4).y(), xyz.at(4 * 3).y(), 1e-9);
  EXPECT_LT(xyz.at(4 * t.marker_ids.back()).y(), xyz.at(4 * 3).y());
  EXPECT_NEAR(xyz.at(4 * t.marker_ids.back()).x(), xyz.at(4 * 3).x(), 1e-9);
}

TEST(Plate, ScaleBarJoinsCorrespondingCornersOfTwoNewMarkers) {
  PlateTarget p;
  p.scale_bar_mm = 150;
  const TargetSheet t = plate_sheet(p, {});
  ASSERT_EQ(t.scale_bars.size(), 4u);
  const int last = t.marker_ids.back();
  for (int c = 0; c < 4; ++c) {
    EXPECT_EQ(t.scale_bars[static_cast<std::size_t>(c)].point_a, 4 * (last + 1) + c);
    EXPECT_EQ(t.scale_bars[static_cast<std::size_t>(c)].point_b, 4 * (last + 2) + c);
    EXPECT_EQ(t.scale_bars[static_cast<std::size_t>(c)].distance_mm, 150);
  }
}

TEST(Targets, RefusalsNameTheSizesAndWhatToChange) {
  CharucoTarget big;
  big.squares_x = 12;
  try {
    charuco_sheet(big, {});
    FAIL() << "a 12x5 board of 30 mm squares does not fit A4";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("360 x 150 mm"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--paper"), std::string::npos) << e.what();
  }
  CharucoTarget small_dict;
  small_dict.squares_x = 11;
  small_dict.squares_y = 11;
  small_dict.square_mm = 15;
  small_dict.marker_mm = 11;
  small_dict.dictionary = "DICT_4X4_50";
  EXPECT_THROW(charuco_sheet(small_dict, {}), UsageError);  // 60 markers, 50 in the dictionary
  PlateTarget many;
  many.layout = PlateLayout::Grid;
  many.marker_mm = 10;
  many.dictionary = "DICT_4X4_50";
  try {
    plate_sheet(many, {});
    FAIL() << "a grid of 10 mm markers on A4 needs more than 50 ids";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("DICT_4X4_50 has 50 markers"), std::string::npos) << e.what();
  }
  PlateTarget tight;
  tight.pitch_mm = 25;  // 24 mm markers: one 4 mm cell of white each side needs 32 mm
  EXPECT_THROW(plate_sheet(tight, {}), UsageError);
  PlateTarget no_room;
  no_room.marker_mm = 150;
  EXPECT_THROW(plate_sheet(no_room, {}), UsageError);
}

// --- The command line ------------------------------------------------------------------------

TEST(Cli, PdfOnStdoutAndEveryOutputOnRequest) {
  test::TempDir dir;
  const auto r = run_tool("targets", {"plate", "--svg", "p.svg", "--control-points", "c.csv", "--scale-bar-mm", "120",
                                      "--scale-bars", "bars.csv", "--orientation", "portrait"},
                          "", dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("%PDF-1.4", 0), 0u);
  EXPECT_NE(r.out.find("/MediaBox [0 0 595.2756 841.8898]"), std::string::npos) << "A4 portrait";
  EXPECT_NE(test::read_file(dir.path() / "p.svg").find("<svg"), std::string::npos);
  std::ifstream c(dir.path() / "c.csv");
  EXPECT_GE(read_control_points(c, "c.csv").size(), 16u);
  std::ifstream b(dir.path() / "bars.csv");
  EXPECT_EQ(read_scale_bars(b, "bars.csv").size(), 4u);
  EXPECT_NE(r.err.find("detect --aruco DICT_4X4_100"), std::string::npos) << r.err;
}

// Control points' largest |x| and |y|, mm.
Eigen::Vector2d control_extent(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  Eigen::Vector2d extent = Eigen::Vector2d::Zero();
  for (const auto& p : read_control_points(in, csv.string())) extent = extent.cwiseMax(p.xyz_mm.head<2>().cwiseAbs());
  return extent;
}

TEST(Cli, MarginMmKeepsTheMarkersFartherFromTheSheetsEdge) {
  test::TempDir dir;
  const auto wide = run_tool("targets", {"plate", "--control-points", "wide.csv", "-o", "wide.pdf"}, "", dir.path());
  const auto narrow = run_tool("targets", {"plate", "--margin-mm", "40", "--control-points", "narrow.csv", "-o", "narrow.pdf"},
                               "", dir.path());
  ASSERT_EQ(wide.exit_code, 0) << wide.err;
  ASSERT_EQ(narrow.exit_code, 0) << narrow.err;
  const Eigen::Vector2d w = control_extent(dir.path() / "wide.csv");
  const Eigen::Vector2d n = control_extent(dir.path() / "narrow.csv");
  EXPECT_LT(n.x(), w.x() - 20);
  EXPECT_LT(n.y(), w.y() - 20);
  const auto bad = run_tool("targets", {"plate", "--margin-mm", "101", "-o", "bad.pdf"}, "", dir.path());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--margin-mm"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "bad.pdf"));
}

TEST(Cli, DictFileDrawsTheMarkersOfACustomDictionary) {
  // OpenCV's tutorial dictionary (35 markers of 6 x 6 bits), as detect --aruco-dict-file reads it.
  const std::string dict = std::string(PHOTOMILL_SHARED_DIR) + "/data/opencv-aruco/tutorial_dict.yml";
  if (!std::filesystem::exists(dict) && !std::getenv("CI")) GTEST_SKIP() << dict << " missing";
  test::TempDir dir;
  const auto custom = run_tool("targets", {"plate", "--dict-file", dict, "-o", "custom.pdf"}, "", dir.path());
  const auto plain = run_tool("targets", {"plate", "-o", "plain.pdf"}, "", dir.path());
  ASSERT_EQ(custom.exit_code, 0) << custom.err;
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_NE(custom.err.find("detect --aruco-dict-file " + dict), std::string::npos) << custom.err;
  EXPECT_NE(test::read_file(dir.path() / "custom.pdf"), test::read_file(dir.path() / "plain.pdf"));
  const auto both = run_tool("targets", {"plate", "--dict-file", dict, "--dict", "DICT_4X4_100", "-o", "both.pdf"}, "",
                             dir.path());
  EXPECT_EQ(both.exit_code, 2) << both.err;
  const auto missing = run_tool("targets", {"plate", "--dict-file", "nodict.yml", "-o", "missing.pdf"}, "", dir.path());
  EXPECT_EQ(missing.exit_code, 1) << missing.err;
  EXPECT_NE(missing.err.find("nodict.yml"), std::string::npos) << missing.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "missing.pdf"));
}

TEST(Cli, BadUsageIsExitTwoAndWritesNothing) {
  test::TempDir dir;
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::vector<Case> cases{
      {{}, "give what to make"},
      {{"plate", "--scale-bar-mm", "100", "-o", "p.pdf"}, "--scale-bar-mm needs --scale-bars"},
      {{"plate", "--scale-bars", "b.csv", "-o", "p.pdf"}, "--scale-bars needs --scale-bar-mm"},
      {{"plate", "--paper", "B5", "-o", "p.pdf"}, "--paper 'B5'"},
      {{"charuco", "--squares", "7", "-o", "p.pdf"}, "--squares"},
      {{"charuco", "--marker-mm", "30", "-o", "p.pdf"}, "--marker-mm"},
      {{"charuco", "--dict", "DICT_9X9", "-o", "p.pdf"}, "DICT_9X9"},
      {{"charuco", "--squares", "9x7", "--square-mm", "50", "-o", "p.pdf"}, "does not fit"},
      {{"charuco", "--squares", "20x20", "-o", "p.pdf"}, "DICT_5X5_100 has 100"},
  };
  for (const auto& c : cases) {
    const auto r = run_tool("targets", c.args, "", dir.path());
    EXPECT_EQ(r.exit_code, 2) << c.message << ": " << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "a refused run leaves no file";
}

// --- The printed sheets, rendered and detected -------------------------------------------------

std::string pdftoppm() {
  for (const char* p : {"/usr/bin/pdftoppm", "/usr/local/bin/pdftoppm"}) {
    if (std::filesystem::exists(p)) return p;
  }
  return "";
}

// Largest distance between the control points and the detected corners (page mm) after the 2D
// rigid fit (Kabsch: R = V diag(1, det) U^T of the cross-covariance; a reflection is not allowed).
double rigid_fit_max_mm(const std::vector<Eigen::Vector2d>& truth, const std::vector<Eigen::Vector2d>& seen, double* rms_mm) {
  Eigen::Vector2d mt = Eigen::Vector2d::Zero(), ms = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < truth.size(); ++i) {
    mt += truth[i];
    ms += seen[i];
  }
  mt /= static_cast<double>(truth.size());
  ms /= static_cast<double>(truth.size());
  Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
  for (std::size_t i = 0; i < truth.size(); ++i) h += (truth[i] - mt) * (seen[i] - ms).transpose();
  Eigen::JacobiSVD<Eigen::Matrix2d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix2d d = Eigen::Matrix2d::Identity();
  d(1, 1) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix2d r = svd.matrixV() * d * svd.matrixU().transpose();
  double worst = 0, sum2 = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const Eigen::Vector2d e = r * (truth[i] - mt) + ms - seen[i];
    worst = std::max(worst, e.norm());
    sum2 += e.squaredNorm();
    if (std::getenv("TARGETS_TEST_DUMP")) std::cout << i << " " << e.transpose() << "\n";
  }
  if (rms_mm) *rms_mm = std::sqrt(sum2 / static_cast<double>(truth.size()));
  return worst;
}

struct Rendered {
  std::vector<ControlPoint> control;
  std::vector<Observation> observations;
  double page_height_mm = 0;
};

// targets ARGS -> sheet.pdf -> pdftoppm at `dpi` -> detect DETECT_ARGS.
Rendered render_and_detect(const std::vector<std::string>& targets_args, int dpi, const std::vector<std::string>& detect_args) {
  Rendered out;
  const std::string tool = pdftoppm();
  if (tool.empty()) {
    if (std::getenv("CI")) ADD_FAILURE() << "pdftoppm (poppler-utils) is not installed: scripts/install-deps.sh --tests installs it";
    return out;
  }
  test::TempDir dir;
  std::vector<std::string> args = targets_args;
  for (const std::string a : {"-o", "sheet.pdf", "--control-points", "control.csv"}) args.push_back(a);
  const auto t = run_tool("targets", args, "", dir.path());
  EXPECT_EQ(t.exit_code, 0) << t.err;
  const auto r = run_tool(tool, {"-r", std::to_string(dpi), "-gray", "-png", "-singlefile", "sheet.pdf", "sheet"}, "", dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> d = detect_args;
  d.push_back((dir.path() / "sheet.png").string());
  const auto found = run_tool("detect", d, "", dir.path());
  EXPECT_EQ(found.exit_code, 0) << found.err;
  std::istringstream obs(found.out);
  out.observations = read_observations(obs, "detect");
  std::ifstream control(dir.path() / "control.csv");
  out.control = read_control_points(control, "control.csv");
  // The page height from the PDF's MediaBox (points).
  const std::string pdf = test::read_file(dir.path() / "sheet.pdf");
  std::smatch m;
  const std::regex box("/MediaBox \\[0 0 ([0-9.]+) ([0-9.]+)\\]");
  EXPECT_TRUE(std::regex_search(pdf, m, box));
  if (!m.empty()) out.page_height_mm = std::stod(m[2]) * 25.4 / 72;
  return out;
}

// pdftoppm's pixel (i, j) covers [i, i + 1) x [j, j + 1) in device pixels; OpenCV's pixel centre
// is at the integer: page x = (u + 0.5) 25.4 / dpi, page y (up) = height - (v + 0.5) 25.4 / dpi.
void expect_corners_match(const Rendered& r, int dpi, bool y_up, std::size_t expect_points) {
  if (r.observations.empty() && !std::getenv("CI") && pdftoppm().empty()) GTEST_SKIP() << "pdftoppm not installed";
  std::map<PointId, Eigen::Vector2d> truth;
  for (const auto& c : r.control) truth[c.point_id] = c.xyz_mm.head<2>();
  std::vector<Eigen::Vector2d> a, b;
  for (const auto& o : r.observations) {
    const auto it = truth.find(o.point_id);
    ASSERT_NE(it, truth.end()) << "detect found point " << o.point_id << ", not in the control points";
    const double x = (o.u_px + 0.5) * 25.4 / dpi;
    const double yd = (o.v_px + 0.5) * 25.4 / dpi;
    a.push_back(it->second);
    b.push_back({x, y_up ? r.page_height_mm - yd : yd});
  }
  EXPECT_EQ(a.size(), expect_points) << "every corner of every marker is found";
  ASSERT_GE(a.size(), 3u);
  double rms = 0;
  const double worst = rigid_fit_max_mm(a, b, &rms);
  std::cout << "[ targets  ] " << a.size() << " corners at " << dpi << " dpi: after a rigid fit RMS " << rms
            << " mm, largest " << worst << " mm\n";
  EXPECT_LT(worst, 0.05);
}

// 300 dpi: poppler's anti-aliasing samples 4 x 4 per pixel, so a rendered edge lands on a quarter
// pixel (0.021 mm at 300 dpi; at 150 dpi 0.042 mm, and the largest corner distance is 0.055 mm).
// TARGETS_TEST_DPI measures other resolutions (docs/measurements/targets.md).
int test_dpi() {
  const char* env = std::getenv("TARGETS_TEST_DPI");
  return env ? std::atoi(env) : 300;
}

TEST(Printed, PlateMarkersAreFoundAtTheirControlPoints) {
  const int dpi = test_dpi();
  const Rendered r = render_and_detect({"plate", "--paper", "A4"}, dpi, {"--aruco", "DICT_4X4_100", "--edge-degree", "1"});
  expect_corners_match(r, dpi, true, r.control.size());
}

TEST(Printed, GridPlateOnLetterWithACustomPitch) {
  const int dpi = test_dpi();
  const Rendered r = render_and_detect({"plate", "--paper", "Letter", "--layout", "grid", "--marker-mm", "20",
                                        "--pitch-mm", "34", "--first-id", "10", "--dict", "DICT_5X5_100"},
                                       dpi, {"--aruco", "DICT_5X5_100", "--edge-degree", "1"});
  expect_corners_match(r, dpi, true, r.control.size());
}

// The board's frame is OpenCV's (y down the sheet, as CharucoBoard::draw renders it): the corners
// match with the image's own orientation.
TEST(Printed, CharucoBoardCornersAreFoundAtTheBoardPoints) {
  const int dpi = test_dpi();
  const Rendered r = render_and_detect({"charuco"}, dpi,
                                       {"--charuco", "7x5", "--square-mm", "30", "--marker-mm", "22", "--dict", "DICT_5X5_100"});
  expect_corners_match(r, dpi, false, r.control.size());
}

}  // namespace
}  // namespace photomill::targets
