#include "formats/run.hpp"

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>

#include "formats/text.hpp"

namespace photomill {
namespace {

bool valid_run_id(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (const char c : s) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == ':' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::string make_run_id() {
  if (const char* env = std::getenv("PHOTOMILL_RUN_ID"); env != nullptr && valid_run_id(env)) return env;
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char when[32];
  std::strftime(when, sizeof when, "%Y%m%dT%H%M%SZ", &utc);
  std::random_device device;
  const std::uint32_t random = device();
  char id[96];
  std::snprintf(id, sizeof id, "%s-%ld-%08x", when, static_cast<long>(getpid()), static_cast<unsigned>(random));
  return id;
}

}  // namespace

const std::string& run_id() {
  static const std::string id = make_run_id();
  return id;
}

std::string stamp_line(std::optional<std::size_t> rows) {
  std::string s = "# photomill run=" + run_id();
  if (rows) s += " rows=" + std::to_string(*rows);
  return s + "\n";
}

std::optional<std::string> find_run_id(std::string_view head) {
  constexpr std::string_view kKey = "photomill run=";
  const auto at = head.find(kKey);
  if (at == std::string_view::npos) return std::nullopt;
  const std::string_view rest = head.substr(at + kKey.size());
  const std::string_view id = rest.substr(0, rest.find_first_of(" \t\r\n\""));
  if (!valid_run_id(id)) return std::nullopt;
  return std::string(id);
}

std::optional<Stamp> parse_stamp(std::string_view line) {
  constexpr std::string_view kPrefix = "# photomill ";
  if (line.substr(0, kPrefix.size()) != kPrefix) return std::nullopt;
  Stamp stamp;
  bool any = false;
  for (const std::string_view word : split_whitespace(line.substr(kPrefix.size()))) {
    const auto eq = word.find('=');
    if (eq == std::string_view::npos) continue;
    const std::string_view key = word.substr(0, eq);
    const std::string_view value = word.substr(eq + 1);
    if (key == "run") {
      if (value.empty()) return std::nullopt;
      stamp.run = std::string(value);
      any = true;
    } else if (key == "rows") {
      const auto n = parse_int(value);
      if (!n || *n < 0 || value.front() == '+') return std::nullopt;
      stamp.rows = static_cast<std::size_t>(*n);
      any = true;
    }
  }
  if (!any) return std::nullopt;
  return stamp;
}

}  // namespace photomill
