#include "formats/cl_data.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "formats/csv.hpp"
#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"
#include "formats/magnitude.hpp"

namespace photomill {
namespace {

void check_move(const ClMove& m) {
  if (!m.tip_mm.allFinite()) throw std::invalid_argument("CL move with a non-finite position");
  if (m.axis && (!m.axis->allFinite() || std::abs(m.axis->norm() - 1.0) > 1e-6)) {
    throw std::invalid_argument("CL move with a tool axis that is not a unit vector");
  }
  if (m.kind == ClMove::Kind::Feed && !(m.feed_mm_per_min > 0 && std::isfinite(m.feed_mm_per_min))) {
    throw std::invalid_argument("CL feed move without a positive feed rate");
  }
}

std::string upper(std::string_view s) {
  std::string u(s);
  std::transform(u.begin(), u.end(), u.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return u;
}

constexpr double kAxisNormTolerance = 1e-6;

// A number in fixed notation (no exponent: many APT post-processors read none), the shortest
// digits that read back to the same double (std::to_chars, chars_format::fixed). 512 characters
// hold any double in fixed form (the largest has 309 digits, the smallest subnormal 327 places).
void append_fixed(std::string& out, double value) {
  char buf[512];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value, std::chars_format::fixed);
  if (ec != std::errc()) throw std::invalid_argument("CL number that cannot be written");
  out.append(buf, ptr);
}

std::string fixed(double value) {
  std::string s;
  append_fixed(s, value);
  return s;
}

}  // namespace

// APT CL text, one record per line: WORD or WORD/arg,arg,... ; '$$' starts a comment. Numbers in
// fixed notation; the tool as LOADTL/1 and CUTTER/d,r (APT's words, read by most posts).
void write_cl_apt(std::ostream& out, const ClData& cl) {
  if (cl.part_name.find_first_of("\r\n") != std::string::npos) throw std::invalid_argument("part name with a line break");
  for (const auto& m : cl.moves) check_move(m);
  std::string t = "$$ photomill CL data v1: tool tip positions, mm\n$$ photomill run=" + run_id() + "\n";
  t += "PARTNO/" + cl.part_name + "\n";
  t += "UNITS/MM\n";
  if (cl.tool_diameter_mm > 0) {  // unknown tool (e.g. from CSV): no tool records
    t += "LOADTL/1\nCUTTER/" + fixed(cl.tool_diameter_mm) + "," + fixed(cl.tool_corner_radius_mm) + "\n";
  }
  if (cl.spindle_rpm) t += "SPINDL/RPM," + fixed(*cl.spindle_rpm) + ",CLW\n";
  if (cl.coolant) t += "COOLNT/ON\n";
  double feed = 0;
  for (const auto& m : cl.moves) {
    if (m.kind == ClMove::Kind::Rapid) {
      t += "RAPID\n";
    } else if (m.feed_mm_per_min != feed) {
      feed = m.feed_mm_per_min;
      t += "FEDRAT/MMPM," + fixed(feed) + "\n";
    }
    t += "GOTO/";
    append_fixed(t, m.tip_mm.x());
    t += ',';
    append_fixed(t, m.tip_mm.y());
    t += ',';
    append_fixed(t, m.tip_mm.z());
    if (m.axis) {
      for (int c = 0; c < 3; ++c) {
        t += ',';
        append_fixed(t, (*m.axis)[c]);
      }
    }
    t += '\n';
    if (t.size() > (1 << 16)) {
      out << t;
      t.clear();
    }
  }
  if (cl.coolant) t += "COOLNT/OFF\n";
  if (cl.spindle_rpm) t += "SPINDL/OFF\n";
  t += "END\nFINI\n";
  out << t;
}

ClData read_cl_apt(std::istream& in, const std::string& source) {
  LineReaderOptions opt;
  opt.skip_comments_and_blank = false;
  LineReader lines(in, source, opt);
  ClData cl;
  cl.part_name.clear();
  bool rapid_next = false;
  bool finished = false;
  double feed = 0;
  bool any = false;
  while (const auto raw = lines.next()) {
    std::string_view line = trim(*raw);
    if (line.empty() || line.rfind("$$", 0) == 0) continue;
    if (finished) lines.fail("content after FINI");
    any = true;
    if (line.back() == '$') lines.fail("APT continuation lines ('$' at the end) are not supported");
    const auto slash = line.find('/');
    // The major word ends at '/' or at a blank (PPRINT text, a bare RAPID).
    const std::string word = upper(trim(line.substr(0, std::min(slash, line.find_first_of(" \t")))));
    const std::string_view rest = slash == std::string_view::npos ? std::string_view() : line.substr(slash + 1);
    const auto args = slash == std::string_view::npos ? std::vector<std::string_view>() : split_fields(rest, ',');
    auto number = [&](std::size_t k, const char* what) {
      if (k >= args.size()) lines.fail(word + ": missing " + what);
      const auto v = parse_bounded(args[k]);
      if (!v) lines.fail(word + ": " + what + " " + number_problem(args[k]));
      return *v;
    };
    if (word == "PARTNO") {
      cl.part_name = std::string(trim(rest));
    } else if (word == "UNITS") {
      if (args.size() != 1 || upper(args[0]) != "MM") lines.fail("only UNITS/MM is supported");
    } else if (word == "TLDATA" || word == "CUTTER") {
      std::size_t k = 0;
      if (word == "TLDATA") {
        if (args.empty() || upper(args[0]) != "MILL") lines.fail("only TLDATA/MILL is supported");
        k = 1;
      }
      cl.tool_diameter_mm = number(k, "tool diameter");
      cl.tool_corner_radius_mm = k + 1 < args.size() ? number(k + 1, "corner radius") : 0.0;
      if (cl.tool_diameter_mm <= 0 || cl.tool_corner_radius_mm < 0 || 2 * cl.tool_corner_radius_mm > cl.tool_diameter_mm) {
        lines.fail(word + ": need diameter > 0 and 0 <= corner radius <= diameter/2");
      }
    } else if (word == "SPINDL") {
      if (args.size() == 1 && upper(args[0]) == "OFF") continue;
      if (args.empty() || upper(args[0]) != "RPM") lines.fail("expected SPINDL/RPM,n[,CLW|CCLW] or SPINDL/OFF");
      cl.spindle_rpm = number(1, "spindle speed");
      if (*cl.spindle_rpm <= 0) lines.fail("spindle speed must be positive");
    } else if (word == "COOLNT") {
      if (args.size() != 1) lines.fail("expected COOLNT/ON or COOLNT/OFF");
      const std::string a = upper(args[0]);
      if (a == "ON" || a == "FLOOD" || a == "MIST") cl.coolant = true;
      else if (a != "OFF") lines.fail("expected COOLNT/ON or COOLNT/OFF");
    } else if (word == "FEDRAT") {
      // FEDRAT/f or FEDRAT/MMPM,f
      const std::size_t k = !args.empty() && upper(args[0]) == "MMPM" ? 1 : 0;
      feed = number(k, "feed rate");
      if (feed <= 0) lines.fail("feed rate must be positive");
    } else if (word == "RAPID") {
      rapid_next = true;
    } else if (word == "GOTO") {
      if (args.size() != 3 && args.size() != 6) lines.fail("GOTO takes x,y,z or x,y,z,i,j,k, got " + std::to_string(args.size()) + " values");
      ClMove m;
      m.tip_mm = {number(0, "x"), number(1, "y"), number(2, "z")};
      if (args.size() == 6) {
        const Eigen::Vector3d a(number(3, "i"), number(4, "j"), number(5, "k"));
        if (std::abs(a.norm() - 1.0) > kAxisNormTolerance) lines.fail("tool axis i,j,k is not a unit vector");
        m.axis = a;
      }
      if (rapid_next) {
        m.kind = ClMove::Kind::Rapid;
        rapid_next = false;
      } else {
        if (feed <= 0) lines.fail("feed move before any FEDRAT");
        m.kind = ClMove::Kind::Feed;
        m.feed_mm_per_min = feed;
      }
      cl.moves.push_back(m);
    } else if (word == "END") {
    } else if (word == "FINI") {
      finished = true;
    } else if (word == "PPRINT" || word == "MULTAX" || word == "LOADTL" || word == "INTOL" ||
               word == "OUTTOL" || word == "TOLER" || word == "CLPRNT") {
      // Informational records: accepted and ignored.
    } else {
      lines.fail("unknown APT record '" + word + "'");
    }
  }
  if (!any) throw InputError(source, 0, "empty input: expected APT CL data");
  // An APT program ends with FINI; without it the file may have been cut anywhere, even inside
  // its last number (GOTO/...,2 of a file that said 27.9077), which no other check can see.
  if (!finished) {
    throw InputError(source, lines.line_number(), "the CL data ends without FINI: the file is cut short or incomplete");
  }
  if (cl.part_name.empty()) cl.part_name = "photomill";
  return cl;
}

void write_cl_csv(std::ostream& out, const ClData& cl) {
  out << stamp_line(cl.moves.size());
  write_csv_row(out, {"move", "x_mm", "y_mm", "z_mm", "i", "j", "k", "feed_mm_per_min"});
  for (const auto& m : cl.moves) {
    check_move(m);
    std::vector<std::string> row{m.kind == ClMove::Kind::Rapid ? "rapid" : "feed", format_double(m.tip_mm.x()),
                                 format_double(m.tip_mm.y()), format_double(m.tip_mm.z())};
    for (int c = 0; c < 3; ++c) row.push_back(m.axis ? format_double((*m.axis)[c]) : "");
    row.push_back(m.kind == ClMove::Kind::Rapid ? "" : format_double(m.feed_mm_per_min));
    write_csv_row(out, row);
  }
}

ClData read_cl_csv(std::istream& in, const std::string& source) {
  CsvReader csv(in, source, {"move", "x_mm", "y_mm", "z_mm"}, {"i", "j", "k", "feed_mm_per_min"});
  ClData cl;
  while (csv.next()) {
    ClMove m;
    const std::string_view kind = csv.text(0);
    if (kind == "rapid") m.kind = ClMove::Kind::Rapid;
    else if (kind == "feed") m.kind = ClMove::Kind::Feed;
    else csv.fail("move must be 'rapid' or 'feed', got '" + std::string(kind) + "'");
    m.tip_mm = {csv.number(1), csv.number(2), csv.number(3)};
    const int n_axis = csv.has(4) + csv.has(5) + csv.has(6);
    if (n_axis == 3) {
      const Eigen::Vector3d a(csv.number(4), csv.number(5), csv.number(6));
      if (std::abs(a.norm() - 1.0) > kAxisNormTolerance) csv.fail("tool axis i,j,k is not a unit vector");
      m.axis = a;
    } else if (n_axis != 0) {
      csv.fail("give all of i, j, k or none");
    }
    if (m.kind == ClMove::Kind::Feed) {
      if (!csv.has(7)) csv.fail("feed move without feed_mm_per_min");
      m.feed_mm_per_min = csv.number(7);
      if (m.feed_mm_per_min <= 0) csv.fail("feed_mm_per_min must be positive");
    }
    cl.moves.push_back(m);
  }
  return cl;
}

ClData read_cl(std::istream& in, const std::string& source) {
  // Sniff: CSV starts with its header "move,"; APT with a word such as PARTNO or '$$'.
  std::string head;
  std::streambuf* sb = in.rdbuf();
  // Cannot un-read more than one char portably from stdin, so buffer the whole input.
  std::string all;
  {
    char buf[1 << 14];
    std::streamsize n;
    while ((n = sb->sgetn(buf, sizeof buf)) > 0) all.append(buf, static_cast<std::size_t>(n));
  }
  std::size_t pos = all.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0;
  while (pos < all.size()) {  // first non-blank, non-'#' line
    const std::size_t end = all.find('\n', pos);
    const std::string_view line = trim(std::string_view(all).substr(pos, end == std::string::npos ? std::string::npos : end - pos));
    if (!line.empty() && line.front() != '#') {
      head = std::string(line);
      break;
    }
    if (end == std::string::npos) break;
    pos = end + 1;
  }
  std::istringstream s(all);
  if (head.rfind("move", 0) == 0) return read_cl_csv(s, source);
  return read_cl_apt(s, source);
}

}  // namespace photomill
