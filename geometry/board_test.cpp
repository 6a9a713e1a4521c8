// Board geometry: grid parsing, corner numbering and control points.
#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "geometry/board.hpp"

namespace photomill::geometry {
namespace {

TEST(Board, ParsesGrids) {
  EXPECT_EQ(parse_grid("9x6", "--chessboard"), std::make_pair(9, 6));
  EXPECT_EQ(parse_grid("5X7", "--charuco"), std::make_pair(5, 7));
  for (const char* bad : {"9", "x6", "9x", "9x6x", "-9x6", "99999x2", ""}) {
    try {
      (void)parse_grid(bad, "--chessboard");
      FAIL() << bad;
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("--chessboard"), std::string::npos);
    }
  }
}

TEST(Board, ControlPointsFollowOpenCVsNumbering) {
  BoardSpec chess{BoardKind::Chessboard, 9, 6, 25, 0, "DICT_6X6_250"};
  const auto c = board_control_points(chess);
  ASSERT_EQ(c.size(), 54u);
  EXPECT_EQ(c[10].xyz_mm, Eigen::Vector3d(25, 25, 0));  // corner (1, 1)
  BoardSpec charuco{BoardKind::Charuco, 5, 7, 30, 20, "DICT_6X6_250"};
  EXPECT_EQ(board_corner_count(charuco), 24);
  const auto h = board_control_points(charuco);
  EXPECT_EQ(h[0].xyz_mm, Eigen::Vector3d(30, 30, 0));
  EXPECT_EQ(h[5].xyz_mm, Eigen::Vector3d(60, 60, 0));  // 4 per row: (1, 1) -> (2, 2) squares
}

TEST(Board, RefusesImpossibleBoards) {
  EXPECT_THROW(validate_board_geometry({BoardKind::Chessboard, 1, 6, 25, 0, ""}), UsageError);
  EXPECT_THROW(validate_board_geometry({BoardKind::Chessboard, 9, 6, 0, 0, ""}), UsageError);
  EXPECT_THROW(validate_board_geometry({BoardKind::Charuco, 5, 7, 30, 30, ""}), UsageError);
  EXPECT_NO_THROW(validate_board_geometry({BoardKind::Charuco, 5, 7, 30, 20, ""}));
  EXPECT_THROW((void)board_control_points({BoardKind::Charuco, 5, 7, -1, 20, ""}), UsageError);
}

}  // namespace
}  // namespace photomill::geometry
