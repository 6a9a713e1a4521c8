// fitsurf's report: a JSON object for --report FILE (keys in docs/fitsurf.md) and the short
// human summary printed on stderr.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "fitsurf/fitsurf.hpp"

namespace photomill::fitsurf {

// A length option that acted in a run on a cloud not in mm, so in the cloud's own unit: fitsurf
// cannot know what its "mm" mean there (cli.hpp's length_options_acting finds them).
struct LengthOption {
  std::string option;          // "--robust-floor-mm"
  std::vector<double> values;  // as given, or the default (--keep-box has 6, --keep-above 4)
  bool is_default = false;     // the default value
  // The length it stands for, in the cloud's unit: the value itself; the 4th root of --smoothing
  // (6th with --smoothing-order 3); the largest side of --keep-box; the distance of --keep-above's
  // plane from the origin.
  double length = 0;
  std::string note;            // that length in words for the warning ("its 4th root 0.316"); empty: the value
};

// length_options: the options that acted in the cloud's unit (empty for a cloud in mm).
void write_report(std::ostream& out, const Result& result, const Options& options, const std::string& source,
                  const std::vector<LengthOption>& length_options = {});

// Two or three lines for stderr (log::info adds the "fitsurf: " prefix).
std::vector<std::string> summary(const Result& result, const Options& options);
// For a cloud whose units are not mm (Result::units): what that means for the surface.
std::string units_warning(const Result& result);
// For those runs: one line naming each length option that acted, its value and its size against
// the cloud's extent (Result::extent), and what to do about it.
std::string length_options_warning(const std::vector<LengthOption>& options, const Result& result);

std::string to_string(KnotPlacement k);
std::string to_string(PlaneChoice p);
std::string to_string(LinearSolver s);
std::string to_string(RobustLoss r);
std::string to_string(OutlineMethod m);

}  // namespace photomill::fitsurf
