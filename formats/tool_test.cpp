// The tool contract's file handling: atomic outputs, clear input errors.
#include <CLI/CLI.hpp>

#include "formats/tool.hpp"

#include <sys/stat.h>

#include <csignal>
#include <fstream>
#include <functional>
#include <thread>
#include <stdexcept>
#include <vector>
#include <sstream>

#include <gtest/gtest.h>

#include "formats/error.hpp"
#include "formats/text.hpp"
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

// run()'s body with the tool contract around it, as a main would call it.
int run_body(const std::function<void()>& body) {
  std::string name = "tool_test";
  std::vector<char*> argv{name.data(), nullptr};
  return run(1, argv.data(), {"tool_test", "test", "tool_test"}, [](CLI::App&) {}, body);
}

TEST(Run, RenamesTheOutputsOnlyWhenTheWholeRunSucceeded) {
  test::TempDir dir;
  const auto first = dir.path() / "first.csv", second = dir.path() / "second.csv";
  std::ofstream(first) << "previous\n";
  // The first output is complete and committed, then the run fails: it keeps its old content.
  EXPECT_EQ(run_body([&] {
              OutputFile a(first.string());
              a.stream() << "new\n";
              a.commit();
              EXPECT_EQ(slurp(first), "previous\n");  // staged, not renamed yet
              OutputFile b(second.string());
              b.stream() << "half";
              throw InputError("x.csv", 3, "bad");
            }),
            1);
  EXPECT_EQ(slurp(first), "previous\n");
  EXPECT_EQ(count_files(dir.path()), 1u) << "a temporary file was left behind";
  // The same run succeeding renames both.
  EXPECT_EQ(run_body([&] {
              OutputFile a(first.string());
              a.stream() << "new\n";
              a.commit();
              OutputFile b(second.string());
              b.stream() << "second\n";
              b.commit();
            }),
            0);
  EXPECT_EQ(slurp(first), "new\n");
  EXPECT_EQ(slurp(second), "second\n");
  EXPECT_EQ(count_files(dir.path()), 2u);
}

// What run() prints for a refusal: one line (an OpenCV exception's message has several and ends
// in a newline), with the output's name where a library named its temporary file.
TEST(Run, ARefusalIsOneLineNamingTheOutputNotItsTemporary) {
  test::TempDir dir;
  const auto target = dir.path() / "part.step";
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_body([] { throw std::runtime_error("OpenCV(4.6.0) x.cpp:1: error: (-215) in function 'f'\n\n"); }), 1);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "tool_test: OpenCV(4.6.0) x.cpp:1: error: (-215) in function 'f'\n");
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_body([] { throw std::runtime_error("first\n  second"); }), 1);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "tool_test: first; second\n");
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_body([&] {
              OutputFile out(target.string());
              throw InputError(out.temp_path(), 0, "write failed");
            }),
            1);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "tool_test: " + target.string() + ": write failed\n");
}

// A write that fails throws from the stream operation, naming the output and the reason.
TEST(OutputFile, AFailedWriteThrowsNamingTheOutputAndTheReason) {
  if (!std::filesystem::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full";
  OutputFile out("/dev/full");
  try {
    out.stream() << std::string(1 << 17, 'x');
    FAIL() << "wrote 128 KiB to /dev/full";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/full: write failed: No space left on device");
  }
}

TEST(OutputFile, ANameAsLongAsTheSystemAllowsCanBeWritten) {
  test::TempDir dir;
  const auto target = dir.path() / (std::string(250, 'n') + ".csv");  // 254 bytes, NAME_MAX is 255
  OutputFile out(target.string());
  out.stream() << "data\n";
  out.commit();
  EXPECT_EQ(slurp(target), "data\n");
  EXPECT_EQ(count_files(dir.path()), 1u);
}

TEST(OutputFile, ASymbolicLinkUpdatesTheFileItNames) {
  test::TempDir dir;
  std::filesystem::create_directory(dir.path() / "real");
  const auto file = dir.path() / "real" / "out.csv";
  std::ofstream(file) << "previous\n";
  const auto link = dir.path() / "link.csv";
  std::filesystem::create_symlink("real/out.csv", link);
  OutputFile out(link.string());
  out.stream() << "new\n";
  out.commit();
  EXPECT_TRUE(std::filesystem::is_symlink(link));
  EXPECT_EQ(slurp(file), "new\n");
  // A dangling link creates the file it names.
  const auto dangling = dir.path() / "dangling.csv";
  std::filesystem::create_symlink("real/made.csv", dangling);
  OutputFile made(dangling.string());
  made.stream() << "made\n";
  made.commit();
  EXPECT_TRUE(std::filesystem::is_symlink(dangling));
  EXPECT_EQ(slurp(dir.path() / "real" / "made.csv"), "made\n");
}

TEST(Run, AHangupRemovesTheTemporaryFiles) {
  test::TempDir dir;
  const auto target = dir.path() / "out.csv";
  std::ofstream(target) << "previous\n";
  for (int sig : {SIGHUP, SIGQUIT, SIGPIPE, SIGTERM}) {
    EXPECT_EXIT(run_body([&] {
                  OutputFile a(target.string());
                  a.stream() << "new\n";
                  a.commit();  // staged
                  OutputFile b((dir.path() / "b.csv").string());
                  b.stream() << "half" << std::flush;
                  std::raise(sig);
                }),
                ::testing::KilledBySignal(sig), "");
    EXPECT_EQ(slurp(target), "previous\n");
    EXPECT_EQ(count_files(dir.path()), 1u) << "signal " << sig << " left a temporary file";
  }
}

TEST(OpenInput, AReadErrorNamesTheFileAndLine) {
  // Reading /proc/self/mem at offset 0 fails with EIO: the first page is never mapped.
  if (!std::filesystem::exists("/proc/self/mem")) GTEST_SKIP() << "no /proc";
  auto in = open_input("/proc/self/mem");
  LineReader lines(*in, "/proc/self/mem");
  try {
    lines.next();
    FAIL() << "read past an I/O error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/proc/self/mem:1: read error: Input/output error");
  }
  try {
    read_all("/proc/self/mem", 1000);
    FAIL() << "read past an I/O error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/proc/self/mem: read error: Input/output error");
  }
}

TEST(OpenInput, EndlessDevicesAreRefusedAtOnceAndPipesAreStreams) {
  try {
    open_input("/dev/zero");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/zero: is a device, not a file (an endless input)");
  }
  EXPECT_EQ(read_all("/dev/null", 10), "");
  test::TempDir dir;
  const auto fifo = dir.path() / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer([&] { std::ofstream(fifo) << "a,b\n1,2\n"; });
  EXPECT_EQ(read_all(fifo.string(), 100), "a,b\n1,2\n");
  writer.join();
}

// --preset: its values for the options not given; an option given wins, before or after it; a
// name that is no preset is bad usage (exit 2); a preset naming no option is a programming error.
struct Parsed {
  int exit_code = -1;
  int width = 10;
  bool fast = false;
};
Parsed parse_with_presets(std::vector<std::string> args) {
  Parsed p;
  std::string chosen;
  args.insert(args.begin(), "tool_test");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  p.exit_code = run(static_cast<int>(args.size()), argv.data(), {"tool_test", "test", "tool_test"},
                    [&](CLI::App& app) {
                      app.add_option("--width", p.width);
                      app.add_flag("--fast", p.fast);
                      add_presets(app, chosen, {{"wide", {{"--width", [&] { p.width = 99; }}, {"--fast", [&] { p.fast = true; }}}}},
                                  "wide: width 99, fast");
                    },
                    [] {});
  return p;
}

TEST(Presets, SetWhatTheCommandLineDoesNotGive) {
  const Parsed none = parse_with_presets({});
  EXPECT_EQ(none.exit_code, 0);
  EXPECT_EQ(none.width, 10);
  EXPECT_FALSE(none.fast);
  const Parsed wide = parse_with_presets({"--preset", "wide"});
  EXPECT_EQ(wide.exit_code, 0);
  EXPECT_EQ(wide.width, 99);
  EXPECT_TRUE(wide.fast);
  for (const auto& args : {std::vector<std::string>{"--preset", "wide", "--width", "5"},
                           std::vector<std::string>{"--width", "5", "--preset", "wide"}}) {
    const Parsed p = parse_with_presets(args);
    EXPECT_EQ(p.exit_code, 0);
    EXPECT_EQ(p.width, 5) << "the option given wins";
    EXPECT_TRUE(p.fast);
  }
  EXPECT_EQ(parse_with_presets({"--preset", "narrow"}).exit_code, 2);
  CLI::App app;
  std::string chosen;
  EXPECT_THROW(add_presets(app, chosen, {{"wide", {{"--no-such-option", [] {}}}}}, ""), std::logic_error);
}

}  // namespace
}  // namespace photomill::tool
