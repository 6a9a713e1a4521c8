// The largest magnitude a number in a photomill file may have, and the words for a field that is
// not a usable number. No real quantity of photomill's (mm, px, mm/min, rpm, knots) comes near
// 1e15 (1e15 mm is 6.7 astronomical units); a larger value is a typo or junk, and the fits would
// overflow squaring it (1e300 * 1e300 = inf), so readers refuse it on its line (docs/errors.md).
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <string_view>

#include "formats/text.hpp"

namespace photomill {

inline constexpr double kMaxMagnitude = 1e15;

// parse_double, and |value| <= kMaxMagnitude.
inline std::optional<double> parse_bounded(std::string_view field) {
  const auto v = parse_double(field);
  if (!v || std::abs(*v) > kMaxMagnitude) return std::nullopt;
  return v;
}

// Why parse_bounded refused `field`: "is not a finite number: 'x'" or "is beyond ±1e15: '1e300'".
inline std::string number_problem(std::string_view field) {
  if (parse_double(field)) return "is beyond ±1e15, not a plausible value: '" + std::string(field) + "'";
  return "is not a finite number: '" + std::string(field) + "'";
}

}  // namespace photomill
