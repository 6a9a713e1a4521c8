// Small helpers for the per-option CLI tests (<stage>/options_test.cpp): read one field of a
// --report JSON file (written by formats/json.hpp's JsonWriter as "key":value, no blanks), count
// substrings, read the numbers of a text line.
#pragma once

#include <cmath>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

namespace photomill::test {

// The raw token after "key": in `json` (a number, true/false/null, or a "string" with its quotes),
// searching from the first occurrence of `after` (a key such as "options", or "" for the start).
// Empty when the key is not there.
inline std::string json_raw(const std::string& json, const std::string& key, const std::string& after = "") {
  std::size_t from = 0;
  if (!after.empty()) {
    from = json.find("\"" + after + "\":");
    if (from == std::string::npos) return "";
  }
  const std::string k = "\"" + key + "\":";
  const std::size_t at = json.find(k, from);
  if (at == std::string::npos) return "";
  std::size_t b = at + k.size(), e = b;
  if (b < json.size() && json[b] == '"') {
    e = json.find('"', b + 1);
    return e == std::string::npos ? "" : json.substr(b, e - b + 1);
  }
  while (e < json.size() && json[e] != ',' && json[e] != '}' && json[e] != ']' && json[e] != '\n') ++e;
  return json.substr(b, e - b);
}

// The number after "key": (NaN when absent or not a number).
inline double json_number(const std::string& json, const std::string& key, const std::string& after = "") {
  const std::string raw = json_raw(json, key, after);
  if (raw.empty() || raw == "null" || raw[0] == '"') return std::nan("");
  char* end = nullptr;
  const double v = std::strtod(raw.c_str(), &end);
  return end == raw.c_str() ? std::nan("") : v;
}

// The numbers of the array after "key": (empty when absent).
inline std::vector<double> json_array(const std::string& json, const std::string& key, const std::string& after = "") {
  std::vector<double> out;
  std::size_t from = 0;
  if (!after.empty()) {
    from = json.find("\"" + after + "\":");
    if (from == std::string::npos) return out;
  }
  const std::string k = "\"" + key + "\":[";
  const std::size_t at = json.find(k, from);
  if (at == std::string::npos) return out;
  const char* p = json.c_str() + at + k.size();
  while (*p && *p != ']') {
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p) break;
    out.push_back(v);
    p = end;
    if (*p == ',') ++p;
  }
  return out;
}

inline std::size_t count_of(std::string_view text, std::string_view what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string_view::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

}  // namespace photomill::test
