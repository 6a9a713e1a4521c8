// The job report page (see report.hpp).
#include "report/report.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <filesystem>
#include <locale>
#include <map>
#include <sstream>

#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/tool.hpp"

namespace photomill::report {
namespace {

namespace fs = std::filesystem;

// A stage report larger than this is not one of photomill's (the largest, triangulate's on
// thousands of images, is a few MB).
constexpr std::size_t kMaxReportBytes = std::size_t{256} << 20;

std::string html(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

// RFC 4648 base64, for data: URIs.
std::string base64(const std::string& bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += kAlphabet[(v >> s) & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (two ? static_cast<unsigned char>(bytes[i + 1]) << 8 : 0u);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += two ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string value_text(const JsonValue& v) {
  switch (v.type) {
    case JsonValue::Type::Null: return "null";
    case JsonValue::Type::Boolean: return v.boolean ? "true" : "false";
    case JsonValue::Type::Number: return format_figure(v.number);
    case JsonValue::Type::String: return v.string;
    case JsonValue::Type::Array: return v.array.empty() ? "[]" : "";
    case JsonValue::Type::Object: return v.object.empty() ? "{}" : "";
  }
  return "";
}

// Every leaf of a report as (dotted path, value): arrays indexed, "per_image[3].rms_px".
void flatten(const JsonValue& v, const std::string& path, std::vector<std::pair<std::string, const JsonValue*>>& out) {
  if (v.type == JsonValue::Type::Object && !v.object.empty()) {
    for (const auto& [k, child] : v.object) flatten(child, path.empty() ? k : path + "." + k, out);
  } else if (v.type == JsonValue::Type::Array && !v.array.empty()) {
    for (std::size_t i = 0; i < v.array.size(); ++i) flatten(v.array[i], path + "[" + std::to_string(i) + "]", out);
  } else {
    out.emplace_back(path, &v);
  }
}

std::string anchor(const std::string& path) {
  std::string a;
  for (char c : path) a += std::isalnum(static_cast<unsigned char>(c)) ? c : '-';
  return a;
}

const char* kStyle = R"(
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1250px; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; }
td.v { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
.drawings { display: grid; grid-template-columns: repeat(auto-fill, minmax(360px, 1fr)); gap: 0.8em; }
.missing { color: #a40; } .warning { color: #a40; }
nav a { margin-right: 1em; } nav p { margin: 0.3em 0; }
)";

}  // namespace

const std::vector<Headline>& headlines() {
  static const std::vector<Headline> h = {
      {"calib.json", "rms_px", "calibration: reprojection RMS", "px"},
      {"calib.json", "points_used", "calibration: board corners used", ""},
      {"calib.json", "projection_sigma_px.corners", "calibration: projection sigma at the image corners", "px"},
      {"triangulate.json", "registered_images", "triangulation: images registered", ""},
      {"triangulate.json", "images", "triangulation: images", ""},
      {"triangulate.json", "points", "triangulation: points", ""},
      {"triangulate.json", "final_rms_px", "triangulation: final reprojection RMS", "px"},
      {"fitsurf.json", "selection.fitted_points", "surface: fitted points", ""},
      {"fitsurf.json", "surface.poles_u", "surface: poles along u", ""},
      {"fitsurf.json", "surface.poles_v", "surface: poles along v", ""},
      {"fitsurf.json", "residuals.rms_mm", "surface: residual RMS", "mm"},
      {"fitsurf.json", "residuals.p99_mm", "surface: residual 99th percentile", "mm"},
      {"fitsurf.json", "fit.outliers", "surface: outliers", ""},
      {"toolpath.json", "path.passes", "tool path: passes", ""},
      {"toolpath.json", "path.cl_points", "tool path: CL points", ""},
      {"toolpath.json", "path.feed_length_mm", "tool path: feed length", "mm"},
      {"toolpath.json", "path.rapid_length_mm", "tool path: rapid length", "mm"},
      {"toolpath.json", "gouges.points", "tool path: gouge points", ""},
      {"toolpath.json", "gouges.max_depth_mm", "tool path: deepest gouge", "mm"},
  };
  return h;
}

const std::vector<KnownFile>& known_reports() {
  static const std::vector<KnownFile> r = {
      {"calib.json", "calib", "the camera calibration (calib --report)", false, {"camera.yaml"}},
      {"triangulate.json", "triangulate", "the point cloud and the photos' poses (triangulate --report)", false,
       {"cloud.ply", "poses.csv", "camera-refined.yaml"}},
      {"fitsurf.json", "fitsurf", "the B-spline surface fitted to the cloud (fitsurf --report)", false, {"surface.txt"}},
      {"toolpath.json", "toolpath", "the finishing tool path (toolpath --report)", false, {"path.cl"}},
      {"markers/triangulate.json", "triangulate", "the markers-only cloud and poses (triangulate --report)", true,
       {"markers/cloud.ply", "markers/poses.csv"}},
      {"scan/fitsurf.json", "fitsurf", "the scan goal's surface (fitsurf --report)", true, {"scan/surface.txt"}},
      {"scan/toolpath.json", "toolpath", "the scan goal's tool path (toolpath --report)", true, {"scan/path.cl"}},
      {"cad/toolpath.json", "toolpath", "the cad goal's tool path (toolpath --report)", true, {"cad/path.cl"}},
  };
  return r;
}

const std::vector<KnownFile>& known_pictures() {
  static const std::vector<KnownFile> p = {
      {"calib.png", "calib", "calibration residuals over the image frame, magnified (calib --plot)"},
      {"cloud.png", "triangulate", "the point cloud and the cameras: an oblique view and a top view (triangulate --preview)"},
      {"surface.png", "fitsurf", "the fitted surface and each point's residual (fitsurf --preview)"},
      {"path.png", "toolpath", "the tool path from above, coloured by height, rapids, start and end (toolpath --preview)"},
      {"scan/path.png", "toolpath", "the scan goal's tool path (toolpath --preview)", true},
  };
  return p;
}

std::string format_figure(double value) {
  std::ostringstream s;
  s.imbue(std::locale::classic());
  if (std::isfinite(value) && std::abs(value) < 1e15 && value == std::round(value)) {
    s << static_cast<long long>(value);
  } else if (std::isfinite(value) && std::abs(value) >= 1e-4 && std::abs(value) < 1e12) {
    // 4 significant digits without an exponent: 10347.7 -> 10348, 0.0501597 -> 0.05016.
    const int magnitude = static_cast<int>(std::floor(std::log10(std::abs(value))));
    s << std::fixed;
    s.precision(std::max(0, 3 - magnitude));
    s << value;
  } else {
    s.precision(4);
    s << value;
  }
  return s.str();
}

namespace {

// The stage reports, by their path in the job folder.
using Reports = std::map<std::string, JsonValue>;

// A stage renames its outputs one after the other: a run killed between two renames leaves some
// from the run before. The report and the data files the same run writes must carry one run id
// (where both carry one: files from before run ids, or from other tools, are not checked).
void check_one_run(const fs::path& root, const KnownFile& k, const JsonValue& report) {
  const JsonValue* run = report.find("run_id");
  if (!run || run->type != JsonValue::Type::String) return;
  for (const std::string& out : k.outputs) {
    const fs::path p = root / out;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) continue;
    const auto id = tool::file_run_id(p.string());  // a read error names the file
    if (!id || *id == run->string) continue;
    throw InputError((root / k.path).string(), 0,
                     "made by another run of " + k.tool + " (" + run->string + ") than " + p.string() + " (" + *id +
                         "): a run was interrupted between the renames of its outputs; run " + k.tool + " again");
  }
}

// The reports: read and checked before anything is written; the main chain's that are absent
// go to `missing`.
Reports read_reports(const fs::path& root, std::vector<const KnownFile*>& missing) {
  std::error_code ec;
  Reports reports;
  for (const KnownFile& k : known_reports()) {
    const fs::path p = root / k.path;
    if (!fs::exists(p, ec)) {
      if (!k.optional) missing.push_back(&k);
      continue;
    }
    const std::string text = tool::read_all(p.string(), kMaxReportBytes);
    JsonValue v = parse_json(text, p.string());
    if (v.type != JsonValue::Type::Object) throw InputError(p.string(), 1, "not a stage report: expected a JSON object");
    const JsonValue* t = v.find("tool");
    if (!t || t->type != JsonValue::Type::String) throw InputError(p.string(), 1, "not a photomill report: no \"tool\" key");
    if (t->string != k.tool) {
      throw InputError(p.string(), 1, "the report of " + t->string + ", not of " + k.tool + " as its name says");
    }
    check_one_run(root, k, v);
    reports.emplace(k.path, std::move(v));
  }
  return reports;
}

// The pictures: complete PNG or JPEG files (read_image_file), embedded as they are.
struct Picture {
  std::string path, what, mime, data;
};

Picture load_picture(const fs::path& p, const std::string& rel, const std::string& what) {
  std::string bytes = read_image_file(p.string());
  const bool png = bytes.size() >= 8 && bytes.compare(1, 3, "PNG") == 0;
  const bool jpeg = bytes.size() >= 3 && bytes.compare(0, 3, "\xFF\xD8\xFF") == 0;
  if (!png && !jpeg) throw InputError(p.string(), 0, "not a PNG or JPEG picture");
  return Picture{rel, what, png ? "image/png" : "image/jpeg", base64(bytes)};
}

// The known pictures in the folder; the main chain's that are absent go to `missing`.
std::vector<Picture> read_pictures(const fs::path& root, std::vector<const KnownFile*>& missing) {
  std::error_code ec;
  std::vector<Picture> pictures;
  for (const KnownFile& k : known_pictures()) {
    const fs::path p = root / k.path;
    if (fs::exists(p, ec)) {
      pictures.push_back(load_picture(p, k.path, k.what));
    } else if (!k.optional) {
      missing.push_back(&k);
    }
  }
  return pictures;
}

// detect's drawings (drawings/*.jpg|png but the .tmp. files of a run in progress), by name.
std::vector<Picture> read_drawings(const fs::path& root) {
  std::error_code ec;
  std::vector<Picture> drawings;
  if (!fs::is_directory(root / "drawings", ec)) return drawings;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(root / "drawings", ec)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".jpg" || ext == ".png") && e.path().filename().string().find(".tmp.") == std::string::npos) {
      files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    drawings.push_back(load_picture(f, "drawings/" + f.filename().string(), "what detect found in " + f.stem().string()));
  }
  return drawings;
}

// Contents: a link to every section, picture and report.
void write_contents(std::ostream& o, const std::vector<Picture>& pictures, const std::vector<Picture>& drawings,
                    const Reports& reports) {
  o << "<nav><p><a href=\"#summary\">headline figures</a><a href=\"#pictures\">pictures</a>";
  if (!drawings.empty()) o << "<a href=\"#drawings\">drawings</a>";
  o << "<a href=\"#figures\">every figure</a></p>\n<p>pictures:";
  for (const auto* list : {&pictures, &drawings}) {
    for (const Picture& p : *list) o << " <a href=\"#" << anchor(p.path) << "\">" << html(p.path) << "</a>";
  }
  o << "</p>\n<p>reports:";
  for (const KnownFile& k : known_reports()) {
    if (reports.count(k.path)) o << " <a href=\"#" << anchor(k.path) << "\">" << html(k.path) << "</a>";
  }
  o << "</p></nav>\n";
}

// Headline figures, one table, grouped by report as headlines() lists them; then the warnings
// the stages wrote into their reports and the files missing.
void write_summary(std::ostream& o, const Reports& reports, const std::vector<const KnownFile*>& missing) {
  o << "<h2 id=\"summary\">Headline figures</h2>\n<table>\n<tr><th>figure</th><th>value</th><th>unit</th><th>from</th></tr>\n";
  for (const Headline& h : headlines()) {
    const auto r = reports.find(h.file);
    if (r == reports.end()) continue;
    const JsonValue* v = r->second.at(h.path);
    o << "<tr><td>" << html(h.label) << "</td>";
    if (v && v->is_number()) {
      o << "<td class=\"v\" data-json=\"" << html(h.file + ":" + h.path) << "\">" << format_figure(v->number) << "</td>";
    } else {
      o << "<td class=\"v missing\">" << (v ? html(value_text(*v)) : "not in the report") << "</td>";
    }
    o << "<td>" << html(h.unit) << "</td><td><a href=\"#" << anchor(h.file) << "\">" << html(h.file) << "</a> "
      << html(h.path) << "</td></tr>\n";
  }
  o << "</table>\n";
  std::vector<std::pair<std::string, std::string>> warnings;
  for (const auto& [file, v] : reports) {
    if (const JsonValue* w = v.find("warnings"); w && w->type == JsonValue::Type::Array) {
      for (const JsonValue& s : w->array) warnings.emplace_back(file, value_text(s));
    }
  }
  if (!warnings.empty()) {
    o << "<h3>Warnings</h3>\n<ul>\n";
    for (const auto& [file, text] : warnings) o << "<li class=\"warning\">" << html(file) << ": " << html(text) << "</li>\n";
    o << "</ul>\n";
  }
  if (!missing.empty()) {
    o << "<h3>Missing</h3>\n<ul>\n";
    for (const KnownFile* k : missing) {
      o << "<li class=\"missing\">" << html(k->path) << ": not in this folder (" << html(k->what) << ")</li>\n";
    }
    o << "</ul>\n";
  }
}

void write_figure(std::ostream& o, const Picture& p) {
  o << "<figure id=\"" << anchor(p.path) << "\"><img alt=\"" << html(p.path) << "\" src=\"data:" << p.mime << ";base64," << p.data
    << "\"><figcaption><b>" << html(p.path) << "</b>: " << html(p.what) << "</figcaption></figure>\n";
}

void write_pictures(std::ostream& o, const std::vector<Picture>& pictures, const std::vector<Picture>& drawings) {
  o << "<h2 id=\"pictures\">Pictures</h2>\n";
  if (pictures.empty()) o << "<p class=\"missing\">No picture in this folder.</p>\n";
  for (const Picture& p : pictures) write_figure(o, p);
  if (!drawings.empty()) {
    o << "<h2 id=\"drawings\">Drawings (detect --draw)</h2>\n<div class=\"drawings\">\n";
    for (const Picture& p : drawings) write_figure(o, p);
    o << "</div>\n";
  }
}

// Every figure of every report, one table each (folded).
void write_every_figure(std::ostream& o, const Reports& reports) {
  o << "<h2 id=\"figures\">Every figure of every report</h2>\n";
  for (const KnownFile& k : known_reports()) {
    const auto r = reports.find(k.path);
    if (r == reports.end()) continue;
    std::vector<std::pair<std::string, const JsonValue*>> rows;
    flatten(r->second, "", rows);
    o << "<details id=\"" << anchor(k.path) << "\"><summary><b>" << html(k.path) << "</b>: " << html(k.what) << ", "
      << rows.size() << " figures</summary>\n<table>\n";
    for (const auto& [path, v] : rows) {
      o << "<tr><td>" << html(path) << "</td><td" << (v->is_number() ? " class=\"v\"" : "") << ">" << html(value_text(*v))
        << "</td></tr>\n";
    }
    o << "</table></details>\n";
  }
}

}  // namespace

std::string build_report_html(const std::string& dir, const ReportOptions& options) {
  std::error_code ec;
  const auto status = fs::status(dir, ec);
  if (!fs::exists(status)) throw InputError(dir, 0, "cannot open: No such file or directory");
  if (!fs::is_directory(status)) throw InputError(dir, 0, "not a folder: give the job's output folder (OUT of Makefile.example)");
  const fs::path root(dir);

  std::vector<const KnownFile*> missing;
  const Reports reports = read_reports(root, missing);
  const std::vector<Picture> pictures = read_pictures(root, missing);
  const std::vector<Picture> drawings = options.drawings ? read_drawings(root) : std::vector<Picture>{};
  if (reports.empty() && pictures.empty() && drawings.empty()) {
    throw InputError(dir, 0,
                     "no photomill report or picture here (calib.json, triangulate.json, fitsurf.json, toolpath.json, "
                     "calib.png, cloud.png, surface.png, path.png, drawings/): give the job's output folder");
  }

  const std::string folder = fs::absolute(root).lexically_normal().filename().string().empty()
                                 ? fs::absolute(root).lexically_normal().parent_path().filename().string()
                                 : fs::absolute(root).lexically_normal().filename().string();
  const std::string title = options.title.empty() ? "photomill job report: " + folder : options.title;
  std::ostringstream o;
  o.imbue(std::locale::classic());
  o << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << html(title)
    << "</title>\n<style>" << kStyle << "</style>\n</head>\n<body>\n<h1>" << html(title) << "</h1>\n";
  write_contents(o, pictures, drawings, reports);
  write_summary(o, reports, missing);
  write_pictures(o, pictures, drawings);
  write_every_figure(o, reports);
  o << "</body>\n</html>\n";
  return o.str();
}

}  // namespace photomill::report
