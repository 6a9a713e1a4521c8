// Interrupted runs (issue 11, item 5): every stage killed by SIGINT or SIGTERM in the middle of a
// long run leaves no output file, or the previous one intact, and no temporary file beside it.
// Each binary gets an input that keeps it busy for a while; the test starts it with -o FILE,
// signals it after kSignalDelay (while it computes; earlier if its temporary output appears
// first) and checks the output folder. For a stage with a large output (clpost) a second case
// waits for the temporary output to appear and signals then, so the signal handler's removal of
// the temporary file is exercised. A run that ends before the signal is repeated with an input
// twice as large.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <array>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "formats/surface.hpp"
#include "tests/run_tool.hpp"
#include "tests/temp_dir.hpp"

namespace photomill::test {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// How long a run may compute before it is signalled (it is signalled earlier once its temporary
// output exists). Long enough for the process to be past start-up and inside its work.
constexpr auto kSignalDelay = std::chrono::milliseconds(250);
// Longest wait for the temporary output in the while-writing cases.
constexpr auto kWriteWait = std::chrono::seconds(15);
// Runs that finish before the signal are repeated with inputs 2x, 4x... as large.
constexpr int kMaxAttempts = 4;

// ---------------------------------------------------------------------------------------------
// Inputs

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

// A pinhole camera without distortion, 2000 x 1500 px.
constexpr double kF = 2000, kCx = 999.5, kCy = 749.5;
constexpr int kWidth = 2000, kHeight = 1500;

const char* const kCameraYaml =
    "%YAML:1.0\n---\nimage_width: 2000\nimage_height: 1500\n"
    "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
    "   data: [ 2000., 0., 999.5, 0., 2000., 749.5, 0., 0., 1. ]\n";

// A synthetic scene: `points` points on a wavy 200 x 200 mm patch seen by `views` cameras on a
// ring 500 mm above it, all looking at its centre. Writes observations (image,point_id,u_px,v_px),
// the same as tracks (track_id,image,u_px,v_px), control points and camera.yaml into `dir`.
void write_scene(const fs::path& dir, int views, int points) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-100, 100);
  std::normal_distribution<double> noise(0, 0.2);
  std::vector<std::array<double, 3>> xyz;
  std::ostringstream control;
  control << "point_id,x_mm,y_mm,z_mm\n";
  for (int i = 0; i < points; ++i) {
    const double x = coord(rng), y = coord(rng);
    const double z = 15 * std::sin(x / 30) * std::cos(y / 25);
    xyz.push_back({x, y, z});
    control << i << "," << x << "," << y << "," << z << "\n";
  }
  std::ostringstream obs, tracks;
  obs.precision(10);
  tracks.precision(10);
  obs << "image,point_id,u_px,v_px\n";
  tracks << "track_id,image,u_px,v_px\n";
  for (int v = 0; v < views; ++v) {
    const double a = 2 * M_PI * v / views;
    const double r = 300 + 60 * std::sin(3 * a);
    const double c[3] = {r * std::cos(a), r * std::sin(a), 500.0 + 40 * std::cos(2 * a)};
    // Rows of the rotation world -> camera: z towards the patch centre, x horizontal.
    double zc[3] = {-c[0], -c[1], -c[2]};
    const double nz = std::sqrt(zc[0] * zc[0] + zc[1] * zc[1] + zc[2] * zc[2]);
    for (double& e : zc) e /= nz;
    double xc[3] = {zc[1], -zc[0], 0};  // zc x (0,0,1)
    const double nx = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1]);
    for (double& e : xc) e /= nx;
    const double yc[3] = {zc[1] * xc[2] - zc[2] * xc[1], zc[2] * xc[0] - zc[0] * xc[2], zc[0] * xc[1] - zc[1] * xc[0]};
    char image[32];
    std::snprintf(image, sizeof image, "v%03d.png", v);
    for (int i = 0; i < points; ++i) {
      const double d[3] = {xyz[i][0] - c[0], xyz[i][1] - c[1], xyz[i][2] - c[2]};
      const double X = xc[0] * d[0] + xc[1] * d[1] + xc[2] * d[2];
      const double Y = yc[0] * d[0] + yc[1] * d[1] + yc[2] * d[2];
      const double Z = zc[0] * d[0] + zc[1] * d[1] + zc[2] * d[2];
      const double u = kF * X / Z + kCx + noise(rng), w = kF * Y / Z + kCy + noise(rng);
      if (u < 0 || w < 0 || u > kWidth - 1 || w > kHeight - 1) continue;
      obs << image << "," << i << "," << u << "," << w << "\n";
      tracks << i << "," << image << "," << u << "," << w << "\n";
    }
  }
  write_text(dir / "obs.csv", obs.str());
  write_text(dir / "tracks.csv", tracks.str());
  write_text(dir / "control.csv", control.str());
  write_text(dir / "camera.yaml", kCameraYaml);
}

// A binary PGM of white noise, `side` px square (detect searches it for markers in vain).
void write_noise_image(const fs::path& p, int side) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> grey(0, 255);
  std::vector<unsigned char> px(static_cast<std::size_t>(side) * side);
  for (auto& v : px) v = static_cast<unsigned char>(grey(rng));
  std::ofstream f(p, std::ios::binary);
  f << "P5\n" << side << " " << side << "\n255\n";
  f.write(reinterpret_cast<const char*>(px.data()), static_cast<std::streamsize>(px.size()));
}

// A bicubic B-spline patch, 100 x 100 mm, 12 x 12 poles with bumps.
BSplineSurface bumpy_surface() {
  BSplineSurface s;
  const int n = 12;
  s.num_poles_u = s.num_poles_v = n;
  auto knots = [&] {
    std::vector<double> k(4, 0.0);
    for (int i = 1; i < n - 3; ++i) k.push_back(static_cast<double>(i) / (n - 3));
    k.insert(k.end(), 4, 1.0);
    return k;
  };
  s.knots_u = knots();
  s.knots_v = knots();
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = 100.0 * i / (n - 1), y = 100.0 * j / (n - 1);
      s.poles_mm.emplace_back(x, y, 8 * std::sin(x / 15) * std::cos(y / 20));
    }
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// The stages and their long runs

struct Stage {
  std::string tool;
  // Writes inputs for a run of size `scale` (1, 2, 4...) into `dir`; returns the arguments
  // (without -o FILE).
  std::function<std::vector<std::string>(const fs::path& dir, int scale)> prepare;
};

std::vector<Stage> stages() {
  return {
      {"calib",
       [](const fs::path& d, int scale) {
         write_scene(d, 24 * scale, 600 * scale);
         return std::vector<std::string>{(d / "obs.csv").string(), "--control", (d / "control.csv").string(),
                                         "--image-size", "2000x1500", "--optimizer", "simplex"};
       }},
      {"detect",
       [](const fs::path& d, int scale) {
         std::vector<std::string> args{"--aruco", "DICT_4X4_50"};
         for (int i = 0; i < scale; ++i) {
           const fs::path p = d / ("noise" + std::to_string(i) + ".pgm");
           write_noise_image(p, 1500);
           args.push_back(p.string());
         }
         args.insert(args.end(), {"-j", "1"});
         return args;
       }},
      {"match",
       [](const fs::path& d, int scale) {
         write_scene(d, 40 * scale, 1500 * scale);
         return std::vector<std::string>{(d / "obs.csv").string(), "--camera", (d / "camera.yaml").string(),
                                         "-j", "1"};
       }},
      {"triangulate",
       [](const fs::path& d, int scale) {
         write_scene(d, 30 * scale, 3000 * scale);
         return std::vector<std::string>{(d / "tracks.csv").string(), "-c", (d / "camera.yaml").string(),
                                         "--arbitrary-scale", "--threads", "1"};
       }},
      {"fitsurf",
       [](const fs::path& d, int scale) {
         std::mt19937 rng(3);
         std::uniform_real_distribution<double> coord(0, 200);
         std::ostringstream xyz;
         for (int i = 0; i < 100000 * scale; ++i) {
           const double x = coord(rng), y = coord(rng);
           xyz << x << " " << y << " " << 10 * std::sin(x / 20) * std::cos(y / 30) << "\n";
         }
         write_text(d / "cloud.xyz", xyz.str());
         const std::string net = std::to_string(60 * scale) + "x" + std::to_string(60 * scale);
         return std::vector<std::string>{(d / "cloud.xyz").string(), "--net", net, "--solver", "cg"};
       }},
      {"toolpath",
       [](const fs::path& d, int scale) {
         std::ofstream f(d / "part.surf");
         write_surface(f, bumpy_surface());
         f.close();
         const std::string scallop = std::to_string(0.002 / scale);
         return std::vector<std::string>{(d / "part.surf").string(), "--tool-radius-mm", "3", "--scallop-mm", scallop,
                                         "--chord-tol-mm", std::to_string(0.001 / scale), "--threads", "1"};
       }},
      {"clpost",
       [](const fs::path& d, int scale) {
         std::ostringstream cl;
         cl << "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nrapid,0,0,50,,,,\n";
         for (int i = 0; i < 400000 * scale; ++i) {
           cl << "feed," << (i % 1000) * 0.1 << "," << (i / 1000) * 0.1 << "," << 1 + 0.001 * (i % 7) << ",,,,1000\n";
         }
         write_text(d / "path.csv", cl.str());
         return std::vector<std::string>{(d / "path.csv").string()};
       }},
  };
}

// ---------------------------------------------------------------------------------------------
// Running and interrupting

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

struct Interrupted {
  bool finished_first = false;  // the run ended before the signal could be sent
  int status = 0;               // waitpid status
  bool while_writing = false;   // the temporary output existed when the signal was sent
  double seconds = 0;           // from start to signal
  std::string err;
};

// Signals the run when something new appears in `out_dir` (its temporary output) or, unless
// `wait_for_output`, after kSignalDelay.
Interrupted run_and_interrupt(const std::string& tool, const std::vector<std::string>& args, const fs::path& out_dir,
                              const fs::path& log_dir, int sig, bool wait_for_output) {
  const std::string exe = bin_path(tool);
  std::vector<std::string> argv_s{exe};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  const fs::path err_path = log_dir / (tool + ".stderr");
  const std::set<std::string> before = listing(out_dir);
  const auto start = Clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int in = ::open("/dev/null", O_RDONLY);
    const int out = ::open((log_dir / (tool + ".stdout")).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(in, 0);
    ::dup2(out, 1);
    ::dup2(err, 2);
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  Interrupted r;
  while (true) {
    if (::waitpid(pid, &r.status, WNOHANG) == pid) {
      r.finished_first = true;
      r.err = read_file(err_path);
      return r;
    }
    if (listing(out_dir) != before) {
      r.while_writing = true;
      break;
    }
    if (Clock::now() - start >= (wait_for_output ? std::chrono::duration_cast<Clock::duration>(kWriteWait) : kSignalDelay)) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  ::kill(pid, sig);
  ::waitpid(pid, &r.status, 0);
  r.err = read_file(err_path);
  return r;
}

struct Case {
  Stage stage;
  int sig;
  bool previous;        // a previous output file exists
  bool while_writing;   // signal once the temporary output exists
};

std::string case_name(const Case& c) {
  return c.stage.tool + (c.sig == SIGINT ? "_SIGINT" : "_SIGTERM") + (c.while_writing ? "_while_writing" : "") +
         (c.previous ? "_over_previous" : "");
}

void PrintTo(const Case& c, std::ostream* os) { *os << case_name(c); }

class Interrupt : public ::testing::TestWithParam<Case> {};

TEST_P(Interrupt, LeavesNoOutputOrThePreviousOne) {
  const Case& c = GetParam();
  TempDir dir;
  const fs::path in = dir.path() / "in", out = dir.path() / "out";
  fs::create_directories(in);
  fs::create_directories(out);
  const fs::path file = out / "result";
  const std::string previous = "previous output, to be kept\n";
  if (c.previous) write_text(file, previous);
  const std::set<std::string> before = listing(out);

  Interrupted r;
  int scale = 1;
  for (int attempt = 0; attempt < kMaxAttempts; ++attempt, scale *= 2) {
    fs::remove_all(in);
    fs::create_directories(in);
    std::vector<std::string> args = c.stage.prepare(in, scale);
    args.insert(args.end(), {"-o", file.string()});
    r = run_and_interrupt(c.stage.tool, args, out, dir.path(), c.sig, c.while_writing);
    if (!r.finished_first) break;
    // A failed run says why; the input is wrong, not too small.
    ASSERT_TRUE(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 0)
        << c.stage.tool << " failed on its long input (exit " << WEXITSTATUS(r.status) << "):\n" << r.err;
    // Finished before the signal: start again from the same folder state.
    fs::remove(file);
    if (c.previous) write_text(file, previous);
  }
  ASSERT_FALSE(r.finished_first) << c.stage.tool << " finished before the signal even at scale " << scale / 2;
  if (c.while_writing) {
    ASSERT_TRUE(r.while_writing) << "no temporary output appeared within " << kWriteWait.count() << " s";
  }
  std::cout << "[ signal   ] " << c.stage.tool << " scale " << scale << " signalled after " << r.seconds << " s, "
            << (r.while_writing ? "while writing its output" : "while computing") << "\n";

  const bool by_signal = WIFSIGNALED(r.status) && WTERMSIG(r.status) == c.sig;
  const bool failed = WIFEXITED(r.status) && WEXITSTATUS(r.status) != 0;
  EXPECT_TRUE(by_signal || failed) << "status " << r.status << "\n" << r.err;
  EXPECT_EQ(listing(out), before) << "files left in the output folder (or the previous output removed)";
  if (c.previous) {
    EXPECT_EQ(read_file(file), previous) << "the previous output was changed";
  } else {
    EXPECT_FALSE(fs::exists(file));
  }
}

std::vector<Case> cases() {
  std::vector<Case> all;
  for (const Stage& s : stages()) {
    all.push_back({s, SIGINT, false, false});
    all.push_back({s, SIGTERM, true, false});
    // clpost writes its G-code for ~0.5 s (measured): long enough to be caught writing.
    if (s.tool == "clpost") {
      all.push_back({s, SIGINT, false, true});
      all.push_back({s, SIGTERM, true, true});
    }
  }
  return all;
}

INSTANTIATE_TEST_SUITE_P(EveryStage, Interrupt, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return case_name(info.param); });

}  // namespace
}  // namespace photomill::test
