// Parse-time checks of numeric options (issue #25, deliverable 4): every numeric option of a
// user tool carries one, so NaN, infinities, negative or zero values where they mean nothing and
// absurd magnitudes are bad usage (exit 2) before any work starts, and --help shows the range
// after the option's type ("FLOAT:in (0, 500]"). CLI11's own CLI::Range and
// CLI::PositiveNumber let NaN through (every comparison with NaN is false) and infinity through
// PositiveNumber; these compare the other way round, so NaN fails every bound.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

namespace photomill::tool {

// A bound as --help shows it: 6 significant digits, exponents without '+' and leading zeros
// (1e6, 1e-6, 0.0005, 45).
inline std::string bound_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  std::string s(buf);
  const auto e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mant = s.substr(0, e), exp = s.substr(e + 1);
  std::string sign;
  if (!exp.empty() && (exp[0] == '+' || exp[0] == '-')) {
    if (exp[0] == '-') sign = "-";
    exp.erase(0, 1);
  }
  while (exp.size() > 1 && exp[0] == '0') exp.erase(0, 1);
  return mant + "e" + sign + exp;
}

// The value is a finite number within [lo, hi], or (lo, hi] when `lo_open` (for sizes, where
// zero means nothing). Integer options use it too (the value is then also converted by CLI11).
inline CLI::Validator finite_in(double lo, double hi, bool lo_open = false) {
  const std::string range = std::string(lo_open ? "(" : "[") + bound_text(lo) + ", " + bound_text(hi) + "]";
  return CLI::Validator(
      [lo, hi, lo_open, range](std::string& input) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(input, v)) return "'" + input + "' is not a number";
        const bool above_lo = lo_open ? v > lo : v >= lo;
        if (!(std::isfinite(v) && above_lo && v <= hi)) return "'" + input + "' is not in " + range;
        return {};
      },
      "in " + range);
}

// (0, hi]: a size, a tolerance, a feed.
inline CLI::Validator positive_up_to(double hi) { return finite_in(0, hi, true); }
// [0, hi]: an allowance, a height above something, a count where 0 means "none" or "auto".
inline CLI::Validator non_negative_up_to(double hi) { return finite_in(0, hi, false); }

}  // namespace photomill::tool
