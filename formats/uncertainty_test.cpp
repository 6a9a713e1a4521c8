// The uncertainty grid (formats/uncertainty.hpp): round trip, malformed input, sampling.
#include "formats/uncertainty.hpp"

#include <cmath>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill {
namespace {

UncertaintyGrid sample_grid() {
  UncertaintyGrid g;
  g.x0_mm = -10.25, g.y0_mm = 3, g.step_mm = 0.5, g.nx = 3, g.ny = 2;
  g.sigma_mm = {0, 0.01, 1.0 / 3, 2.5, 1e-9, 0.125};
  return g;
}

UncertaintyGrid parse(const std::string& text) {
  std::istringstream in(text);
  return read_uncertainty_grid(in, "grid.csv");
}

std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(UncertaintyGrid, RoundTripsThroughAStream) {
  const UncertaintyGrid g = sample_grid();
  std::ostringstream out;
  write_uncertainty_grid(out, g);
  EXPECT_EQ(out.str().rfind("# photomill run=", 0), 0u) << out.str();
  EXPECT_NE(out.str().find("rows=6"), std::string::npos);
  EXPECT_EQ(parse(out.str()), g);
}

TEST(UncertaintyGrid, RoundTripsASpacingThatIsNotExactInBinary) {
  UncertaintyGrid g;
  g.x0_mm = 0.1, g.y0_mm = -0.3, g.step_mm = 0.1, g.nx = 40, g.ny = 7;
  for (std::size_t k = 0; k < g.nx * g.ny; ++k) g.sigma_mm.push_back(0.001 * static_cast<double>(k));
  std::ostringstream out;
  write_uncertainty_grid(out, g);
  const UncertaintyGrid r = parse(out.str());
  EXPECT_EQ(r.nx, g.nx);
  EXPECT_EQ(r.ny, g.ny);
  EXPECT_NEAR(r.step_mm, 0.1, 1e-12);
  EXPECT_EQ(r.sigma_mm, g.sigma_mm);
}

TEST(UncertaintyGrid, RowsInAnyOrderAndOneNodeAreAccepted) {
  const UncertaintyGrid g = parse("x_mm,y_mm,sigma_mm\n1,2,0.5\n0,2,0.25\n1,1,0\n0,1,0.125\n");
  EXPECT_EQ(g.nx, 2u);
  EXPECT_EQ(g.ny, 2u);
  EXPECT_EQ(g.at(0, 1), 0.25);
  EXPECT_EQ(g.at(1, 0), 0.0);
  const UncertaintyGrid one = parse("x_mm,y_mm,sigma_mm\n5,6,0.02\n");
  EXPECT_EQ(one.nx * one.ny, 1u);
  EXPECT_EQ(one.sample(-100, 100), 0.02);
}

TEST(UncertaintyGrid, MalformedInputNamesTheLineAndTheProblem) {
  const std::string h = "x_mm,y_mm,sigma_mm\n";
  EXPECT_NE(error_of(h).find("at least one node"), std::string::npos);
  EXPECT_NE(error_of("x_mm,sigma_mm\n1,2\n").find("y_mm"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,0.1\n1,0,-0.1\n").find("grid.csv:3: sigma_mm"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,nan\n").find("grid.csv:2:"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,inf\n").find("grid.csv:2:"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,0.1\n0,0,0.2\n").find("every node once"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,1\n1,0,1\n0,1,1\n").find("every node once"), std::string::npos);  // a node missing
  EXPECT_NE(error_of(h + "0,0,1\n1,0,1\n3,0,1\n0,1.5,1\n1,1.5,1\n3,1.5,1\n").find("grid.csv:3: node (1, 0) is not on a regular grid"),
            std::string::npos);
  EXPECT_NE(error_of(h + "0,0,1\n1,0,1\n0,2,1\n1,2,1\n").find("differ"), std::string::npos);
  EXPECT_NE(error_of(h + "0,0,1,2\n").find("grid.csv:2:"), std::string::npos);
  EXPECT_NE(error_of(h + "2e9,0,1\n").find("within 1e9"), std::string::npos);
  EXPECT_NE(error_of(h + "1e300,0,1\n").find("grid.csv:2: field 'x_mm'"), std::string::npos);
  EXPECT_NE(error_of("# photomill run=a rows=3\n" + h + "0,0,1\n").find("grid.csv"), std::string::npos);  // cut short
}

TEST(UncertaintyGrid, WriterRefusesWhatItCannotStore) {
  std::ostringstream out;
  UncertaintyGrid g = sample_grid();
  g.sigma_mm[2] = -1;
  EXPECT_THROW(write_uncertainty_grid(out, g), std::invalid_argument);
  g = sample_grid();
  g.sigma_mm.pop_back();
  EXPECT_THROW(write_uncertainty_grid(out, g), std::invalid_argument);
  g = sample_grid();
  g.step_mm = 0;
  EXPECT_THROW(write_uncertainty_grid(out, g), std::invalid_argument);
}

TEST(UncertaintyGrid, SamplesBilinearlyAndBoundsADiskFromAbove) {
  UncertaintyGrid g;
  g.x0_mm = 0, g.y0_mm = 0, g.step_mm = 1, g.nx = 5, g.ny = 5;
  g.sigma_mm.assign(25, 0);
  g.sigma_mm[2 * 5 + 2] = 1;  // (2, 2)
  EXPECT_DOUBLE_EQ(g.sample(2, 2), 1);
  EXPECT_DOUBLE_EQ(g.sample(2.5, 2), 0.5);
  EXPECT_DOUBLE_EQ(g.sample(1.5, 1.5), 0.25);
  EXPECT_DOUBLE_EQ(g.sample(-50, 2), 0);      // clamped to the edge node (0, 2)
  EXPECT_DOUBLE_EQ(g.max_within(0.2, 0.2, 0.5), 0);
  EXPECT_DOUBLE_EQ(g.max_within(0.2, 0.2, 1.9), 1);  // the disk reaches the cell of (2, 2)
  EXPECT_DOUBLE_EQ(g.max_within(4, 4, 0.9), 0);
  // Every point of the disk samples at most max_within.
  for (double a = 0; a < 6.3; a += 0.1) {
    EXPECT_LE(g.sample(0.7 + 1.2 * std::cos(a), 0.9 + 1.2 * std::sin(a)), g.max_within(0.7, 0.9, 1.2));
  }
}

}  // namespace
}  // namespace photomill
