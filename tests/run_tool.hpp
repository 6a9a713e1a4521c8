// Runs a photomill executable as a child process with given arguments and standard input, and
// captures its exit code, stdout and stderr (through temporary files, so no pipe can deadlock).
// Used by the golden CLI tests of every stage.
#pragma once

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/temp_dir.hpp"

namespace photomill::test {

struct ToolResult {
  int exit_code = -1;    // exit status, or 128 + signal number
  std::string out;
  std::string err;
};

// A user tool of the build (bin/), and a test or benchmark tool of tools/ (synth, synth_accuracy, ...).
inline std::string bin_path(const std::string& tool) { return std::string(PHOTOMILL_BIN_DIR) + "/" + tool; }
inline std::string tools_path(const std::string& tool) { return std::string(PHOTOMILL_TOOLS_DIR) + "/" + tool; }

inline std::string read_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// Environment variables set in the child only (name, value), e.g. LD_PRELOAD.
using Environment = std::vector<std::pair<std::string, std::string>>;

// Runs `tool` (a name in the build's bin/ folder, or a path) in `cwd` (default: a fresh temp dir),
// with `env` added to the environment.
inline ToolResult run_tool(const std::string& tool, const std::vector<std::string>& args, const std::string& stdin_text = "",
                           const std::filesystem::path& cwd = {}, const Environment& env = {}) {
  TempDir io;
  const auto in_path = io.path() / "stdin";
  const auto out_path = io.path() / "stdout";
  const auto err_path = io.path() / "stderr";
  std::ofstream(in_path, std::ios::binary) << stdin_text;
  const std::string exe = tool.find('/') == std::string::npos ? bin_path(tool) : tool;
  std::vector<std::string> argv_s{exe};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int in = ::open(in_path.c_str(), O_RDONLY);
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(in, 0);
    ::dup2(out, 1);
    ::dup2(err, 2);
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
    for (const auto& [name, value] : env) ::setenv(name.c_str(), value.c_str(), 1);
    // One run id for every run of a test (formats/run.hpp) unless `env` gives one: two runs on the
    // same input then write the same bytes, which the tests of determinism and of options without
    // effect compare.
    ::setenv("PHOTOMILL_RUN_ID", "test", 0);
    std::vector<char*> argv;
    for (auto& a : argv_s) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ToolResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_file(out_path);
  r.err = read_file(err_path);
  return r;
}

}  // namespace photomill::test
