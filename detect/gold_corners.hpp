// The gold marker corners of OpenCV's ArUco tests for its tutorial photos
// (../shared/data/opencv-aruco/gold_corners.txt: image marker_id x0 y0 .. x3 y3, TL TR BR BL).
// Test helper shared by markers_test.cpp and board_lines_test.cpp.
#pragma once

#include <array>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <Eigen/Core>

namespace photomill::detect {

inline std::map<int, std::array<Eigen::Vector2d, 4>> read_gold_corners(const std::string& path, const std::string& image) {
  std::map<int, std::array<Eigen::Vector2d, 4>> g;
  std::ifstream f(path);
  for (std::string line; std::getline(f, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    std::string name;
    int id = 0;
    s >> name >> id;
    if (name != image) continue;
    for (auto& p : g[id]) s >> p.x() >> p.y();
  }
  return g;
}

}  // namespace photomill::detect
