// toolpath: iso-parametric ball-end finishing path on a B-spline surface (the paper's section 5).
// Reads a surface (photomill text, STEP or IGES; a file or '-'), writes CL data (APT or CSV) to
// stdout or -o; optionally a PNG preview, a JSON report and a z-map verification.
#include <map>

#include "formats/cl_data.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "toolpath/input.hpp"
#include "toolpath/preview.hpp"
#include "toolpath/report.hpp"
#include "toolpath/toolpath.hpp"
#include "toolpath/zmap.hpp"

using namespace photomill;
using namespace photomill::toolpath;

int main(int argc, char** argv) {
  ToolpathOptions o;
  std::string input = "-", output = "-", format = "apt", direction = "u", pattern = "zigzag", preview, report;
  std::optional<std::size_t> face;
  bool no_lift = false, verify = false;
  ZmapOptions zmap;
  return tool::run(
      argc, argv,
      {"toolpath", "ball-end finishing tool path (CL data) on a B-spline surface: iso-parametric passes, chord and scallop control, gouge-free",
       "toolpath --tool-radius-mm 3 --scallop-mm 0.01 --chord-tol-mm 0.005 part.surf | clpost -o part.ngc"},
      [&](CLI::App& app) {
        app.add_option("surface", input, "Surface: photomill surface text, STEP or IGES ('-' = stdin)")->capture_default_str();
        app.add_option("-o,--output", output, "CL data output ('-' = stdout)")->capture_default_str();
        app.add_option("--format", format, "CL data format")->check(CLI::IsMember({"apt", "csv"}))->capture_default_str();
        app.add_option("--face", face, "Face of a STEP/IGES file, 0-based in file order (default 0)");
        app.add_option("--tool-radius-mm", o.tool_radius_mm, "Ball-end radius R")->capture_default_str();
        app.add_option("--scallop-mm", o.scallop_mm, "Highest material left above the surface h (cusps and chords)")->capture_default_str();
        app.add_option("--chord-tol-mm", o.chord_tol_mm, "Chord tolerance e between CC points, below --scallop-mm")->capture_default_str();
        app.add_option("--gouge-tol-mm", o.gouge_tol_mm, "Deepest a straight move may dip into the surface")->capture_default_str();
        app.add_option("--stock-mm", o.stock_mm, "Allowance left on the surface (roughing)")->capture_default_str();
        app.add_option("--direction", direction, "Passes run along u (v constant) or v")->check(CLI::IsMember({"u", "v"}))->capture_default_str();
        app.add_option("--pattern", pattern, "zigzag: alternate directions, linked; oneway: retract after every pass")
            ->check(CLI::IsMember({"zigzag", "oneway"}))->capture_default_str();
        app.add_flag("--no-lift", no_lift, "Report gouges but do not lift the tool out of them");
        app.add_option("--max-step-mm", o.max_step_mm, "Longest forward step")->capture_default_str();
        app.add_option("--feed-mm-per-min", o.feed_mm_per_min, "Cutting feed")->capture_default_str();
        app.add_option("--plunge-feed-mm-per-min", o.plunge_feed_mm_per_min, "Feed down onto a pass")->capture_default_str();
        app.add_option("--safe-z-mm", o.safe_z_mm, "Rapid plane, tool tip (default: top of surface and path + --retract-mm)");
        app.add_option("--retract-mm", o.retract_mm, "Safe plane above the highest point")->capture_default_str();
        app.add_option("--clearance-mm", o.clearance_mm, "Rapid down to this height above a pass start, then feed")->capture_default_str();
        app.add_option("--ramp-angle-deg", o.ramp_angle_deg, "Enter a pass by a ramp back along it this steep, [0, 45] (0: straight down)")->capture_default_str();
        app.add_option("--drop-sample-mm", o.drop_sample_mm, "Drop-cutter surface sample spacing")->capture_default_str();
        app.add_option("--side-sample-mm", o.side_sample_mm, "Spacing along a pass of the side-step samples")->capture_default_str();
        app.add_option("--threads", o.threads, "Worker threads (0 = all cores)")->capture_default_str();
        app.add_option("--part-name", o.part_name, "PARTNO in the CL data")->capture_default_str();
        app.add_option("--spindle-rpm", o.spindle_rpm, "Spindle speed written to the CL data (SPINDL)");
        app.add_flag("--coolant", o.coolant, "Coolant on during the program (COOLNT)");
        app.add_option("--preview", preview, "Write a PNG top view of the path: x/y in mm, coloured by height, rapids, start and end");
        app.add_option("--report", report, "Write a JSON report (statistics, gouges, verification)");
        app.add_flag("--verify", verify, "Simulate the cut on a z-map; report max scallop and deepest gouge");
        app.add_option("--zmap-cell-mm", zmap.cell_mm, "Z-map grid spacing for --verify")->capture_default_str();
      },
      [&] {
        o.lift = !no_lift;
        o.direction = direction == "u" ? PassDirection::U : PassDirection::V;
        o.pattern = pattern == "zigzag" ? Pattern::ZigZag : Pattern::OneWay;
        validate(o);
        const LoadedSurface in = load_surface(input, face);
        log::debug("surface: degrees " + std::to_string(in.surface.degree_u) + " x " + std::to_string(in.surface.degree_v) +
                   ", " + std::to_string(in.surface.num_poles_u) + " x " + std::to_string(in.surface.num_poles_v) +
                   " poles, face " + std::to_string(in.face) + " of " + std::to_string(in.faces));
        std::optional<log::Step> step(std::in_place, "planning the passes and stepping along them");
        const ToolpathResult result = generate_toolpath(in.surface, o);
        std::optional<ZmapResult> checked;
        if (verify) {
          step.emplace("verifying the path on a z-map");
          zmap.tool_radius_mm = o.tool_radius_mm, zmap.stock_mm = o.stock_mm, zmap.threads = o.threads;
          checked = simulate_zmap(in.surface, result.cl, zmap);
        }
        step.reset();
        const ReportContext ctx{input, in.face, in.faces, &o, &result, checked ? &*checked : nullptr, direction, pattern};
        const auto lines = summary_lines(ctx);
        for (std::size_t k = 0; k < lines.size(); ++k) (k == 1 && !result.gouges.empty() ? log::warn : log::info)(lines[k]);

        tool::OutputFile cl_out(output);
        (format == "csv" ? write_cl_csv : write_cl_apt)(cl_out.stream(), result.cl);
        std::optional<tool::OutputFile> png_out, report_out;
        if (!preview.empty()) {
          const auto png = render_preview_png(in.surface, result);
          png_out.emplace(preview);
          png_out->stream().write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
        }
        if (!report.empty()) {
          report_out.emplace(report);
          write_report(report_out->stream(), ctx);
        }
        if (png_out) png_out->commit();
        if (report_out) report_out->commit();
        cl_out.commit();
      });
}
