// The B-spline surface text format: round trips (polynomial, rational, with boundary) and
// malformed files named by line.
#include "formats/surface.hpp"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/temp_dir.hpp"

namespace photomill {
namespace {

BSplineSurface sample_surface(bool rational, bool boundary) {
  BSplineSurface s;
  s.degree_u = 3;
  s.degree_v = 2;
  s.num_poles_u = 5;
  s.num_poles_v = 4;
  s.knots_u = {0, 0, 0, 0, 0.3, 1, 1, 1, 1};
  s.knots_v = {-1, -1, -1, 0.5, 2, 2, 2};
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) s.poles_mm.emplace_back(10.0 * i + 0.1, 7.5 * j - 1.0 / 3, (i * j) % 3 + 1e-9);
  }
  if (rational) {
    for (int k = 0; k < 20; ++k) s.weights.push_back(0.5 + k / 7.0);
  }
  if (boundary) s.boundary_uv = {{0.1, -0.9}, {0.9, -0.9}, {0.9, 1.9}, {0.1, 1.9}};
  return s;
}

class SurfaceRoundTrip : public ::testing::TestWithParam<std::pair<bool, bool>> {};

TEST_P(SurfaceRoundTrip, IsExact) {
  const auto s = sample_surface(GetParam().first, GetParam().second);
  std::stringstream io;
  write_surface(io, s);
  EXPECT_EQ(read_surface(io, "s.txt"), s) << io.str();
}

TEST_P(SurfaceRoundTrip, ThroughATempFile) {
  const auto s = sample_surface(GetParam().first, GetParam().second);
  test::TempDir dir;
  {
    std::ofstream f(dir.path() / "s.surf");
    write_surface(f, s);
  }
  std::ifstream f(dir.path() / "s.surf");
  EXPECT_EQ(read_surface(f, "s.surf"), s);
}

INSTANTIATE_TEST_SUITE_P(Variants, SurfaceRoundTrip,
                         ::testing::Values(std::pair{false, false}, std::pair{true, false}, std::pair{false, true},
                                           std::pair{true, true}));

std::string surface_error(const std::string& text) {
  std::istringstream in(text);
  try {
    read_surface(in, "s.surf");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string good_text() {
  std::ostringstream out;
  write_surface(out, sample_surface(false, false));
  return out.str();
}

std::string replace_line(std::string text, const std::string& prefix, const std::string& with) {
  const auto pos = text.find(prefix);
  const auto end = text.find('\n', pos);
  return text.replace(pos, end - pos, with);
}

struct BadSurface {
  const char* name;
  std::string text;
  const char* message;
};

class SurfaceMalformed : public ::testing::TestWithParam<BadSurface> {};

TEST_P(SurfaceMalformed, IsRejectedWithLine) {
  const std::string e = surface_error(GetParam().text);
  EXPECT_NE(e.find(GetParam().message), std::string::npos) << e;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, SurfaceMalformed,
    ::testing::Values(
        BadSurface{"empty", "", "s.surf: unexpected end of input"},
        BadSurface{"wrong_magic", "hello\n", "s.surf:1: not a photomill surface file"},
        BadSurface{"version", "photomill-surface v9\n", "s.surf:1: unsupported surface format version"},
        BadSurface{"degree", replace_line(good_text(), "degrees", "degrees 0 3"), "s.surf:3: degree p must be an integer in 1..25"},
        BadSurface{"huge_net", replace_line(good_text(), "poles", "poles 100000 100000"), "s.surf:4: control net too large"},
        BadSurface{"knot_count", replace_line(good_text(), "knots_u", "knots_u 0 0 1 1"), "s.surf:6: 'knots_u' takes 9 values, got 4"},
        BadSurface{"knot_nan", replace_line(good_text(), "knots_u", "knots_u 0 0 0 0 nan 1 1 1 1"), "s.surf:6: knots_u is not a finite number"},
        BadSurface{"decreasing", replace_line(good_text(), "knots_u", "knots_u 0 0 0 0 2 1 1 1 1"), "knots_u decreases at knot 5"},
        BadSurface{"pole_order", replace_line(good_text(), "pole 0 1 ", "pole 0 2 1 2 3"), "s.surf:10: expected pole 0 1"},
        BadSurface{"pole_nan", replace_line(good_text(), "pole 0 1 ", "pole 0 1 1 inf 3"), "s.surf:10: y_mm is not a finite number"},
        BadSurface{"truncated", good_text().substr(0, good_text().find("pole 2 0")), "unexpected end of input: expected 'pole 2 0"},
        BadSurface{"trailing", good_text() + "pole 9 9 1 2 3\n", "unexpected content after 'end'"},
        BadSurface{"unit_word", replace_line(good_text(), "degrees", "units inch\ndegrees 3 2"),
                   "s.surf:3: unknown unit 'inch': a surface is in mm (no 'units' line) or 'units arbitrary'"},
        BadSurface{"unit_values", replace_line(good_text(), "degrees", "units arbitrary mm\ndegrees 3 2"),
                   "s.surf:3: 'units' takes 1 values, got 2"},
        BadSurface{"unit_late", replace_line(good_text(), "poles", "units arbitrary\npoles 5 4"),
                   "s.surf:4: expected 'poles', got 'units'"}),
    [](const auto& info) { return std::string(info.param.name); });

// A surface fitted to a cloud without a datum keeps its unit: the writer adds `units arbitrary`
// (and only then), the reader gives it back; a file without the line is in mm.
TEST(Surface, ArbitraryUnitsRoundTrip) {
  for (const auto& [rational, boundary] : {std::pair{false, false}, std::pair{true, true}}) {
    BSplineSurface s = sample_surface(rational, boundary);
    std::ostringstream mm;
    write_surface(mm, s);
    EXPECT_EQ(mm.str().find("units"), std::string::npos) << mm.str();
    s.units = "arbitrary";
    std::stringstream io;
    write_surface(io, s);
    EXPECT_NE(io.str().find("\nunits arbitrary\ndegrees "), std::string::npos) << io.str();
    const BSplineSurface back = read_surface(io, "s.surf");
    EXPECT_EQ(back.units, "arbitrary");
    EXPECT_FALSE(back.in_mm());
    EXPECT_EQ(back, s);
  }
  std::istringstream in(good_text());
  EXPECT_TRUE(read_surface(in, "s.surf").in_mm());
  std::istringstream explicit_mm(replace_line(good_text(), "degrees", "units mm\ndegrees 3 2"));
  EXPECT_EQ(read_surface(explicit_mm, "s.surf"), sample_surface(false, false));
}

TEST(Surface, UnknownUnitIsNotWritten) {
  BSplineSurface s = sample_surface(false, false);
  s.units = "inch";
  std::ostringstream out;
  EXPECT_THROW(write_surface(out, s), InputError);
  EXPECT_EQ(out.str(), "");
}

TEST(Surface, CrlfIsAccepted) {
  std::string text = good_text();
  std::string crlf;
  for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  std::istringstream in(crlf);
  EXPECT_EQ(read_surface(in, "s"), sample_surface(false, false));
}

}  // namespace
}  // namespace photomill
