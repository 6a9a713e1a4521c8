#include "toolpath/gcode.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::toolpath {
namespace {

// Comment text safe in both dialects: printable ASCII without parentheses, bounded length.
std::string comment(std::string text) {
  for (char& c : text) {
    if (c < 0x20 || c > 0x7e || c == '(' || c == ')' || c == ';') c = ' ';
  }
  constexpr std::size_t kMax = 70;
  if (text.size() > kMax) text.resize(kMax);
  return "(" + text + ")\n";
}

}  // namespace

std::string gcode_number(double value, int decimals) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed, decimals);
  // A value too long for the buffer (|value| > ~1e57) leaves buf unspecified: never write it. The
  // readers refuse magnitudes beyond 1e15 (formats/magnitude.hpp), so this is a caller's bug.
  if (r.ec != std::errc()) throw std::out_of_range("G-code number out of range: " + std::to_string(value));
  std::string s(buf, r.ptr);
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

void write_gcode(std::ostream& out, const ClData& cl, const GcodeOptions& o, const std::string& source) {
  if (o.decimals < 0 || o.decimals > 6) throw UsageError("--decimals must be 0..6");
  if (cl.moves.empty()) throw InputError(source, 0, "the CL data has no moves");
  double top = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < cl.moves.size(); ++k) {
    const ClMove& m = cl.moves[k];
    if (m.axis && (std::abs((*m.axis).x()) > 1e-9 || std::abs((*m.axis).y()) > 1e-9 || (*m.axis).z() <= 0)) {
      throw InputError(source, 0,
                       "move " + std::to_string(k + 1) + " has tool axis (" + gcode_number((*m.axis).x(), 6) + ", " +
                           gcode_number((*m.axis).y(), 6) + ", " + gcode_number((*m.axis).z(), 6) +
                           "): only +Z can be posted for a 3-axis mill");
    }
    if (m.kind == ClMove::Kind::Feed && !(m.feed_mm_per_min > 0)) {
      throw InputError(source, 0, "feed move " + std::to_string(k + 1) + " has no feed rate");
    }
    top = std::max(top, m.tip_mm.z());
  }
  if (o.safe_z_mm && !std::isfinite(*o.safe_z_mm)) throw UsageError("--safe-z-mm must be a finite number");
  if (o.spindle_rpm && !(std::isfinite(*o.spindle_rpm) && *o.spindle_rpm > 0)) {
    throw UsageError("--spindle-rpm must be a positive number (--no-spindle writes no S, M3 or M5)");
  }
  const double safe = o.safe_z_mm.value_or(top);
  if (safe < top) {
    throw UsageError("--safe-z-mm " + gcode_number(safe, o.decimals) + " is below the highest point of the CL data (" +
                     gcode_number(top, o.decimals) + ")");
  }
  // Spindle speed to write, 0 = none.
  double rpm = 0;
  if (o.spindle) rpm = o.spindle_rpm.value_or(cl.spindle_rpm.value_or(0.0));
  // A program that feeds into the part with the spindle standing breaks the tool: say so.
  const bool feeds = std::any_of(cl.moves.begin(), cl.moves.end(), [](const ClMove& m) { return m.kind == ClMove::Kind::Feed; });
  if (o.spindle && !(rpm > 0) && feeds) {
    log::warn(source + ": no spindle speed (no SPINDL in the CL data, no --spindle-rpm): the program starts no spindle "
              "before its feed moves; give --spindle-rpm RPM, or --no-spindle if the spindle is started by hand");
  }
  const bool coolant = o.coolant == CoolantMode::On || (o.coolant == CoolantMode::Auto && cl.coolant);
  const int d = o.decimals;

  std::string t;
  if (o.percent) t += "%\n";
  t += comment("photomill clpost: " + cl.part_name);
  if (cl.tool_diameter_mm > 0) {
    t += comment("tool D" + gcode_number(cl.tool_diameter_mm, 3) + " R" + gcode_number(cl.tool_corner_radius_mm, 3) +
                 " mm, Z = tool tip");
  }
  t += "G21 G90 G94 G17\n";
  Eigen::Vector3d pos = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  bool pos_known = false;
  double feed = -1;
  // One motion line; only the axes that change are written (all three on the first move).
  const auto move = [&](bool rapid, const Eigen::Vector3d& p, double f) {
    std::string line = rapid ? "G0" : "G1";
    const char axes[3] = {'X', 'Y', 'Z'};
    bool any = false;
    for (int c = 0; c < 3; ++c) {
      const std::string v = gcode_number(p[c], d);
      if (!pos_known || v != gcode_number(pos[c], d)) {
        line += ' ';
        line += axes[c];
        line += v;
        any = true;
      }
    }
    if (!rapid && f != feed) {
      line += " F" + gcode_number(f, 1);
      feed = f;
    }
    pos = p;
    pos_known = true;
    if (any) t += line + "\n";
  };
  // First move: straight up to the safe plane where the machine stands (no horizontal move yet).
  t += "G0 Z" + gcode_number(safe, d) + "\n";
  if (rpm > 0) t += "S" + gcode_number(rpm, 1) + " M3\n";
  if (coolant) t += "M8\n";
  double cur_z = safe;
  bool xy_known = false;
  Eigen::Vector2d cur_xy = Eigen::Vector2d::Zero();
  for (const ClMove& m : cl.moves) {
    const Eigen::Vector3d& p = m.tip_mm;
    if (m.kind == ClMove::Kind::Rapid) {
      const bool horizontal = !xy_known || (p.head<2>() - cur_xy).norm() > 0;
      if (!xy_known) {
        // From the safe plane: across at safe Z, then down.
        move(true, {p.x(), p.y(), safe}, 0);
        if (p.z() != safe) move(true, p, 0);
      } else if (horizontal && p.z() < cur_z) {
        move(true, {p.x(), p.y(), cur_z}, 0);
        move(true, p, 0);
      } else if (horizontal && p.z() > cur_z) {
        move(true, {cur_xy.x(), cur_xy.y(), p.z()}, 0);
        move(true, p, 0);
      } else {
        move(true, p, 0);
      }
    } else {
      if (!xy_known) move(true, {p.x(), p.y(), safe}, 0);  // never feed in from an unknown place
      move(false, p, m.feed_mm_per_min);
    }
    cur_xy = p.head<2>();
    cur_z = p.z();
    xy_known = true;
    if (t.size() > (1 << 16)) {
      out << t;
      t.clear();
    }
  }
  if (cur_z < safe) move(true, {cur_xy.x(), cur_xy.y(), safe}, 0);
  if (coolant) t += "M9\n";
  if (rpm > 0) t += "M5\n";
  t += o.end == ProgramEnd::M30 ? "M30\n" : "M2\n";
  if (o.percent) t += "%\n";
  out << t;
}

}  // namespace photomill::toolpath
