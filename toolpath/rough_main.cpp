// rough: z-level roughing of a stock box down to a B-spline surface plus an allowance, with a
// flat or bull-nose end mill (offset-contour area clearing, ramp or helix entries). Reads a
// surface (photomill text, STEP or IGES; a file or '-'), writes CL data (APT or CSV).
#include <cstdio>
#include <string>

#include "formats/cl_data.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"
#include "toolpath/input.hpp"
#include "toolpath/roughing.hpp"

using namespace photomill;
using namespace photomill::toolpath;

namespace {
std::string f3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}
}  // namespace

int main(int argc, char** argv) {
  RoughingOptions o;
  std::string input = "-", output = "-", format = "apt", direction = "climb";
  std::string box;
  std::optional<std::size_t> face;
  bool verify = false;
  std::vector<std::string> rest_after;
  double verify_cell_mm = 0.2;
  return tool::run(
      argc, argv,
      {"rough", "z-level roughing (CL data) of a stock box down to a B-spline surface plus an allowance, flat or bull-nose end mill",
       "rough --tool-diameter-mm 6 --step-down-mm 2 --allowance-mm 0.5 part.surf | clpost -o rough.ngc"},
      [&](CLI::App& app) {
        app.add_option("surface", input, "Surface: photomill surface text, STEP or IGES ('-' = stdin)")->capture_default_str();
        app.add_option("-o,--output", output, "CL data output ('-' = stdout)")->capture_default_str();
        app.add_option("--format", format, "CL data format")->check(CLI::IsMember({"apt", "csv"}))->capture_default_str();
        app.add_option("--face", face, "Face of a STEP/IGES file, 0-based in file order (default 0)")->check(tool::finite_in(0, 1e6));
        app.add_option("--tool-diameter-mm", o.tool_diameter_mm, "End mill diameter (> 0)")->capture_default_str()->check(tool::positive_up_to(200));
        app.add_option("--corner-radius-mm", o.corner_radius_mm, "Corner radius: 0 flat, up to half the diameter (bull-nose)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--step-down-mm", o.step_down_mm, "Depth between z levels (> 0)")->capture_default_str()->check(tool::positive_up_to(1000));
        app.add_option("--step-over-mm", o.step_over_mm, "Between offset contours, up to the tool radius (0: 40 % of the diameter)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--flat-tol-mm", o.flat_tol_mm, "A level at the top of each flat: tip heights within this over 2 % of the stock (0: none)")->capture_default_str()->check(tool::non_negative_up_to(1000));
        app.add_option("--allowance-mm", o.allowance_mm, "Material left on the surface for finishing (>= 0)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--stock-box-mm", box, "Stock XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX, each within ±1e6 (default: the surface's box grown by --stock-margin-mm)");
        app.add_option("--stock-margin-mm", o.stock_margin_mm, "Default stock: this much around and above the surface")->capture_default_str()->check(tool::non_negative_up_to(1e4));
        app.add_option("--direction", direction, "Milling direction with an M3 spindle")->check(CLI::IsMember({"climb", "conventional"}))->capture_default_str();
        app.add_option("--ramp-angle-deg", o.ramp_angle_deg, "Steepest entry ramp or helix, (0, 30]")->capture_default_str()->check(tool::positive_up_to(30));
        app.add_option("--helix-radius-mm", o.helix_radius_mm, "Helix entry radius (0: half the tool radius)")->capture_default_str()->check(tool::non_negative_up_to(100));
        app.add_option("--feed-mm-per-min", o.feed_mm_per_min, "Cutting feed")->capture_default_str()->check(tool::positive_up_to(1e6));
        app.add_option("--plunge-feed-mm-per-min", o.plunge_feed_mm_per_min, "Feed of ramps, helices and descents")->capture_default_str()->check(tool::positive_up_to(1e6));
        app.add_option("--retract-mm", o.retract_mm, "Safe plane above the stock top")->capture_default_str()->check(tool::positive_up_to(1e4));
        app.add_option("--clearance-mm", o.clearance_mm, "Rapid down to this height above the material, then feed")->capture_default_str()->check(tool::non_negative_up_to(1e4));
        app.add_option("--cell-mm", o.cell_mm, "Grid spacing of the part's height map (> 0)")->capture_default_str()->check(tool::positive_up_to(100));
        app.add_option("--simplify-mm", o.simplify_mm, "Path simplification tolerance (0: half a cell)")->capture_default_str()->check(tool::non_negative_up_to(400));
        app.add_option("--max-moves", o.max_moves, "Work limit: more CL moves than this is an error")->capture_default_str()->check(tool::finite_in(1, 1e10));
        app.add_option("--threads", o.threads, "Worker threads (0 = all cores)")->capture_default_str()->check(tool::non_negative_up_to(1024));
        app.add_option("--part-name", o.part_name, "PARTNO in the CL data")->capture_default_str();
        app.add_option("--spindle-rpm", o.spindle_rpm, "Spindle speed written to the CL data (SPINDL)")->check(tool::positive_up_to(1e6));
        app.add_flag("--coolant", o.coolant, "Coolant on during the program (COOLNT)");
        app.add_option("--rest-after", rest_after,
                       "Rest machining: clear only what this earlier CL program (APT, with its CUTTER) left of the stock; repeatable")
            ->allow_extra_args(false)
            ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
        app.add_option("--rest-min-mm", o.rest_min_mm, "Rest machining: material thinner than this above a level is left")
            ->capture_default_str()->check(tool::positive_up_to(100));
        app.add_flag("--verify", verify, "Cut the stock on a z-map; report material left and any cut into the allowance");
        app.add_option("--zmap-cell-mm", verify_cell_mm, "Z-map grid spacing for --verify")->capture_default_str()->check(tool::positive_up_to(100));
      },
      [&] {
        if (!box.empty()) o.stock = parse_stock_box(box);
        o.direction = direction == "climb" ? MillingDirection::Climb : MillingDirection::Conventional;
        for (const std::string& path : rest_after) {
          const auto in = tool::open_input(path);
          PriorCut prior;
          prior.cl = read_cl(*in, tool::source_name(path));
          if (!(prior.cl.tool_diameter_mm > 0)) {
            throw InputError(tool::source_name(path), 0,
                             "no tool size (no CUTTER record): rest machining needs the earlier program's cutter (APT CL data)");
          }
          prior.cutter = {prior.cl.tool_diameter_mm / 2, prior.cl.tool_corner_radius_mm};
          o.rest_after.push_back(std::move(prior));
        }
        validate(o);
        const LoadedSurface in = load_surface(input, face);
        std::optional<log::Step> step(std::in_place, "z-level roughing");
        const RoughingResult r = generate_roughing(in.surface, o);
        const RoughingStats& s = r.stats;
        step.reset();
        log::info(std::to_string(s.levels) + " levels (" + std::to_string(s.flat_levels) + " at flats) from z " + f3(s.top_level_mm) + " to " + f3(s.bottom_level_mm) + " mm, " +
                  std::to_string(s.loops) + " loops (" + std::to_string(s.ramps) + " ramp, " + std::to_string(s.helices) +
                  " helix, " + std::to_string(s.straight_entries) + " straight entries), feed " + f3(s.feed_length_mm) +
                  " mm, about " + f3(s.cycle_time_min) + " min at feed, " + f3(s.seconds) + " s");
        log::info("stock " + f3(s.stock.min_mm.x()) + "," + f3(s.stock.min_mm.y()) + "," + f3(s.stock.min_mm.z()) + " to " +
                  f3(s.stock.max_mm.x()) + "," + f3(s.stock.max_mm.y()) + "," + f3(s.stock.max_mm.z()) + " mm, step-over " +
                  f3(s.step_over_mm) + " mm, safe z " + f3(s.safe_z_mm) + " mm");
        if (!o.rest_after.empty()) {
          log::info("rest machining after " + std::to_string(o.rest_after.size()) + " program(s): material left at " +
                    std::to_string(s.rest_levels) + " of " + std::to_string(s.levels) + " levels");
        }
        if (s.skipped_loops > 0) {
          log::warn(std::to_string(s.skipped_loops) + " loops too narrow for a ramp or a helix were left uncut (material left there)");
        }
        if (verify) {
          step.emplace("cutting the stock on a z-map");
          std::vector<CutProgram> programs;
          for (const PriorCut& prior : o.rest_after) programs.push_back({&prior.cl, prior.cutter});
          programs.push_back({&r.cl, {o.tool_diameter_mm / 2, o.corner_radius_mm}});
          const StockCheck c = check_stock(in.surface, s.stock, programs, o.allowance_mm, verify_cell_mm, o.threads);
          step.reset();
          (c.max_into_allowance_mm > 1e-3 ? log::warn : log::info)(
              "verify: " + f3(c.cell_mm) + " mm z-map, " + std::to_string(c.nodes) + " nodes: material above surface + allowance p95 " +
              f3(c.p95_left_mm) + ", max " + f3(c.max_left_mm) + " mm; deepest cut into the allowance " + f3(c.max_into_allowance_mm) +
              " mm at " + f3(c.into_allowance_at.x()) + "," + f3(c.into_allowance_at.y()) + "; gouge " + f3(c.max_gouge_mm) + " mm");
        }
        tool::OutputFile out(output);
        (format == "csv" ? write_cl_csv : write_cl_apt)(out.stream(), r.cl);
        out.commit();
      });
}
