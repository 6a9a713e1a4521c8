// cutsim: cuts a stock box with CL programs in turn (roughing, then finishing; each with the
// cutter its CL data names) on a z-map and says what is left against the surface: material left,
// gouges, rapids and plunges into material; a JSON report and a PNG picture on request.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "formats/cl_data.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"
#include "toolpath/cutsim.hpp"
#include "toolpath/input.hpp"

using namespace photomill;
using namespace photomill::toolpath;

int main(int argc, char** argv) {
  CutsimOptions o;
  std::string surface_path, box, report, picture;
  std::vector<std::string> cl_paths;
  std::optional<std::size_t> face;
  std::optional<double> diameter, corner;
  return tool::run(
      argc, argv,
      {"cutsim", "cut a stock box with CL programs in turn on a z-map; report material left, gouges, rapids and plunges into material",
       "cutsim part.surf rough.cl path.cl --picture cut.png --report cut.json"},
      [&](CLI::App& app) {
        app.add_option("surface", surface_path, "Surface: photomill surface text, STEP or IGES")->required();
        app.add_option("cl", cl_paths, "CL programs (APT or CSV) in the order they run")->required();
        app.add_option("--face", face, "Face of a STEP/IGES file, 0-based in file order (default 0)")->check(tool::finite_in(0, 1e6));
        app.add_option("--stock-box-mm", box, "Stock XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX, each within ±1e6 (default: the surface's box grown by --stock-margin-mm)");
        app.add_option("--stock-margin-mm", o.stock_margin_mm, "Default stock: this much around and above the surface")->capture_default_str()->check(tool::non_negative_up_to(1e4));
        app.add_option("--cell-mm", o.cell_mm, "Z-map grid spacing (> 0)")->capture_default_str()->check(tool::positive_up_to(100));
        app.add_option("--allowance-mm", o.allowance_mm, "Material meant to stay on the surface (0 after finishing)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--plunge-angle-deg", o.plunge_angle_deg, "A feed move going down into material more steeply than this is a plunge, (0, 90]")->capture_default_str()->check(tool::positive_up_to(90));
        app.add_option("--tool-diameter-mm", diameter, "Cutter of CL data without a CUTTER/TLDATA record (CSV)")->check(tool::positive_up_to(200));
        app.add_option("--corner-radius-mm", corner, "Its corner radius (default: a ball, half the diameter)")->check(tool::non_negative_up_to(100));
        app.add_option("--threads", o.threads, "Worker threads (0 = all cores)")->capture_default_str()->check(tool::non_negative_up_to(1024));
        app.add_option("--report", report, "Write a JSON report");
        app.add_option("--picture", picture, "Write a PNG top view of the material left");
      },
      [&] {
        if (!box.empty()) o.stock = parse_stock_box(box);
        std::vector<CutsimProgram> programs;
        for (const std::string& path : cl_paths) {
          const auto in = tool::open_input(path);
          CutsimProgram p{tool::source_name(path), read_cl(*in, tool::source_name(path)), {}};
          const double d = p.cl.tool_diameter_mm > 0 ? p.cl.tool_diameter_mm : diameter.value_or(0);
          const double rc = p.cl.tool_diameter_mm > 0 ? p.cl.tool_corner_radius_mm : corner.value_or(d / 2);
          p.cutter = {d / 2, rc};
          programs.push_back(std::move(p));
        }
        const LoadedSurface in = load_surface(surface_path, face);
        std::optional<log::Step> step(std::in_place, "cutting the stock");
        const CutsimResult r = simulate_cutting(in.surface, programs, o);
        step.reset();
        for (const std::string& line : cutsim_summary(r)) log::info(line);
        for (const CutsimProgramFigures& f : r.programs) {
          if (!f.first_fault.empty()) log::warn(f.name + ": " + f.first_fault);
        }
        if (r.max_gouge_mm > 1e-3) log::warn("a gouge of " + std::to_string(r.max_gouge_mm) + " mm below the surface");
        std::optional<tool::OutputFile> report_out, picture_out;
        if (!report.empty()) {
          report_out.emplace(report);
          write_cutsim_report(report_out->stream(), r, o);
        }
        if (!picture.empty()) {
          const auto png = render_cutsim_png(r, o.allowance_mm);
          picture_out.emplace(picture);
          picture_out->stream().write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
        }
        if (report_out) report_out->commit();
        if (picture_out) picture_out->commit();
      });
}
