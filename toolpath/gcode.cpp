#include "toolpath/gcode.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::toolpath {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

bool has_tool_change(Dialect d) { return d == Dialect::LinuxCnc || d == Dialect::Fanuc || d == Dialect::Mach3; }

// Comment text safe in every dialect: printable ASCII without parentheses, bounded length. Fanuc
// comments in upper case and without the characters its ISO table may not carry.
std::string comment(std::string text, Dialect d) {
  for (char& c : text) {
    if (c < 0x20 || c > 0x7e || c == '(' || c == ')' || c == ';') c = ' ';
    if (d == Dialect::Fanuc) {
      if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
      const bool plain = (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || std::string_view(" .,:=+-/*").find(c) != std::string_view::npos;
      if (!plain) c = ' ';
    }
  }
  constexpr std::size_t kMax = 70;
  if (text.size() > kMax) text.resize(kMax);
  return "(" + text + ")\n";
}

// The dialect's spelling of numbers and M words.
struct Words {
  Dialect dialect;
  int decimals;
  // Fanuc reads a coordinate without a decimal point as a count of least input increments
  // (X10 = 0.010 mm with IS-B) unless a parameter says otherwise: every coordinate and feed there
  // carries its point ("X10.").
  std::string point(std::string s) const {
    if (dialect == Dialect::Fanuc && s.find('.') == std::string::npos) s += '.';
    return s;
  }
  std::string coord(double v) const { return point(gcode_number(v, decimals)); }
  std::string feed(double f) const { return point(gcode_number(f, 1)); }
  // Spindle speed: Fanuc's S is an integer.
  std::string rpm(double s) const { return dialect == Dialect::Fanuc ? gcode_number(std::round(s), 0) : gcode_number(s, 1); }
  std::string m(int code) const {
    std::string s = dialect == Dialect::Fanuc && code < 10 ? "M0" : "M";
    s += std::to_string(code);
    return s;
  }
  double rounded(double v) const { return std::round(v * std::pow(10.0, decimals)) / std::pow(10.0, decimals); }
};

// Circumcentre of three points in the XY plane: with a = p1 - p0, b = p2 - p0 and
// D = 2 (a.x b.y - a.y b.x), centre = p0 + ((b.y |a|^2 - a.y |b|^2) / D, (a.x |b|^2 - b.x |a|^2) / D).
// None when the points are (nearly) collinear.
std::optional<Vector2d> circumcentre(const Vector2d& p0, const Vector2d& p1, const Vector2d& p2) {
  const Vector2d a = p1 - p0, b = p2 - p0;
  const double D = 2 * (a.x() * b.y() - a.y() * b.x());
  if (std::abs(D) <= 1e-12 * a.norm() * b.norm()) return std::nullopt;
  return p0 + Vector2d(b.y() * a.squaredNorm() - a.y() * b.squaredNorm(), a.x() * b.squaredNorm() - b.x() * a.squaredNorm()) / D;
}

struct Arc {
  Vector2d centre;
  double sweep_rad;  // signed: > 0 counter-clockwise (G3)
};

// Whether the polyline pts[0..m] (same Z) can be replaced by one arc within `tol`. The circle
// goes through pts[0], pts[m/2] and pts[m]. Every point must lie within tol of it (radial error
// e_k = | |p_k - c| - r |) and the arc between two consecutive points within tol of their chord:
// that distance is at most max(e_k, e_k+1) + s_k, s_k = r - sqrt(r^2 - (l_k / 2)^2) the sagitta of
// a chord of length l_k = |p_k+1 - p_k| + e_k + e_k+1 (the chord between the points moved onto the
// circle). The points must go round the centre in one direction, at most max_sweep in all; a run
// straight within tol (whole-arc sagitta r (1 - cos(sweep / 2)) <= tol) is left to G1 lines.
std::optional<Arc> try_arc(const std::vector<Vector3d>& pts, double tol, double max_sweep) {
  const std::size_t m = pts.size() - 1;
  for (const Vector3d& p : pts) {
    if (std::abs(p.z() - pts[0].z()) > 1e-9) return std::nullopt;
  }
  const auto c = circumcentre(pts[0].head<2>(), pts[m / 2].head<2>(), pts[m].head<2>());
  if (!c) return std::nullopt;
  const double r = (pts[0].head<2>() - *c).norm();
  double sweep = 0;
  for (std::size_t k = 0; k < m; ++k) {
    const Vector2d u = pts[k].head<2>() - *c, v = pts[k + 1].head<2>() - *c;
    const double e0 = std::abs(u.norm() - r), e1 = std::abs(v.norm() - r);
    if (e0 > tol || e1 > tol) return std::nullopt;
    const double angle = std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));
    if (angle == 0 || (sweep != 0 && (angle > 0) != (sweep > 0))) return std::nullopt;
    const double half = ((v - u).norm() + e0 + e1) / 2;
    if (half >= r) return std::nullopt;
    if (std::max(e0, e1) + r - std::sqrt(r * r - half * half) > tol) return std::nullopt;
    sweep += angle;
  }
  if (std::abs(sweep) > max_sweep) return std::nullopt;
  return Arc{*c, sweep};
}

double arc_length(const Vector3d& from, const Motion& m) {
  if (m.kind == Motion::Kind::Rapid || m.kind == Motion::Kind::Line) return (m.end_mm - from).norm();
  const Vector2d u = from.head<2>() - m.centre_mm, v = m.end_mm.head<2>() - m.centre_mm;
  double a = std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));  // (-pi, pi]: fitted arcs sweep <= 180 deg
  return std::abs(a) * u.norm();
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

std::vector<Motion> fit_arcs(const Vector3d& start, const std::vector<Motion>& motions, double tol_mm, double max_sweep_deg) {
  const double max_sweep = max_sweep_deg * std::numbers::pi / 180;
  std::vector<Motion> out;
  out.reserve(motions.size());
  Vector3d prev = start;
  std::size_t i = 0;
  while (i < motions.size()) {
    const Motion& first = motions[i];
    if (first.kind != Motion::Kind::Line) {
      out.push_back(first);
      prev = first.end_mm;
      ++i;
      continue;
    }
    // Greedy: the longest run from `prev` that still fits; at least three lines.
    std::vector<Vector3d> pts{prev, first.end_mm};
    std::optional<Arc> best;
    std::size_t best_j = i;
    for (std::size_t j = i + 1; j < motions.size(); ++j) {
      if (motions[j].kind != Motion::Kind::Line || motions[j].feed_mm_per_min != first.feed_mm_per_min) break;
      pts.push_back(motions[j].end_mm);
      if (j - i + 1 < 3) continue;
      const auto arc = try_arc(pts, tol_mm, max_sweep);
      if (!arc) break;
      // A run straight within tol so far (whole-arc sagitta r (1 - cos(sweep / 2)) <= tol) is
      // left to G1 lines unless it bends further on: its centre may lie anywhere far away.
      const double r = (pts[0].head<2>() - arc->centre).norm();
      if (r * (1 - std::cos(std::abs(arc->sweep_rad) / 2)) <= tol_mm) continue;
      best = arc;
      best_j = j;
    }
    if (best) {
      Motion a;
      a.kind = best->sweep_rad > 0 ? Motion::Kind::ArcCcw : Motion::Kind::ArcCw;
      a.end_mm = motions[best_j].end_mm;
      a.centre_mm = best->centre;
      a.feed_mm_per_min = first.feed_mm_per_min;
      out.push_back(a);
      prev = a.end_mm;
      i = best_j + 1;
    } else {
      out.push_back(first);
      prev = first.end_mm;
      ++i;
    }
  }
  return out;
}

PostStats write_gcode(std::ostream& out, const ClData& cl, const GcodeOptions& o, const std::string& source) {
  return write_gcode(out, std::vector<ClInput>{{cl, source}}, o);
}

PostStats write_gcode(std::ostream& out, const std::vector<ClInput>& inputs, const GcodeOptions& o) {
  const Dialect dialect = o.dialect;
  const bool fanuc = dialect == Dialect::Fanuc;
  const int d = o.decimals.value_or(fanuc ? 3 : 4);
  if (d < 0 || d > 6) throw UsageError("--decimals must be 0..6");
  if (inputs.empty()) throw UsageError("no CL input");
  if (o.work_offset && (*o.work_offset < 54 || *o.work_offset > 59)) throw UsageError("--work-offset must be G54..G59");
  if (o.program_number < 1 || o.program_number > 7999) {
    throw UsageError("--program-number must be 1..7999 (Fanuc keeps 8000-9999 for protected programs and macros)");
  }
  if (!o.tool_numbers.empty() && o.tool_numbers.size() != inputs.size()) {
    throw UsageError("--tool-numbers gives " + std::to_string(o.tool_numbers.size()) + " numbers for " +
                     std::to_string(inputs.size()) + " CL inputs: give one per input");
  }
  for (int t : o.tool_numbers) {
    if (t < 1 || t > 9999) throw UsageError("--tool-numbers: tool numbers must be 1..9999, got " + std::to_string(t));
  }
  if (!(std::isfinite(o.rapid_mm_per_min) && o.rapid_mm_per_min > 0)) throw UsageError("--rapid-mm-per-min must be a positive number");
  if (!(std::isfinite(o.tool_change_s) && o.tool_change_s >= 0)) throw UsageError("--tool-change-s must be a number >= 0");
  if (o.arc_tol_mm && !(std::isfinite(*o.arc_tol_mm) && *o.arc_tol_mm > 0)) throw UsageError("--arc-tol-mm must be a positive number");
  if (!(o.max_arc_deg > 0 && o.max_arc_deg <= 180)) throw UsageError("the largest arc sweep must be in (0, 180] degrees");
  if (o.blend_tol_mm) {
    if (dialect != Dialect::LinuxCnc) throw UsageError("--blend-tol-mm is LinuxCNC's G64 P: it needs --dialect linuxcnc");
    if (!(std::isfinite(*o.blend_tol_mm) && *o.blend_tol_mm > 0)) throw UsageError("--blend-tol-mm must be a positive number");
  }
  if (o.percent && dialect == Dialect::Grbl) throw UsageError("--percent: grbl 1.1 does not accept '%' lines");
  if (o.stock) {
    for (int c = 0; c < 3; ++c) {
      if (!(std::isfinite(o.stock->min_mm[c]) && std::isfinite(o.stock->max_mm[c]) && o.stock->min_mm[c] < o.stock->max_mm[c])) {
        throw UsageError("--stock-box-mm: each minimum must be below its maximum (XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX)");
      }
    }
  }
  if (o.origin != Origin::Plate && !o.stock) {
    throw UsageError(std::string("--origin ") + (o.origin == Origin::TopCorner ? "top-corner" : "top-centre") +
                     " needs --stock-box-mm XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (the stock in the CL data's frame)");
  }

  double top = -std::numeric_limits<double>::infinity();
  for (const ClInput& in : inputs) {
    const ClData& cl = in.cl;
    if (cl.moves.empty()) throw InputError(in.source, 0, "the CL data has no moves");
    for (std::size_t k = 0; k < cl.moves.size(); ++k) {
      const ClMove& m = cl.moves[k];
      if (m.axis && (std::abs((*m.axis).x()) > 1e-9 || std::abs((*m.axis).y()) > 1e-9 || (*m.axis).z() <= 0)) {
        throw InputError(in.source, 0,
                         "move " + std::to_string(k + 1) + " has tool axis (" + gcode_number((*m.axis).x(), 6) + ", " +
                             gcode_number((*m.axis).y(), 6) + ", " + gcode_number((*m.axis).z(), 6) +
                             "): only +Z can be posted for a 3-axis mill");
      }
      if (m.kind == ClMove::Kind::Feed && !(m.feed_mm_per_min > 0)) {
        throw InputError(in.source, 0, "feed move " + std::to_string(k + 1) + " has no feed rate");
      }
      top = std::max(top, m.tip_mm.z());
    }
  }
  if (o.safe_z_mm && !std::isfinite(*o.safe_z_mm)) throw UsageError("--safe-z-mm must be a finite number");
  if (o.spindle_rpm && !(std::isfinite(*o.spindle_rpm) && *o.spindle_rpm > 0)) {
    throw UsageError("--spindle-rpm must be a positive number (--no-spindle writes no S, M3 or M5)");
  }
  const double safe_cl = o.safe_z_mm.value_or(top);
  if (safe_cl < top) {
    throw UsageError("--safe-z-mm " + gcode_number(safe_cl, d) + " is below the highest point of the CL data (" +
                     gcode_number(top, d) + ")");
  }
  // The program's origin in the CL data's frame: program = CL - offset.
  Vector3d offset = Vector3d::Zero();
  if (o.origin == Origin::TopCorner) offset = {o.stock->min_mm.x(), o.stock->min_mm.y(), o.stock->max_mm.z()};
  if (o.origin == Origin::TopCentre) {
    offset = {(o.stock->min_mm.x() + o.stock->max_mm.x()) / 2, (o.stock->min_mm.y() + o.stock->max_mm.y()) / 2, o.stock->max_mm.z()};
  }
  const double safe = safe_cl - offset.z();
  const Words w{dialect, d};

  // Per input: tool number, spindle speed (0 = none), coolant; warnings for what looks wrong.
  struct Section {
    int tool;
    double rpm;
    bool coolant;
  };
  std::vector<Section> sections;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const ClData& cl = inputs[i].cl;
    const std::string& source = inputs[i].source;
    Section s{o.tool_numbers.empty() ? static_cast<int>(i + 1) : o.tool_numbers[i], 0, false};
    if (o.spindle) s.rpm = o.spindle_rpm.value_or(cl.spindle_rpm.value_or(0.0));
    s.coolant = o.coolant == CoolantMode::On || (o.coolant == CoolantMode::Auto && cl.coolant);
    // A program that feeds into the part with the spindle standing breaks the tool: say so.
    const bool feeds = std::any_of(cl.moves.begin(), cl.moves.end(), [](const ClMove& m) { return m.kind == ClMove::Kind::Feed; });
    if (o.spindle && !(s.rpm > 0) && feeds) {
      log::warn(source + ": no spindle speed (no SPINDL in the CL data, no --spindle-rpm): the program starts no spindle "
                "before its feed moves; give --spindle-rpm RPM, or --no-spindle if the spindle is started by hand");
    }
    if (o.stock) {
      // A feed move beyond the stock's sides by more than the tool radius, or below its bottom,
      // cuts air or the fixture: most likely a stock box in another frame than the CL data.
      const double r = cl.tool_diameter_mm / 2;
      for (std::size_t k = 0; k < cl.moves.size(); ++k) {
        const Vector3d& p = cl.moves[k].tip_mm;
        if (cl.moves[k].kind != ClMove::Kind::Feed) continue;
        const bool outside = p.x() < o.stock->min_mm.x() - r - 1e-9 || p.x() > o.stock->max_mm.x() + r + 1e-9 ||
                             p.y() < o.stock->min_mm.y() - r - 1e-9 || p.y() > o.stock->max_mm.y() + r + 1e-9;
        if (outside || p.z() < o.stock->min_mm.z() - 1e-9) {
          log::warn(source + ": feed move " + std::to_string(k + 1) + " at (" + gcode_number(p.x(), 3) + ", " +
                    gcode_number(p.y(), 3) + ", " + gcode_number(p.z(), 3) + ") is " +
                    (outside ? "beyond the sides of --stock-box-mm by more than the tool radius" : "below the bottom of --stock-box-mm") +
                    ": is the stock box in the CL data's frame?");
          break;
        }
      }
    }
    sections.push_back(s);
  }
  if (o.stock && safe_cl <= o.stock->max_mm.z()) {
    log::warn("the rapid plane (Z " + gcode_number(safe_cl, d) + " in the CL data's frame) is not above the top of "
              "--stock-box-mm (" + gcode_number(o.stock->max_mm.z(), d) + "): rapids may hit the stock; give --safe-z-mm");
  }

  PostStats st;
  std::string t;  // the body, after the header (which carries the estimate of the whole body)
  Vector3d pos = Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  bool pos_known = false;
  std::optional<Vector3d> length_from;  // last position known for the path lengths
  double feed = -1;
  const auto count = [&](const Motion& m) {
    if (length_from) {
      const double l = arc_length(*length_from, m);
      if (m.kind == Motion::Kind::Rapid) {
        st.rapid_mm += l;
      } else {
        st.feed_mm += l;
        st.time_s += l / m.feed_mm_per_min * 60;
      }
    }
    length_from = m.end_mm;
  };
  // One motion line; only the axes that change are written (all three on the first move).
  const auto emit = [&](const Motion& m) {
    const bool arc = m.kind == Motion::Kind::ArcCw || m.kind == Motion::Kind::ArcCcw;
    std::string line = m.kind == Motion::Kind::Rapid ? "G0" : m.kind == Motion::Kind::Line ? "G1" : m.kind == Motion::Kind::ArcCw ? "G2" : "G3";
    const char axes[3] = {'X', 'Y', 'Z'};
    bool any = false;
    for (int c = 0; c < 3; ++c) {
      const std::string v = w.coord(m.end_mm[c]);
      if (!pos_known || v != w.coord(pos[c]) || (arc && c < 2)) {
        line += ' ';
        line += axes[c];
        line += v;
        any = true;
      }
    }
    if (arc) {
      // I J: the centre relative to the start as the controller holds it (the written, rounded one).
      line += " I" + w.coord(m.centre_mm.x() - w.rounded(pos.x())) + " J" + w.coord(m.centre_mm.y() - w.rounded(pos.y()));
      ++st.arcs;
    }
    // A move shorter than the program's resolution writes no line, and so no F: the feed it
    // would have set is set by the next line that is written.
    if (any && m.kind != Motion::Kind::Rapid && m.feed_mm_per_min != feed) {
      line += " F" + w.feed(m.feed_mm_per_min);
      feed = m.feed_mm_per_min;
    }
    count(m);
    pos = m.end_mm;
    pos_known = true;
    if (any) t += line + "\n";
  };
  const auto rapid = [](const Vector3d& p) { return Motion{Motion::Kind::Rapid, p, Vector2d::Zero(), 0}; };

  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const ClData& cl = inputs[i].cl;
    const Section& s = sections[i];
    if (i > 0) {
      const Section& prev = sections[i - 1];
      if (prev.coolant) t += w.m(9) + "\n";
      if (prev.rpm > 0) t += w.m(5) + "\n";
    }
    // Tool change, then straight up (or down) to the safe plane where the machine stands.
    if (has_tool_change(dialect)) {
      t += std::string("T") + std::to_string(s.tool) + " " + w.m(6) + "\n";
      t += "G0 G43 H" + std::to_string(s.tool) + " Z" + w.coord(safe) + "\n";
      ++st.tool_changes;
    } else {
      if (i > 0) {
        t += comment("tool " + std::to_string(s.tool) + ": D" + gcode_number(cl.tool_diameter_mm, 3) + " R" +
                         gcode_number(cl.tool_corner_radius_mm, 3) + " mm - change it, touch off Z, resume",
                     dialect);
        t += w.m(0) + "\n";
        ++st.tool_changes;
      }
      t += "G0 Z" + w.coord(safe) + "\n";
    }
    pos_known = false;
    if (length_from) length_from->z() = safe;
    if (s.rpm > 0) t += std::string("S") + w.rpm(s.rpm) + " " + w.m(3) + "\n";
    if (s.coolant) t += w.m(8) + "\n";

    // The motions: rapids split so that none descends across; feeds as lines.
    std::vector<Motion> motions;
    double cur_z = safe;
    bool xy_known = false;
    Vector2d cur_xy = Vector2d::Zero();
    for (const ClMove& m : cl.moves) {
      const Vector3d p = m.tip_mm - offset;
      if (m.kind == ClMove::Kind::Rapid) {
        const bool horizontal = !xy_known || (p.head<2>() - cur_xy).norm() > 0;
        if (!xy_known) {
          // From the safe plane: across at safe Z, then down.
          motions.push_back(rapid({p.x(), p.y(), safe}));
          if (p.z() != safe) motions.push_back(rapid(p));
        } else if (horizontal && p.z() < cur_z) {
          motions.push_back(rapid({p.x(), p.y(), cur_z}));
          motions.push_back(rapid(p));
        } else if (horizontal && p.z() > cur_z) {
          motions.push_back(rapid({cur_xy.x(), cur_xy.y(), p.z()}));
          motions.push_back(rapid(p));
        } else {
          motions.push_back(rapid(p));
        }
      } else {
        if (!xy_known) motions.push_back(rapid({p.x(), p.y(), safe}));  // never feed in from an unknown place
        motions.push_back({Motion::Kind::Line, p, Vector2d::Zero(), m.feed_mm_per_min});
      }
      cur_xy = p.head<2>();
      cur_z = p.z();
      xy_known = true;
    }
    if (cur_z < safe) motions.push_back(rapid({cur_xy.x(), cur_xy.y(), safe}));
    if (o.arc_tol_mm) motions = fit_arcs(motions.front().end_mm, motions, *o.arc_tol_mm, o.max_arc_deg);
    for (const Motion& m : motions) emit(m);
  }
  if (sections.back().coolant) t += w.m(9) + "\n";
  if (sections.back().rpm > 0) t += w.m(5) + "\n";
  t += w.m(o.end == ProgramEnd::M30 ? 30 : 2) + "\n";
  if (o.percent || fanuc) t += "%\n";
  st.time_s += st.rapid_mm / o.rapid_mm_per_min * 60 + static_cast<double>(st.tool_changes) * o.tool_change_s;

  // The header: part, tools, estimate, where the work zero is, the modes.
  std::string h;
  if (o.percent || fanuc) h += "%\n";
  if (fanuc) h += "O" + std::to_string(o.program_number) + "\n";
  h += comment("photomill clpost: " + inputs.front().cl.part_name, dialect);
  if (dialect == Dialect::Generic && inputs.size() == 1) {
    const ClData& cl = inputs.front().cl;
    if (cl.tool_diameter_mm > 0) {
      h += comment("tool D" + gcode_number(cl.tool_diameter_mm, 3) + " R" + gcode_number(cl.tool_corner_radius_mm, 3) +
                       " mm, Z = tool tip",
                   dialect);
    }
  } else {
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      const ClData& cl = inputs[i].cl;
      h += comment(std::string("T") + std::to_string(sections[i].tool) + " D" + gcode_number(cl.tool_diameter_mm, 3) + " R" +
                       gcode_number(cl.tool_corner_radius_mm, 3) + " mm, Z = tool tip: " + inputs[i].source,
                   dialect);
    }
  }
  if (dialect != Dialect::Generic) {
    h += comment("estimated cycle time " + gcode_number(st.time_s / 60, 1) + " min, " + std::to_string(st.tool_changes) +
                     " tool changes, no acceleration",
                 dialect);
    h += comment("feed " + gcode_number(st.feed_mm, 0) + " mm, rapid " + gcode_number(st.rapid_mm, 0) + " mm at " +
                     gcode_number(o.rapid_mm_per_min, 0) + " mm/min, " + gcode_number(o.tool_change_s, 1) + " s a change",
                 dialect);
  }
  const int offset_word = o.work_offset.value_or(fanuc ? 54 : 0);  // 0: none written
  if (dialect != Dialect::Generic || o.origin != Origin::Plate || o.work_offset) {
    const std::string set = offset_word != 0 ? "set G" + std::to_string(offset_word) : "set the work zero";
    if (o.origin == Origin::Plate) {
      h += comment(set + ": X0 Y0 Z0 = the origin of the CL data, the plate", dialect);
    } else {
      h += comment(set + (o.origin == Origin::TopCorner ? ": X0 Y0 = stock corner at min X, min Y" : ": X0 Y0 = centre of the stock top"),
                   dialect);
      h += comment(set + ": Z0 = top of the stock, Z " + gcode_number(o.stock->max_mm.z(), 3) + " of the CL data", dialect);
    }
  }
  if (has_tool_change(dialect) || (dialect == Dialect::Grbl && inputs.size() > 1)) {
    h += comment(has_tool_change(dialect) ? "tool length offsets H = T from the tool table"
                                          : "no tool changer: M0 pauses for each change, touch off Z again",
                 dialect);
  }
  if (fanuc) {
    h += "G21\nG17 G40 G49 G80 G90 G94\n";
  } else if (dialect == Dialect::LinuxCnc || dialect == Dialect::Mach3) {
    h += "G21 G90 G94 G17 G40 G49 G80\n";
  } else {
    h += "G21 G90 G94 G17\n";
  }
  if (offset_word != 0) h += "G" + std::to_string(offset_word) + "\n";
  if (dialect == Dialect::LinuxCnc) h += "G64 P" + gcode_number(o.blend_tol_mm.value_or(0.005), 4) + "\n";
  if (dialect == Dialect::Mach3) h += "G64\n";
  out << h << t;
  st.lines = static_cast<std::size_t>(std::count(h.begin(), h.end(), '\n') + std::count(t.begin(), t.end(), '\n'));
  return st;
}

}  // namespace photomill::toolpath
