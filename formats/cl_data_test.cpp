// CL data: APT text and CSV round trips, APT records accepted from other systems, and
// malformed records named by line.
#include "formats/cl_data.hpp"

#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill {
namespace {

ClData sample_cl(bool with_header_data) {
  ClData cl;
  if (with_header_data) {
    cl.part_name = "handle left";
    cl.tool_diameter_mm = 6;
    cl.tool_corner_radius_mm = 3;
    cl.spindle_rpm = 12000;
    cl.coolant = true;
  }
  cl.moves = {
      {ClMove::Kind::Rapid, {0, 0, 50}, std::nullopt, 0},
      {ClMove::Kind::Rapid, {-75.5, 1.0 / 3, 50}, std::nullopt, 0},
      {ClMove::Kind::Feed, {-75.5, 1.0 / 3, 12.25}, std::nullopt, 300},
      {ClMove::Kind::Feed, {-70, 1e-9, 12.5}, Eigen::Vector3d(0, 0, 1), 1200},
      {ClMove::Kind::Feed, {-65, 0.5, 12.75}, std::nullopt, 1200},
      {ClMove::Kind::Rapid, {-65, 0.5, 50}, std::nullopt, 0},
  };
  return cl;
}

TEST(ClApt, RoundTripsExactly) {
  const ClData cl = sample_cl(true);
  std::stringstream s;
  write_cl_apt(s, cl);
  EXPECT_EQ(read_cl_apt(s, "p.cl"), cl) << s.str();
}

// Numbers in fixed notation (many posts read no exponent), still exact; the tool as LOADTL and
// CUTTER (issue 27).
TEST(ClApt, WritesFixedPointNumbersAndTheToolRecords) {
  ClData cl = sample_cl(true);
  cl.moves.push_back({ClMove::Kind::Feed, {-5.76e-05, 1e-300, -123456789.125}, std::nullopt, 1200});
  std::stringstream s;
  write_cl_apt(s, cl);
  const std::string text = s.str();
  std::string records;  // the text without its '$$' comments (the run id's hex may hold an 'e')
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("$$", 0) != 0) records += line + "\n";
  }
  EXPECT_FALSE(std::regex_search(records, std::regex("[0-9.][eE][-+]?[0-9]"))) << text;
  EXPECT_NE(text.find("GOTO/-0.0000576,0.0000"), std::string::npos) << text;
  EXPECT_NE(text.find(",-123456789.125\n"), std::string::npos) << text;
  EXPECT_NE(text.find("GOTO/-70,0.000000001,12.5,0,0,1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("UNITS/MM\nLOADTL/1\nCUTTER/6,3\nSPINDL/RPM,12000,CLW\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("TLDATA"), std::string::npos) << text;
  EXPECT_EQ(read_cl_apt(s, "p.cl"), cl);
}

TEST(ClCsv, RoundTripsTheMoves) {
  const ClData cl = sample_cl(false);
  std::stringstream s;
  write_cl_csv(s, cl);
  EXPECT_EQ(read_cl_csv(s, "p.csv"), cl) << s.str();
}

TEST(Cl, SniffsTheFormat) {
  for (bool apt : {true, false}) {
    std::stringstream s;
    if (apt) write_cl_apt(s, sample_cl(false));
    else write_cl_csv(s, sample_cl(false));
    EXPECT_EQ(read_cl(s, "x").moves, sample_cl(false).moves);
  }
}

TEST(ClApt, AcceptsRecordsOfOtherSystems) {
  std::istringstream in("$$ header\r\nPARTNO/part\r\nMULTAX/OFF\nCUTTER/6,3\nloadtl/1\nFEDRAT/500\nGOTO/ 1, 2, 3\nPPRINT anything\nEND\nFINI\n");
  const ClData cl = read_cl_apt(in, "x.cl");
  ASSERT_EQ(cl.moves.size(), 1u);
  EXPECT_EQ(cl.moves[0].feed_mm_per_min, 500);
  EXPECT_EQ(cl.tool_corner_radius_mm, 3);
}

struct BadCl {
  const char* name;
  const char* text;
  const char* message;
};

class ClMalformed : public ::testing::TestWithParam<BadCl> {};

TEST_P(ClMalformed, IsRejectedWithLine) {
  std::istringstream in(GetParam().text);
  try {
    read_cl(in, "p.cl");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(GetParam().message), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ClMalformed,
    ::testing::Values(BadCl{"empty", "", "p.cl: empty input"},
                      BadCl{"unknown", "PARTNO/x\nCIRCLE/1,2,3\n", "p.cl:2: unknown APT record 'CIRCLE'"},
                      BadCl{"goto_arity", "FEDRAT/100\nGOTO/1,2\n", "p.cl:2: GOTO takes x,y,z or x,y,z,i,j,k, got 2"},
                      BadCl{"goto_nan", "FEDRAT/100\nGOTO/1,nan,3\n", "p.cl:2: GOTO: y is not a finite number"},
                      BadCl{"no_feed", "GOTO/1,2,3\n", "p.cl:1: feed move before any FEDRAT"},
                      BadCl{"axis", "FEDRAT/100\nGOTO/1,2,3,0,0,2\n", "p.cl:2: tool axis i,j,k is not a unit vector"},
                      BadCl{"inches", "UNITS/INCHES\n", "p.cl:1: only UNITS/MM is supported"},
                      BadCl{"continuation", "GOTO/1,2,$\n", "continuation lines"},
                      BadCl{"after_fini", "FINI\nGOTO/1,2,3\n", "p.cl:2: content after FINI"},
                      BadCl{"no_fini", "FEDRAT/100\nGOTO/1,2,3\nEND\n", "p.cl:3: the CL data ends without FINI"},
                      // Cut inside its last number: GOTO/1,2,27.9077 read as z = 2 unless FINI is required.
                      BadCl{"cut_inside_a_number", "FEDRAT/100\nGOTO/1,2,27.9077\nGOTO/1,2,2", "p.cl:3: the CL data ends without FINI"},
                      BadCl{"csv_kind", "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\njump,1,2,3,,,,\n", "p.cl:2: move must be 'rapid' or 'feed'"},
                      BadCl{"csv_feed", "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nfeed,1,2,3,,,,\n", "p.cl:2: feed move without feed_mm_per_min"},
                      BadCl{"csv_axis", "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nfeed,1,2,3,0,,1,5\n", "p.cl:2: give all of i, j, k or none"}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace photomill
