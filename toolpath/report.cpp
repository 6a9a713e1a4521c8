#include "toolpath/report.hpp"

#include <cmath>
#include <sstream>

#include "formats/run.hpp"
#include "formats/json.hpp"

namespace photomill::toolpath {
namespace {

void xyz(JsonWriter& j, std::string_view key, const Eigen::Vector3d& p) {
  j.key(key).begin_array().value(p.x()).value(p.y()).value(p.z()).end_array();
}

std::string fmt(double v, int precision = 4) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

std::string point(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(3);
  s << '(' << p.x() << ", " << p.y() << ", " << p.z() << ')';
  return s.str();
}

// The tolerances both reports start their options with.
void tolerance_fields(JsonWriter& j, const ToolpathOptions& o) {
  j.field("tool_radius_mm", o.tool_radius_mm);
  j.field("scallop_mm", o.scallop_mm);
  j.field("chord_tol_mm", o.chord_tol_mm);
  j.field("gouge_tol_mm", o.gouge_tol_mm);
  j.field("stock_mm", o.stock_mm);
}

}  // namespace

void write_report(std::ostream& out, const ReportContext& c) {
  const ToolpathOptions& o = *c.options;
  const ToolpathResult& r = *c.result;
  const ToolpathStats& s = r.stats;
  JsonWriter j(out);
  j.begin_object();
  j.field("tool", "toolpath");
  j.field("run_id", run_id());
  j.field("version", PHOTOMILL_VERSION);
  j.field("input", c.input);
  j.field("face", c.face);
  j.field("faces", c.faces);
  j.key("options").begin_object();
  tolerance_fields(j, o);
  j.field("direction", c.direction);
  j.field("pattern", c.pattern);
  j.field("lift", o.lift);
  j.field("max_step_mm", o.max_step_mm);
  j.field("feed_mm_per_min", o.feed_mm_per_min);
  j.field("plunge_feed_mm_per_min", o.plunge_feed_mm_per_min);
  j.field("safe_z_mm", s.safe_z_mm);
  j.field("drop_sample_mm", o.drop_sample_mm);
  j.end_object();
  j.key("path").begin_object();
  j.field("passes", s.passes);
  j.field("edge_passes", s.edge_passes);
  j.field("segments", s.segments);
  j.field("cl_points", s.cl_points);
  j.field("moves", s.moves);
  j.field("feed_length_mm", s.feed_length_mm);
  j.field("rapid_length_mm", s.rapid_length_mm);
  j.field("retracts", s.retracts);
  j.field("min_side_step_mm", s.min_side_step_mm);
  j.field("max_side_step_mm", s.max_side_step_mm);
  j.field("min_forward_step_mm", s.min_forward_step_mm);
  j.field("max_forward_step_mm", s.max_forward_step_mm);
  j.field("max_chord_error_mm", s.max_chord_error_mm);
  j.field("max_ball_dip_mm", s.max_ball_dip_mm);
  j.field("seconds", s.seconds);
  j.end_object();
  j.key("gouges").begin_object();
  j.field("points", s.gouge_points);
  j.field("max_depth_mm", s.max_gouge_depth_mm);
  j.field("lifted", o.lift);
  j.key("runs").begin_array();
  for (const GougeRun& g : r.gouges) {
    j.begin_object();
    j.field("pass", g.pass);
    j.field("points", g.points);
    xyz(j, "first_cc", g.first_cc);
    xyz(j, "last_cc", g.last_cc);
    xyz(j, "deepest_contact", g.deepest_contact);
    j.field("max_depth_mm", g.max_depth_mm);
    j.field("min_concave_radius_mm", g.min_concave_radius_mm);  // null when not concave
    j.field("lifted", g.lifted);
    j.end_object();
  }
  j.end_array();
  j.end_object();
  // Uncertainty-aware stock (uncertain_stock.hpp); null when off.
  j.key("uncertainty_stock");
  if (c.stock != nullptr) {
    const UncertainStockStats& u = *c.stock;
    j.begin_object();
    j.field("file", c.stock_file);
    j.field("k", u.k);
    j.field("sigma_max_mm", u.sigma_max_mm);
    j.field("max_mm", u.max_mm);
    j.field("mean_mm", u.mean_mm);
    j.field("area_mm2", u.area_mm2);
    j.field("area_threshold_mm", u.threshold_mm);
    j.end_object();
  } else {
    j.null();
  }
  if (c.verify) {
    const ZmapResult& z = *c.verify;
    j.key("verify").begin_object();
    j.field("cell_mm", z.cell_mm);
    j.field("nodes", z.nodes);
    j.field("unmachined_nodes", z.unmachined);
    j.field("max_scallop_mm", z.max_scallop_mm);
    xyz(j, "max_scallop_at", z.max_scallop_at);
    j.field("grid_max_scallop_mm", z.grid_max_scallop_mm);
    j.field("max_gouge_mm", z.max_gouge_mm);
    xyz(j, "max_gouge_at", z.max_gouge_at);
    j.field("grid_max_gouge_mm", z.grid_max_gouge_mm);
    j.field("max_excess_z_mm", z.max_excess_z_mm);
    j.field("seconds", z.seconds);
    j.end_object();
  }
  j.end_object();
  out << "\n";
}

std::vector<std::string> summary_lines(const ReportContext& c, std::size_t max_gouges) {
  const ToolpathResult& r = *c.result;
  const ToolpathStats& s = r.stats;
  std::vector<std::string> lines;
  lines.push_back(std::to_string(s.passes) + " passes" +
                  (s.edge_passes > 0 ? " + " + std::to_string(s.edge_passes) + " along slanted edges" : std::string()) + ", " +
                  std::to_string(s.cl_points) + " CL points, feed path " +
                  fmt(s.feed_length_mm, 1) + " mm, side step " + fmt(s.min_side_step_mm, 3) + ".." +
                  fmt(s.max_side_step_mm, 3) + " mm, chord error <= " + fmt(s.max_chord_error_mm, 5) + " mm, " +
                  fmt(s.seconds, 3) + " s");
  if (!r.gouges.empty()) {
    lines.push_back(std::to_string(s.gouge_points) + " CL points in " + std::to_string(r.gouges.size()) +
                    " places would gouge the surface (deepest " + fmt(s.max_gouge_depth_mm, 4) + " mm); " +
                    (c.options->lift ? "the tool was lifted clear" : "NOT lifted (--no-lift): this path cuts into the part"));
    for (std::size_t k = 0; k < r.gouges.size() && k < max_gouges; ++k) {
      const GougeRun& g = r.gouges[k];
      std::string why = std::isfinite(g.min_concave_radius_mm) && g.min_concave_radius_mm < c.options->tool_radius_mm + c.options->stock_mm
                            ? "concave radius " + fmt(g.min_concave_radius_mm, 3) + " mm < tool radius"
                            : "ball touches the surface away from the contact point";
      lines.push_back("  gouge on pass " + std::to_string(g.pass) + " from " + point(g.first_cc) + " to " +
                      point(g.last_cc) + ": depth " + fmt(g.max_depth_mm, 4) + " mm, " + why + ", contact at " +
                      point(g.deepest_contact));
    }
    if (r.gouges.size() > max_gouges) {
      lines.push_back("  ... and " + std::to_string(r.gouges.size() - max_gouges) + " more (see --report)");
    }
  }
  if (c.verify) {
    const ZmapResult& z = *c.verify;
    lines.push_back("z-map (" + fmt(z.cell_mm, 3) + " mm cells, " + std::to_string(z.nodes) + " nodes): max scallop " +
                    fmt(z.max_scallop_mm, 5) + " mm at " + point(z.max_scallop_at) + ", deepest gouge " +
                    fmt(z.max_gouge_mm, 5) + " mm" + (z.max_gouge_mm > 0 ? " at " + point(z.max_gouge_at) : "") +
                    (z.unmachined > 0 ? ", " + std::to_string(z.unmachined) + " nodes not reached" : ""));
  }
  return lines;
}

void write_part_report(std::ostream& out, const std::string& input, const ToolpathOptions& o,
                       const PartToolpathResult& r, double mesh_tol_mm, std::size_t mesh_triangles,
                       const PartZmapResult* z) {
  JsonWriter j(out);
  j.begin_object();
  j.field("tool", "toolpath");
  j.field("run_id", run_id());
  j.field("version", PHOTOMILL_VERSION);
  j.field("input", input);
  j.field("all_faces", true);
  j.key("options").begin_object();
  tolerance_fields(j, o);
  j.field("mesh_tol_mm", mesh_tol_mm);
  j.field("safe_z_mm", r.safe_z_mm);
  j.end_object();
  j.key("faces").begin_array();
  for (const PartFace& f : r.faces) {
    j.begin_object();
    j.field("face", f.index);
    j.field("kind", f.kind == PartFace::Kind::Machined ? "machined" : f.kind == PartFace::Kind::Wall ? "wall" : "down");
    j.field("area_mm2", f.area_mm2);
    j.field("up_share", f.up_share);
    j.field("down_share", f.down_share);
    xyz(j, "min_mm", f.min_mm);
    xyz(j, "max_mm", f.max_mm);
    if (f.kind == PartFace::Kind::Machined) {
      j.field("passes", f.stats.passes);
      j.field("cl_points", f.stats.cl_points);
      j.field("min_side_step_mm", f.stats.min_side_step_mm);
      j.field("max_side_step_mm", f.stats.max_side_step_mm);
      j.field("max_chord_error_mm", f.stats.max_chord_error_mm);
      j.field("gouge_runs", f.gouge_runs);
      j.field("seconds", f.stats.seconds);
    }
    j.end_object();
  }
  j.end_array();
  j.key("path").begin_object();
  j.field("machined_faces", r.machined);
  j.field("wall_faces", r.walls);
  j.field("down_faces", r.down);
  j.field("cl_points", r.cl_points);
  j.field("moves", r.cl.moves.size());
  j.field("feed_length_mm", r.feed_length_mm);
  j.field("rapid_length_mm", r.rapid_length_mm);
  j.field("seconds", r.seconds);
  j.end_object();
  j.key("whole_part_check").begin_object();
  j.field("mesh_triangles", mesh_triangles);
  j.field("lifted_points", r.mesh_lifted_points);
  j.field("max_lift_mm", r.max_mesh_lift_mm);
  j.field("added_points", r.mesh_split_points);
  j.end_object();
  j.key("verify");
  if (z) {
    j.begin_object();
    j.field("cell_mm", z->cell_mm);
    j.field("nodes", z->nodes);
    j.field("max_penetration_mm", z->max_penetration_mm);
    xyz(j, "max_penetration_at", z->max_penetration_at);
    j.field("penetration_step_mm", z->penetration_step_mm);
    j.field("max_gouge_vertical_mm", z->max_gouge_mm);
    xyz(j, "max_gouge_vertical_at", z->max_gouge_at);
    j.field("max_gouge_normal_mm", z->max_gouge_normal_mm);
    j.field("p95_left_normal_mm", z->p95_left_normal_mm);
    j.field("max_left_normal_mm", z->max_left_normal_mm);
    xyz(j, "max_left_normal_at", z->max_left_normal_at);
    j.field("p95_left_vertical_mm", z->p95_left_mm);
    j.field("max_left_vertical_mm", z->max_left_mm);
    j.end_object();
  } else {
    j.null();
  }
  j.end_object();
  out << "\n";
}

}  // namespace photomill::toolpath
