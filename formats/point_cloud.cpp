#include "formats/point_cloud.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>

#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"
#include "formats/magnitude.hpp"

namespace photomill {

const PointProperty* PointCloud::find(std::string_view name) const {
  for (const auto& p : properties) {
    if (p.name == name) return &p;
  }
  for (const auto& p : properties) {
    if (p.name.size() == name.size() + 7 && p.name.compare(0, 7, "scalar_") == 0 && p.name.compare(7, name.size(), name) == 0) {
      return &p;
    }
  }
  return nullptr;
}

PointProperty& PointCloud::add_property(const std::string& name, PlyScalar type) {
  for (auto& p : properties) {
    if (p.name == name) return p;
  }
  properties.push_back({name, type, std::vector<double>(points_mm.size(), 0.0)});
  return properties.back();
}

namespace {

// The header comment that carries PointCloud::units.
constexpr const char* kUnitsComment = "photomill point cloud, units ";

// --- PLY scalar types -----------------------------------------------------------------------
struct TypeName {
  PlyScalar type;
  const char* canonical;  // written
  const char* alias;      // also read
  std::size_t bytes;
};
constexpr std::array<TypeName, 8> kTypes{{
    {PlyScalar::Int8, "char", "int8", 1},     {PlyScalar::UInt8, "uchar", "uint8", 1},
    {PlyScalar::Int16, "short", "int16", 2},  {PlyScalar::UInt16, "ushort", "uint16", 2},
    {PlyScalar::Int32, "int", "int32", 4},    {PlyScalar::UInt32, "uint", "uint32", 4},
    {PlyScalar::Float32, "float", "float32", 4}, {PlyScalar::Float64, "double", "float64", 8},
}};

const TypeName& info(PlyScalar t) {
  return *std::find_if(kTypes.begin(), kTypes.end(), [t](const TypeName& n) { return n.type == t; });
}

std::optional<PlyScalar> parse_type(std::string_view s) {
  for (const auto& n : kTypes) {
    if (s == n.canonical || s == n.alias) return n.type;
  }
  return std::nullopt;
}

bool is_float(PlyScalar t) { return t == PlyScalar::Float32 || t == PlyScalar::Float64; }

// Range of the integer types, to reject values an ASCII file cannot mean.
std::pair<double, double> int_range(PlyScalar t) {
  switch (t) {
    case PlyScalar::Int8: return {-128, 127};
    case PlyScalar::UInt8: return {0, 255};
    case PlyScalar::Int16: return {-32768, 32767};
    case PlyScalar::UInt16: return {0, 65535};
    case PlyScalar::Int32: return {-2147483648.0, 2147483647.0};
    case PlyScalar::UInt32: return {0, 4294967295.0};
    default: return {-std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  }
}

// Converts a value to what the declared type can hold, so ASCII and binary agree exactly.
std::optional<double> coerce(double v, PlyScalar t) {
  if (t == PlyScalar::Float32) {
    if (std::abs(v) > std::numeric_limits<float>::max()) return std::nullopt;
    return static_cast<double>(static_cast<float>(v));
  }
  if (t == PlyScalar::Float64) return v;
  const auto [lo, hi] = int_range(t);
  if (v != std::floor(v) || v < lo || v > hi) return std::nullopt;
  return v;
}

// --- header ---------------------------------------------------------------------------------
enum class Format { Ascii, BinaryLE, BinaryBE };

struct Property {
  std::string name;
  PlyScalar type = PlyScalar::Float64;
  bool is_list = false;
  PlyScalar count_type = PlyScalar::UInt8;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Format format = Format::Ascii;
  std::size_t lines = 0;  // header lines, including "end_header"
  std::string units = "mm";
  std::vector<Element> elements;
};

Header read_header(std::istream& in, const std::string& source, const PointCloudLimits& limits) {
  LineReaderOptions opt;
  opt.max_line_bytes = limits.max_header_bytes;
  opt.skip_comments_and_blank = false;
  LineReader lines(in, source, opt);
  Header h;
  std::size_t bytes = 0;
  bool have_format = false;
  for (;;) {
    const auto line = lines.next();
    if (!line) throw InputError(source, lines.line_number(), "PLY header has no 'end_header'");
    bytes += line->size() + 1;
    if (bytes > limits.max_header_bytes) lines.fail("PLY header longer than " + std::to_string(limits.max_header_bytes) + " bytes");
    const auto f = split_whitespace(*line);
    if (lines.line_number() == 1) {
      if (f.size() != 1 || f[0] != "ply") lines.fail("not a PLY file (first line is not 'ply')");
      continue;
    }
    if (f.empty()) continue;
    if (f[0] == "comment" && line->rfind(std::string("comment ") + kUnitsComment, 0) == 0) {
      const std::string rest(line->substr(8 + std::string_view(kUnitsComment).size()));
      h.units = rest.substr(0, rest.find_first_of(": \t\r"));
      if (h.units.empty()) lines.fail("PLY units comment names no unit");
      continue;
    }
    if (f[0] == "comment" || f[0] == "obj_info") continue;
    if (f[0] == "end_header") {
      h.lines = lines.line_number();
      break;
    }
    if (f[0] == "format") {
      if (f.size() != 3) lines.fail("malformed 'format' line");
      if (f[1] == "ascii") h.format = Format::Ascii;
      else if (f[1] == "binary_little_endian") h.format = Format::BinaryLE;
      else if (f[1] == "binary_big_endian") h.format = Format::BinaryBE;
      else lines.fail("unknown PLY format '" + std::string(f[1]) + "'");
      if (f[2] != "1.0") lines.fail("unsupported PLY version '" + std::string(f[2]) + "'");
      have_format = true;
    } else if (f[0] == "element") {
      if (f.size() != 3) lines.fail("malformed 'element' line (expected: element NAME COUNT)");
      const auto count = parse_int(f[2]);
      if (!count || *count < 0) lines.fail("element count is not a non-negative integer: '" + std::string(f[2]) + "'");
      h.elements.push_back({std::string(f[1]), static_cast<std::uint64_t>(*count), {}});
    } else if (f[0] == "property") {
      if (h.elements.empty()) lines.fail("'property' before any 'element'");
      Property p;
      if (f.size() == 5 && f[1] == "list") {
        const auto ct = parse_type(f[2]);
        const auto it = parse_type(f[3]);
        if (!ct || !it) lines.fail("unknown type in list property");
        if (is_float(*ct)) lines.fail("list count type must be an integer type");
        p = {std::string(f[4]), *it, true, *ct};
      } else if (f.size() == 3) {
        const auto t = parse_type(f[1]);
        if (!t) lines.fail("unknown property type '" + std::string(f[1]) + "'");
        p = {std::string(f[2]), *t, false, PlyScalar::UInt8};
      } else {
        lines.fail("malformed 'property' line");
      }
      for (const auto& q : h.elements.back().properties) {
        if (q.name == p.name) lines.fail("property '" + p.name + "' declared twice");
      }
      h.elements.back().properties.push_back(p);
    } else {
      lines.fail("unknown PLY header keyword '" + std::string(f[0]) + "'");
    }
  }
  if (!have_format) throw InputError(source, lines.line_number(), "PLY header has no 'format' line");
  return h;
}

// --- binary values --------------------------------------------------------------------------
class BinaryIn {
public:
  BinaryIn(std::istream& in, bool big_endian) : sb_(*in.rdbuf()), big_(big_endian) {}
  // Returns false at end of input.
  bool read(PlyScalar t, double& out) {
    const std::size_t n = info(t).bytes;
    unsigned char b[8];
    if (static_cast<std::size_t>(sb_.sgetn(reinterpret_cast<char*>(b), static_cast<std::streamsize>(n))) != n) return false;
    if (big_) std::reverse(b, b + n);
    switch (t) {
      case PlyScalar::Int8: out = static_cast<std::int8_t>(b[0]); break;
      case PlyScalar::UInt8: out = b[0]; break;
      case PlyScalar::Int16: { std::int16_t v; std::memcpy(&v, b, 2); out = v; break; }
      case PlyScalar::UInt16: { std::uint16_t v; std::memcpy(&v, b, 2); out = v; break; }
      case PlyScalar::Int32: { std::int32_t v; std::memcpy(&v, b, 4); out = v; break; }
      case PlyScalar::UInt32: { std::uint32_t v; std::memcpy(&v, b, 4); out = v; break; }
      case PlyScalar::Float32: { float v; std::memcpy(&v, b, 4); out = v; break; }
      case PlyScalar::Float64: { double v; std::memcpy(&v, b, 8); out = v; break; }
    }
    return true;
  }
  // Skips n bytes; false if the input ends first.
  bool skip(std::uint64_t n) {
    char buf[4096];
    while (n > 0) {
      const auto chunk = static_cast<std::streamsize>(std::min<std::uint64_t>(n, sizeof buf));
      if (sb_.sgetn(buf, chunk) != chunk) return false;
      n -= static_cast<std::uint64_t>(chunk);
    }
    return true;
  }

private:
  std::streambuf& sb_;
  bool big_;
};

static_assert(std::endian::native == std::endian::little, "photomill assumes a little-endian host");

}  // namespace

PointCloud read_ply(std::istream& in, const std::string& source, PointCloudLimits limits) {
  const Header h = read_header(in, source, limits);
  const auto vertex_it = std::find_if(h.elements.begin(), h.elements.end(),
                                      [](const Element& e) { return e.name == "vertex"; });
  if (vertex_it == h.elements.end()) throw InputError(source, 0, "PLY has no 'vertex' element");
  const Element& vertex = *vertex_it;

  PointCloud cloud;
  cloud.units = h.units;
  int ix = -1, iy = -1, iz = -1;
  std::vector<int> column(vertex.properties.size(), -1);  // property -> cloud.properties index
  for (std::size_t k = 0; k < vertex.properties.size(); ++k) {
    const Property& p = vertex.properties[k];
    if (p.is_list) continue;
    if (p.name == "x") ix = static_cast<int>(k);
    else if (p.name == "y") iy = static_cast<int>(k);
    else if (p.name == "z") iz = static_cast<int>(k);
    else {
      column[k] = static_cast<int>(cloud.properties.size());
      cloud.properties.push_back({p.name, p.type, {}});
    }
  }
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(source, 0, "PLY vertex element lacks x, y or z");
  cloud.xyz_type = vertex.properties[static_cast<std::size_t>(ix)].type;
  // Never trust the count for allocation: reserve at most what a modest file holds.
  const std::size_t reserve = static_cast<std::size_t>(std::min<std::uint64_t>(vertex.count, 1 << 20));
  cloud.points_mm.reserve(reserve);
  for (auto& p : cloud.properties) p.values.reserve(reserve);

  std::vector<double> record(vertex.properties.size(), 0.0);
  auto store = [&](std::size_t index) {
    Eigen::Vector3d xyz(record[static_cast<std::size_t>(ix)], record[static_cast<std::size_t>(iy)],
                        record[static_cast<std::size_t>(iz)]);
    if (!xyz.allFinite()) {
      throw InputError(source, 0, "vertex " + std::to_string(index) + " has a non-finite coordinate");
    }
    if (xyz.cwiseAbs().maxCoeff() > kMaxMagnitude) {
      throw InputError(source, 0, "vertex " + std::to_string(index) + " has a coordinate beyond ±1e15 mm, not a plausible value");
    }
    cloud.points_mm.push_back(xyz);
    for (std::size_t k = 0; k < record.size(); ++k) {
      if (column[k] >= 0) {
        if (!std::isfinite(record[k])) {
          throw InputError(source, 0, "vertex " + std::to_string(index) + " property '" +
                                          vertex.properties[k].name + "' is not finite");
        }
        cloud.properties[static_cast<std::size_t>(column[k])].values.push_back(record[k]);
      }
    }
  };

  if (h.format == Format::Ascii) {
    // ASCII PLY: one record per line. Line numbers count from the start of the file.
    LineReaderOptions opt;
    opt.max_line_bytes = limits.max_line_bytes;
    opt.skip_comments_and_blank = false;
    opt.first_line_number = h.lines + 1;
    LineReader lines(in, source, opt);
    for (const Element& e : h.elements) {
      const bool is_vertex = &e == &vertex;
      for (std::uint64_t r = 0; r < e.count; ++r) {
        const auto line = lines.next();
        if (!line) {
          throw InputError(source, 0, "truncated: element '" + e.name + "' promises " +
                                          std::to_string(e.count) + " records, found " + std::to_string(r));
        }
        if (!is_vertex) continue;
        const auto f = split_whitespace(*line);
        std::size_t t = 0;
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
          const Property& p = e.properties[k];
          if (t >= f.size()) lines.fail("vertex record has too few values");
          if (p.is_list) {
            const auto n = parse_int(f[t]);
            if (!n || *n < 0 || static_cast<std::uint64_t>(*n) > f.size() - t - 1) lines.fail("bad list length in vertex record");
            t += 1 + static_cast<std::size_t>(*n);
            continue;
          }
          const auto v = parse_double(f[t]);
          if (!v) lines.fail("property '" + p.name + "' is not a finite number: '" + std::string(f[t]) + "'");
          const auto c = coerce(*v, p.type);
          if (!c) lines.fail("property '" + p.name + "' value '" + std::string(f[t]) + "' does not fit type " + info(p.type).canonical);
          record[k] = *c;
          ++t;
        }
        if (t != f.size()) lines.fail("vertex record has " + std::to_string(f.size()) + " values, expected " + std::to_string(t));
        store(cloud.points_mm.size());
      }
      if (is_vertex) break;
    }
    return cloud;
  }

  BinaryIn bin(in, h.format == Format::BinaryBE);
  for (const Element& e : h.elements) {
    const bool is_vertex = &e == &vertex;
    if (e.properties.empty()) continue;  // zero-size records: nothing to read or skip
    for (std::uint64_t r = 0; r < e.count; ++r) {
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const Property& p = e.properties[k];
        bool ok = true;
        if (p.is_list) {
          double n = 0;
          ok = bin.read(p.count_type, n);
          if (ok && n < 0) throw InputError(source, 0, "negative list length in element '" + e.name + "'");
          if (ok) ok = bin.skip(static_cast<std::uint64_t>(n) * info(p.type).bytes);
        } else {
          double v = 0;
          ok = bin.read(p.type, v);
          // Only the vertex element's values are kept: `record` has its size, and an element
          // before it may have more properties (a heap overflow found by fuzzing).
          if (is_vertex) record[k] = v;
        }
        if (!ok) {
          throw InputError(source, 0, "truncated: element '" + e.name + "' promises " +
                                          std::to_string(e.count) + " records, found " + std::to_string(r));
        }
      }
      if (is_vertex) store(cloud.points_mm.size());
    }
    if (is_vertex) break;
  }
  return cloud;
}

namespace {

void append_value(std::string& out, double v, PlyScalar t) {
  if (t == PlyScalar::Float64) {
    append_double(out, v);
  } else if (t == PlyScalar::Float32) {
    char buf[32];
    const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, static_cast<float>(v));
    out.append(buf, ec == std::errc() ? ptr : buf);
  } else {
    out += std::to_string(static_cast<long long>(v));
  }
}

void put_binary(std::string& out, double v, PlyScalar t) {
  char b[8];
  std::size_t n = info(t).bytes;
  switch (t) {
    case PlyScalar::Int8: { auto x = static_cast<std::int8_t>(v); std::memcpy(b, &x, 1); break; }
    case PlyScalar::UInt8: { auto x = static_cast<std::uint8_t>(v); std::memcpy(b, &x, 1); break; }
    case PlyScalar::Int16: { auto x = static_cast<std::int16_t>(v); std::memcpy(b, &x, 2); break; }
    case PlyScalar::UInt16: { auto x = static_cast<std::uint16_t>(v); std::memcpy(b, &x, 2); break; }
    case PlyScalar::Int32: { auto x = static_cast<std::int32_t>(v); std::memcpy(b, &x, 4); break; }
    case PlyScalar::UInt32: { auto x = static_cast<std::uint32_t>(v); std::memcpy(b, &x, 4); break; }
    case PlyScalar::Float32: { auto x = static_cast<float>(v); std::memcpy(b, &x, 4); break; }
    case PlyScalar::Float64: std::memcpy(b, &v, 8); break;
  }
  out.append(b, n);
}

}  // namespace

void write_ply(std::ostream& out, const PointCloud& cloud, PlyEncoding encoding, const std::string& comment) {
  const std::size_t n = cloud.points_mm.size();
  for (const auto& p : cloud.properties) {
    if (p.values.size() != n) {
      throw std::invalid_argument("property '" + p.name + "' has " + std::to_string(p.values.size()) +
                                  " values for " + std::to_string(n) + " points");
    }
    if (p.name.empty() || p.name.find_first_of(" \t\r\n") != std::string::npos || p.name == "x" || p.name == "y" || p.name == "z") {
      throw std::invalid_argument("invalid PLY property name '" + p.name + "'");
    }
    for (double v : p.values) {
      if (!coerce(v, p.type) || *coerce(v, p.type) != v) {
        throw std::invalid_argument("property '" + p.name + "' holds a value its type cannot store");
      }
    }
  }
  for (const auto& x : cloud.points_mm) {
    if (!x.allFinite()) throw std::invalid_argument("cannot write a non-finite point");
  }
  std::string text = "ply\nformat ";
  text += encoding == PlyEncoding::Ascii ? "ascii" : "binary_little_endian";
  if (cloud.units.empty() || cloud.units.find_first_of(": \t\r\n") != std::string::npos) {
    throw std::invalid_argument("invalid point cloud units '" + cloud.units + "'");
  }
  text += " 1.0\ncomment " + std::string(kUnitsComment) + cloud.units +
          (cloud.units == "arbitrary" ? ": not mm, no datum (control points, scale bars or known poses) fixed the scale" : "") +
          "\n";
  text += "comment photomill run=" + run_id() + "\n";
  if (!comment.empty() && comment.find('\n') == std::string::npos) text += "comment " + comment + "\n";
  text += "element vertex " + std::to_string(n) + "\n";
  const char* xyz_type = info(cloud.xyz_type).canonical;
  for (const char* c : {"x", "y", "z"}) text += std::string("property ") + xyz_type + " " + c + "\n";
  for (const auto& p : cloud.properties) text += std::string("property ") + info(p.type).canonical + " " + p.name + "\n";
  text += "end_header\n";
  out << text;
  text.clear();
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      if (encoding == PlyEncoding::Ascii) {
        if (c) text += ' ';
        append_value(text, cloud.points_mm[i][c], cloud.xyz_type);
      } else {
        put_binary(text, cloud.points_mm[i][c], cloud.xyz_type);
      }
    }
    for (const auto& p : cloud.properties) {
      if (encoding == PlyEncoding::Ascii) {
        text += ' ';
        append_value(text, p.values[i], p.type);
      } else {
        put_binary(text, p.values[i], p.type);
      }
    }
    if (encoding == PlyEncoding::Ascii) text += '\n';
    if (text.size() > (1 << 16)) {
      out << text;
      text.clear();
    }
  }
  out << text;
}

PointCloud read_xyz(std::istream& in, const std::string& source, PointCloudLimits limits) {
  LineReaderOptions opt;
  opt.max_line_bytes = limits.max_line_bytes;
  LineReader lines(in, source, opt);
  PointCloud cloud;
  bool first = true;
  while (const auto line = lines.next()) {
    const auto f = split_whitespace(*line);
    if (first && !f.empty() && !parse_double(f[0]) &&
        std::all_of(f[0].begin(), f[0].end(), [](char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '/' || c == '_'; })) {
      first = false;  // a column-name header such as "x y z" or "//X Y Z"
      lines.uncount_row();
      continue;
    }
    first = false;
    if (f.size() < 3) lines.fail("expected at least 3 numbers (x y z), got " + std::to_string(f.size()));
    Eigen::Vector3d p;
    for (int c = 0; c < 3; ++c) {
      const auto v = parse_bounded(f[static_cast<std::size_t>(c)]);
      if (!v) lines.fail(std::string(1, "xyz"[c]) + " " + number_problem(f[static_cast<std::size_t>(c)]));
      p[c] = *v;
    }
    cloud.points_mm.push_back(p);
  }
  return cloud;
}

void write_xyz(std::ostream& out, const PointCloud& cloud) {
  std::string text = stamp_line(cloud.points_mm.size());
  for (const auto& p : cloud.points_mm) {
    if (!p.allFinite()) throw std::invalid_argument("cannot write a non-finite point");
    append_double(text, p.x());
    text += ' ';
    append_double(text, p.y());
    text += ' ';
    append_double(text, p.z());
    text += '\n';
    if (text.size() > (1 << 16)) {
      out << text;
      text.clear();
    }
  }
  out << text;
}

PointCloud read_point_cloud(std::istream& in, const std::string& source, PointCloudLimits limits) {
  // Peek at the first bytes without consuming them.
  std::streambuf* sb = in.rdbuf();
  int c0 = sb->sgetc();
  if (c0 == 0xEF) {
    // A UTF-8 byte order mark (some Windows editors write one): skipped, as the CSV readers do.
    sb->sbumpc();
    if (sb->sbumpc() != 0xBB || sb->sbumpc() != 0xBF) throw InputError(source, 1, "not a point cloud (neither PLY nor x y z text)");
    c0 = sb->sgetc();
  }
  if (c0 == 'p') {
    // "ply" must be the whole first line; read_ply checks that.
    return read_ply(in, source, limits);
  }
  return read_xyz(in, source, limits);
}

}  // namespace photomill
