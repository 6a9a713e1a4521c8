// Photos and their cameras by image name prefix, for the stages that take several cameras
// (match, triangulate: --camera-for PREFIX=FILE, --rig). The matching rule is match_rig_prefix's
// (formats/camera.hpp).
#pragma once

#include <set>
#include <string>
#include <utility>
#include <vector>

#include "formats/camera.hpp"
#include "formats/error.hpp"

namespace photomill {

// match_rig_prefix, or InputError(source, 0, "image 'X' starts with none of the cameras' prefixes
// ('a', 'b'): give its camera").
inline RigMatch require_rig_prefix(const std::vector<std::string>& prefixes, const std::string& image,
                                   const std::string& source) {
  if (auto m = match_rig_prefix(prefixes, image)) return *m;
  std::string list;
  for (const auto& p : prefixes) list += (list.empty() ? "'" : ", '") + p + "'";
  throw InputError(source, 0, "image '" + image + "' starts with none of the cameras' prefixes (" + list +
                                  "): give its camera");
}

// The values of --camera-for (PREFIX=FILE; or of `option`, e.g. --refined-camera-for) as (prefix,
// file); UsageError for a value without both parts or a prefix given twice.
inline std::vector<std::pair<std::string, std::string>> parse_camera_for(const std::vector<std::string>& values,
                                                                          const std::string& option = "--camera-for") {
  std::vector<std::pair<std::string, std::string>> out;
  std::set<std::string> seen;
  for (const std::string& v : values) {
    const auto eq = v.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == v.size()) {
      throw UsageError(option + " '" + v + "': expected PREFIX=FILE (e.g. left=left.yaml)");
    }
    out.emplace_back(v.substr(0, eq), v.substr(eq + 1));
    if (!seen.insert(out.back().first).second) throw UsageError(option + ": prefix '" + out.back().first + "' given twice");
  }
  return out;
}

}  // namespace photomill
