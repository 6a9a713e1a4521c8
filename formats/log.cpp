#include "formats/log.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <vector>

#include <pthread.h>

#include "formats/text.hpp"

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

double progress_delay_s() {
  static const double delay = [] {
    const char* e = std::getenv("PHOTOMILL_PROGRESS_AFTER_S");
    if (e == nullptr || *e == '\0') return 2.0;
    const auto v = parse_double(e);
    return v && *v >= 0 ? *v : 2.0;
  }();
  return delay;
}

namespace {

using Clock = std::chrono::steady_clock;

std::string seconds_text(Clock::duration d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f s", std::chrono::duration<double>(d).count());
  return buf;
}

// The steps alive and the thread that reports the innermost one. A function-local static: its
// destructor (at exit) stops and joins the thread. A child made by fork() (formats/cad.cpp) has
// no watcher thread and leaves by _exit, so it never joins one.
//
// fork() copies only the forking thread: a lock another thread held at that moment (the
// allocator's, taken while the watcher formats a line or while the thread is being set up) stays
// locked in the child forever, and the child hangs in its first allocation (seen under
// AddressSanitizer: toolpath --all-faces starts a step, so the thread, then forks the STEP
// reader at once). So the thread has finished starting before push() returns, it does all its
// work under m_, and the fork handlers hold m_ across every fork.
class Watcher {
public:
  Watcher() {
    ::pthread_atfork([] { watcher_for_fork().m_.lock(); }, [] { watcher_for_fork().m_.unlock(); },
                     [] { watcher_for_fork().m_.unlock(); });
  }

  struct Entry {
    unsigned long id;
    std::string what;
    Clock::time_point start;
    Clock::time_point next;
    bool printed = false;
  };

  unsigned long push(std::string what) {
    std::unique_lock<std::mutex> lock(m_);
    if (!thread_.joinable()) {
      thread_ = std::thread([this] { loop(); });
      cv_.wait(lock, [this] { return running_; });
    }
    const auto now = Clock::now();
    const auto delay = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(progress_delay_s()));
    steps_.push_back({++last_id_, std::move(what), now, now + delay});
    if (progress_delay_s() <= 0) {  // every step at once, here rather than by the thread: no race
      info(steps_.back().what + " ...");
      steps_.back().printed = true;
      steps_.back().next = now + std::chrono::seconds(10);
    }
    cv_.notify_all();
    return last_id_;
  }
  void set(unsigned long id, std::string what) {
    std::unique_lock<std::mutex> lock(m_);
    for (auto& e : steps_) {
      if (e.id != id) continue;
      if (progress_delay_s() <= 0 && e.what != what) info(what + " ...");
      e.what = std::move(what);
    }
  }
  void pop(unsigned long id) {
    std::unique_lock<std::mutex> lock(m_);
    for (auto it = steps_.begin(); it != steps_.end(); ++it) {
      if (it->id != id) continue;
      if (it->printed) info(it->what + ": done in " + seconds_text(Clock::now() - it->start));
      steps_.erase(it);
      break;
    }
    cv_.notify_all();
  }
  ~Watcher() {
    {
      std::unique_lock<std::mutex> lock(m_);
      stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

private:
  static Watcher& watcher_for_fork();

  void loop() {
    std::unique_lock<std::mutex> lock(m_);
    running_ = true;
    cv_.notify_all();
    while (!stop_) {
      if (steps_.empty()) {
        cv_.wait(lock);
        continue;
      }
      Entry& top = steps_.back();
      const auto now = Clock::now();
      if (now >= top.next) {
        info(top.what + " ... (" + seconds_text(now - top.start) + ")");
        top.printed = true;
        top.next = now + std::chrono::seconds(10);
      }
      const Clock::time_point until = top.next;  // a copy: steps_ may change while we wait
      cv_.wait_until(lock, until);
    }
  }

  std::mutex m_;
  std::condition_variable cv_;
  std::vector<Entry> steps_;
  unsigned long last_id_ = 0;
  bool stop_ = false;
  bool running_ = false;  // the thread has started (loop() holds or waits on m_)
  std::thread thread_;
};

Watcher& watcher() {
  static Watcher w;
  return w;
}

Watcher& Watcher::watcher_for_fork() { return watcher(); }

}  // namespace

Step::Step(std::string what) : id_(watcher().push(std::move(what))) {}
Step::~Step() { watcher().pop(id_); }
void Step::set(std::string what) { watcher().set(id_, std::move(what)); }

}  // namespace photomill::log
