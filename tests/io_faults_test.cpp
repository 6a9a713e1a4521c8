// I/O faults injected into every binary (issue #25): tests/fault_shim.c, preloaded into the run,
// makes the reads of one input fail with EIO in the middle of the file, or the writes of one
// output fail with ENOSPC (a failing disk, a full one). Each binary runs on small valid inputs
// with all its outputs asked for, each of them holding a previous run's content first:
//  - EIO on an input: exit 1, one line on stderr naming the file (and the line of a text file)
//    and the error, every previous output byte-identical, no file left behind;
//  - ENOSPC on an output (second outputs included: --report, --poses, --step, ...): exit 1, one
//    line naming that output, every previous output byte-identical, no temporary left;
//  - EIO from fsync of an output (formats/tool.cpp syncs each temporary before its rename): the
//    same.
// The same runs without a fault write every output (so the fixtures are valid inputs and every
// fault below is reached); the shim's log says that each fault was injected. Under AddressSanitizer
// the shim is not first in the library list: ASAN_OPTIONS gets verify_asan_link_order=0.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/fixtures.hpp"
#include "tests/run_tool.hpp"

namespace photomill::test {
namespace {

namespace fs = std::filesystem;

// One run of a binary: its arguments (in the fixture folder), the inputs whose reads a fault
// breaks (text files name the line too), and every file it writes.
struct ToolRun {
  std::string name;  // test name part: binary and what differs
  std::string binary;
  std::vector<std::string> args;
  std::vector<std::string> text_inputs;
  std::vector<std::string> binary_inputs;
  std::vector<std::string> outputs;
  std::string stdin_file;  // fixture given as standard input, if any
};

const std::vector<ToolRun>& runs() {
  static const std::vector<ToolRun> r{
      {"calib", "calib",
       {"--control", "ctl.csv", "--image-size", "2000x1500", "obs.csv", "-o", "out/cam.yaml", "--report", "out/calib.json",
        "--plot", "out/calib.png"},
       {"obs.csv", "ctl.csv"}, {}, {"out/cam.yaml", "out/calib.json", "out/calib.png"}, ""},
      {"detect", "detect",
       {"--aruco", "DICT_4X4_50", "a.png", "b.png", "-o", "out/markers.csv", "--marker-mm", "20", "--scale-bars-out",
        "out/bars.csv", "--features", "out/feats", "--draw", "out/drawings", "--draw-format", "jpg"},
       {}, {"a.png", "b.png"},
       {"out/markers.csv", "out/bars.csv", "out/feats/a.png.feat", "out/feats/b.png.feat", "out/drawings/a.jpg",
        "out/drawings/b.jpg"}, ""},
      {"detect_list", "detect", {"--aruco", "DICT_4X4_50", "-", "-o", "out/markers.csv"}, {"list.txt"}, {},
       {"out/markers.csv"}, "list.txt"},
      {"match", "match", {"pobs.csv", "--camera", "cam.yaml", "--poses", "poses.csv", "-o", "out/tracks.csv"},
       {"pobs.csv", "cam.yaml", "poses.csv"}, {}, {"out/tracks.csv"}, ""},
      {"triangulate", "triangulate",
       {"-c", "cam.yaml", "--control-points", "pctl.csv", "tracks.csv", "-o", "out/cloud.ply", "--poses",
        "out/poses.csv", "--report", "out/triangulate.json", "--preview", "out/cloud.png"},
       {"tracks.csv", "pctl.csv", "cam.yaml"}, {},
       {"out/cloud.ply", "out/poses.csv", "out/triangulate.json", "out/cloud.png"}, ""},
      {"fitsurf", "fitsurf",
       {"--net", "6x6", "cloud.xyz", "-o", "out/part.surf", "--step", "out/part.step", "--iges", "out/part.iges",
        "--report", "out/fitsurf.json", "--preview", "out/surface.png", "--residuals", "out/residuals.ply"},
       {"cloud.xyz"}, {},
       {"out/part.surf", "out/part.step", "out/part.iges", "out/fitsurf.json", "out/surface.png", "out/residuals.ply"}, ""},
      {"fitsurf_ply", "fitsurf", {"--net", "6x6", "cloud.ply", "-o", "out/part.surf"}, {}, {"cloud.ply"},
       {"out/part.surf"}, ""},
      {"toolpath", "toolpath",
       {"part.surf", "-o", "out/part.cl", "--report", "out/toolpath.json", "--preview", "out/path.png", "--scallop-mm", "0.5",
        "--tool-radius-mm", "10", "--max-step-mm", "10"},
       {"part.surf"},
       {}, {"out/part.cl", "out/toolpath.json", "out/path.png"}, ""},
      {"clpost", "clpost", {"part.cl", "-o", "out/part.nc"}, {"part.cl"}, {}, {"out/part.nc"}, ""},
      {"clpost_csv", "clpost", {"part_cl.csv", "-o", "out/part.nc"}, {"part_cl.csv"}, {}, {"out/part.nc"}, ""},
      {"rough", "rough", {"part.surf", "-o", "out/rough.cl", "--cell-mm", "2", "--tool-diameter-mm", "20", "--step-down-mm", "10"}, {"part.surf"}, {}, {"out/rough.cl"}, ""},
      {"targets", "targets",
       {"plate", "-o", "out/plate.pdf", "--svg", "out/plate.svg", "--control-points", "out/plate_points.csv"}, {}, {},
       {"out/plate.pdf", "out/plate.svg", "out/plate_points.csv"}, ""},
      {"report", "report", {"job", "-o", "out/report.html"}, {"job/calib.json"}, {"job/calib.png"}, {"out/report.html"}, ""},
      {"cutsim", "cutsim", {"part.surf", "part.cl", "--cell-mm", "2", "--report", "out/cutsim.json", "--picture", "out/cutsim.png"},
       {"part.surf", "part.cl"}, {}, {"out/cutsim.json", "out/cutsim.png"}, ""},
  };
  return r;
}

void PrintTo(const ToolRun& r, std::ostream* os) {
  *os << r.binary;
  for (const auto& a : r.args) *os << " " << a;
}

// The fixtures every run reads, in `dir`.
void write_fixtures(const fs::path& dir) {
  const fs::path demo = fs::path(PHOTOMILL_SOURCE_DIR) / "data" / "demo";
  fs::copy_file(demo / "board_observations.csv", dir / "obs.csv");
  fs::copy_file(demo / "board_points.csv", dir / "ctl.csv");
  fs::copy_file(demo / "observations.csv", dir / "pobs.csv");
  fs::copy_file(demo / "control_points.csv", dir / "pctl.csv");
  fs::copy_file(demo / "camera.yaml", dir / "cam.yaml");
  fs::copy_file(demo / "poses.csv", dir / "poses.csv");
  fs::copy_file(demo / "surface.ply", dir / "cloud.ply");
  std::string tracks = read_file(demo / "observations.csv");
  tracks.replace(tracks.find("point_id"), 8, "track_id");
  std::ofstream(dir / "tracks.csv", std::ios::binary) << tracks;
  std::ofstream(dir / "cloud.xyz", std::ios::binary) << cloud_xyz();
  std::ofstream(dir / "part.surf", std::ios::binary) << surface();
  std::ofstream(dir / "part.cl", std::ios::binary) << cl_apt();
  std::ofstream(dir / "part_cl.csv", std::ios::binary) << cl_csv();
  std::ofstream(dir / "list.txt", std::ios::binary) << "a.png\nb.png\n";
  // Grey pictures with some texture (PNG compresses a flat one to a few bytes).
  cv::Mat a(96, 128, CV_8UC1), b(120, 160, CV_8UC1);
  cv::randu(a, 0, 255);
  cv::randu(b, 0, 255);
  cv::imwrite((dir / "a.png").string(), a);
  cv::imwrite((dir / "b.png").string(), b);
  // A job folder for report: a calibration report and its picture.
  fs::create_directories(dir / "job");
  std::ofstream(dir / "job" / "calib.json", std::ios::binary)
      << "{\n  \"tool\":\"calib\",\n  \"rms_px\":0.1,\n  \"points_used\":240,\n  \"projection_sigma_px\":{\n"
         "    \"corners\":0.2\n  }\n}\n";
  cv::imwrite((dir / "job" / "calib.png").string(), a);
}

std::map<std::string, std::string> contents(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string name = fs::relative(e.path(), dir).string();
    out[name] = e.is_regular_file() ? read_file(e.path()) : "<folder>";
  }
  return out;
}

std::string ident(std::string s) {
  for (char& c : s) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return s;
}

std::string base_name(const std::string& path) { return fs::path(path).filename().string(); }

// A fixture folder with the outputs of a previous run in place (each file's content says which).
struct Folder {
  TempDir dir;
  TempDir log_dir;
  explicit Folder(const ToolRun& run) {
    write_fixtures(dir.path());
    for (const auto& o : run.outputs) {
      fs::create_directories((dir.path() / o).parent_path());
      std::ofstream(dir.path() / o, std::ios::binary) << "the previous run's " << o << "\n";
    }
  }
  fs::path log() const { return log_dir.path() / "faults.log"; }
};

ToolResult run_with(const ToolRun& run, const Folder& folder, Environment env) {
  std::vector<std::string> args{"-q"};
  args.insert(args.end(), run.args.begin(), run.args.end());
  const std::string in = run.stdin_file.empty() ? "" : read_file(folder.dir.path() / run.stdin_file);
  if (!env.empty()) {
    env.emplace_back("LD_PRELOAD", PHOTOMILL_FAULT_SHIM);
    env.emplace_back("PHOTOMILL_FAULT_LOG", folder.log().string());
    const char* asan = std::getenv("ASAN_OPTIONS");
    env.emplace_back("ASAN_OPTIONS", std::string(asan != nullptr && *asan != '\0' ? std::string(asan) + ":" : "") +
                                         "verify_asan_link_order=0");
  }
  return run_tool(run.binary, args, in, folder.dir.path(), env);
}

// ---------------------------------------------------------------------------------------------

class Baseline : public ::testing::TestWithParam<ToolRun> {};

// Without a fault every output is written (new content), and nothing else is left.
TEST_P(Baseline, WritesEveryOutput) {
  const ToolRun& run = GetParam();
  Folder folder(run);
  const auto before = contents(folder.dir.path());
  const ToolResult r = run_with(run, folder, {{"PHOTOMILL_FAULT_WRITE", "no-such-file-name"}});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const auto after = contents(folder.dir.path());
  std::set<std::string> names_before, names_after;
  for (const auto& [name, text] : before) names_before.insert(name);
  for (const auto& [name, text] : after) names_after.insert(name);
  EXPECT_EQ(names_after, names_before) << "files appeared or went";
  for (const auto& o : run.outputs) {
    EXPECT_NE(after.at(o), before.at(o)) << o << " was not written";
  }
  EXPECT_FALSE(fs::exists(folder.log())) << read_file(folder.log());
}

INSTANTIATE_TEST_SUITE_P(Runs, Baseline, ::testing::ValuesIn(runs()),
                         [](const ::testing::TestParamInfo<ToolRun>& info) { return info.param.name; });

struct Fault {
  ToolRun run;
  std::string file;  // the input whose reads fail, or the output whose writes fail
  bool write = false;
  bool text = false;  // a text input: the message names the line
  bool sync = false;  // an output whose fsync fails (write is true too)
};

void PrintTo(const Fault& f, std::ostream* os) {
  *os << f.run.binary << " " << (f.sync ? "EIO syncing " : f.write ? "ENOSPC writing " : "EIO reading ") << f.file;
}

std::vector<Fault> faults() {
  std::vector<Fault> out;
  for (const ToolRun& run : runs()) {
    for (const auto& f : run.text_inputs) out.push_back({run, f, false, true});
    for (const auto& f : run.binary_inputs) out.push_back({run, f, false, false});
    for (const auto& f : run.outputs) out.push_back({run, f, true, false});
    for (const auto& f : run.outputs) out.push_back({run, f, true, false, true});
  }
  return out;
}

class IoFault : public ::testing::TestWithParam<Fault> {};

TEST_P(IoFault, FailsNamingTheFileAndLeavesEveryOutputAsItWas) {
  const Fault& f = GetParam();
  Folder folder(f.run);
  const auto before = contents(folder.dir.path());
  // Standard input is the file run_tool names "stdin".
  const bool from_stdin = !f.write && f.file == f.run.stdin_file;
  const char* variable = f.sync ? "PHOTOMILL_FAULT_FSYNC" : f.write ? "PHOTOMILL_FAULT_WRITE" : "PHOTOMILL_FAULT_READ";
  const ToolResult r = run_with(f.run, folder, {{variable, from_stdin ? "stdin" : base_name(f.file)}});
  ASSERT_TRUE(fs::exists(folder.log())) << "the fault was never injected: exit " << r.exit_code << ", " << r.err;
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(r.out, "");
  ASSERT_FALSE(r.err.empty());
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "more than one line on stderr:\n" << r.err;
  const std::string line = r.err.substr(0, r.err.find('\n'));
  const std::string expected_error = f.write && !f.sync ? "No space left on device" : "Input/output error";
  // The message names the file as the user gave it (for a file in a folder given on the command
  // line, its path), the line of a text input, and the system's reason.
  const std::string shown = from_stdin ? "<stdin>" : f.file;
  const std::string pattern = f.run.binary + ": " + std::regex_replace(shown, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
                              (f.text ? ":[0-9]+" : "") + ": .*";
  EXPECT_TRUE(std::regex_match(line, std::regex(pattern))) << line << "\nexpected: " << pattern;
  EXPECT_NE(line.find(expected_error), std::string::npos) << line;
  const auto after = contents(folder.dir.path());
  EXPECT_EQ(after.size(), before.size()) << "files appeared or went";
  for (const auto& [name, text] : before) {
    const auto it = after.find(name);
    ASSERT_NE(it, after.end()) << name << " was removed";
    EXPECT_TRUE(it->second == text) << name << " was changed";
  }
  for (const auto& [name, text] : after) EXPECT_TRUE(before.count(name)) << name << " was left behind";
}

INSTANTIATE_TEST_SUITE_P(Runs, IoFault, ::testing::ValuesIn(faults()), [](const ::testing::TestParamInfo<Fault>& info) {
  return info.param.run.name + (info.param.sync ? "_EIO_fsync_" : info.param.write ? "_ENOSPC_" : "_EIO_") +
         ident(info.param.file);
});

}  // namespace
}  // namespace photomill::test
