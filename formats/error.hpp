// Typed errors thrown by photomill library code. Only a main() turns them into exit codes:
// InputError and GeometryError -> 1, UsageError -> 2.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace photomill {

// Malformed or unreadable input. what() is "source:line: message" (line 0 = the whole source,
// printed as "source: message"), the form PROJ's cct and compilers use.
class InputError : public std::runtime_error {
public:
  InputError(std::string source, std::size_t line, const std::string& message);
  const std::string& source() const noexcept { return source_; }
  std::size_t line() const noexcept { return line_; }
  // The message without the "source:line: " prefix.
  const std::string& message() const noexcept { return message_; }

private:
  std::string source_;
  std::size_t line_;
  std::string message_;
};

// The input is well formed but its geometry cannot give an answer (too few points, all cameras
// on a line, a flat cloud for a curved fit). The message explains what is missing.
class GeometryError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// The command line asks for something impossible (conflicting options, a bad value).
class UsageError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

}  // namespace photomill
