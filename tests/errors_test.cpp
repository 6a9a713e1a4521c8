// The golden test of docs/errors.md: it reads the table from the document itself and runs every
// row, so the table cannot drift from what the binaries print. Each row runs the binary with -q
// in a fresh temporary folder holding every fixture (generated here, most of them derived from
// data/demo by one small change), and asserts the exit code, that stderr is exactly the one line
// the row gives (with '…' matching any text), and that a failed run leaves no file behind (the
// folder lists the same files before and after). Rows of accepted inputs (exit 0) assert that
// the output was written. A second test asserts that every binary has a row (or an 'n/a' row
// giving the reason) for every class of bad input that issue #11 lists.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/fixtures.hpp"
#include "tests/run_tool.hpp"

namespace photomill::test {
namespace {

namespace fs = std::filesystem;

const std::vector<std::string> kBinaries{"calib", "detect", "match", "triangulate", "fitsurf", "toolpath", "clpost", "targets"};

// The classes of bad input of issue #11, item 4, in the words of the table's class column.
const std::vector<std::string> kClasses{
    "missing file",       "unreadable file",          "empty",         "header only",
    "truncated",          "wrong column count",       "non-numeric field", "NaN/inf",
    "absurdly large values", "CRLF line ends",         "UTF-8 BOM",     "binary junk",
    "not an image",       "images of different sizes", "duplicate ids", "ids that exist nowhere else",
    "camera for another image size", "output in a missing folder", "outputs of two runs"};

struct Row {
  std::size_t doc_line = 0;
  std::string binary, cls, args, exit, message;
};

void PrintTo(const Row& r, std::ostream* os) { *os << "docs/errors.md:" << r.doc_line << ": " << r.binary << " " << r.args; }

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

// A cell's text without its backticks (`...` -> ...). Messages never contain a backtick.
std::string unquote(const std::string& cell) {
  std::string s = trim(cell);
  if (s.size() >= 2 && s.front() == '`' && s.back() == '`') s = s.substr(1, s.size() - 2);
  return s;
}

// Splits a table row on '|' (cells never contain one: messages that would are written with '¦').
std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (std::size_t i = 1; i < line.size(); ++i) {
    if (line[i] == '|') {
      out.push_back(trim(cur));
      cur.clear();
    } else {
      cur += line[i];
    }
  }
  return out;
}

// Every row of the tables in docs/errors.md whose first cell is a binary of kBinaries.
std::vector<Row> read_rows() {
  std::ifstream f(std::string(PHOTOMILL_SOURCE_DIR) + "/docs/errors.md");
  std::vector<Row> rows;
  std::string line;
  std::size_t n = 0;
  while (std::getline(f, line)) {
    ++n;
    if (line.rfind("| ", 0) != 0) continue;
    const auto c = cells(line);
    if (c.size() != 5) continue;
    const std::string bin = unquote(c[0]);
    if (std::find(kBinaries.begin(), kBinaries.end(), bin) == kBinaries.end()) continue;
    rows.push_back({n, bin, c[1], unquote(c[2]), c[3], unquote(c[4])});
  }
  return rows;
}

std::vector<std::string> split_args(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  std::string a;
  while (in >> a) out.push_back(a);
  return out;
}

// '…' matches any run of characters; everything else literally.
bool glob_match(const std::string& text, const std::string& pattern) {
  const std::string any = "…";
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t p; (p = pattern.find(any, start)) != std::string::npos; start = p + any.size()) {
    parts.push_back(pattern.substr(start, p - start));
  }
  parts.push_back(pattern.substr(start));
  if (parts.size() == 1) return text == pattern;
  if (text.rfind(parts.front(), 0) != 0) return false;
  std::size_t pos = parts.front().size();
  for (std::size_t i = 1; i + 1 < parts.size(); ++i) {
    const auto p = text.find(parts[i], pos);
    if (p == std::string::npos) return false;
    pos = p + parts[i].size();
  }
  const std::string& last = parts.back();
  return text.size() >= pos + last.size() && text.compare(text.size() - last.size(), last.size(), last) == 0;
}

// ---------------------------------------------------------------------------------------------
// Fixtures

std::string read_text(const fs::path& p) { return read_file(p); }

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string l;
  while (std::getline(in, l)) out.push_back(l);
  return out;
}

std::string join(const std::vector<std::string>& lines) {
  std::string s;
  for (const auto& l : lines) s += l + "\n";
  return s;
}

std::string header_only(const std::string& text) { return text.substr(0, text.find('\n') + 1); }

// Cut inside the record in the middle of the file, after its second field: a file whose writer
// stopped (a full disk, a killed process).
std::string truncated_csv(const std::string& text) {
  const std::size_t mid = text.find('\n', text.size() / 2) + 1;
  const std::size_t comma = text.find(',', text.find(',', mid) + 1);
  return text.substr(0, comma);
}

// As photomill writes it (issue #25): a stamp announcing the rows, then `text` (a header and rows).
std::string stamped_csv(const std::string& text) {
  const auto rows = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) - 1;
  return "# photomill run=fixture rows=" + std::to_string(rows) + "\n" + text;
}

// A stamped file cut at a line boundary, its last `lines` lines gone (a half copied file whose
// every line is whole: a reader without the stamp cannot tell).
std::string cut_lines(const std::string& text, std::size_t lines) {
  std::size_t end = text.size();
  for (std::size_t k = 0; k <= lines; ++k) end = text.rfind('\n', end - 1);
  return text.substr(0, end + 1);
}

// Replaces field `col` (0-based) of line `line` (1-based) of a CSV.
std::string set_field(const std::string& text, std::size_t line, std::size_t col, const std::string& value) {
  auto ls = lines_of(text);
  std::vector<std::string> f;
  std::string cur;
  for (char c : ls.at(line - 1) + ",") {
    if (c == ',') {
      f.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  f.at(col) = value;
  std::string l;
  for (std::size_t i = 0; i < f.size(); ++i) l += (i ? "," : "") + f[i];
  ls[line - 1] = l;
  return join(ls);
}

std::string drop_last_field(const std::string& text, std::size_t line) {
  auto ls = lines_of(text);
  ls.at(line - 1) = ls[line - 1].substr(0, ls[line - 1].rfind(','));
  return join(ls);
}

std::string replace_line(const std::string& text, std::size_t line, const std::string& with) {
  auto ls = lines_of(text);
  ls.at(line - 1) = with;
  return join(ls);
}

std::string insert_line(const std::string& text, std::size_t after, const std::string& line) {
  auto ls = lines_of(text);
  ls.insert(ls.begin() + static_cast<std::ptrdiff_t>(after), line);
  return join(ls);
}

std::string crlf(const std::string& text) {
  std::string s;
  for (char c : text) {
    if (c == '\n') s += '\r';
    s += c;
  }
  return s;
}

std::string bom(const std::string& text) { return "\xEF\xBB\xBF" + text; }

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t p = 0; (p = s.find(from, p)) != std::string::npos; p += to.size()) s.replace(p, from.size(), to);
  return s;
}

// 512 bytes of deterministic noise with NUL bytes in it.
std::string junk() {
  std::string s;
  std::uint32_t x = 12345;
  for (int i = 0; i < 512; ++i) {
    x = x * 1664525u + 1013904223u;
    s += static_cast<char>(x >> 24);
  }
  s[7] = '\0';
  return s;
}

std::string ply_header(std::size_t n, const std::string& format) {
  return "ply\nformat " + format + " 1.0\nelement vertex " + std::to_string(n) +
         "\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
}

std::string cloud_ply_binary() {
  std::string body;
  std::size_t n = 0;
  for (const auto& l : lines_of(cloud_xyz())) {
    std::istringstream in(l);
    double v[3];
    in >> v[0] >> v[1] >> v[2];
    body.append(reinterpret_cast<const char*>(v), sizeof v);
    ++n;
  }
  return ply_header(n, "binary_little_endian") + body;
}

// CRC-32 of PNG chunks (ISO/IEC 15948 annex D).
std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
  }
  return c ^ 0xFFFFFFFFu;
}

std::string be32(std::uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}

std::string png_chunk(const std::string& type, const std::string& data) {
  return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc32(type + data));
}

// A complete, well-formed PNG whose header claims width x height grey pixels and holds no pixel
// data (an empty zlib stream): a decoder that trusted the header would allocate them first.
std::string png_claiming(std::uint32_t width, std::uint32_t height) {
  const std::string ihdr = be32(width) + be32(height) + std::string("\x08\x00\x00\x00\x00", 5);
  return std::string("\x89PNG\r\n\x1a\n", 8) + png_chunk("IHDR", ihdr) +
         png_chunk("IDAT", std::string("\x78\x9c\x03\x00\x00\x00\x00\x01", 8)) + png_chunk("IEND", "");
}

// Writes every fixture the table's rows name into `dir`. Named after what they are; the table's
// legend in docs/errors.md says the same.
void write_fixtures(const fs::path& dir) {
  const fs::path demo = fs::path(PHOTOMILL_SOURCE_DIR) / "data" / "demo";
  std::map<std::string, std::string> f;
  const std::string obs = read_text(demo / "board_observations.csv");  // calib's views of the board
  const std::string ctl = read_text(demo / "board_points.csv");
  const std::string pobs = read_text(demo / "observations.csv");      // the part views' markers
  const std::string pctl = read_text(demo / "control_points.csv");
  const std::string cam = read_text(demo / "camera.yaml");
  const std::string tracks = replace_all(header_only(pobs), "point_id", "track_id") + pobs.substr(header_only(pobs).size());

  f["empty.csv"] = "";
  f["junk.bin"] = junk();

  // Observations (calib, match): the board and part sets of data/demo.
  for (const auto& [name, text] : std::map<std::string, std::string>{{"obs", obs}, {"pobs", pobs}}) {
    f[name + ".csv"] = text;
    f[name + "_header.csv"] = header_only(text);
    f[name + "_trunc.csv"] = truncated_csv(text);
    f[name + "_cut.csv"] = cut_lines(stamped_csv(text), 40);
    f[name + "_cutfield.csv"] = stamped_csv(text).substr(0, stamped_csv(text).size() - 4);
    f[name + "_cols.csv"] = drop_last_field(text, 5);
    f[name + "_text.csv"] = set_field(text, 5, 2, "12,5");   // a decimal comma: one field too many
    f[name + "_word.csv"] = set_field(text, 5, 2, "left");
    f[name + "_nan.csv"] = set_field(text, 5, 3, "nan");
    f[name + "_inf.csv"] = set_field(text, 5, 3, "-inf");
    f[name + "_huge.csv"] = set_field(text, 5, 2, "1e300");
    f[name + "_crlf.csv"] = crlf(text);
    f[name + "_bom.csv"] = bom(text);
    f[name + "_dup.csv"] = insert_line(text, 5, lines_of(text)[3]);   // line 4 again as line 6
  }
  // Point ids no control point has: every id + 100000.
  {
    auto ls = lines_of(obs);
    for (std::size_t i = 1; i < ls.size(); ++i) {
      const auto a = ls[i].find(','), b = ls[i].find(',', a + 1);
      ls[i] = ls[i].substr(0, a + 1) + std::to_string(100000 + std::stol(ls[i].substr(a + 1, b - a - 1))) + ls[i].substr(b);
    }
    f["obs_unknown.csv"] = join(ls);
  }
  // The board observations naming two images of different sizes (a.png 64x48, b.png 80x60),
  // and naming an image that is a text file.
  f["obs_sizes.csv"] = replace_all(replace_all(obs, "board_00.jpg", "a.png"), "board_01.jpg", "b.png");
  f["obs_notimage.csv"] = replace_all(obs, "board_00.jpg", "notimage.png");
  // One view given twice: board_00.jpg's lines again under the name copy.jpg.
  {
    std::string copy;
    for (const auto& l : lines_of(obs)) {
      if (l.rfind("board_00.jpg,", 0) == 0) copy += replace_all(l, "board_00.jpg", "copy.jpg") + "\n";
    }
    f["obs_repeated.csv"] = obs + copy;
  }

  // Control points.
  f["ctl.csv"] = ctl;
  f["ctl_dup.csv"] = insert_line(ctl, 4, lines_of(ctl)[1]);
  f["ctl_huge.csv"] = set_field(ctl, 3, 1, "1e300");
  f["pctl.csv"] = pctl;
  f["pctl_dup.csv"] = insert_line(pctl, 4, lines_of(pctl)[1]);
  f["pctl_unknown.csv"] = "point_id,x_mm,y_mm,z_mm\n90000,0,0,0\n90001,10,0,0\n90002,0,10,0\n90003,10,10,0\n";

  // Tracks (triangulate): the part observations under a tracks header (columns go by name).
  f["tracks.csv"] = tracks;
  f["tracks_header.csv"] = header_only(tracks);
  f["tracks_trunc.csv"] = truncated_csv(tracks);
  f["tracks_cut.csv"] = cut_lines(stamped_csv(tracks), 40);
  f["tracks_cols.csv"] = drop_last_field(tracks, 5);
  f["tracks_word.csv"] = set_field(tracks, 5, 2, "left");
  f["tracks_nan.csv"] = set_field(tracks, 5, 3, "nan");
  f["tracks_huge.csv"] = set_field(tracks, 5, 2, "1e300");
  f["tracks_crlf.csv"] = crlf(tracks);
  f["tracks_bom.csv"] = bom(tracks);
  f["tracks_dup.csv"] = insert_line(tracks, 5, lines_of(tracks)[3]);

  // Cameras: the demo's, its CRLF and BOM twins, cut in the middle, and one for 1000 x 750 images.
  f["cam.yaml"] = cam;
  f["cam_crlf.yaml"] = crlf(cam);
  f["cam_trunc.yaml"] = cam.substr(0, cam.find("data:") + 12);
  f["cam_small.yaml"] = replace_all(replace_all(cam, "image_width: 2000", "image_width: 1000"), "image_height: 1500",
                                    "image_height: 750");
  f["cam_nan.yaml"] = replace_all(cam, "2400., 0., 999.5", "nan, 0., 999.5");
  f["cam_huge.yaml"] = replace_all(cam, "image_width: 2000", "image_width: 2000000000");
  f["cam_fx.yaml"] = replace_all(cam, "2400., 0., 999.5", "1e308, 0., 999.5");

  // Rigs (calib --rig's rig.yaml): the demo camera twice, as "left" and "right" (no photo of the
  // demo has those prefixes), and the same file cut before its second camera.
  {
    auto camera_block = [&](int k, const std::string& prefix, const std::string& tx) {
      std::string out = "camera_" + std::to_string(k) + "_prefix: \"" + prefix + "\"\n";
      for (const auto& l : lines_of(cam)) {
        if (l.empty() || l[0] == '%' || l[0] == '#' || l.rfind("---", 0) == 0) continue;
        out += (l[0] == ' ' ? "" : "camera_" + std::to_string(k) + "_") + l + "\n";
      }
      out += "camera_" + std::to_string(k) + "_cam_from_rig_rotation: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
             "   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\n";
      out += "camera_" + std::to_string(k) + "_cam_from_rig_translation_mm: !!opencv-matrix\n   rows: 3\n   cols: 1\n"
             "   dt: d\n   data: [ " + tx + ", 0., 0. ]\n";
      return out;
    };
    const std::string head = "%YAML:1.0\n---\nrig_cameras: 2\n";
    f["rig_lr.yaml"] = head + camera_block(0, "left", "0.") + camera_block(1, "right", "-100.");
    f["rig_cut.yaml"] = head + camera_block(0, "left", "0.");
  }

  // Point clouds (fitsurf).
  const std::string xyz = cloud_xyz();
  f["cloud.xyz"] = xyz;
  f["cloud_header.xyz"] = "x y z\n";
  f["cloud_cols.xyz"] = replace_line(xyz, 5, "5 20");
  f["cloud_word.xyz"] = replace_line(xyz, 5, "5 20 high");
  f["cloud_nan.xyz"] = replace_line(xyz, 5, "5 20 nan");
  f["cloud_huge.xyz"] = replace_line(xyz, 5, "1e300 20 0.5");
  f["cloud_crlf.xyz"] = crlf(xyz);
  f["cloud_bom.xyz"] = bom(xyz);
  const std::string ply = cloud_ply_binary();
  f["cloud.ply"] = ply;
  f["cloud_header.ply"] = ply_header(0, "binary_little_endian");
  f["cloud_trunc.ply"] = ply.substr(0, ply.size() / 2);
  f["cloud_crlf.ply"] = crlf(ply_header(lines_of(xyz).size(), "ascii") + xyz);
  f["cloud_bom.ply"] = bom(ply);

  // Surfaces (toolpath).
  const std::string surf = surface();
  f["part.surf"] = surf;
  f["part_header.surf"] = header_only(surf);
  f["part_trunc.surf"] = surf.substr(0, surf.find("pole 2 1"));
  f["part_cols.surf"] = replace_all(surf, "pole 1 1 -25 -16.666666666666668 30", "pole 1 1 -25 -16.666666666666668");
  f["part_word.surf"] = replace_all(surf, "pole 1 1 -25 -16.666666666666668 30", "pole 1 1 -25 -16.666666666666668 high");
  f["part_nan.surf"] = replace_all(surf, "pole 1 1 -25 -16.666666666666668 30", "pole 1 1 -25 -16.666666666666668 nan");
  f["part_huge.surf"] = replace_all(surf, "pole 1 1 -25 -16.666666666666668 30", "pole 1 1 -25 -16.666666666666668 1e300");
  f["part_crlf.surf"] = crlf(surf);
  f["part_bom.surf"] = bom(surf);
  f["part_dup.surf"] = replace_all(surf, "pole 1 2 ", "pole 1 1 ");
  f["part_unit.surf"] = replace_all(surf, "degrees 3 3\n", "units inch\ndegrees 3 3\n");
  f["part_arbitrary.surf"] = replace_all(surf, "degrees 3 3\n", "units arbitrary\ndegrees 3 3\n");
  f["junk.step"] = junk();
  f["empty.step"] = "";

  // CL data (clpost).
  const std::string apt = cl_apt();
  f["part.cl"] = apt;
  f["part_header.cl"] = "$$ photomill CL data v1: tool tip positions, mm\nPARTNO/handle\nUNITS/MM\nEND\nFINI\n";
  f["part_trunc.cl"] = apt.substr(0, apt.find("GOTO/-74.25") + 9);
  f["part_cut.cl"] = apt.substr(0, apt.find("12.375") + 4);  // inside the last GOTO's z, a valid number
  f["part_cols.cl"] = replace_all(apt, "GOTO/-74.25,-50,12.3125", "GOTO/-74.25,-50");
  f["part_word.cl"] = replace_all(apt, "GOTO/-74.25,-50,12.3125", "GOTO/-74.25,-50,high");
  f["part_nan.cl"] = replace_all(apt, "GOTO/-74.25,-50,12.3125", "GOTO/-74.25,-50,nan");
  f["part_huge.cl"] = replace_all(apt, "GOTO/-74.25,-50,12.3125", "GOTO/1e300,-50,12.3125");
  f["part_crlf.cl"] = crlf(apt);
  f["part_bom.cl"] = bom(apt);
  const std::string clcsv = cl_csv();
  f["part_cl.csv"] = clcsv;
  f["part_cl_header.csv"] = header_only(clcsv);
  f["part_cl_cols.csv"] = drop_last_field(clcsv, 3);
  f["part_cl_crlf.csv"] = crlf(clcsv);

  // Poses (match --poses): the demo's, and the same poses of images no observation names.
  const std::string poses = read_text(demo / "poses.csv");
  f["poses.csv"] = poses;
  f["poses_other.csv"] = replace_all(poses, "part_", "other_");
  f["poses_header.csv"] = header_only(poses);
  f["poses_nan.csv"] = set_field(poses, 3, 5, "nan");
  // Two photos that share no point: part_01.jpg's point ids + 100000.
  {
    std::string two = header_only(pobs);
    for (const auto& l : lines_of(pobs)) {
      if (l.rfind("part_00.jpg,", 0) == 0) two += l + "\n";
      if (l.rfind("part_01.jpg,", 0) != 0) continue;
      const auto a = l.find(','), b = l.find(',', a + 1);
      two += l.substr(0, a + 1) + std::to_string(100000 + std::stol(l.substr(a + 1, b - a - 1))) + l.substr(b) + "\n";
    }
    f["pobs_apart.csv"] = two;
  }

  // Feature files (match --refine lsm reads the photos they name): two keypoints each.
  auto feat = [](const std::string& image, int w, int h) {
    std::string t = "photomill-features v1\nimage " + image + "\nsize " + std::to_string(w) + " " + std::to_string(h) +
                    "\ncount 2\ndim 4\n";
    t += "20.5 20.25 4 10 0.1 1 2 3 4\n30 25 5 20 0.1 5 6 7 8\n";
    return t;
  };
  f["a.feat"] = feat("a.png", 64, 48);
  // a.png's features and observations from two runs of detect (issue #25: a run killed between renames).
  f["a_run.feat"] = replace_all(feat("a.png", 64, 48), "image a.png", "# photomill run=one\nimage a.png");
  f["obs_a_run.csv"] = "# photomill run=two rows=2\nimage,point_id,u_px,v_px\na.png,0,10,10\na.png,1,20,10\n";
  f["b_size.feat"] = feat("b.png", 64, 48);      // b.png is 80x60
  f["notimage.feat"] = feat("notimage.png", 64, 48);
  f["missing_image.feat"] = feat("missing.png", 64, 48);

  // Image lists on stdin (detect -).
  f["list_crlf.txt"] = crlf("a.png\nb.png\n");
  f["list_bom.txt"] = bom("a.png\nb.png\n");
  f["list_dup.txt"] = "a.png\na.png\n";

  for (const auto& [name, text] : f) std::ofstream(dir / name, std::ios::binary) << text;
  std::ofstream(dir / "huge.png", std::ios::binary) << png_claiming(100000, 100000);
  // 16000 x 16000 (256 Mpx) passed the old limit of 2^28 and made detect decode 2 GB (issue #25).
  std::ofstream(dir / "huge16k.png", std::ios::binary) << png_claiming(16000, 16000);

  // Images (detect, calib): two grey PNGs of different sizes, a PNG cut short, a JPEG cut short,
  // a text file named .png, an empty .png.
  cv::Mat a(48, 64, CV_8UC1, cv::Scalar(128)), b(60, 80, CV_8UC1, cv::Scalar(128));
  cv::imwrite((dir / "a.png").string(), a);
  cv::imwrite((dir / "b.png").string(), b);
  std::vector<uchar> buf;
  cv::imencode(".png", a, buf);
  std::ofstream(dir / "trunc.png", std::ios::binary).write(reinterpret_cast<const char*>(buf.data()),
                                                             static_cast<std::streamsize>(buf.size() / 2));
  cv::imencode(".jpg", a, buf);
  std::ofstream(dir / "trunc.jpg", std::ios::binary).write(reinterpret_cast<const char*>(buf.data()),
                                                             static_cast<std::streamsize>(buf.size() / 2));
  std::ofstream(dir / "notimage.png") << "image,point_id,u_px,v_px\n";
  std::ofstream(dir / "empty.png");
  std::ofstream(dir / "junk.png", std::ios::binary) << junk();

  // Unreadable: a folder where a file is expected (the test runs as root, for whom no mode bits
  // make a regular file unreadable).
  fs::create_directory(dir / "folder.csv");
  fs::create_directory(dir / "folder.png");
}

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) names.insert(fs::relative(e.path(), dir).string());
  return names;
}

// The file a row writes with -o / --output, if any.
std::string output_of(const std::vector<std::string>& args) {
  for (std::size_t i = 0; i + 1 < args.size(); ++i) {
    if (args[i] == "-o" || args[i] == "--output") return args[i + 1];
  }
  return "";
}

std::vector<Row> runnable_rows() {
  std::vector<Row> out;
  for (const auto& r : read_rows()) {
    if (r.exit != "n/a") out.push_back(r);
  }
  return out;
}

class ErrorsTable : public ::testing::TestWithParam<Row> {};

TEST_P(ErrorsTable, BinaryAnswersAsDocumented) {
  const Row& r = GetParam();
  TempDir dir;
  write_fixtures(dir.path());
  const auto before = listing(dir.path());
  // The arguments, with "< FILE" giving standard input from a fixture.
  std::vector<std::string> args{"-q"};
  std::string stdin_text;
  const auto words = split_args(r.args);
  for (std::size_t i = 0; i < words.size(); ++i) {
    if (words[i] == "<" && i + 1 < words.size()) {
      stdin_text = read_file(dir.path() / words[++i]);
    } else {
      args.push_back(words[i]);
    }
  }
  const ToolResult res = run_tool(r.binary, args, stdin_text, dir.path());

  ASSERT_TRUE(r.exit == "0" || r.exit == "1") << "exit column must be 0, 1 or n/a: " << r.exit;
  EXPECT_EQ(res.exit_code, std::stoi(r.exit)) << "stderr: " << res.err;
  EXPECT_EQ(res.out.empty(), !output_of(args).empty() || r.exit != "0") << "stdout: " << res.out.substr(0, 300);
  if (r.exit == "1") {
    // The one line it prints: exactly one line on stderr with -q, the documented one.
    ASSERT_FALSE(res.err.empty());
    EXPECT_EQ(res.err.find('\n'), res.err.size() - 1) << "more than one line on stderr:\n" << res.err;
    const std::string line = res.err.substr(0, res.err.find('\n'));
    EXPECT_TRUE(glob_match(line, r.message)) << "printed:    " << line << "\ndocumented: " << r.message;
    // Nothing left behind: not the output, not a temporary file.
    EXPECT_EQ(listing(dir.path()), before) << "a failed run left files behind";
  } else {
    EXPECT_EQ(res.err, "") << "an accepted input prints nothing with -q";
    const std::string out = output_of(args);
    if (!out.empty()) {
      EXPECT_TRUE(fs::is_regular_file(dir.path() / out)) << out << " was not written";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Rows, ErrorsTable, ::testing::ValuesIn(runnable_rows()),
                         [](const ::testing::TestParamInfo<Row>& info) {
                           return "line" + std::to_string(info.param.doc_line) + "_" + info.param.binary;
                         });

// Every binary answers every class of the list: a row that runs, or an 'n/a' row that
// says why the class does not apply to it.
TEST(ErrorsTableCoverage, EveryBinaryHasEveryClass) {
  const auto rows = read_rows();
  ASSERT_GT(rows.size(), 100u) << "docs/errors.md not found or not parsed";
  std::set<std::pair<std::string, std::string>> have;
  for (const auto& r : rows) {
    EXPECT_NE(std::find(kClasses.begin(), kClasses.end(), r.cls), kClasses.end())
        << "docs/errors.md:" << r.doc_line << ": unknown class '" << r.cls << "'";
    if (r.exit == "n/a") {
      EXPECT_FALSE(r.message.empty()) << "docs/errors.md:" << r.doc_line << ": n/a needs a reason";
    }
    have.insert({r.binary, r.cls});
  }
  for (const auto& b : kBinaries) {
    for (const auto& c : kClasses) EXPECT_TRUE(have.count({b, c})) << "no row for " << b << " / " << c;
  }
}

// Rows with exit 1 name their source first, as docs/formats.md says: "binary: FILE: ..." or
// "binary: FILE:LINE: ...", FILE a path with an extension (an argument, or a file an argument
// names, such as an image in the observations) or <stdin>.
TEST(ErrorsTableCoverage, FailuresNameTheirSource) {
  for (const auto& r : read_rows()) {
    if (r.exit != "1") continue;
    const std::string prefix = r.binary + ": ";
    ASSERT_EQ(r.message.rfind(prefix, 0), 0u) << "docs/errors.md:" << r.doc_line;
    const std::string rest = r.message.substr(prefix.size());
    const std::string source = rest.substr(0, rest.find(':'));
    const bool file = source == "<stdin>" || (source.find(' ') == std::string::npos &&
                                              (source.find('.') != std::string::npos || source.front() == '/'));
    EXPECT_TRUE(file) << "docs/errors.md:" << r.doc_line << ": the message does not begin with its source: " << r.message;
  }
}

// A run whose last output fails (a full disk: /dev/full) exits 1 and leaves every output of the
// previous run as it was, the ones it had already written complete included (issue #25: a
// failed triangulate left its new cloud.ply, so make saw a finished target; a failed detect
// deleted the previous run's feature files).
TEST(FailedRuns, LeaveEveryPreviousOutputAsItWas) {
  if (!fs::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full on this machine";
  TempDir dir;
  write_fixtures(dir.path());
  const std::string previous = "the previous run's content\n";
  struct Case {
    std::string binary;
    std::vector<std::string> args;
    std::vector<std::string> outputs;  // written by the run before its last output fails
  };
  const std::vector<Case> cases{
      {"triangulate", {"-c", "cam.yaml", "--control-points", "pctl.csv", "tracks.csv", "-o", "old.ply", "--poses", "old_poses.csv",
                       "--report", "/dev/full"}, {"old.ply", "old_poses.csv"}},
      {"calib", {"--control", "ctl.csv", "--image-size", "2000x1500", "obs.csv", "-o", "old.yaml", "--report", "/dev/full"},
       {"old.yaml"}},
      {"toolpath", {"part.surf", "-o", "old.cl", "--report", "/dev/full"}, {"old.cl"}},
      {"fitsurf", {"--net", "6x6", "cloud.xyz", "-o", "old.surf", "--step", "/dev/full"}, {"old.surf"}},
      {"detect", {"--features", "feats", "a.png", "b.png", "--aruco", "DICT_4X4_50", "-o", "/dev/full"},
       {"feats/a.png.feat", "feats/b.png.feat"}},
  };
  fs::create_directories(dir.path() / "feats");
  for (const auto& c : cases) {
    for (const auto& o : c.outputs) std::ofstream(dir.path() / o, std::ios::binary) << previous;
    const auto before = listing(dir.path());
    std::vector<std::string> args{"-q"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const ToolResult r = run_tool(c.binary, args, "", dir.path());
    EXPECT_EQ(r.exit_code, 1) << c.binary << ": " << r.err;
    EXPECT_NE(r.err.find("/dev/full"), std::string::npos) << c.binary << ": the failed write is not named: " << r.err;
    for (const auto& o : c.outputs) EXPECT_EQ(read_file(dir.path() / o), previous) << c.binary << " changed " << o;
    EXPECT_EQ(listing(dir.path()), before) << c.binary << " left files behind";
  }
  // The same runs with every output writable write them all.
  const ToolResult ok = run_tool("triangulate", {"-q", "-c", "cam.yaml", "--control-points", "pctl.csv", "tracks.csv",
                                                 "-o", "old.ply", "--poses", "old_poses.csv", "--report", "new.json"},
                                 "", dir.path());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_NE(read_file(dir.path() / "old.ply"), previous);
  EXPECT_TRUE(fs::is_regular_file(dir.path() / "new.json"));
}

}  // namespace
}  // namespace photomill::test
