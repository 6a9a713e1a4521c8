// report: a job's output folder (Makefile.example's OUT) -> one self-contained HTML page with the
// stages' headline figures, every picture and every report figure (issue 27).
#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "formats/tool.hpp"
#include "report/report.hpp"

using namespace photomill;

int main(int argc, char** argv) {
  std::string folder, output = "-";
  report::ReportOptions o;
  bool no_drawings = false;
  return tool::run(
      argc, argv,
      {"report", "A job's output folder to one HTML page: headline figures, pictures, every report figure",
       "report out/job1 -o out/job1/report.html"},
      [&](CLI::App& app) {
        app.add_option("folder", folder, "The job's output folder (calib.json, cloud.png, ... as Makefile.example writes them)");
        app.add_option("-o,--output", output, "The HTML page ('-' = stdout)")->capture_default_str();
        app.add_option("--title", o.title, "The page's title (default: photomill job report: <folder name>)");
        app.add_flag("--no-drawings", no_drawings, "Leave out detect's drawings/ (the page is smaller)");
      },
      [&] {
        if (folder.empty()) throw UsageError("give the job's output folder (Makefile.example's OUT)");
        o.drawings = !no_drawings;
        const std::string page = report::build_report_html(folder, o);
        tool::OutputFile out(output);
        out.stream() << page;
        out.commit();
      });
}
