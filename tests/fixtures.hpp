// Small valid inputs shared by the tests that run the binaries on files of every kind
// (errors_test: docs/errors.md's fixtures; io_faults_test: the I/O fault runs).
#pragma once

#include <cmath>
#include <sstream>
#include <string>

namespace photomill::test {

// A smooth height field on a 21 x 21 grid, 5 mm apart: fitsurf's input.
inline std::string cloud_xyz() {
  std::ostringstream s;
  s.precision(17);
  for (int i = 0; i <= 20; ++i) {
    for (int j = 0; j <= 20; ++j) {
      const double x = 5.0 * i, y = 5.0 * j;
      s << x << " " << y << " " << 2 * std::sin(x / 30) + std::cos(y / 25) << "\n";
    }
  }
  return s.str();
}

// The example surface of docs/formats.md.
inline std::string surface() {
  std::string s = "photomill-surface v1\ndegrees 3 3\npoles 4 4\nrational 0\nknots_u 0 0 0 0 1 1 1 1\n"
                  "knots_v 0 0 0 0 1 1 1 1\n";
  const double x[4] = {-75, -25, 25, 75}, y[4] = {-50, -16.666666666666668, 16.666666666666668, 50};
  const double z[4][4] = {{0, 10, 10, 0}, {10, 30, 30, 10}, {10, 30, 30, 10}, {0, 10, 10, 0}};
  std::ostringstream p;
  p.precision(17);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) p << "pole " << i << " " << j << " " << x[i] << " " << y[j] << " " << z[i][j] << "\n";
  }
  return s + p.str() + "boundary 4\nuv 0.05 0.05\nuv 0.95 0.05\nuv 0.95 0.95\nuv 0.05 0.95\nend\n";
}

inline std::string cl_apt() {
  return "$$ photomill CL data v1: tool tip positions, mm\nPARTNO/handle\nUNITS/MM\nTLDATA/MILL,6,3\n"
         "SPINDL/RPM,12000,CLW\nRAPID\nGOTO/-75.5,-50,40\nRAPID\nGOTO/-75.5,-50,12.25\nFEDRAT/MMPM,1200\n"
         "GOTO/-74.25,-50,12.3125\nGOTO/-73,-50,12.375,0,0,1\nSPINDL/OFF\nEND\nFINI\n";
}

inline std::string cl_csv() {
  return "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\nrapid,-75.5,-50,40,,,,\nfeed,-75.5,-50,12.25,,,,1200\n"
         "feed,-74.25,-50,12.3125,0,0,1,1200\n";
}

}  // namespace photomill::test
