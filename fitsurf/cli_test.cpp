// Golden CLI cases for the fitsurf executable (args, stdin -> exit code, stdout, stderr), and its
// outputs read back independently: surface text, JSON report, residual PLY, mesh, and STEP/IGES
// reopened through Open CASCADE (formats/cad) with identical poles and knots.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "fitsurf/preview.hpp"
#include "formats/plot.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/cad.hpp"
#include "formats/point_cloud.hpp"
#include "formats/surface.hpp"
#include "tests/run_tool.hpp"

namespace photomill::fitsurf {
namespace {

using photomill::test::run_tool;
using photomill::test::TempDir;
using photomill::test::ToolResult;

std::string xyz_text(const std::vector<Eigen::Vector3d>& pts) {
  PointCloud c;
  c.points_mm = pts;
  std::ostringstream out;
  write_xyz(out, c);
  return out.str();
}

std::string dome_points(std::size_t n) { return xyz_text(fitsurf::test::sample(fitsurf::test::shape("dome"), n, 0.01, 41)); }

struct CliCase {
  std::string name;
  std::vector<std::string> args;
  std::string stdin_text;
  int exit_code;
  std::string stdout_has;  // empty: stdout must be empty
  std::string stderr_has;  // empty: not checked
};

void PrintTo(const CliCase& c, std::ostream* os) { *os << c.name; }

class FitsurfGolden : public ::testing::TestWithParam<CliCase> {};

TEST_P(FitsurfGolden, Case) {
  const CliCase& c = GetParam();
  const ToolResult r = run_tool("fitsurf", c.args, c.stdin_text);
  EXPECT_EQ(r.exit_code, c.exit_code) << "stderr: " << r.err;
  if (c.stdout_has.empty()) {
    EXPECT_EQ(r.out, "");
  } else {
    EXPECT_NE(r.out.find(c.stdout_has), std::string::npos) << r.out.substr(0, 200);
  }
  EXPECT_NE(r.err.find(c.stderr_has), std::string::npos) << r.err;
}

std::vector<CliCase> golden_cases() {
  std::string collinear, flat;
  for (int k = 0; k < 100; ++k) collinear += std::to_string(k) + " " + std::to_string(2 * k) + " 30\n";
  for (int k = 0; k < 400; ++k) flat += std::to_string(k % 20) + " " + std::to_string(k / 20) + " 0\n";
  const std::string dome = dome_points(3000);
  const std::string markers = xyz_text(fitsurf::test::sample_grid(fitsurf::test::shape("dome"), 15, 10, 3.0, 0.01, 43));
  return {
      {"missing_input", {"no-such-cloud.xyz"}, "", 1, "", "no-such-cloud.xyz"},
      {"short_line", {"-"}, "1 2 3\n4 5\n", 1, "", "<stdin>:2:"},
      {"nan", {}, "1 2 3\n4 5 nan\n", 1, "", "<stdin>:2:"},
      {"empty_input", {}, "", 1, "", "no points"},
      {"too_few", {}, "1 2 3\n4 5 6\n7 8 10\n", 1, "", "too few"},
      {"collinear", {}, collinear, 1, "", "line"},
      {"flat_after_drop_plane", {"--drop-plane"}, flat, 1, "", "the cloud is flat"},
      {"bad_net", {"--net", "3y"}, dome, 2, "", "--net"},
      {"net_below_degree", {"--net", "3x30"}, dome, 2, "", "at least 4x4"},
      {"bad_knots", {"--knots", "bogus"}, dome, 2, "", "--knots"},
      {"bad_smoothing_order", {"--smoothing-order", "4"}, dome, 2, "", "--smoothing-order"},
      {"weight_by_sigma_without_sigma", {"--weight-by-sigma"}, dome, 1, "", "<stdin>: --weight-by-sigma: the cloud has no sigma_mm"},
      {"bad_sigma_floor", {"--weight-by-sigma", "--sigma-floor-mm", "0"}, dome, 2, "", "--sigma-floor-mm"},
      {"bad_mesh_extension", {"--mesh", "out.ply"}, dome, 2, "", ".stl or .obj"},
      {"report_on_stdout", {"--report", "-"}, dome, 2, "", "only -o"},
      {"box_needs_six", {"--keep-box", "1,2,3"}, dome, 2, "", "--keep-box"},
      {"tolerance_below_noise", {"--tolerance", "0.001"}, dome, 1, "", "cannot be met"},
      {"fits_stdin", {}, dome, 0, "photomill-surface v1", "residuals: RMS"},
      {"fits_order_3", {"--smoothing-order", "3", "--smoothing", "2"}, dome, 0, "photomill-surface v1", "smoothing 2 mm^6 (order 3)"},
      {"fits_with_options", {"-", "--net", "12x9", "--knots", "averaged", "--robust", "huber", "--solver", "cg"}, dome, 0,
       "poles 12 9", "12x9 poles, degree 3x3, averaged knots"},
      {"fits_adaptive_knots", {"--net", "20x14", "--knots", "adaptive"}, dome, 0, "photomill-surface v1",
       "20x14 poles, degree 3x3, adaptive knots"},
      {"sparse_gets_the_kernel", {}, markers, 0, "photomill-surface v1", "kernel prefit (150 points, fewer than the net's poles)"},
      {"sparse_spline_only", {"--prefit", "none"}, markers, 0, "photomill-surface v1", "residuals: RMS"},
      {"bad_prefit", {"--prefit", "rbf"}, markers, 2, "", "--prefit"},
      {"kernel_with_tolerance", {"--prefit", "kernel", "--tolerance", "0.05"}, markers, 2, "", "--prefit kernel and --tolerance"},
      {"tolerance_met", {"--tolerance", "0.05", "--tolerance-stat", "p95"}, dome, 0, "photomill-surface v1", "tolerance 0.05 mm (p95) met"},
      // A write that fails on a full device is an error, for outputs Open CASCADE writes too.
      {"step_to_a_full_device", {"--step", "/dev/full"}, dome, 1, "", "/dev/full: write failed"},
      {"iges_to_a_full_device", {"--iges", "/dev/full"}, dome, 1, "", "/dev/full: write failed"},
      {"surface_to_a_full_device", {"-o", "/dev/full"}, dome, 1, "", "/dev/full: write failed"},
  };
}

INSTANTIATE_TEST_SUITE_P(Cases, FitsurfGolden, ::testing::ValuesIn(golden_cases()), [](const auto& info) { return info.param.name; });

TEST(FitsurfCli, QuietMeansNothingOnStderr) {
  const ToolResult r = run_tool("fitsurf", {"-q"}, dome_points(2000));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  std::istringstream in(r.out);
  EXPECT_NO_THROW(read_surface(in, "<stdout>"));
}

// A cloud oriented without any datum (its PLY says units arbitrary): fitted, with a warning that
// nothing is in mm, and the report says the unit; a cloud in mm gives no such warning.
// A cloud without a datum (units arbitrary): fitsurf warns that its scale is not mm, names the
// length options that acted in the cloud's unit (only those: no --plane-threshold-mm without
// --drop-plane), lists them in the report, and writes `units arbitrary` into the surface (and
// into nothing for a cloud in mm).
TEST(FitsurfCli, WarnsThatAnArbitraryScaleIsNotMm) {
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  const auto has = [](const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; };
  PointCloud in;
  in.points_mm = fitsurf::test::sample(fitsurf::test::shape("dome"), 2000, 0.01, 41);
  for (const char* units : {"arbitrary", "mm"}) {
    in.units = units;
    const bool arbitrary = in.units == "arbitrary";
    {
      std::ofstream f(p("in.ply"), std::ios::binary);
      write_ply(f, in, PlyEncoding::BinaryLittleEndian);
    }
    const ToolResult r = run_tool("fitsurf", {p("in.ply"), "-o", p("s.surf"), "--report", p("r.json"), "--mesh", p("m.stl"),
                                              "--step", p("s.step")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(has(r.err, "warning: the point cloud's scale is arbitrary, not mm"), arbitrary) << r.err;
    EXPECT_EQ(has(r.err, "warning: these length options act in the cloud's unit, not in mm (the cloud's extent: "), arbitrary)
        << r.err;
    for (const char* acting : {"--mesh-step-mm 1 (default; ", "--wall-radius-mm 2 (default; ",
                               "--smoothing 0.01 (default; its 4th root 0.316, ", "--robust-floor-mm 0.02 (default; "}) {
      EXPECT_EQ(has(r.err, acting), arbitrary) << acting << "\n" << r.err;
    }
    for (const char* idle : {"--plane-threshold-mm", "--sigma-floor-mm", "--uncertainty-cell-mm", "--keep-box", "--tolerance"}) {
      EXPECT_FALSE(has(r.err, idle)) << idle << "\n" << r.err;
    }
    EXPECT_EQ(has(r.err, "give lengths in the cloud's unit, or give triangulate a datum"), arbitrary) << r.err;
    EXPECT_EQ(has(r.err, "s.step: the CAD file says millimetres, but the surface's scale is arbitrary"), arbitrary) << r.err;
    const std::string report = photomill::test::read_file(dir.path() / "r.json");
    EXPECT_TRUE(has(report, "\"units\":\"" + in.units + "\""));
    EXPECT_EQ(has(report, "\"length_options_in_cloud_units\":[{\"option\":\"--mesh-step-mm\",\"value\":1,\"default\":true,"),
              arbitrary) << report;
    EXPECT_EQ(has(report, "\"length_options_in_cloud_units\":[]"), !arbitrary) << report;
    std::ifstream sf(p("s.surf"));
    const BSplineSurface s = read_surface(sf, "s.surf");
    EXPECT_EQ(s.units, in.units);
    EXPECT_EQ(has(photomill::test::read_file(dir.path() / "s.surf"), "\nunits arbitrary\n"), arbitrary);
  }
  // Other options, other acting lengths: a plane off the origin, a given smoothing; no robust
  // floor without a robust mode, no wall radius with --walls off.
  const ToolResult r = run_tool("fitsurf", {p("in.ply"), "-o", p("s.surf"), "--robust", "none", "--walls", "off",
                                            "--keep-above", "0,0,1,100", "--smoothing", "0.5"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(has(r.err, "length options")) << "the cloud is in mm again\n" << r.err;
  in.units = "arbitrary";
  {
    std::ofstream f(p("in.ply"), std::ios::binary);
    write_ply(f, in, PlyEncoding::BinaryLittleEndian);
  }
  const ToolResult a = run_tool("fitsurf", {p("in.ply"), "-o", p("s.surf"), "--robust", "none", "--walls", "off",
                                            "--keep-above", "0,0,1,100", "--smoothing", "0.5"});
  ASSERT_EQ(a.exit_code, 0) << a.err;
  EXPECT_TRUE(has(a.err, "--keep-above 0,0,1,100 (a plane 100 from the origin, ")) << a.err;
  EXPECT_TRUE(has(a.err, "--smoothing 0.5 (its 4th root 0.841, ")) << a.err;
  for (const char* idle : {"--robust-floor-mm", "--wall-radius-mm", "--mesh-step-mm"}) {
    EXPECT_FALSE(has(a.err, idle)) << idle << "\n" << a.err;
  }
}

TEST(FitsurfCli, WritesEveryOutput) {
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  // A binary PLY input with an extra per-point property, which the residual cloud keeps.
  PointCloud in;
  in.points_mm = fitsurf::test::sample(fitsurf::test::shape("wave"), 5000, 0.01, 42);
  PointProperty& views = in.add_property("views", PlyScalar::UInt8);
  for (std::size_t k = 0; k < views.values.size(); ++k) views.values[k] = static_cast<double>(k % 9);
  {
    std::ofstream f(p("in.ply"), std::ios::binary);
    write_ply(f, in, PlyEncoding::BinaryLittleEndian);
  }
  const ToolResult r = run_tool("fitsurf", {p("in.ply"), "-o", p("s.surf"), "--report", p("r.json"), "--residuals", p("res.ply"),
                                            "--mesh", p("m.stl"), "--mesh-step-mm", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  std::ifstream sf(p("s.surf"));
  const BSplineSurface s = read_surface(sf, "s.surf");
  EXPECT_EQ(s.num_poles_u, 30);
  EXPECT_GE(s.boundary_uv.size(), 4u);
  const std::string report = photomill::test::read_file(p("r.json"));
  for (const char* key : {"\"rms_mm\":", "\"max_abs_mm\":", "\"p95_mm\":", "\"poles_u\":30", "\"smoothing_mm4\":", "\"round_rms_mm\":[",
                          "\"outliers\":", "\"tolerance\":null"}) {
    EXPECT_NE(report.find(key), std::string::npos) << key << " in " << report;
  }
  std::ifstream rf(p("res.ply"), std::ios::binary);
  const PointCloud res = read_ply(rf, "res.ply");
  ASSERT_EQ(res.points_mm.size(), in.points_mm.size());
  ASSERT_NE(res.find("residual_mm"), nullptr);
  ASSERT_NE(res.find("weight"), nullptr);
  ASSERT_NE(res.find("views"), nullptr);
  EXPECT_EQ(res.find("views")->values, views.values);
  double sum2 = 0;
  for (double d : res.find("residual_mm")->values) sum2 += d * d;
  EXPECT_NEAR(std::sqrt(sum2 / static_cast<double>(res.points_mm.size())), 0.01, 0.002);
  const std::string stl = photomill::test::read_file(p("m.stl"));
  ASSERT_GT(stl.size(), 84u);
  std::uint32_t triangles = 0;
  std::memcpy(&triangles, stl.data() + 80, 4);
  EXPECT_EQ(stl.size(), 84u + 50u * triangles);
  EXPECT_GT(triangles, 1000u);
}

TEST(FitsurfCli, AFailureLeavesNoFile) {
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  const ToolResult r = run_tool("fitsurf", {"-", "-o", p("s.surf"), "--report", p("r.json"), "--step", p("s.step"), "--mesh", p("m.obj")},
                                "1 2 3\n4 5 6\n7 8 10\n");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "no output and no temporary file";
}

// --preview (issue #9): a PNG of the size preview_size_px gives for the part's extent (read from
// the report), showing the shaded surface (grey) and points coloured by residual on both sides
// (red above, blue below).
struct PreviewCase {
  std::string name;
  std::size_t points;
  std::vector<std::string> args;
};

void PrintTo(const PreviewCase& c, std::ostream* os) { *os << c.name; }

class FitsurfPreview : public ::testing::TestWithParam<PreviewCase> {};

double json_number(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + key.size() + 3));
}

TEST_P(FitsurfPreview, WritesAPngOfTheExpectedSize) {
  const PreviewCase& c = GetParam();
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  const std::string points =
      c.points >= 2000 ? dome_points(c.points)
                       : xyz_text(fitsurf::test::sample_grid(fitsurf::test::shape("dome"), 15, 10, 3.0, 0.01, 43));
  std::vector<std::string> args = {"-", "-o", p("s.surf"), "--report", p("r.json"), "--preview", p("view.png")};
  args.insert(args.end(), c.args.begin(), c.args.end());
  const ToolResult r = run_tool("fitsurf", args, points);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string report = photomill::test::read_file(p("r.json"));
  PreviewOptions o;
  for (std::size_t k = 0; k + 1 < c.args.size(); ++k) {
    if (c.args[k] == "--preview-width-px") o.width_px = std::stoi(c.args[k + 1]);
  }
  const Eigen::Vector2i size = preview_size_px(json_number(report, "extent_u_mm"), json_number(report, "extent_v_mm"), o);
  const std::string png = photomill::test::read_file(p("view.png"));
  ASSERT_GT(png.size(), 24u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const auto be32 = [&](std::size_t at) {
    return (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at])) << 24) |
           (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 1])) << 16) |
           (static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 2])) << 8) |
           static_cast<std::uint32_t>(static_cast<unsigned char>(png[at + 3]));
  };
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(be32(16), static_cast<std::uint32_t>(size.x()));
  EXPECT_EQ(be32(20), static_cast<std::uint32_t>(size.y()));
  EXPECT_EQ(size.x(), o.width_px);
  // Count the colours: grey surface, red (above) and blue (below) dots.
  const cv::Mat img = cv::imdecode(cv::Mat(1, static_cast<int>(png.size()), CV_8UC1, const_cast<char*>(png.data())),
                                   cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, size.x());
  ASSERT_EQ(img.rows, size.y());
  std::size_t grey = 0, red = 0, blue = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b v = img.at<cv::Vec3b>(y, x);  // BGR
      if (v[0] == v[1] && v[1] == v[2] && v[0] > 90 && v[0] < 240) ++grey;
      if (v[2] > v[0] + 60) ++red;
      if (v[0] > v[2] + 60) ++blue;
    }
  }
  // The plot: the picture less the room of the axes, the colour bar and the legend line.
  const double area = static_cast<double>(img.rows - plot::kAxisTopPx - plot::kAxisBottomPx - 28) *
                      (img.cols - plot::kAxisLeftPx - plot::kColourBarAreaPx);
  EXPECT_GT(grey, 0.3 * area) << "the surface covers most of the plot";
  EXPECT_GT(red, 50u);
  EXPECT_GT(blue, 50u);
}

INSTANTIATE_TEST_SUITE_P(Cases, FitsurfPreview,
                         ::testing::Values(PreviewCase{"dense_default_width", 20000, {}},
                                           PreviewCase{"dense_narrow", 5000, {"--preview-width-px", "640"}},
                                           PreviewCase{"markers", 150, {"--preview-width-px", "900"}}),
                         [](const auto& info) { return info.param.name; });

TEST(FitsurfCli, APreviewIsNotWrittenOnFailure) {
  TempDir dir;
  const auto png = (dir.path() / "view.png").string();
  std::string collinear;
  for (int k = 0; k < 100; ++k) collinear += std::to_string(k) + " " + std::to_string(2 * k) + " 30\n";
  EXPECT_EQ(run_tool("fitsurf", {"-", "--preview", png}, collinear).exit_code, 1);
  EXPECT_EQ(run_tool("fitsurf", {"-", "--preview", png, "--preview-width-px", "10"}, dome_points(500)).exit_code, 2);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path())) << "no preview and no temporary file";
}

// Done-when: STEP and IGES written by fitsurf reopen with identical poles and knots; Open CASCADE
// prints nothing on stdout (stdout is byte for byte the surface text).
TEST(FitsurfCli, StepAndIgesReopenIdentical) {
  TempDir dir;
  const auto p = [&](const char* name) { return (dir.path() / name).string(); };
  const std::string points = dome_points(4000);
  const ToolResult r = run_tool("fitsurf", {"-", "--step", p("s.step"), "--iges", p("s.igs"), "--net", "14x11"}, points);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ToolResult plain = run_tool("fitsurf", {"-", "--net", "14x11"}, points);
  EXPECT_EQ(r.out, plain.out) << "stdout carries the surface only";
  std::istringstream in(r.out);
  const BSplineSurface s = read_surface(in, "<stdout>");
  for (const char* file : {"s.step", "s.igs"}) {
    const std::vector<BSplineSurface> back = read_cad(p(file));
    ASSERT_EQ(back.size(), 1u) << file;
    const BSplineSurface& b = back[0];
    EXPECT_EQ(b.degree_u, s.degree_u) << file;
    EXPECT_EQ(b.degree_v, s.degree_v) << file;
    EXPECT_EQ(b.knots_u, s.knots_u) << file;
    EXPECT_EQ(b.knots_v, s.knots_v) << file;
    EXPECT_EQ(b.poles_mm, s.poles_mm) << file;
    EXPECT_TRUE(b.weights.empty()) << file;
    ASSERT_EQ(b.boundary_uv.size(), s.boundary_uv.size()) << file;
    for (std::size_t k = 0; k < s.boundary_uv.size(); ++k) {
      double nearest = 1;
      for (const auto& x : b.boundary_uv) nearest = std::min(nearest, (x - s.boundary_uv[k]).norm());
      EXPECT_LT(nearest, 1e-9) << file << " boundary vertex " << k;
    }
  }
}

}  // namespace
}  // namespace photomill::fitsurf
