// Logging to stderr for library and tool code. stdout carries data only; everything a person
// reads goes through here. Verbosity is set once by the tool (-q / -v).
#pragma once

#include <string>

namespace photomill::log {

enum class Level { Quiet = 0, Normal = 1, Verbose = 2 };

void set_level(Level level);
Level level();
// Prefix for every message, normally the tool's name.
void set_program(std::string name);

// "program: warning: message" unless -q.
void warn(const std::string& message);
// "program: message" unless -q (reports, summaries).
void info(const std::string& message);
// Only with -v (details).
void debug(const std::string& message);

// Progress of a long computation on stderr, by default (not with -q): while a Step lives, a
// watcher thread prints "program: <what> ... (N s)" once the step has run progress_delay_s()
// seconds, then every 10 s, and "program: <what>: done in N s" at its end if it printed. Short
// steps print nothing. Steps nest; the innermost is the one shown. set() changes its text (e.g.
// "matching pairs: 40 of 66"). The delay is 2 s, or the environment variable
// PHOTOMILL_PROGRESS_AFTER_S (0: every step at once; the tests use it).
class Step {
public:
  explicit Step(std::string what);
  ~Step();
  Step(const Step&) = delete;
  Step& operator=(const Step&) = delete;
  void set(std::string what);

private:
  unsigned long id_;
};
double progress_delay_s();

}  // namespace photomill::log
