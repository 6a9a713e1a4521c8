// The scene layout and the synth-scene / synth-board text formats: round trips, errors with line
// numbers, the point-id scheme, the texture's marker bits.
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tools/synth/dataset.hpp"
#include "tools/synth/test_scene.hpp"
#include "tools/synth/texture.hpp"

namespace photomill::synth {
namespace {

PartScene scene() { return make_part_scene(test::small_options()); }

TEST(Scene, LayoutHasPlateAndPartMarkersWithUniqueIds) {
  const PartScene s = scene();
  int plate = 0, part = 0;
  for (const Marker& m : s.markers) (m.on_part ? part : plate)++;
  EXPECT_GE(plate, 12);
  EXPECT_EQ(part, 6);
  EXPECT_NO_THROW(validate(s));
  // The plate extends well beyond the part.
  EXPECT_LT(s.plate_x_min_mm, s.surface.x_min_mm - 50);
  EXPECT_GT(s.plate_y_max_mm, s.surface.y_max_mm + 50);
}

TEST(Scene, CornerIdsAndPositionsFollowTheDocumentedScheme) {
  const PartScene s = scene();
  const auto plate = marker_corners(s, false);
  const auto part = marker_corners(s, true);
  const Marker& m = s.markers.front();
  ASSERT_FALSE(m.on_part);
  // point_id = id * 4 + corner; corners TL, TR, BR, BL seen from above (+y up); plate at z = 0.
  EXPECT_EQ(plate[0].point_id, m.id * 4);
  EXPECT_EQ(plate[3].point_id, m.id * 4 + 3);
  EXPECT_EQ(plate[0].xyz_mm, Eigen::Vector3d(m.top_left_mm.x(), m.top_left_mm.y(), 0));
  EXPECT_EQ(plate[1].xyz_mm, Eigen::Vector3d(m.top_left_mm.x() + m.size_mm, m.top_left_mm.y(), 0));
  EXPECT_EQ(plate[2].xyz_mm, Eigen::Vector3d(m.top_left_mm.x() + m.size_mm, m.top_left_mm.y() - m.size_mm, 0));
  // Part-marker corners lie on the surface.
  ASSERT_FALSE(part.empty());
  for (const ControlPoint& p : part) {
    EXPECT_DOUBLE_EQ(p.xyz_mm.z(), s.surface.height_mm(p.xyz_mm.x(), p.xyz_mm.y()));
    EXPECT_GT(p.xyz_mm.z(), 1.0);
  }
}

TEST(Scene, RoundTripsThroughItsTextFormat) {
  const PartScene s = scene();
  std::stringstream io;
  write_scene(io, s, "made by a test\nsecond line");
  const PartScene back = read_scene(io, "scene.txt");
  EXPECT_EQ(back, s);
  // Exactly the same surface, so tests can evaluate the truth from the file.
  EXPECT_EQ(back.surface.height_mm(12.3, -4.5), s.surface.height_mm(12.3, -4.5));
}

struct BadScene {
  std::string replace, with;
  std::string message;
};

class SceneErrors : public ::testing::TestWithParam<BadScene> {};

TEST_P(SceneErrors, NameTheLineAndTheProblem) {
  std::stringstream io;
  write_scene(io, scene());
  std::string text = io.str();
  const BadScene& c = GetParam();
  const auto at = text.find(c.replace);
  ASSERT_NE(at, std::string::npos);
  text.replace(at, c.replace.size(), c.with);
  std::istringstream in(text);
  try {
    read_scene(in, "scene.txt");
    FAIL() << "accepted: " << c.with;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
    EXPECT_EQ(e.source(), "scene.txt");
  }
}

INSTANTIATE_TEST_SUITE_P(
    All, SceneErrors,
    ::testing::Values(BadScene{"# photomill synth-scene v1", "# photomill synth-scene v9", "scene.txt:1:"},
                      BadScene{"edge_blend_mm 20", "edge_blend_mm 20 3", "needs 1 values"},
                      BadScene{"edge_blend_mm 20", "edge_blend_mm nan", "not a finite number"},
                      BadScene{"edge_blend_mm 20", "edge_blend 20", "unknown record 'edge_blend'"},
                      BadScene{"term gauss", "term cube", "unknown shape term 'cube'"},
                      BadScene{"dictionary DICT_4X4_100", "dictionary DICT_9X9", "unknown ArUco dictionary"},
                      BadScene{"marker 1 ", "marker 0 ", "marker 0 is used twice"},
                      BadScene{"part\n", "roof\n", "must be 'plate' or 'part'"},
                      BadScene{"plate_rect_mm", "plate_rect_mm 0 1 0 1\n#", "plate must contain the part"}));

TEST(Scene, EmptyInputIsAnError) {
  std::istringstream in("");
  EXPECT_THROW(read_scene(in, "empty"), InputError);
  std::istringstream header_only("# photomill synth-scene v1\n");
  EXPECT_THROW(read_scene(header_only, "h"), InputError);
}

TEST(Board, RoundTripsAndValidates) {
  BoardSpec b;
  b.squares_x = 9;
  b.marker_mm = 21.5;
  std::stringstream io;
  write_board(io, b);
  EXPECT_EQ(read_board(io, "board.txt"), b);
  std::istringstream bad("# photomill synth-board v1\nsquares_x 7\nsquare_mm 10\nmarker_mm 12\n");
  EXPECT_THROW(read_board(bad, "board.txt"), InputError);
}

TEST(Board, CornersAreOpenCvsChessboardCorners) {
  BoardSpec b;
  const BoardTexture t(b);
  ASSERT_EQ(t.corners().size(), static_cast<std::size_t>((b.squares_x - 1) * (b.squares_y - 1)));
  EXPECT_EQ(t.corners()[0].xyz_mm, Eigen::Vector3d(b.square_mm, b.square_mm, 0));
  // A square corner sits between black and white: the box filter there gives the mean.
  const double at_corner = t.albedo(b.square_mm, b.square_mm, 1.0);
  const Palette p;
  EXPECT_NEAR(at_corner, 0.5 * (p.black + p.white), 1e-12);
}

TEST(Texture, MarkerBitsHaveABlackBorder) {
  const MarkerBits bits = marker_bits("DICT_4X4_100", 7);
  ASSERT_EQ(bits.cells, 6);
  for (int k = 0; k < bits.cells; ++k) {
    EXPECT_FALSE(bits.white[k]);
    EXPECT_FALSE(bits.white[(bits.cells - 1) * bits.cells + k]);
    EXPECT_FALSE(bits.white[k * bits.cells]);
  }
}

TEST(Texture, MarkerEdgeIsFilteredSymmetrically) {
  // Across the left edge of a plate marker the filtered albedo is the mean of black and white
  // exactly on the edge: no half-texel shift.
  const PartScene s = scene();
  const PartTexture t(s);
  const Marker& m = s.markers.front();
  const double x = m.top_left_mm.x();
  const double y = m.top_left_mm.y() - m.size_mm / 2;
  const Palette p;
  EXPECT_NEAR(t.albedo(x, y, 0.5), 0.5 * (p.black + p.white), 1e-12);
  EXPECT_NEAR(t.albedo(x - 0.3, y, 0.5), p.white, 1e-12);
  EXPECT_NEAR(t.albedo(x + 0.3, y, 0.5), p.black, 1e-12);
}

}  // namespace
}  // namespace photomill::synth
