// densify's tests: the bundled demo's files (its photos, true camera and poses).
#pragma once

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace photomill::densify::test {

inline const std::filesystem::path kDemo = std::filesystem::path(PHOTOMILL_SOURCE_DIR) / "data" / "demo";

// Writes to `file` the demo's poses.csv with only the rows of `photos` (header kept), each row's
// fields passed through `edit` first.
inline void write_demo_poses(const std::filesystem::path& file, const std::vector<std::string>& photos,
                             const std::function<void(std::vector<std::string>&)>& edit = {}) {
  std::ifstream in(kDemo / "poses.csv");
  std::ofstream out(file);
  std::string line;
  std::getline(in, line);
  out << line << "\n";
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    if (std::find(photos.begin(), photos.end(), f[0]) == photos.end()) continue;
    if (edit) edit(f);
    for (std::size_t k = 0; k < f.size(); ++k) out << (k ? "," : "") << f[k];
    out << "\n";
  }
}

}  // namespace photomill::densify::test
