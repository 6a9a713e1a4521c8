#include "formats/log.hpp"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace photomill::log {
namespace {
std::atomic<int> g_level{static_cast<int>(Level::Normal)};
std::string g_program = "photomill";
std::mutex g_mutex;

void emit(const std::string& line) {
  const std::lock_guard<std::mutex> lock(g_mutex);
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
}
}  // namespace

void set_level(Level l) { g_level = static_cast<int>(l); }
Level level() { return static_cast<Level>(g_level.load()); }
void set_program(std::string name) { g_program = std::move(name); }

void warn(const std::string& m) {
  if (g_level >= static_cast<int>(Level::Normal)) emit(g_program + ": warning: " + m + "\n");
}
void info(const std::string& m) {
  if (g_level >= static_cast<int>(Level::Normal)) emit(g_program + ": " + m + "\n");
}
void debug(const std::string& m) {
  if (g_level >= static_cast<int>(Level::Verbose)) emit(g_program + ": " + m + "\n");
}

}  // namespace photomill::log
