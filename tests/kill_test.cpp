// kill -9 at any moment (issue #25, "Done when"): each stage of a small chain on the demo data is
// killed at random times, 20 runs in all; after each kill every output holds either its previous
// content (byte for byte) or the complete new content of the killed run (its reader accepts it and
// its run id is the killed run's), and where the outputs are a mix of the two runs the next stage
// refuses them, naming the run. As a kill between two renames (microseconds apart) is rare, every
// mix of one new output with the previous others is also made by hand and must be refused.
// Runs are told their run id through PHOTOMILL_RUN_ID (formats/run.hpp).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "formats/camera.hpp"
#include "formats/cl_data.hpp"
#include "formats/features.hpp"
#include "formats/json_value.hpp"
#include "formats/point_cloud.hpp"
#include "formats/run.hpp"
#include "formats/surface.hpp"
#include "formats/tables.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::test {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const fs::path kDemo = fs::path(PHOTOMILL_SOURCE_DIR) / "data" / "demo";
constexpr int kKillsPerStage = 5;  // 4 stages: 20 kills

// Starts `args` (args[0] a binary of the build) in `cwd` with PHOTOMILL_RUN_ID=run, stdout and
// stderr to files in `cwd`; returns the child's pid.
// `env`: more variables for the child (name, value).
pid_t start(const std::vector<std::string>& args, const fs::path& cwd, const std::string& run,
            const std::vector<std::pair<std::string, std::string>>& env = {}) {
  std::fflush(nullptr);  // else the child's freopen writes the parent's pending output again
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(cwd.c_str()) != 0) ::_exit(126);
    std::freopen("stdout.txt", "w", stdout);
    std::freopen("stderr.txt", "w", stderr);
    ::setenv("PHOTOMILL_RUN_ID", run.c_str(), 1);
    for (const auto& [name, value] : env) ::setenv(name.c_str(), value.c_str(), 1);
    std::vector<std::string> a = args;
    a[0] = bin_path(a[0]);
    std::vector<char*> argv;
    for (auto& s : a) argv.push_back(s.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

int wait_exit(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

int run(const std::vector<std::string>& args, const fs::path& cwd, const std::string& run_id) {
  return wait_exit(start(args, cwd, run_id));
}

// The run id a complete output carries; throws if its reader refuses it (cut short, malformed).
std::string complete_run(const fs::path& p) {
  const std::string text = read_file(p);
  std::istringstream in(text);
  const std::string name = p.filename().string(), src = p.string();
  if (p.extension() == ".json") {
    const JsonValue v = parse_json(text, src);
    const JsonValue* r = v.find("run_id");
    return r ? r->string : "";
  }
  if (name == "obs.csv") read_observations(in, src);
  else if (name == "poses.csv") read_poses(in, src);
  else if (p.extension() == ".feat") read_features(in, src);
  else if (p.extension() == ".ply") read_point_cloud(in, src);
  else if (p.extension() == ".txt") read_surface(in, src);
  else if (p.extension() == ".cl") read_cl_apt(in, src);
  else ADD_FAILURE() << "no reader for " << p;
  return find_run_id(text.substr(0, 4096)).value_or("");
}

struct Stage {
  std::string name;
  std::vector<std::string> args;     // run in the work folder
  std::vector<std::string> outputs;  // relative to it
  std::vector<std::string> next;     // the next stage, which must refuse a mix
};

class KillTest : public ::testing::Test {
protected:
  void SetUp() override {
    for (const char* f : {"part_00.jpg", "camera.yaml", "control_points.csv", "observations.csv", "surface.ply"}) {
      fs::copy_file(kDemo / f, dir_.path() / "in" / f, fs::copy_options::none);
    }
  }
  fs::path in(const std::string& f) const { return dir_.path() / "in" / f; }
  TempDir dir_{};
  bool made_in_ = fs::create_directories(dir_.path() / "in");
};

// The four stages (`i`: the input folder, with "/"), each with its outputs and the next stage.
std::vector<Stage> chain(const std::string& i) {
  return {
      {"detect",
       {"detect", "--aruco", "DICT_4X4_100", "--features", "feat", i + "part_00.jpg", "-o", "obs.csv"},
       {"obs.csv", "feat/part_00.jpg.feat"},
       {"match", "--refine", "none", "obs.csv", "feat/part_00.jpg.feat", "--camera", i + "camera.yaml", "-o", "tracks.csv"}},
      {"triangulate",
       {"triangulate", i + "tracks.csv", "--camera", i + "camera.yaml", "--control-points", i + "control_points.csv",
        "--poses", "poses.csv", "--report", "triangulate.json", "-o", "cloud.ply"},
       {"cloud.ply", "poses.csv", "triangulate.json"},
       {"report", ".", "-o", "report.html"}},
      {"fitsurf",
       {"fitsurf", i + "surface.ply", "--net", "20x15", "--report", "fitsurf.json", "-o", "surface.txt"},
       {"surface.txt", "fitsurf.json"},
       {"report", ".", "-o", "report.html"}},
      {"toolpath",
       {"toolpath", "surface.txt", "--tool-radius-mm", "3", "--scallop-mm", "0.05", "--report", "toolpath.json", "-o", "path.cl"},
       {"path.cl", "toolpath.json"},
       {"report", ".", "-o", "report.html"}},
  };
}

// After a killed run in `work` (a copy of `prev` before it), the number of outputs it left new.
// Each output must be the previous one byte for byte or complete with the killed run's id `id`;
// `when` says which kill, in the failure messages.
int new_outputs(const Stage& s, const fs::path& work, const fs::path& prev, const std::string& id,
                const std::string& when) {
  int n_new = 0;
  for (const auto& o : s.outputs) {
    if (read_file(work / o) == read_file(prev / o)) continue;
    std::string got;
    try {
      got = complete_run(work / o);
    } catch (const std::exception& e) {
      ADD_FAILURE() << o << " " << when << ": neither the previous content nor complete: " << e.what();
      continue;
    }
    EXPECT_EQ(got, id) << o << " " << when;
    ++n_new;
  }
  return n_new;
}

TEST_F(KillTest, EveryOutputIsPreviousOrCompleteAndAMixIsRefused) {
  const std::string i = (dir_.path() / "in").string() + "/";
  ASSERT_EQ(run({"match", i + "observations.csv", "--camera", i + "camera.yaml", "-o", i + "tracks.csv"}, dir_.path(), "setup"), 0);
  const std::vector<Stage> stages = chain(i);
  std::mt19937 rng(25);
  int kills = 0, mixes = 0;
  for (const Stage& s : stages) {
    SCOPED_TRACE(s.name);
    // The previous run's outputs, and one complete new run (its outputs and its duration).
    const fs::path prev = dir_.path() / (s.name + "-prev"), fresh = dir_.path() / (s.name + "-new");
    for (const fs::path& d : {prev, fresh}) {
      fs::create_directories(d / "feat");
      if (s.name == "toolpath") fs::copy_file(dir_.path() / "fitsurf-prev" / "surface.txt", d / "surface.txt");
    }
    ASSERT_EQ(run(s.args, prev, "old"), 0) << read_file(prev / "stderr.txt");
    const auto t0 = Clock::now();
    ASSERT_EQ(run(s.args, fresh, "new"), 0) << read_file(fresh / "stderr.txt");
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    for (const auto& o : s.outputs) {
      ASSERT_EQ(complete_run(prev / o), "old") << o;
      ASSERT_EQ(complete_run(fresh / o), "new") << o;
    }
    // Every mix of one new output with the previous others, made by hand, is refused next.
    for (const auto& o : s.outputs) {
      const fs::path mix = dir_.path() / (s.name + "-mix");
      fs::remove_all(mix);
      fs::copy(prev, mix, fs::copy_options::recursive);
      fs::copy_file(fresh / o, mix / o, fs::copy_options::overwrite_existing);
      EXPECT_EQ(run(s.next, mix, "next"), 1) << o << " new, the others previous: not refused";
      EXPECT_NE(read_file(mix / "stderr.txt").find("run"), std::string::npos) << read_file(mix / "stderr.txt");
    }
    // Killed at random moments of a run.
    std::uniform_real_distribution<double> when(0.0, 1.2 * seconds);
    for (int k = 0; k < kKillsPerStage; ++k, ++kills) {
      const fs::path work = dir_.path() / (s.name + "-kill");
      fs::remove_all(work);
      fs::copy(prev, work, fs::copy_options::recursive);
      const std::string id = "kill" + std::to_string(kills);
      const double at = when(rng);
      const pid_t pid = start(s.args, work, id);
      std::this_thread::sleep_for(std::chrono::duration<double>(at));
      ::kill(pid, SIGKILL);
      const int code = wait_exit(pid);
      const int n_new = new_outputs(s, work, prev, id, "after a kill at " + std::to_string(at) + " s");
      std::printf("%s killed at %.3f s of %.3f (exit %d): %d of %zu outputs new\n", s.name.c_str(), at, seconds, code, n_new,
                  s.outputs.size());
      if (n_new > 0 && n_new < static_cast<int>(s.outputs.size())) {
        ++mixes;
        EXPECT_EQ(run(s.next, work, "next"), 1) << "a mix left by a kill was not refused";
      }
    }
  }
  EXPECT_EQ(kills, 20);
  std::printf("%d kills, %d left a mix of two runs\n", kills, mixes);
}

// A kill between two renames, made certain rather than left to chance: the fault shim
// (tests/fault_shim.c, PHOTOMILL_FAULT_KILL_RENAME=N) kills the run with SIGKILL at its N-th
// rename, before making it, for every N from 2 to the stage's number of outputs. Then exactly the
// N - 1 outputs renamed first hold the killed run's complete content, the others their previous
// bytes, and the next stage refuses the mix, naming the run. (The temporaries not yet renamed
// stay behind: nothing runs after SIGKILL to remove them.)
TEST_F(KillTest, KilledBetweenTwoRenamesLeavesAMixTheNextStageRefuses) {
  const std::string i = (dir_.path() / "in").string() + "/";
  ASSERT_EQ(run({"match", i + "observations.csv", "--camera", i + "camera.yaml", "-o", i + "tracks.csv"}, dir_.path(), "setup"), 0);
  const char* asan = std::getenv("ASAN_OPTIONS");
  const std::string asan_options =
      std::string(asan != nullptr && *asan != '\0' ? std::string(asan) + ":" : "") + "verify_asan_link_order=0";
  int windows = 0;
  for (const Stage& s : chain(i)) {
    SCOPED_TRACE(s.name);
    const fs::path prev = dir_.path() / (s.name + "-prev");
    fs::create_directories(prev / "feat");
    if (s.name == "toolpath") fs::copy_file(dir_.path() / "fitsurf-prev" / "surface.txt", prev / "surface.txt");
    ASSERT_EQ(run(s.args, prev, "old"), 0) << read_file(prev / "stderr.txt");
    for (std::size_t n = 2; n <= s.outputs.size(); ++n, ++windows) {
      const fs::path work = dir_.path() / (s.name + "-rename-" + std::to_string(n));
      fs::copy(prev, work, fs::copy_options::recursive);
      const std::string id = "window" + std::to_string(windows);
      const fs::path log = dir_.path() / (s.name + "-faults-" + std::to_string(n) + ".log");
      const int code = wait_exit(start(s.args, work, id,
                                       {{"LD_PRELOAD", PHOTOMILL_FAULT_SHIM},
                                        {"PHOTOMILL_FAULT_KILL_RENAME", std::to_string(n)},
                                        {"PHOTOMILL_FAULT_LOG", log.string()},
                                        {"ASAN_OPTIONS", asan_options}}));
      EXPECT_EQ(code, 128 + SIGKILL) << "killed before rename " << n << "? " << read_file(work / "stderr.txt");
      EXPECT_NE(read_file(log).find("kill before rename"), std::string::npos) << "no kill injected at rename " << n;
      const int n_new = new_outputs(s, work, prev, id, "killed before rename " + std::to_string(n));
      EXPECT_EQ(n_new, static_cast<int>(n) - 1) << "killed before rename " << n;
      EXPECT_EQ(run(s.next, work, "next"), 1) << "the mix left by a kill before rename " << n << " was not refused";
      EXPECT_NE(read_file(work / "stderr.txt").find("run"), std::string::npos) << read_file(work / "stderr.txt");
    }
  }
  EXPECT_EQ(windows, 1 + 2 + 1 + 1);  // detect 2 outputs, triangulate 3, fitsurf 2, toolpath 2
}

// Two runs of one stage at once on the same outputs (two jobs started in one folder): both
// finish, every output is complete and one of theirs, and the report accepts the set only if it
// is one run's.
TEST_F(KillTest, TwoRunsAtOnceOnTheSameOutputs) {
  const std::string i = (dir_.path() / "in").string() + "/";
  ASSERT_EQ(run({"match", i + "observations.csv", "--camera", i + "camera.yaml", "-o", i + "tracks.csv"}, dir_.path(), "setup"), 0);
  const fs::path work = dir_.path() / "both";
  fs::create_directories(work / "a");
  fs::create_directories(work / "b");
  const std::vector<std::string> outs{"cloud.ply", "poses.csv", "triangulate.json"};
  for (int round = 0; round < 3; ++round) {
    const std::vector<std::string> a{"triangulate", i + "tracks.csv", "--camera", i + "camera.yaml", "--control-points",
                                     i + "control_points.csv", "--poses", "../poses.csv", "--report", "../triangulate.json",
                                     "-o", "../cloud.ply"};
    const pid_t pa = start(a, work / "a", "job-a"), pb = start(a, work / "b", "job-b");
    ASSERT_EQ(wait_exit(pa), 0) << read_file(work / "a" / "stderr.txt");
    ASSERT_EQ(wait_exit(pb), 0) << read_file(work / "b" / "stderr.txt");
    std::set<std::string> runs;
    for (const auto& o : outs) {
      const std::string id = complete_run(work / o);
      EXPECT_TRUE(id == "job-a" || id == "job-b") << o << ": " << id;
      runs.insert(id);
    }
    EXPECT_EQ(run({"report", ".", "-o", "report.html"}, work, "next"), runs.size() == 1 ? 0 : 1)
        << runs.size() << " runs: " << read_file(work / "stderr.txt");
    for (const auto& e : fs::directory_iterator(work)) {
      EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << "left behind: " << e.path();
    }
  }
}

}  // namespace
}  // namespace photomill::test
