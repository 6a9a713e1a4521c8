// PLY and plain-text point clouds: round trips (ASCII, binary), every scalar type, hostile
// headers, truncation, big-endian input, and an independent reader (Python standard library).
#include "formats/point_cloud.hpp"

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/temp_dir.hpp"

namespace photomill {
namespace {

PointCloud sample_cloud() {
  PointCloud c;
  c.points_mm = {{0, 0, 0}, {-150.125, 1e-9, 32.5}, {1.0 / 3, 2.0 / 3, -0.0}};
  c.properties = {
      {"track_id", PlyScalar::UInt32, {0, 4294967295.0, 17}},
      {"views", PlyScalar::UInt8, {2, 255, 12}},
      {"temperature", PlyScalar::Int8, {-128, 127, 0}},
      {"label", PlyScalar::Int16, {-32768, 32767, 5}},
      {"count16", PlyScalar::UInt16, {0, 65535, 9}},
      {"offset", PlyScalar::Int32, {-2147483648.0, 2147483647.0, -1}},
      {"reproj_rms_px", PlyScalar::Float32, {static_cast<float>(0.1), 1e-30f, 3.5}},
      {"sigma_mm", PlyScalar::Float64, {0.001, 1.0 / 7, 1e300}},
  };
  return c;
}

class PlyRoundTrip : public ::testing::TestWithParam<PlyEncoding> {};

// Values are found under their name or with CloudCompare's "scalar_" prefix, the exact name first.
TEST(PointCloudFind, TakesTheNameOrItsScalarPrefixedForm) {
  PointCloud c;
  c.points_mm = {{0, 0, 0}};
  c.properties = {{"scalar_sigma_mm", PlyScalar::Float64, {1}}, {"views", PlyScalar::UInt8, {2}},
                  {"scalar_views", PlyScalar::UInt8, {3}}};
  ASSERT_NE(c.find("sigma_mm"), nullptr);
  EXPECT_EQ(c.find("sigma_mm")->values[0], 1);
  EXPECT_EQ(c.find("scalar_sigma_mm")->values[0], 1);
  EXPECT_EQ(c.find("views")->values[0], 2);  // the exact name wins
  EXPECT_EQ(c.find("sigma"), nullptr);
  EXPECT_EQ(c.find("mm"), nullptr);
  EXPECT_EQ(c.find("reproj_rms_px"), nullptr);
}

TEST_P(PlyRoundTrip, PreservesPointsAndEveryPropertyType) {
  const PointCloud c = sample_cloud();
  std::stringstream s;
  write_ply(s, c, GetParam(), "a test");
  EXPECT_EQ(read_ply(s, "mem"), c);
}

TEST_P(PlyRoundTrip, ArbitraryUnitsAreSaidAndReadBack) {
  PointCloud c = sample_cloud();
  c.units = "arbitrary";
  std::stringstream s;
  write_ply(s, c, GetParam());
  EXPECT_NE(s.str().find("comment photomill point cloud, units arbitrary: not mm"), std::string::npos) << s.str();
  EXPECT_EQ(read_ply(s, "mem"), c);
  // A PLY of another writer, or photomill's in mm, is in mm.
  std::stringstream mm;
  write_ply(mm, sample_cloud(), GetParam());
  EXPECT_NE(mm.str().find("comment photomill point cloud, units mm\n"), std::string::npos);
  EXPECT_EQ(read_ply(mm, "mem").units, "mm");
  std::istringstream foreign("ply\nformat ascii 1.0\ncomment made elsewhere\nelement vertex 0\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n");
  EXPECT_EQ(read_ply(foreign, "mem").units, "mm");
  c.units = "two words";
  EXPECT_THROW(write_ply(s, c, GetParam()), std::invalid_argument);
}

TEST_P(PlyRoundTrip, Float32CoordinatesStayFloat32) {
  PointCloud c;
  c.xyz_type = PlyScalar::Float32;
  c.points_mm = {{static_cast<float>(0.1), static_cast<float>(1.0 / 3), 1e6}};
  std::stringstream s;
  write_ply(s, c, GetParam());
  EXPECT_EQ(read_ply(s, "mem"), c);
}

TEST_P(PlyRoundTrip, EmptyCloud) {
  std::stringstream s;
  write_ply(s, PointCloud{}, GetParam());
  EXPECT_TRUE(read_ply(s, "mem").points_mm.empty());
}

TEST_P(PlyRoundTrip, ThroughATempFileAndTheSniffer) {
  test::TempDir dir;
  const auto path = dir.path() / "cloud.ply";
  {
    std::ofstream f(path, std::ios::binary);
    write_ply(f, sample_cloud(), GetParam());
  }
  std::ifstream f(path, std::ios::binary);
  EXPECT_EQ(read_point_cloud(f, path.string()), sample_cloud());
}

INSTANTIATE_TEST_SUITE_P(Encodings, PlyRoundTrip, ::testing::Values(PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian));

std::string ply_error(const std::string& text) {
  std::istringstream in(text);
  try {
    read_ply(in, "c.ply");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

struct BadPly {
  const char* name;
  std::string text;
  const char* message;
};

class PlyMalformed : public ::testing::TestWithParam<BadPly> {};

TEST_P(PlyMalformed, IsRejectedWithAClearMessage) {
  const std::string e = ply_error(GetParam().text);
  EXPECT_NE(e.find(GetParam().message), std::string::npos) << e;
}

const std::string kHead = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, PlyMalformed,
    ::testing::Values(
        BadPly{"empty", "", "c.ply: PLY header has no 'end_header'"},
        BadPly{"not_ply", "solid stl\n", "c.ply:1: not a PLY file"},
        BadPly{"no_format", "ply\nelement vertex 0\nend_header\n", "no 'format' line"},
        BadPly{"no_vertex", "ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no 'vertex' element"},
        BadPly{"no_z", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n", "lacks x, y or z"},
        BadPly{"bad_type", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", "c.ply:4: unknown property type 'quad'"},
        BadPly{"truncated", kHead + "1 2 3\n", "truncated: element 'vertex' promises 2 records, found 1"},
        BadPly{"short_record", kHead + "1 2 3\n1 2\n", "c.ply:9: vertex record has too few values"},
        BadPly{"long_record", kHead + "1 2 3\n1 2 3 4\n", "c.ply:9: vertex record has 4 values"},
        BadPly{"nan", kHead + "1 2 3\n1 nan 3\n", "c.ply:9: property 'y' is not a finite number"},
        BadPly{"overflow_float", kHead + "1 2 3\n1 1e39 3\n", "does not fit type float"},
        BadPly{"uchar_range", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nend_header\n1 2 3 256\n", "does not fit type uchar"},
        BadPly{"binary_truncated", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n" + std::string(30, '\0'), "found 1"},
        BadPly{"version", "ply\nformat ascii 2.0\nend_header\n", "unsupported PLY version"},
        BadPly{"units_empty", "ply\nformat ascii 1.0\ncomment photomill point cloud, units \nelement vertex 0\nend_header\n",
               "c.ply:3: PLY units comment names no unit"},
        BadPly{"negative_count", "ply\nformat ascii 1.0\nelement vertex -5\nend_header\n", "element count is not a non-negative integer"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(PlyHostile, HugeCountsCostNeitherMemoryNorTime) {
  const auto start = std::chrono::steady_clock::now();
  for (const char* fmt : {"ascii", "binary_little_endian"}) {
    // 10^12 vertices promised, a list element of 10^12 records with no properties, 100 bytes given.
    const std::string text = std::string("ply\nformat ") + fmt +
                             " 1.0\nelement junk 1000000000000\nelement vertex 1000000000000\nproperty float x\n"
                             "property float y\nproperty float z\nproperty list uint int idx\nend_header\n" +
                             std::string(100, '\x01');
    EXPECT_NE(ply_error(text), "no error");
  }
  // A binary list claiming 10^9 items is skipped by reading, so it ends at the input's end.
  const std::string list = "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uint int v\nelement vertex 1\n"
                           "property float x\nproperty float y\nproperty float z\nend_header\n" +
                           std::string("\x00\xca\x9a\x3b", 4) + std::string(20, '\0');
  EXPECT_NE(ply_error(list).find("truncated: element 'face'"), std::string::npos) << ply_error(list);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

TEST(Ply, ReadsBigEndianAndSkipsOtherElementsAndLists) {
  std::string text = "ply\nformat binary_big_endian 1.0\ncomment from elsewhere\nelement camera 1\nproperty uchar id\n"
                     "element vertex 1\nproperty list uchar int neighbours\nproperty float x\nproperty float y\n"
                     "property float z\nproperty uchar red\nend_header\n";
  text += '\x07';                                   // camera id
  text += std::string("\x02\x00\x00\x00\x01\x00\x00\x00\x02", 9);  // list of 2 ints
  const auto be = [](float f) {
    char b[4];
    std::memcpy(b, &f, 4);
    return std::string{b[3], b[2], b[1], b[0]};
  };
  text += be(1.5f) + be(-2.0f) + be(0.25f) + '\xff';
  std::istringstream in(text);
  const PointCloud c = read_ply(in, "be.ply");
  ASSERT_EQ(c.points_mm.size(), 1u);
  EXPECT_EQ(c.points_mm[0], Eigen::Vector3d(1.5, -2.0, 0.25));
  ASSERT_NE(c.find("red"), nullptr);
  EXPECT_EQ(c.find("red")->values[0], 255);
}

// Found by fuzzing: an element before 'vertex' with more properties than the vertex element wrote
// its values past the end of the vertex record (heap overflow under ASan).
TEST(Ply, AnEarlierElementWithMorePropertiesThanTheVertexIsSkipped) {
  std::string text = "ply\nformat binary_little_endian 1.0\nelement face 2\nproperty double a\nproperty double b\n"
                     "property double c\nproperty double d\nproperty double e\nelement vertex 1\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n";
  text += std::string(2 * 5 * sizeof(double), '\x01');
  for (const float f : {1.0f, 2.0f, 3.0f}) text += std::string(reinterpret_cast<const char*>(&f), sizeof f);
  std::istringstream in(text);
  const PointCloud c = read_ply(in, "faces_first.ply");
  ASSERT_EQ(c.points_mm.size(), 1u);
  EXPECT_EQ(c.points_mm[0], Eigen::Vector3d(1, 2, 3));
}

TEST(Ply, AnIndependentReaderSeesTheSameBinaryValues) {
  if (std::system("python3 --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3 not available";
  test::TempDir dir;
  const auto ply = dir.path() / "c.ply";
  const auto txt = dir.path() / "c.txt";
  {
    std::ofstream f(ply, std::ios::binary);
    write_ply(f, sample_cloud(), PlyEncoding::BinaryLittleEndian);
  }
  const std::string cmd = std::string("python3 ") + PHOTOMILL_SOURCE_DIR + "/tests/read_ply.py " + ply.string() + " > " + txt.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  // The Python reader prints one line per vertex: every property in file order, repr() of floats.
  std::ifstream f(txt);
  const PointCloud c = sample_cloud();
  for (std::size_t i = 0; i < c.points_mm.size(); ++i) {
    std::string line;
    ASSERT_TRUE(std::getline(f, line));
    std::istringstream fields(line);
    for (int k = 0; k < 3; ++k) {
      std::string v;
      fields >> v;
      EXPECT_EQ(std::strtod(v.c_str(), nullptr), c.points_mm[i][k]) << line;
    }
    for (const auto& p : c.properties) {
      std::string v;
      fields >> v;
      EXPECT_EQ(std::strtod(v.c_str(), nullptr), p.values[i]) << p.name << ": " << line;
    }
  }
}

TEST(Xyz, RoundTripsAndAcceptsHeadersCommasAndExtraColumns) {
  PointCloud c;
  c.points_mm = {{1, 2, 3}, {-0.1, 1e-20, 1.0 / 3}};
  std::stringstream s;
  write_xyz(s, c);
  EXPECT_EQ(read_xyz(s, "mem").points_mm, c.points_mm);
  std::istringstream other("//X Y Z R G B\r\n1,2,3,255,0,0\r\n# comment\n4\t5\t6 7\n");
  const auto d = read_point_cloud(other, "scan.txt");
  ASSERT_EQ(d.points_mm.size(), 2u);
  EXPECT_EQ(d.points_mm[1], Eigen::Vector3d(4, 5, 6));
}

TEST(Xyz, MalformedLinesAreNamed) {
  std::istringstream a("1 2 3\n1 2\n");
  try {
    read_xyz(a, "s.xyz");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "s.xyz:2: expected at least 3 numbers (x y z), got 2");
  }
  std::istringstream b("1 2 3\n1 2 inf\n");
  EXPECT_THROW(read_xyz(b, "s.xyz"), InputError);
}

}  // namespace
}  // namespace photomill
