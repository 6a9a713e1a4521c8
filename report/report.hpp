// The job report (issue 27): one self-contained HTML page from a job's output folder (what
// Makefile.example writes in $(OUT)): the headline figures of each stage's JSON report in tables,
// their warnings, every picture (calib.png, cloud.png, surface.png, path.png, the drawings/ of
// detect) embedded as data: URIs, and every figure of every report in a table of its own. No
// script, no style sheet or font from elsewhere: the page opens without a network.
#pragma once

#include <string>
#include <vector>

#include "formats/json_value.hpp"

namespace photomill::report {

// One headline figure: where it is in which report, what it is called on the page, its unit.
struct Headline {
  std::string file;   // "calib.json", relative to the job folder
  std::string path;   // dotted key path inside it: "residuals.rms_mm"
  std::string label;  // "reprojection RMS"
  std::string unit;   // "px", "mm", "" for counts
};

// The headline figures the page shows (in this order), the stage reports it reads and the
// pictures it embeds, each relative to the job folder.
const std::vector<Headline>& headlines();
struct KnownFile {
  std::string path;     // "calib.json", "markers/triangulate.json", "path.png"
  std::string tool;     // the stage that writes it: its JSON report's "tool"
  std::string what;     // a caption: what it is and how it was made
  bool optional = false;  // made by a goal besides the main chain (markers/, scan/, cad/): not
                          // named as missing when absent
  std::vector<std::string> outputs = {};  // a report's: the data files the same run writes
};
const std::vector<KnownFile>& known_reports();
const std::vector<KnownFile>& known_pictures();

struct ReportOptions {
  std::string title;       // the page's title; empty: "photomill job report: <folder name>"
  bool drawings = true;    // embed drawings/*.jpg|png (a few MB for a dozen photos)
};

// A figure as the page writes it: an integer exactly, any other number to 4 significant digits
// without an exponent from 1e-4 to 1e12 (C locale: "0.05016", "15.28", "10348"); what the
// browser test reads back.
std::string format_figure(double value);

// The page for the job folder `dir`. A report or picture that is not there is named on the page
// as missing (with the stage and option that make it). Throws InputError naming the file and
// the problem for a folder that cannot be read or holds none of the known files, a report that
// is not JSON (file:line: problem) or is another stage's, and a picture that is not a complete
// PNG or JPEG.
std::string build_report_html(const std::string& dir, const ReportOptions& options = {});

}  // namespace photomill::report
