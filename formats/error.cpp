#include "formats/error.hpp"

namespace photomill {
namespace {
std::string prefix(const std::string& source, std::size_t line) {
  return line == 0 ? source + ": " : source + ":" + std::to_string(line) + ": ";
}
}  // namespace

InputError::InputError(std::string source, std::size_t line, const std::string& message)
    : std::runtime_error(prefix(source, line) + message),
      source_(std::move(source)),
      line_(line),
      message_(message) {}

}  // namespace photomill
