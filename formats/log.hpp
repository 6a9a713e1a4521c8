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
// Only with -v (progress, details).
void debug(const std::string& message);

}  // namespace photomill::log
