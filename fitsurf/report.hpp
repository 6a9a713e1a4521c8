// fitsurf's report: a JSON object for --report FILE (keys in docs/fitsurf.md) and the short
// human summary printed on stderr.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "fitsurf/fitsurf.hpp"

namespace photomill::fitsurf {

void write_report(std::ostream& out, const Result& result, const Options& options, const std::string& source);

// Two or three lines for stderr (log::info adds the "fitsurf: " prefix).
std::vector<std::string> summary(const Result& result, const Options& options);
// For a cloud whose units are not mm (Result::units): what that means for the surface.
std::string units_warning(const Result& result);

std::string to_string(KnotPlacement k);
std::string to_string(PlaneChoice p);
std::string to_string(LinearSolver s);
std::string to_string(RobustLoss r);
std::string to_string(OutlineMethod m);

}  // namespace photomill::fitsurf
