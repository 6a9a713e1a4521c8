// The JSON reader (formats/json_value) and the job report (report/): the reader takes back what
// JsonWriter writes and names the line of what is wrong; the page holds every headline figure as
// the report has it, every picture byte for byte, names what is missing; bad input fails with one
// line naming the file, exit 1, and no page.
#include "report/report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/json.hpp"
#include "formats/json_value.hpp"
#include "tests/run_tool.hpp"

namespace photomill {
namespace {

namespace fs = std::filesystem;
using test::run_tool;
using test::TempDir;

// --- the JSON reader ----------------------------------------------------------------------------

TEST(JsonRead, TakesBackWhatTheWriterWrites) {
  std::ostringstream s;
  JsonWriter j(s);
  const double awkward = 0.1 + 0.2, tiny = 5e-324, big = 1.7976931348623157e308;
  j.begin_object().field("tool", "calib").field("rms_px", awkward).field("n", 42).field("ok", true);
  j.key("nested").begin_object().field("tiny", tiny).field("big", big).field("text", "a \"quoted\"\n\\ line é").end_object();
  j.key("list").begin_array().value(-1.5).value(std::numeric_limits<double>::quiet_NaN()).value("x").end_array();
  j.end_object();
  const JsonValue v = parse_json(s.str(), "mem.json");
  ASSERT_EQ(v.type, JsonValue::Type::Object);
  EXPECT_EQ(v.object.front().key, "tool") << "keys keep the file's order";
  EXPECT_EQ(v.find("tool")->string, "calib");
  EXPECT_EQ(v.find("rms_px")->number, awkward) << "numbers round-trip exactly";
  EXPECT_EQ(v.find("n")->number, 42);
  EXPECT_TRUE(v.find("ok")->boolean);
  EXPECT_EQ(v.at("nested.tiny")->number, tiny);
  EXPECT_EQ(v.at("nested.big")->number, big);
  EXPECT_EQ(v.at("nested.text")->string, "a \"quoted\"\n\\ line é");
  EXPECT_EQ(v.at("nested.none"), nullptr);
  EXPECT_EQ(v.at("tool.x"), nullptr) << "a path through a non-object";
  ASSERT_EQ(v.find("list")->array.size(), 3u);
  EXPECT_EQ(v.find("list")->array[0].number, -1.5);
  EXPECT_EQ(v.find("list")->array[1].type, JsonValue::Type::Null) << "NaN is written as null";
  EXPECT_EQ(parse_json(R"("\u00e9\ud83d\ude00")", "m").string, "\xC3\xA9\xF0\x9F\x98\x80") << "\\u escapes and a surrogate pair";
}

struct BadJson {
  const char* name;
  std::string text;
  std::size_t line;
  const char* message;
};
void PrintTo(const BadJson& c, std::ostream* os) { *os << c.name; }
class JsonReadBad : public ::testing::TestWithParam<BadJson> {};

TEST_P(JsonReadBad, NamesTheLineAndTheProblem) {
  const BadJson& c = GetParam();
  try {
    parse_json(c.text, "r.json");
    FAIL() << "accepted: " << c.text.substr(0, 40);
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "r.json");
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_NE(e.message().find(c.message), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cases, JsonReadBad,
    ::testing::Values(BadJson{"empty", "", 1, "empty file"}, BadJson{"blank", " \n\n", 3, "empty file"},
                      BadJson{"trailing_comma", "{\n\"a\": 1,\n}", 3, "expected a string key"},
                      BadJson{"missing_comma", "[1\n 2]", 2, "expected ',' or ']'"},
                      BadJson{"missing_colon", "{\"a\" 1}", 1, "expected ':' after the key \"a\""},
                      BadJson{"leading_zero", "{\"a\": 01}", 1, "leading zero"},
                      BadJson{"bare_word", "{\"a\": nan}", 1, "expected a value"},
                      BadJson{"cut_short", "{\"a\": [1, 2", 1, "found the end of the file"},
                      BadJson{"open_string", "\"abc", 1, "ends inside a string"},
                      BadJson{"control_char", "\"a\tb\"", 1, "control character"},
                      BadJson{"bad_escape", "\"a\\qb\"", 1, "unknown escape"},
                      BadJson{"lone_surrogate", "\"\\ud83d\"", 1, "surrogate"},
                      BadJson{"overflow", "1e999", 1, "beyond the range"},
                      BadJson{"after_value", "{}\n{}", 2, "after the JSON value"},
                      BadJson{"too_deep", std::string(kMaxJsonDepth + 5, '['), 1, "nested deeper"}),
    [](const auto& info) { return std::string(info.param.name); });

// --- the report page ----------------------------------------------------------------------------

TEST(ReportFigure, IntegersExactlyOthersToFourDigits) {
  EXPECT_EQ(report::format_figure(16482), "16482");
  EXPECT_EQ(report::format_figure(-3), "-3");
  EXPECT_EQ(report::format_figure(0.0501597067375946), "0.05016");
  EXPECT_EQ(report::format_figure(10347.738229122213), "10348");
  EXPECT_EQ(report::format_figure(15.279526874996318), "15.28");
  EXPECT_EQ(report::format_figure(-0.0622473), "-0.06225");
  EXPECT_EQ(report::format_figure(5.25e-4), "0.0005250");
  EXPECT_EQ(report::format_figure(3.2e-7), "3.2e-07");
}

std::string decode_base64(const std::string& s) {
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  unsigned bits = 0;
  int n = 0;
  for (char c : s) {
    if (c == '=') break;
    bits = (bits << 6) | static_cast<unsigned>(alphabet.find(c));
    n += 6;
    if (n >= 8) {
      n -= 8;
      out += static_cast<char>((bits >> n) & 0xFF);
    }
  }
  return out;
}

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

void write_png(const fs::path& p, int width, int height, cv::Scalar colour) {
  fs::create_directories(p.parent_path());
  ASSERT_TRUE(cv::imwrite(p.string(), cv::Mat(height, width, CV_8UC3, colour)));
}

// A job folder as Makefile.example leaves it, with small reports whose figures are awkward numbers.
struct Job {
  TempDir tmp;
  fs::path dir = tmp.path() / "job1";
  Job() {
    write(dir / "calib.json", R"({"tool":"calib","rms_px":0.0501597067375946,"points_used":240,
      "projection_sigma_px":{"centre":0.0256,"corners":15.279526874996318},"warnings":["k3 is poorly determined"]})");
    write(dir / "triangulate.json", R"({"tool":"triangulate","images":12,"registered_images":11,"points":17690,
      "final_rms_px":0.029126721660603483,"warnings":[]})");
    write(dir / "fitsurf.json", R"({"tool":"fitsurf","selection":{"fitted_points":7703},"surface":{"poles_u":75,"poles_v":50},
      "fit":{"outliers":21},"residuals":{"rms_mm":0.01703507408186929,"p99_mm":0.06224733741895046}})");
    write(dir / "toolpath.json", R"({"tool":"toolpath","path":{"passes":120,"cl_points":16482,
      "feed_length_mm":10347.738229122213,"rapid_length_mm":30.267695861150692},"gouges":{"points":0,"max_depth_mm":0}})");
    write_png(dir / "calib.png", 40, 30, {255, 0, 0});
    write_png(dir / "cloud.png", 50, 25, {0, 255, 0});
    write_png(dir / "surface.png", 30, 20, {0, 0, 255});
    write_png(dir / "path.png", 60, 30, {0, 255, 255});
    write_png(dir / "drawings" / "part_00.png", 20, 15, {9, 9, 9});
  }
};

// Every <img src="data:..."> of the page, decoded, by its alt text (the file's path).
std::map<std::string, std::string> images_of(const std::string& page) {
  std::map<std::string, std::string> out;
  const std::regex img(R"re(<img alt="([^"]*)" src="data:image/(png|jpeg);base64,([A-Za-z0-9+/=]*)")re");
  for (auto it = std::sregex_iterator(page.begin(), page.end(), img); it != std::sregex_iterator(); ++it) {
    out[(*it)[1]] = decode_base64((*it)[3]);
  }
  return out;
}

TEST(Report, HoldsEveryHeadlineFigureAndEveryPicture) {
  Job job;
  const fs::path page_path = job.tmp.path() / "report.html";
  const auto r = run_tool("report", {job.dir.string(), "-o", page_path.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "");
  const std::string page = test::read_file(page_path);
  // Each headline figure: the cell tagged with its report and key shows the report's value.
  std::size_t found = 0;
  for (const report::Headline& h : report::headlines()) {
    std::ifstream f(job.dir / h.file);
    const JsonValue v = read_json(f, h.file);
    const JsonValue* x = v.at(h.path);
    ASSERT_TRUE(x && x->is_number()) << h.file << " " << h.path;
    const std::regex cell("data-json=\"" + h.file + ":" + std::regex_replace(h.path, std::regex("\\."), "\\.") + "\">([^<]*)<");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(page, m, cell)) << h.file << ":" << h.path << " not on the page";
    const double shown = std::stod(m[1]);
    EXPECT_NEAR(shown, x->number, 5e-4 * std::abs(x->number)) << h.path;
    ++found;
  }
  EXPECT_EQ(found, report::headlines().size());
  EXPECT_NE(page.find("k3 is poorly determined"), std::string::npos) << "the reports' warnings";
  // Every picture, byte for byte.
  const auto images = images_of(page);
  for (const std::string name : {"calib.png", "cloud.png", "surface.png", "path.png", "drawings/part_00.png"}) {
    ASSERT_TRUE(images.count(name)) << name << " not embedded";
    EXPECT_EQ(images.at(name), test::read_file(job.dir / name)) << name;
  }
  EXPECT_EQ(images.size(), 5u);
  // The contents link every picture and every report, and every link lands on its anchor.
  const std::regex link("href=\"#([^\"]*)\"");
  std::set<std::string> targets;
  for (auto it = std::sregex_iterator(page.begin(), page.end(), link); it != std::sregex_iterator(); ++it) {
    targets.insert((*it)[1]);
    EXPECT_NE(page.find("id=\"" + std::string((*it)[1]) + "\""), std::string::npos) << "a link to nowhere: #" << (*it)[1];
  }
  EXPECT_GE(targets.size(), 5u + 4u + 4u) << "pictures, reports and sections linked";
  // Self-contained: nothing fetched from elsewhere.
  EXPECT_EQ(page.find("://"), std::string::npos);
  EXPECT_EQ(page.find("<script"), std::string::npos);
  EXPECT_EQ(page.find("<h3>Missing"), std::string::npos) << "nothing is missing here";
  // The page to stdout is the same page.
  const auto to_stdout = run_tool("report", {job.dir.string()});
  EXPECT_EQ(to_stdout.exit_code, 0);
  EXPECT_EQ(to_stdout.out, page);
}

TEST(Report, NamesWhatIsMissing) {
  Job job;
  fs::remove(job.dir / "fitsurf.json");
  fs::remove(job.dir / "path.png");
  const auto r = run_tool("report", {job.dir.string(), "--no-drawings"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("fitsurf.json: not in this folder"), std::string::npos);
  EXPECT_NE(r.out.find("path.png: not in this folder"), std::string::npos);
  EXPECT_EQ(r.out.find("data-json=\"fitsurf.json"), std::string::npos);
  EXPECT_NE(r.out.find("data-json=\"toolpath.json:path.passes\""), std::string::npos) << "the rest is there";
  EXPECT_EQ(images_of(r.out).count("drawings/part_00.png"), 0u) << "--no-drawings";
}

TEST(Report, TitleNamesThePageEscaped) {
  Job job;
  const auto plain = run_tool("report", {job.dir.string()});
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_NE(plain.out.find("<h1>photomill job report: " + job.dir.filename().string() + "</h1>"), std::string::npos);
  const auto titled = run_tool("report", {job.dir.string(), "--title", "Handle <B> & mould"});
  ASSERT_EQ(titled.exit_code, 0) << titled.err;
  EXPECT_NE(titled.out.find("<title>Handle &lt;B&gt; &amp; mould</title>"), std::string::npos);
  EXPECT_NE(titled.out.find("<h1>Handle &lt;B&gt; &amp; mould</h1>"), std::string::npos);
  EXPECT_EQ(titled.out.find("photomill job report:"), std::string::npos);
}

// Bad input: one line naming the file and the problem, exit 1, the previous page left as it was.
struct BadJob {
  const char* name;
  std::function<void(const fs::path&)> spoil;
  std::string message;  // "DIR" stands for the job folder
};
void PrintTo(const BadJob& c, std::ostream* os) { *os << c.name; }
class ReportFails : public ::testing::TestWithParam<BadJob> {};

TEST_P(ReportFails, OneLineNoPage) {
  const BadJob& c = GetParam();
  Job job;
  c.spoil(job.dir);
  const fs::path page = job.tmp.path() / "report.html";
  write(page, "the previous page");
  const auto entries = [&] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(job.tmp.path())) ++n;
    return n;
  };
  const std::size_t before = entries();
  const auto r = run_tool("report", {job.dir.string(), "-o", page.string()});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const std::string expected = "report: " + std::regex_replace(c.message, std::regex("DIR"), job.dir.string());
  EXPECT_EQ(r.err.substr(0, expected.size()), expected) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(test::read_file(page), "the previous page");
  EXPECT_EQ(entries(), before) << "a temporary file left beside the page";
}

INSTANTIATE_TEST_SUITE_P(
    Cases, ReportFails,
    ::testing::Values(
        BadJob{"bad_json", [](const fs::path& d) { write(d / "fitsurf.json", "{\"tool\": \"fitsurf\",\n\"a\": 1,\n}"); },
               "DIR/fitsurf.json:3: expected a string key in an object, found '}'"},
        BadJob{"another_stage", [](const fs::path& d) { write(d / "toolpath.json", R"({"tool":"fitsurf"})"); },
               "DIR/toolpath.json:1: the report of fitsurf, not of toolpath as its name says"},
        BadJob{"not_a_report", [](const fs::path& d) { write(d / "calib.json", "[1, 2]"); },
               "DIR/calib.json:1: not a stage report: expected a JSON object"},
        BadJob{"truncated_png",
               [](const fs::path& d) {
                 const std::string png = test::read_file(d / "cloud.png");
                 write(d / "cloud.png", png.substr(0, png.size() / 2));
               },
               "DIR/cloud.png: truncated PNG: the file ends before its IEND chunk"},
        // Issue #25: a stage's report and a data file of the same stage from two runs (a run
        // killed between the renames of its outputs).
        BadJob{"two_runs",
               [](const fs::path& d) {
                 write(d / "fitsurf.json", R"({"tool":"fitsurf","run_id":"run-a"})");
                 write(d / "surface.txt", "photomill-surface v1\n# photomill run=run-b\n");
               },
               "DIR/fitsurf.json: made by another run of fitsurf (run-a) than DIR/surface.txt (run-b): a run was "
               "interrupted between the renames of its outputs; run fitsurf again"},
        BadJob{"empty_folder", [](const fs::path& d) { fs::remove_all(d), fs::create_directories(d); },
               "DIR: no photomill report or picture here"},
        BadJob{"no_folder", [](const fs::path& d) { fs::remove_all(d); }, "DIR: cannot open: No such file or directory"}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Report, NoFolderIsBadUsage) {
  const auto r = run_tool("report", {});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("folder"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace photomill
