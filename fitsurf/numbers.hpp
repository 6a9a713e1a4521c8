// Numbers in fitsurf's messages and summaries: short, locale-independent (std::to_chars).
// Data files never use these: formats/ writes numbers that round-trip.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

namespace photomill::fitsurf {

// v with a fixed number of decimals ("0.0125").
inline std::string fixed(double v, int decimals) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  return r.ec == std::errc() ? std::string(buf, r.ptr) : std::string("?");
}

// v with `digits` significant digits, without trailing zeros ("0.0125", "1.5e-05", "1200").
inline std::string sig(double v, int digits = 4) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, digits);
  return r.ec == std::errc() ? std::string(buf, r.ptr) : std::string("?");
}

}  // namespace photomill::fitsurf
