// The tool contract's file handling: atomic outputs, clear input errors.
#include "formats/tool.hpp"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::tool {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::size_t count_files(const std::filesystem::path& dir) {
  return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator(dir), {}));
}

TEST(OutputFile, CommitRenamesOntoTheTarget) {
  test::TempDir dir;
  const auto target = dir.path() / "out.csv";
  {
    OutputFile out(target.string());
    out.stream() << "data\n";
    EXPECT_FALSE(std::filesystem::exists(target));  // only the temporary exists so far
    out.commit();
  }
  EXPECT_EQ(slurp(target), "data\n");
  EXPECT_EQ(count_files(dir.path()), 1u);
}

TEST(OutputFile, WithoutCommitTheOldFileIsIntactAndNoTemporaryRemains) {
  test::TempDir dir;
  const auto target = dir.path() / "out.csv";
  std::ofstream(target) << "previous\n";
  {
    OutputFile out(target.string());
    out.stream() << "half-writ";
  }  // e.g. an exception unwinding
  EXPECT_EQ(slurp(target), "previous\n");
  EXPECT_EQ(count_files(dir.path()), 1u);
}

TEST(OutputFile, LibrariesWritingByNameGoThroughTheTemporary) {
  test::TempDir dir;
  const auto target = dir.path() / "s.step";
  OutputFile out(target.string());
  std::ofstream(out.temp_path()) << "ISO-10303-21;";
  out.commit();
  EXPECT_EQ(slurp(target), "ISO-10303-21;");
}

TEST(OutputFile, MissingFolderIsAnInputErrorNamingThePath) {
  test::TempDir dir;
  const auto target = dir.path() / "no" / "such" / "out.csv";
  OutputFile out(target.string());
  try {
    out.stream();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(target.string() + ": cannot write"), std::string::npos) << e.what();
  }
}

TEST(OutputFile, DevicesAreWrittenInPlaceNeverReplaced) {
  // Renaming a temporary onto /dev/null would replace the device (as root it succeeds).
  if (!std::filesystem::is_character_file("/dev/null")) GTEST_SKIP() << "/dev/null is not a device on this machine";
  for (int round = 0; round < 2; ++round) {
    OutputFile out("/dev/null");
    if (round == 0) {
      out.stream() << "discarded\n";
    } else {
      std::ofstream(out.temp_path()) << "written by name";
    }
    out.commit();
  }
  EXPECT_TRUE(std::filesystem::is_character_file("/dev/null"));
}

TEST(OutputFile, ADirectoryIsNotAnOutput) {
  test::TempDir dir;
  EXPECT_THROW(OutputFile(dir.path().string()), InputError);
}

TEST(OpenInput, MissingFileAndDirectoryAreNamed) {
  test::TempDir dir;
  const auto missing = (dir.path() / "nope.csv").string();
  try {
    open_input(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), missing + ": cannot open: No such file or directory");
  }
  EXPECT_THROW(open_input(dir.path().string()), InputError);
  EXPECT_EQ(source_name("-"), "<stdin>");
}

TEST(ReadAll, RefusesOversizedInputs) {
  test::TempDir dir;
  const auto p = dir.path() / "big";
  std::ofstream(p) << std::string(1000, 'x');
  EXPECT_EQ(read_all(p.string(), 1000).size(), 1000u);
  EXPECT_THROW(read_all(p.string(), 999), InputError);
}

}  // namespace
}  // namespace photomill::tool
