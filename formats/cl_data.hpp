// Cutter-location (CL) data: the tool-tip positions a 3-axis mill moves through, as APT-style CL
// text (PARTNO, UNITS/MM, TLDATA, SPINDL, COOLNT, FEDRAT, RAPID, GOTO/x,y,z[,i,j,k], END, FINI)
// or CSV. CL points are tool tips (centre of a ball end minus R along the tool axis), world mm.
#pragma once

#include <istream>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace photomill {

struct ClMove {
  enum class Kind { Rapid, Feed };
  Kind kind = Kind::Feed;
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();  // tool tip, world mm
  std::optional<Eigen::Vector3d> axis;  // tool axis (i, j, k), unit; absent = +Z (3-axis)
  double feed_mm_per_min = 0;           // feed moves: > 0; rapid moves: 0
  bool operator==(const ClMove&) const = default;
};

struct ClData {
  std::string part_name = "photomill";
  double tool_diameter_mm = 0;       // TLDATA/MILL,diameter,corner_radius
  double tool_corner_radius_mm = 0;  // ball end: diameter / 2
  std::optional<double> spindle_rpm;  // SPINDL/RPM,n,CLW when set
  bool coolant = false;               // COOLNT/ON ... COOLNT/OFF
  std::vector<ClMove> moves;
  bool operator==(const ClData&) const = default;
};

ClData read_cl_apt(std::istream& in, const std::string& source);
void write_cl_apt(std::ostream& out, const ClData& cl);

// CSV: move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min (move is "rapid" or "feed"; i,j,k may be
// empty). Only the moves are stored; tool, spindle and coolant stay at their defaults.
ClData read_cl_csv(std::istream& in, const std::string& source);
void write_cl_csv(std::ostream& out, const ClData& cl);

// APT if the first record is an APT word, CSV if the first line is the CSV header.
ClData read_cl(std::istream& in, const std::string& source);

}  // namespace photomill
