// toolpath: iso-parametric ball-end finishing path on a B-spline surface (the paper's section 5).
// Reads a surface (photomill text, STEP or IGES; a file or '-'), writes CL data (APT or CSV) to
// stdout or -o; optionally a PNG preview, a JSON report and a z-map verification.
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "formats/cl_data.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"
#include "formats/uncertainty.hpp"
#include "toolpath/input.hpp"
#include "toolpath/part.hpp"
#include "toolpath/preview.hpp"
#include "toolpath/report.hpp"
#include "toolpath/toolpath.hpp"
#include "toolpath/uncertain_stock.hpp"
#include "toolpath/zmap.hpp"

using namespace photomill;
using namespace photomill::toolpath;

namespace {

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

std::string box(const PartFace& f) {
  return "x " + fixed(f.min_mm.x(), 1) + ".." + fixed(f.max_mm.x(), 1) + " y " + fixed(f.min_mm.y(), 1) + ".." +
         fixed(f.max_mm.y(), 1) + " z " + fixed(f.min_mm.z(), 1) + ".." + fixed(f.max_mm.z(), 1) + " mm";
}

// --all-faces: the whole part in one program (toolpath/part.hpp), one line per face on stderr.
void run_part(const std::string& input, const std::string& output, const std::string& format, const std::string& report,
              const ToolpathOptions& o,
              PartToolpathOptions part_options, double mesh_tol_mm, std::optional<double> verify_cell_mm) {
  std::optional<log::Step> step(std::in_place, "reading the part and meshing it");
  const LoadedPart part = load_part(input, mesh_tol_mm, verify_cell_mm.has_value());
  step.emplace("machining its faces");
  log::info(std::to_string(part.faces.size()) + " faces, mesh of " + std::to_string(part.mesh.triangles.size()) +
            " triangles within " + fixed(mesh_tol_mm, 4) + " mm");
  part_options.toolpath = o;
  const PartToolpathResult r = generate_part_toolpath(part.faces, part.mesh, part.triangle_face, part_options, [&](const PartFace& f, std::size_t of) {
    const std::string head = "face " + std::to_string(f.index) + " of " + std::to_string(of) + " (" + box(f) + "): ";
    if (f.kind == PartFace::Kind::Wall) {
      log::warn(head + "vertical wall, not machined: a ball end from above cannot follow it (finish it with the side of an end mill)");
    } else if (f.kind == PartFace::Kind::Down) {
      log::info(head + "faces down, not machined (the part's underside or an undercut)");
    } else {
      log::info(head + std::to_string(f.stats.passes) + " passes, " + std::to_string(f.stats.cl_points) + " CL points, side step " +
                fixed(f.stats.min_side_step_mm, 3) + ".." + fixed(f.stats.max_side_step_mm, 3) + " mm");
      if (f.down_share > 0.01) {
        log::warn(head + fixed(100 * f.down_share, 1) + " % of it overhangs (faces down): a ball from above leaves it");
      }
      if (f.gouge_runs > 0) log::warn(head + std::to_string(f.gouge_runs) + " gouge runs against the face itself (lifted)");
    }
  });
  step.reset();
  log::info("part: " + std::to_string(r.machined) + " of " + std::to_string(r.faces.size()) + " faces machined (" +
            std::to_string(r.walls) + " vertical walls, " + std::to_string(r.down) + " facing down), " +
            std::to_string(r.cl.moves.size()) + " moves, feed path " + fixed(r.feed_length_mm, 1) + " mm, " +
            fixed(r.seconds, 1) + " s");
  log::info("whole-part check against all faces: " + std::to_string(r.mesh_lifted_points) + " CL points raised (by up to " +
            fixed(r.max_mesh_lift_mm, 4) + " mm), " + std::to_string(r.mesh_split_points) + " points added to moves");
  std::optional<PartZmapResult> checked;
  if (verify_cell_mm) {
    step.emplace("verifying the program on a z-map of the part");
    const PartZmapResult& z = checked.emplace( verify_part_zmap(part.mesh, part.triangle_face, r.faces, r.cl, o.tool_radius_mm, *verify_cell_mm, o.threads));
    step.reset();
    const auto at = [](const Eigen::Vector3d& p) { return "(" + fixed(p.x(), 2) + ", " + fixed(p.y(), 2) + ", " + fixed(p.z(), 2) + ")"; };
    (z.max_penetration_mm > o.gouge_tol_mm ? log::warn : log::info)(
        "swept ball against the part's mesh: deepest gouge " + fixed(z.max_penetration_mm, 4) + " mm" +
        (z.max_penetration_mm > 0 ? " at " + at(z.max_penetration_at) : "") + " (ball positions every " +
        fixed(z.penetration_step_mm, 2) + " mm)");
    log::info("z-map of the part's mesh (" + fixed(z.cell_mm, 3) + " mm cells, " + std::to_string(z.nodes) +
              " nodes on machined faces): gouge vertically " + fixed(z.max_gouge_mm, 4) + " mm" +
              (z.max_gouge_mm > 0 ? " at " + at(z.max_gouge_at) : "") + ", along the normal " + fixed(z.max_gouge_normal_mm, 4) +
              " mm; material left along the normal p95 " + fixed(z.p95_left_normal_mm, 4) + " mm, max " +
              fixed(z.max_left_normal_mm, 4) + " mm at " + at(z.max_left_normal_at) + " (vertically p95 " +
              fixed(z.p95_left_mm, 4) + ", max " + fixed(z.max_left_mm, 4) + " mm)");
  }
  tool::OutputFile cl_out(output);
  (format == "csv" ? write_cl_csv : write_cl_apt)(cl_out.stream(), r.cl);
  std::optional<tool::OutputFile> report_out;
  if (!report.empty()) {
    report_out.emplace(report);
    write_part_report(report_out->stream(), input, o, r, mesh_tol_mm, part.mesh.triangles.size(), checked ? &*checked : nullptr);
    report_out->commit();
  }
  cl_out.commit();
}

}  // namespace

int main(int argc, char** argv) {
  ToolpathOptions o;
  std::string input = "-", output = "-", format = "apt", direction = "u", pattern = "zigzag", preview, report;
  std::optional<std::size_t> face;
  bool no_lift = false, verify = false, all_faces = false;
  PartToolpathOptions part_options;
  double mesh_tol_mm = 0.0002;
  ZmapOptions zmap;
  std::string stock_file;
  std::optional<double> stock_k;
  return tool::run(
      argc, argv,
      {"toolpath", "ball-end finishing tool path (CL data) on a B-spline surface: iso-parametric passes, chord and scallop control, gouge-free",
       "toolpath --tool-radius-mm 3 --scallop-mm 0.01 --chord-tol-mm 0.005 part.surf | clpost -o part.ngc"},
      [&](CLI::App& app) {
        app.add_option("surface", input, "Surface: photomill surface text, STEP or IGES ('-' = stdin)")->capture_default_str();
        app.add_option("-o,--output", output, "CL data output ('-' = stdout)")->capture_default_str();
        app.add_option("--format", format, "CL data format")->check(CLI::IsMember({"apt", "csv"}))->capture_default_str();
        app.add_option("--face", face, "Face of a STEP/IGES file, 0-based in file order (default 0)")->check(tool::finite_in(0, 1e6));
        app.add_flag("--all-faces", all_faces,
                     "Machine the whole STEP/IGES part: every face that faces up, checked against all faces (walls and faces facing down are reported)");
        app.add_option("--mesh-tol-mm", mesh_tol_mm, "--all-faces: the part's mesh for the whole-part check is within this of the faces")
            ->capture_default_str()->check(tool::positive_up_to(1));
        app.add_option("--tool-radius-mm", o.tool_radius_mm, "Ball-end radius R")->capture_default_str()->check(tool::positive_up_to(kMaxToolRadiusMm));
        app.add_option("--scallop-mm", o.scallop_mm, "Highest material left above the surface h (cusps and chords)")->capture_default_str()->check(tool::positive_up_to(10));
        app.add_option("--chord-tol-mm", o.chord_tol_mm, "Chord tolerance e between CC points, below --scallop-mm")->capture_default_str()->check(tool::positive_up_to(10));
        app.add_option("--gouge-tol-mm", o.gouge_tol_mm, "Deepest a straight move may dip into the surface")->capture_default_str()->check(tool::positive_up_to(10));
        app.add_option("--stock-mm", o.stock_mm, "Allowance left on the surface (roughing)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--stock-uncertainty", stock_file,
                       "Uncertainty-aware stock: fitsurf --uncertainty's grid of the surface's height sigma; the path is "
                       "raised to stay above the surface offset up by --stock-sigma-k sigma, so a finishing pass leaves "
                       "material where the surface was poorly measured (docs/toolpath.md)");
        app.add_option("--stock-sigma-k", stock_k, "Sigmas of extra stock with --stock-uncertainty (default 2)")
            ->check(tool::non_negative_up_to(100));
        app.add_option("--direction", direction, "Passes run along u (v constant) or v")->check(CLI::IsMember({"u", "v"}))->capture_default_str();
        app.add_option("--pattern", pattern, "zigzag: alternate directions, linked; oneway: retract after every pass")
            ->check(CLI::IsMember({"zigzag", "oneway"}))->capture_default_str();
        app.add_flag("--no-lift", no_lift, "Report gouges but do not lift the tool out of them");
        app.add_option("--max-step-mm", o.max_step_mm, "Longest forward step")->capture_default_str()->check(tool::positive_up_to(1000));
        app.add_option("--feed-mm-per-min", o.feed_mm_per_min, "Cutting feed")->capture_default_str()->check(tool::positive_up_to(1e6));
        app.add_option("--plunge-feed-mm-per-min", o.plunge_feed_mm_per_min, "Feed down onto a pass")->capture_default_str()->check(tool::positive_up_to(1e6));
        app.add_option("--safe-z-mm", o.safe_z_mm, "Rapid plane, tool tip (default: top of surface and path + --retract-mm)")->check(tool::finite_in(-1e6, 1e6));
        app.add_option("--retract-mm", o.retract_mm, "Safe plane above the highest point")->capture_default_str()->check(tool::non_negative_up_to(1e4));
        app.add_option("--clearance-mm", o.clearance_mm, "Rapid down to this height above a pass start, then feed")->capture_default_str()->check(tool::non_negative_up_to(1e4));
        app.add_option("--ramp-angle-deg", o.ramp_angle_deg, "Enter a pass by a ramp back along it this steep, [0, 45] (0: straight down)")->capture_default_str()->check(tool::non_negative_up_to(45));
        app.add_option("--drop-sample-mm", o.drop_sample_mm, "Drop-cutter surface sample spacing")->capture_default_str()->check(tool::positive_up_to(100));
        app.add_option("--side-sample-mm", o.side_sample_mm, "Spacing along a pass of the side-step samples")->capture_default_str()->check(tool::positive_up_to(100));
        app.add_option("--max-cl-points", o.max_cl_points,
                       "Work limit: more CL points on the passes than this is an error (exit 1), not a run without end")
            ->capture_default_str()->check(tool::finite_in(1, 1e10));
        app.add_option("--threads", o.threads, "Worker threads (0 = all cores)")->capture_default_str()->check(tool::non_negative_up_to(1024));
        app.add_option("--part-name", o.part_name, "PARTNO in the CL data")->capture_default_str();
        app.add_option("--spindle-rpm", o.spindle_rpm, "Spindle speed written to the CL data (SPINDL)")->check(tool::positive_up_to(1e6));
        app.add_flag("--coolant", o.coolant, "Coolant on during the program (COOLNT)");
        app.add_option("--preview", preview, "Write a PNG top view of the path: x/y in mm, coloured by height, rapids, start and end");
        app.add_option("--report", report, "Write a JSON report (statistics, gouges, verification)");
        app.add_flag("--verify", verify, "Simulate the cut on a z-map; report max scallop and deepest gouge");
        app.add_option("--zmap-cell-mm", zmap.cell_mm, "Z-map grid spacing for --verify")->capture_default_str()->check(tool::positive_up_to(100));
      },
      [&] {
        o.lift = !no_lift;
        o.direction = direction == "u" ? PassDirection::U : PassDirection::V;
        o.pattern = pattern == "zigzag" ? Pattern::ZigZag : Pattern::OneWay;
        validate(o);
        if (stock_k && stock_file.empty()) throw UsageError("--stock-sigma-k needs --stock-uncertainty FILE");
        if (all_faces) {
          if (!stock_file.empty()) throw UsageError("--stock-uncertainty is not available with --all-faces");
          if (face) throw UsageError("--face and --all-faces exclude each other");
          if (!preview.empty()) throw UsageError("--preview is not available with --all-faces yet");
          if (!(mesh_tol_mm > 0) || !(mesh_tol_mm < o.gouge_tol_mm)) throw UsageError("--mesh-tol-mm must be > 0 and below --gouge-tol-mm");
          return run_part(input, output, format, report, o, part_options, mesh_tol_mm,
                          verify ? std::optional<double>(zmap.cell_mm) : std::nullopt);
        }
        std::optional<UncertaintyGrid> stock_grid;
        if (!stock_file.empty()) {
          std::ifstream f(stock_file, std::ios::binary);
          if (!f) throw InputError(stock_file, 0, "cannot open");
          stock_grid = read_uncertainty_grid(f, stock_file);
        }
        const LoadedSurface in = load_surface(input, face);
        log::debug("surface: degrees " + std::to_string(in.surface.degree_u) + " x " + std::to_string(in.surface.degree_v) +
                   ", " + std::to_string(in.surface.num_poles_u) + " x " + std::to_string(in.surface.num_poles_v) +
                   " poles, face " + std::to_string(in.face) + " of " + std::to_string(in.faces));
        std::optional<log::Step> step(std::in_place, "planning the passes and stepping along them");
        // Uncertainty-aware stock: the path is made on the surface offset up by k sigma.
        std::optional<UncertainStockStats> stock;
        std::optional<BSplineSurface> offset;
        if (stock_grid) {
          stock.emplace();
          offset = offset_by_uncertainty(in.surface, *stock_grid, stock_k.value_or(2), o.scallop_mm, &*stock);
          log::info("uncertainty-aware stock (" + fixed(stock->k, 2) + " sigma, sigma up to " + fixed(stock->sigma_max_mm, 4) +
                    " mm): the surface raised by up to " + fixed(stock->max_mm, 4) + " mm, " + fixed(stock->mean_mm, 4) +
                    " mm on average; more than the scallop height over " + fixed(stock->area_mm2, 0) + " mm^2");
        }
        const BSplineSurface& machined = offset ? *offset : in.surface;
        const ToolpathResult result = generate_toolpath(machined, o);
        std::optional<ZmapResult> checked;
        if (verify) {
          step.emplace("verifying the path on a z-map");
          zmap.tool_radius_mm = o.tool_radius_mm, zmap.stock_mm = o.stock_mm, zmap.threads = o.threads;
          checked = simulate_zmap(machined, result.cl, zmap);
        }
        step.reset();
        const ReportContext ctx{input, in.face, in.faces, &o, &result, checked ? &*checked : nullptr, direction, pattern,
                                stock ? &*stock : nullptr, stock_file};
        const auto lines = summary_lines(ctx);
        for (std::size_t k = 0; k < lines.size(); ++k) (k == 1 && !result.gouges.empty() ? log::warn : log::info)(lines[k]);

        tool::OutputFile cl_out(output);
        (format == "csv" ? write_cl_csv : write_cl_apt)(cl_out.stream(), result.cl);
        std::optional<tool::OutputFile> png_out, report_out;
        if (!preview.empty()) {
          PreviewOptions po;
          if (stock_grid) po.stock = &*stock_grid, po.stock_k = stock->k, po.stock_threshold_mm = o.scallop_mm;
          const auto png = render_preview_png(machined, result, po);
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
