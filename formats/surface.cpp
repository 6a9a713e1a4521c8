#include "formats/surface.hpp"

#include <cmath>
#include <string_view>
#include <tuple>

#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"
#include "formats/magnitude.hpp"

namespace photomill {
namespace {

// Open CASCADE's limit (Geom_BSplineSurface::MaxDegree) and a net size no real surface exceeds;
// both keep a hostile header from asking for absurd allocations.
constexpr int kMaxDegree = 25;
constexpr long long kMaxPoles = 100'000'000;

void check_knots(const std::vector<double>& knots, int degree, int num_poles, const char* dir,
                 const std::string& source) {
  const std::string d(dir);
  if (knots.size() != static_cast<std::size_t>(num_poles + degree + 1)) {
    throw InputError(source, 0,
                     "knots_" + d + " has " + std::to_string(knots.size()) + " knots, expected " +
                         std::to_string(num_poles + degree + 1) + " (poles + degree + 1)");
  }
  for (std::size_t k = 0; k < knots.size(); ++k) {
    if (!std::isfinite(knots[k])) throw InputError(source, 0, "knots_" + d + " has a non-finite knot");
    if (k > 0 && knots[k] < knots[k - 1]) {
      throw InputError(source, 0, "knots_" + d + " decreases at knot " + std::to_string(k));
    }
  }
  // Interior knots of multiplicity > degree would split the surface in two.
  std::size_t run = 1;
  for (std::size_t k = 1; k < knots.size(); ++k) {
    run = knots[k] == knots[k - 1] ? run + 1 : 1;
    const bool interior = knots[k] > knots[static_cast<std::size_t>(degree)] &&
                          knots[k] < knots[static_cast<std::size_t>(num_poles)];
    if (interior && run > static_cast<std::size_t>(degree)) {
      throw InputError(source, 0, "knots_" + d + " has an interior knot of multiplicity > degree");
    }
  }
  if (!(knots[static_cast<std::size_t>(degree)] < knots[static_cast<std::size_t>(num_poles)])) {
    throw InputError(source, 0, "knots_" + d + " gives an empty parameter domain");
  }
}

}  // namespace

void validate_surface(const BSplineSurface& s, const std::string& source) {
  if (s.units != kSurfaceUnitMm && s.units != kSurfaceUnitArbitrary) {
    throw InputError(source, 0, "unknown unit '" + s.units + "': a surface is in mm or 'arbitrary'");
  }
  for (const auto& [deg, dir] : {std::pair{s.degree_u, "u"}, std::pair{s.degree_v, "v"}}) {
    if (deg < 1 || deg > kMaxDegree) {
      throw InputError(source, 0, std::string("degree in ") + dir + " must be 1.." +
                                      std::to_string(kMaxDegree) + ", got " + std::to_string(deg));
    }
  }
  if (s.num_poles_u < s.degree_u + 1 || s.num_poles_v < s.degree_v + 1) {
    throw InputError(source, 0, "a degree (" + std::to_string(s.degree_u) + "," +
                                    std::to_string(s.degree_v) + ") surface needs at least " +
                                    std::to_string(s.degree_u + 1) + "x" +
                                    std::to_string(s.degree_v + 1) + " poles");
  }
  if (static_cast<long long>(s.num_poles_u) * s.num_poles_v > kMaxPoles) {
    throw InputError(source, 0, "control net too large");
  }
  check_knots(s.knots_u, s.degree_u, s.num_poles_u, "u", source);
  check_knots(s.knots_v, s.degree_v, s.num_poles_v, "v", source);
  const std::size_t n = static_cast<std::size_t>(s.num_poles_u) * s.num_poles_v;
  if (s.poles_mm.size() != n) {
    throw InputError(source, 0, "control net has " + std::to_string(s.poles_mm.size()) +
                                    " poles, expected " + std::to_string(n));
  }
  for (const auto& p : s.poles_mm) {
    if (!p.allFinite()) throw InputError(source, 0, "a pole has a non-finite coordinate");
  }
  if (!s.weights.empty()) {
    if (s.weights.size() != n) throw InputError(source, 0, "weights and poles differ in number");
    for (double w : s.weights) {
      if (!(w > 0) || !std::isfinite(w)) throw InputError(source, 0, "weights must be positive");
    }
  }
  if (!s.boundary_uv.empty()) {
    if (s.boundary_uv.size() < 3) throw InputError(source, 0, "a boundary needs at least 3 vertices");
    for (const auto& uv : s.boundary_uv) {
      if (!uv.allFinite()) throw InputError(source, 0, "a boundary vertex is not finite");
    }
  }
}

// Text format (docs/formats.md):
//   photomill-surface v1
//   units arbitrary                 (optional; absent: mm)
//   degrees p q
//   poles nu nv
//   rational 0|1
//   knots_u U0 ... U(nu+p)
//   knots_v V0 ... V(nv+q)
//   pole i j x_mm y_mm z_mm [w]      (nu*nv lines, i major)
//   boundary N                      (optional)
//   uv u v                          (N lines)
//   end
BSplineSurface read_surface(std::istream& in, const std::string& source) {
  LineReader lines(in, source);
  BSplineSurface s;
  auto expect_line = [&](std::string_view what) {
    const auto line = lines.next();
    if (!line) throw InputError(source, lines.line_number(), "unexpected end of input: expected " + std::string(what));
    return split_whitespace(*line);
  };
  auto number = [&](std::string_view f, std::string_view what) {
    const auto v = parse_bounded(f);
    if (!v) lines.fail(std::string(what) + " " + number_problem(f));
    return *v;
  };
  auto integer = [&](std::string_view f, std::string_view what, long long lo, long long hi) {
    const auto v = parse_int(f);
    if (!v || *v < lo || *v > hi) {
      lines.fail(std::string(what) + " must be an integer in " + std::to_string(lo) + ".." +
                 std::to_string(hi) + ", got '" + std::string(f) + "'");
    }
    return static_cast<int>(*v);
  };
  auto keyword = [&](const std::vector<std::string_view>& f, std::string_view kw, std::size_t n_args) {
    if (f.empty() || f[0] != kw) {
      lines.fail("expected '" + std::string(kw) + "', got '" + (f.empty() ? std::string() : std::string(f[0])) + "'");
    }
    if (n_args != static_cast<std::size_t>(-1) && f.size() != n_args + 1) {
      lines.fail("'" + std::string(kw) + "' takes " + std::to_string(n_args) + " values, got " +
                 std::to_string(f.size() - 1));
    }
  };

  {
    const auto f = expect_line("the header 'photomill-surface v1'");
    if (f.size() != 2 || f[0] != "photomill-surface") lines.fail("not a photomill surface file (expected 'photomill-surface v1')");
    if (f[1] != "v1") lines.fail("unsupported surface format version '" + std::string(f[1]) + "'");
  }
  {
    auto f = expect_line("'degrees p q'");
    if (!f.empty() && f[0] == "units") {
      keyword(f, "units", 1);
      if (f[1] != kSurfaceUnitMm && f[1] != kSurfaceUnitArbitrary) {
        lines.fail("unknown unit '" + std::string(f[1]) + "': a surface is in mm (no 'units' line) or 'units arbitrary'");
      }
      s.units = std::string(f[1]);
      f = expect_line("'degrees p q'");
    }
    keyword(f, "degrees", 2);
    s.degree_u = integer(f[1], "degree p", 1, kMaxDegree);
    s.degree_v = integer(f[2], "degree q", 1, kMaxDegree);
  }
  {
    const auto f = expect_line("'poles nu nv'");
    keyword(f, "poles", 2);
    s.num_poles_u = integer(f[1], "nu", s.degree_u + 1, 1'000'000);
    s.num_poles_v = integer(f[2], "nv", s.degree_v + 1, 1'000'000);
    if (static_cast<long long>(s.num_poles_u) * s.num_poles_v > kMaxPoles) lines.fail("control net too large");
  }
  bool rational = false;
  {
    const auto f = expect_line("'rational 0|1'");
    keyword(f, "rational", 1);
    rational = integer(f[1], "rational", 0, 1) == 1;
  }
  for (const auto& [name, knots, count] :
       {std::tuple{"knots_u", &s.knots_u, s.num_poles_u + s.degree_u + 1},
        std::tuple{"knots_v", &s.knots_v, s.num_poles_v + s.degree_v + 1}}) {
    const auto f = expect_line(std::string("'") + name + " ...'");
    keyword(f, name, static_cast<std::size_t>(count));
    for (std::size_t k = 1; k < f.size(); ++k) knots->push_back(number(f[k], name));
  }
  const std::size_t n = static_cast<std::size_t>(s.num_poles_u) * s.num_poles_v;
  for (std::size_t k = 0; k < n; ++k) {
    const int i = static_cast<int>(k / static_cast<std::size_t>(s.num_poles_v));
    const int j = static_cast<int>(k % static_cast<std::size_t>(s.num_poles_v));
    const auto f = expect_line("'pole " + std::to_string(i) + " " + std::to_string(j) + " x y z" +
                               (rational ? " w'" : "'"));
    keyword(f, "pole", rational ? 6 : 5);
    if (parse_int(f[1]) != i || parse_int(f[2]) != j) {
      lines.fail("expected pole " + std::to_string(i) + " " + std::to_string(j) + " (poles in order, i major), got " +
                 std::string(f[1]) + " " + std::string(f[2]));
    }
    s.poles_mm.emplace_back(number(f[3], "x_mm"), number(f[4], "y_mm"), number(f[5], "z_mm"));
    if (rational) {
      const double w = number(f[6], "weight");
      if (!(w > 0)) lines.fail("weight must be positive");
      s.weights.push_back(w);
    }
  }
  auto f = expect_line("'boundary N' or 'end'");
  if (!f.empty() && f[0] == "boundary") {
    keyword(f, "boundary", 1);
    const int count = integer(f[1], "boundary vertex count", 3, 10'000'000);
    for (int k = 0; k < count; ++k) {
      const auto g = expect_line("'uv u v'");
      keyword(g, "uv", 2);
      s.boundary_uv.emplace_back(number(g[1], "u"), number(g[2], "v"));
    }
    f = expect_line("'end'");
  }
  keyword(f, "end", 0);
  if (const auto extra = lines.next()) lines.fail("unexpected content after 'end'");
  try {
    validate_surface(s, source);
  } catch (const InputError& e) {
    throw InputError(source, lines.line_number(), e.message());
  }
  return s;
}

void write_surface(std::ostream& out, const BSplineSurface& s) {
  validate_surface(s, "surface to write");
  std::string text = "photomill-surface v1\n" + stamp_line(std::nullopt);
  // Only a surface not in mm says so: a file without the line reads as mm, as before.
  if (!s.in_mm()) text += "units " + s.units + "\n";
  text += "degrees " + std::to_string(s.degree_u) + " " + std::to_string(s.degree_v) + "\n";
  text += "poles " + std::to_string(s.num_poles_u) + " " + std::to_string(s.num_poles_v) + "\n";
  text += std::string("rational ") + (s.rational() ? "1" : "0") + "\n";
  for (const auto& [name, knots] : {std::pair{"knots_u", &s.knots_u}, std::pair{"knots_v", &s.knots_v}}) {
    text += name;
    for (double k : *knots) {
      text += ' ';
      append_double(text, k);
    }
    text += '\n';
  }
  text += (s.in_mm() ? "# pole i j x_mm y_mm z_mm" : "# pole i j x y z") + std::string(s.rational() ? " weight" : "") +
          (s.in_mm() ? "" : " (units " + s.units + ": not mm)") + "\n";
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      const auto& p = s.pole(i, j);
      text += "pole " + std::to_string(i) + " " + std::to_string(j);
      for (int c = 0; c < 3; ++c) {
        text += ' ';
        append_double(text, p[c]);
      }
      if (s.rational()) {
        text += ' ';
        append_double(text, s.weights[static_cast<std::size_t>(i) * s.num_poles_v + j]);
      }
      text += '\n';
    }
    out << text;
    text.clear();
  }
  if (!s.boundary_uv.empty()) {
    text += "boundary " + std::to_string(s.boundary_uv.size()) + "\n";
    for (const auto& uv : s.boundary_uv) {
      text += "uv ";
      append_double(text, uv.x());
      text += ' ';
      append_double(text, uv.y());
      text += '\n';
    }
  }
  text += "end\n";
  out << text;
}

}  // namespace photomill
