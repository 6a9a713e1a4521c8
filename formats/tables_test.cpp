// Round-trip and malformed-input tests for the CSV tables, one typed test suite run over every
// format (observations, control points, tracks, poses, scale bars).
#include "formats/tables.hpp"

#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/temp_dir.hpp"

namespace photomill {
namespace {

struct ObservationsFormat {
  using T = std::vector<Observation>;
  static T sample() { return {{"img 01.jpg", 0, 0.0, -0.0}, {"dir/img_02.jpg", 123456789, 1999.5, 0.1}, {"a", 7, -1e-9, 1.0 / 3}}; }
  static T read(std::istream& in, const std::string& s) { return read_observations(in, s); }
  static void write(std::ostream& out, const T& v) { write_observations(out, v); }
  static std::string header() { return "image,point_id,u_px,v_px"; }
  static std::string row() { return "x.jpg,3,10.5,20.25"; }
  static std::string short_row() { return "x.jpg,3,10.5"; }
  static std::string nan_row() { return "x.jpg,3,nan,1"; }
  static std::string duplicate_rows() { return "x.jpg,3,1,1\nx.jpg,3,2,2"; }
};

struct ControlPointsFormat {
  using T = std::vector<ControlPoint>;
  static T sample() { return {{0, {0, 0, 0}, 0.01}, {41, {-150.25, 1e-12, 1e6}, std::nullopt}}; }
  static T read(std::istream& in, const std::string& s) { return read_control_points(in, s); }
  static void write(std::ostream& out, const T& v) { write_control_points(out, v); }
  static std::string header() { return "point_id,x_mm,y_mm,z_mm"; }
  static std::string row() { return "3,1,2,3"; }
  static std::string short_row() { return "3,1,2"; }
  static std::string nan_row() { return "3,1,inf,3"; }
  static std::string duplicate_rows() { return "3,1,2,3\n3,1,2,3"; }
};

struct TracksFormat {
  using T = std::vector<TrackObservation>;
  static T sample() { return {{5, "a.jpg", 1.5, 2.5, 3.25}, {5, "b.jpg", 0.0, 1e-7}, {9, "a.jpg", 1999.999999, 0.5, 0.1}}; }
  static T read(std::istream& in, const std::string& s) { return read_tracks(in, s); }
  static void write(std::ostream& out, const T& v) { write_tracks(out, v); }
  static std::string header() { return "track_id,image,u_px,v_px"; }
  static std::string row() { return "1,a.jpg,1,2"; }
  static std::string short_row() { return "1,a.jpg,1"; }
  static std::string nan_row() { return "1,a.jpg,NaN,2"; }
  static std::string duplicate_rows() { return "1,a.jpg,1,2\n1,a.jpg,3,4"; }
};

struct PosesFormat {
  using T = std::vector<Pose>;
  static T sample() {
    Pose a{"a.jpg", Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())), {1.5, -2, 500}};
    Pose b{"b.jpg", Eigen::Quaterniond::Identity(), {0, 0, 0}};
    return {a, b};
  }
  static T read(std::istream& in, const std::string& s) { return read_poses(in, s); }
  static void write(std::ostream& out, const T& v) { write_poses(out, v); }
  static std::string header() { return "image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm"; }
  static std::string row() { return "a.jpg,1,0,0,0,1,2,3"; }
  static std::string short_row() { return "a.jpg,1,0,0,0,1,2"; }
  static std::string nan_row() { return "a.jpg,1,0,0,0,1,2,-inf"; }
  static std::string duplicate_rows() { return "a.jpg,1,0,0,0,1,2,3\na.jpg,1,0,0,0,1,2,3"; }
};

struct ScaleBarsFormat {
  using T = std::vector<ScaleBar>;
  static T sample() { return {{0, 1, 20.0, 0.002}, {4, 8, 1e-3, std::nullopt}}; }
  static T read(std::istream& in, const std::string& s) { return read_scale_bars(in, s); }
  static void write(std::ostream& out, const T& v) { write_scale_bars(out, v); }
  static std::string header() { return "point_a,point_b,distance_mm"; }
  static std::string row() { return "0,1,20"; }
  static std::string short_row() { return "0,1"; }
  static std::string nan_row() { return "0,1,nan"; }
  static std::string duplicate_rows() { return "0,1,20\n2,2,20"; }  // a bar from a point to itself
};

template <typename F>
class TableFormatTest : public ::testing::Test {};
using Formats = ::testing::Types<ObservationsFormat, ControlPointsFormat, TracksFormat, PosesFormat, ScaleBarsFormat>;
TYPED_TEST_SUITE(TableFormatTest, Formats);

template <typename F>
typename F::T parse(const std::string& text, const std::string& source = "t.csv") {
  std::istringstream in(text);
  return F::read(in, source);
}

template <typename F>
std::string error_of(const std::string& text) {
  try {
    parse<F>(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TYPED_TEST(TableFormatTest, RoundTripsThroughAStream) {
  const auto v = TypeParam::sample();
  std::ostringstream out;
  TypeParam::write(out, v);
  EXPECT_EQ(parse<TypeParam>(out.str()), v) << out.str();
}

TYPED_TEST(TableFormatTest, RoundTripsThroughATempFile) {
  test::TempDir dir;
  const auto path = dir.path() / "table.csv";
  {
    std::ofstream f(path);
    TypeParam::write(f, TypeParam::sample());
  }
  std::ifstream f(path);
  EXPECT_EQ(TypeParam::read(f, path.string()), TypeParam::sample());
}

TYPED_TEST(TableFormatTest, HeaderOnlyIsEmpty) { EXPECT_TRUE(parse<TypeParam>(TypeParam::header() + "\n").empty()); }

TYPED_TEST(TableFormatTest, EmptyInputNamesTheSource) {
  EXPECT_EQ(error_of<TypeParam>(""), "t.csv: empty input: expected a CSV header naming the columns");
  EXPECT_EQ(error_of<TypeParam>("# only a comment\n\n"), "t.csv: empty input: expected a CSV header naming the columns");
}

TYPED_TEST(TableFormatTest, CrlfAndBomAndCommentsAreAccepted) {
  const std::string text = "\xEF\xBB\xBF# written on Windows\r\n" + TypeParam::header() + "\r\n" + TypeParam::row() + "\r\n";
  EXPECT_EQ(parse<TypeParam>(text).size(), 1u);
}

TYPED_TEST(TableFormatTest, WrongColumnCountNamesTheLine) {
  const std::string text = TypeParam::header() + "\n" + TypeParam::row() + "\n" + TypeParam::short_row() + "\n";
  const std::string e = error_of<TypeParam>(text);
  EXPECT_NE(e.find("t.csv:3: expected"), std::string::npos) << e;
  EXPECT_NE(e.find("columns, got"), std::string::npos) << e;
}

TYPED_TEST(TableFormatTest, NanAndInfinityAreRejected) {
  const std::string e = error_of<TypeParam>(TypeParam::header() + "\n" + TypeParam::nan_row() + "\n");
  EXPECT_NE(e.find("t.csv:2: field"), std::string::npos) << e;
  EXPECT_NE(e.find("not a finite number"), std::string::npos) << e;
}

TYPED_TEST(TableFormatTest, DuplicatesAreRejected) {
  const std::string e = error_of<TypeParam>(TypeParam::header() + "\n" + TypeParam::duplicate_rows() + "\n");
  EXPECT_NE(e.find("t.csv:3:"), std::string::npos) << e;
}

TYPED_TEST(TableFormatTest, MissingColumnIsNamed) {
  const std::string e = error_of<TypeParam>("foo,bar\n1,2\n");
  EXPECT_NE(e.find("t.csv:1: header lacks column"), std::string::npos) << e;
}

// Issue #25: a file photomill wrote opens with a stamp announcing its rows; one cut at a line
// boundary, or inside its last line, or holding more rows, is refused naming the stamp's line.
TYPED_TEST(TableFormatTest, AStampedFileCutShortIsRefused) {
  std::ostringstream out;
  TypeParam::write(out, TypeParam::sample());
  const std::string whole = out.str();
  ASSERT_EQ(whole.rfind("# photomill run=", 0), 0u) << whole;
  ASSERT_NE(whole.find(" rows=" + std::to_string(TypeParam::sample().size()) + "\n"), std::string::npos) << whole;
  const std::string without_last_row = whole.substr(0, whole.rfind('\n', whole.size() - 2) + 1);
  EXPECT_NE(error_of<TypeParam>(without_last_row).find("t.csv:1: its stamp announces"), std::string::npos)
      << error_of<TypeParam>(without_last_row);
  EXPECT_NE(error_of<TypeParam>(without_last_row).find("cut short"), std::string::npos);
  const std::string without_line_end = whole.substr(0, whole.size() - 1);
  EXPECT_NE(error_of<TypeParam>(without_line_end).find("no line end"), std::string::npos)
      << error_of<TypeParam>(without_line_end);
  const std::string cut_in_last_field = whole.substr(0, whole.size() - 3);  // "855.957" read as "855.9"
  EXPECT_NE(error_of<TypeParam>(cut_in_last_field), "no error");
  const std::size_t n = TypeParam::sample().size();
  std::string one_fewer_announced = whole;
  one_fewer_announced.replace(whole.find(" rows="), 7 + std::to_string(n).size(), " rows=" + std::to_string(n - 1) + "\n");
  EXPECT_NE(error_of<TypeParam>(one_fewer_announced).find("rows were added"), std::string::npos)
      << error_of<TypeParam>(one_fewer_announced);
  // Without its stamp the same rows read as any other tool's file: the check is the stamp's.
  EXPECT_NO_THROW(parse<TypeParam>(without_last_row.substr(without_last_row.find('\n') + 1)));
}

TYPED_TEST(TableFormatTest, ExtraColumnsAnywhereAreIgnored) {
  const std::string text = "extra," + TypeParam::header() + ",note\nzz," + TypeParam::row() + ",hello\n";
  const std::string plain = TypeParam::header() + "\n" + TypeParam::row() + "\n";
  EXPECT_EQ(parse<TypeParam>(text), parse<TypeParam>(plain));
}

TEST(Observations, NonIntegerAndNegativeIdsAreRejected) {
  EXPECT_NE(error_of<ObservationsFormat>("image,point_id,u_px,v_px\na,1.5,1,1\n").find("t.csv:2: field 'point_id' is not an integer"), std::string::npos);
  EXPECT_NE(error_of<ObservationsFormat>("image,point_id,u_px,v_px\na,-1,1,1\n").find("t.csv:2: field 'point_id' is negative"), std::string::npos);
}

TEST(Observations, WriterRefusesNamesCsvCannotHold) {
  std::ostringstream out;
  EXPECT_THROW(write_observations(out, {{"a,b.jpg", 1, 0, 0}}), std::invalid_argument);
  EXPECT_THROW(write_observations(out, {{"#a.jpg", 1, 0, 0}}), std::invalid_argument);
  EXPECT_THROW(write_observations(out, {{"a.jpg", 1, std::nan(""), 0}}), std::invalid_argument);
}

TEST(Poses, NonUnitQuaternionIsRejectedAndCentreIsMinusRtT) {
  EXPECT_NE(error_of<PosesFormat>("image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm\na,2,0,0,0,0,0,0\n").find("t.csv:2: rotation quaternion"), std::string::npos);
  Pose p{"a", Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())), {1, 2, 3}};
  const Eigen::Vector3d c = p.centre_mm();
  EXPECT_TRUE((p.rotation() * c + p.cam_from_world_translation_mm).norm() < 1e-12);
}

TEST(Tracks, SizeColumnIsOptionalPerRowAndPositive) {
  const auto v = parse<TracksFormat>("track_id,image,u_px,v_px,size_px\n1,a,0,0,\n1,b,0,0,4.5\n");
  ASSERT_EQ(v.size(), 2u);
  EXPECT_FALSE(v[0].size_px);
  EXPECT_EQ(v[1].size_px, 4.5);
  EXPECT_NE(error_of<TracksFormat>("track_id,image,u_px,v_px,size_px\n1,a,0,0,0\n").find("t.csv:2: size_px must be positive"), std::string::npos);
  EXPECT_NE(error_of<TracksFormat>("track_id,image,u_px,v_px,size_px\n1,a,0,0,-2\n").find("t.csv:2: size_px must be positive"), std::string::npos);
  // Written only when some observation has a size.
  std::ostringstream out;
  write_tracks(out, {{1, "a", 0, 0}});
  const std::string text = out.str().substr(out.str().find('\n') + 1);  // after the stamp
  EXPECT_EQ(text.substr(0, text.find('\n')), "track_id,image,u_px,v_px");
}

TEST(ControlPoints, SigmaColumnIsOptionalPerRow) {
  const auto v = parse<ControlPointsFormat>("point_id,x_mm,y_mm,z_mm,sigma_mm\n1,0,0,0,\n2,0,0,0,0.5\n");
  ASSERT_EQ(v.size(), 2u);
  EXPECT_FALSE(v[0].sigma_mm);
  EXPECT_EQ(v[1].sigma_mm, 0.5);
}

// Per-photo observation files joined as Makefile.example joins them (each file's stamp kept, the
// later files' column headers dropped) read as one, each segment checked, each image's run known.
TEST(Observations, JoinedPerPhotoFilesKeepEachStampAndRun) {
  const std::string a = "# photomill run=r1 rows=2\nimage,point_id,u_px,v_px\na.jpg,1,1,1\na.jpg,2,2,2\n";
  const std::string b = "# photomill run=r2 rows=1\nb.jpg,1,3,3\n";  // its header dropped
  std::map<std::string, std::string> runs;
  std::istringstream in(a + b);
  EXPECT_EQ(read_observations_with_runs(in, "j.csv", &runs).size(), 3u);
  EXPECT_EQ(runs, (std::map<std::string, std::string>{{"a.jpg", "r1"}, {"b.jpg", "r2"}}));
  std::istringstream cut(a + "# photomill run=r2 rows=2\nb.jpg,1,3,3\n");
  try {
    read_observations(cut, "j.csv");
    ADD_FAILURE() << "a segment with 1 of its 2 rows was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "j.csv:5: its stamp announces 2 rows, 1 follow: the file was cut short");
  }
}

}  // namespace
}  // namespace photomill
