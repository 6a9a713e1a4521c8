// Unit tests for the shared text primitives: strict number parsing, round-trip formatting,
// and the line reader's handling of CRLF, BOM, comments, NUL bytes and hostile line lengths.
#include "formats/text.hpp"

#include <cmath>
#include <limits>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill {
namespace {

struct ParseCase {
  const char* text;
  bool valid;
  double value;
};

class ParseDoubleTest : public ::testing::TestWithParam<ParseCase> {};

TEST_P(ParseDoubleTest, AcceptsOnlyWholeFiniteNumbers) {
  const auto& c = GetParam();
  const auto v = parse_double(c.text);
  ASSERT_EQ(v.has_value(), c.valid) << c.text;
  if (c.valid) {
    EXPECT_EQ(*v, c.value) << c.text;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ParseDoubleTest,
    ::testing::Values(ParseCase{"1", true, 1.0}, ParseCase{"-2.5", true, -2.5}, ParseCase{"+3", true, 3.0},
                      ParseCase{"1e-3", true, 1e-3}, ParseCase{"0.1", true, 0.1}, ParseCase{"-0", true, -0.0},
                      ParseCase{"", false, 0}, ParseCase{"nan", false, 0}, ParseCase{"NaN", false, 0},
                      ParseCase{"inf", false, 0}, ParseCase{"-infinity", false, 0}, ParseCase{"1e400", false, 0},
                      ParseCase{"1,5", false, 0}, ParseCase{"1.5x", false, 0}, ParseCase{"0x10", false, 0},
                      ParseCase{"abc", false, 0}, ParseCase{"++1", false, 0}));

TEST(ParseInt, RejectsFractionsAndOverflow) {
  EXPECT_EQ(parse_int("42"), 42);
  EXPECT_EQ(parse_int("-7"), -7);
  EXPECT_FALSE(parse_int("1.0"));
  EXPECT_FALSE(parse_int("99999999999999999999"));
  EXPECT_FALSE(parse_int(""));
}

class FormatDoubleTest : public ::testing::TestWithParam<double> {};

TEST_P(FormatDoubleTest, RoundTripsExactly) {
  const double v = GetParam();
  const auto back = parse_double(format_double(v));
  ASSERT_TRUE(back) << format_double(v);
  EXPECT_EQ(*back, v);
  EXPECT_EQ(std::signbit(*back), std::signbit(v));
}

INSTANTIATE_TEST_SUITE_P(
    EdgeValues, FormatDoubleTest,
    ::testing::Values(0.0, -0.0, 0.1, 1.0 / 3.0, -1234.5678901234567, 1e-300, 4.9406564584124654e-324,
                      std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
                      std::numeric_limits<double>::min(), 123456789012345678.0, 0.30000000000000004));

TEST(FormatDouble, IgnoresTheGlobalLocale) {
  // A German locale would print "0,5"; formats must not care (to_chars is locale-free).
  EXPECT_EQ(format_double(0.5), "0.5");
}

TEST(LineReader, StripsCrlfBomAndSkipsComments) {
  std::istringstream in("\xEF\xBB\xBF# comment\r\n\r\nfirst\r\n  # indented comment\nsecond");
  LineReader r(in, "mem");
  auto a = r.next();
  ASSERT_TRUE(a);
  EXPECT_EQ(*a, "first");
  EXPECT_EQ(r.line_number(), 3u);
  auto b = r.next();
  ASSERT_TRUE(b);
  EXPECT_EQ(*b, "second");
  EXPECT_EQ(r.line_number(), 5u);
  EXPECT_FALSE(r.next());
}

TEST(LineReader, RejectsOverlongLinesWithoutReadingThemWhole) {
  std::string big(5000, 'x');
  std::istringstream in("ok\n" + big + "\n");
  LineReaderOptions opt;
  opt.max_line_bytes = 100;
  LineReader r(in, "big.csv", opt);
  EXPECT_TRUE(r.next());
  try {
    r.next();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2u);
    EXPECT_NE(std::string(e.what()).find("big.csv:2: line longer than 100 bytes"), std::string::npos) << e.what();
  }
}

TEST(LineReader, RejectsNulBytes) {
  std::istringstream in(std::string("a,b\n1,\0\n", 8));
  LineReader r(in, "junk");
  EXPECT_TRUE(r.next());
  EXPECT_THROW(r.next(), InputError);
}

TEST(SplitFields, TrimsBlanks) {
  const auto f = split_fields(" a , b,c ,", ',');
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0], "a");
  EXPECT_EQ(f[1], "b");
  EXPECT_EQ(f[2], "c");
  EXPECT_EQ(f[3], "");
}

TEST(SplitWhitespace, AcceptsSpacesTabsAndCommas) {
  const auto f = split_whitespace("1\t2,  3 ,4");
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[3], "4");
}

}  // namespace
}  // namespace photomill
