#include "toolpath/toolpath.hpp"

#include <algorithm>
#include <atomic>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>
#include <vector>

#include "formats/error.hpp"
#include "toolpath/forward_step.hpp"
#include "geometry/parallel.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void require(bool ok, const std::string& message) {
  if (!ok) throw UsageError(message);
}

std::string mm(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// One machined piece of a pass line, as planned before marching.
struct WorkItem {
  std::size_t line;          // pass index (lines, then edge passes)
  PassDirection direction;   // of the curve
  double w;                  // its fixed parameter
  double t_from, t_to;
};

// Passes that meet a domain edge t = t_end at a slant leave, between their ends, slivers that
// only the end positions of the balls cover: there neighbouring ends are g / sin(angle) apart,
// and the cusp grows as the square of that. Such an edge gets a pass of its own (along the
// other parameter) when sin(angle) < kEdgeSin somewhere, i.e. when the cusps there would grow by
// more than 1 / 0.99^2 - 1 = 2 %.
constexpr double kEdgeSin = 0.99;

// A surface whose projection onto the xy plane is below this share of its area (sin of about
// 1.1 degrees from vertical on average) is a vertical wall: no pass from above follows it.
constexpr double kWallShare = 0.02;

bool edge_is_slanted(const BSplineSurface& s, PassDirection dir, double t_end, const std::vector<PassLine>& lines) {
  for (const PassLine& line : lines) {
    const Eigen::Vector2d uv = dir == PassDirection::U ? Eigen::Vector2d(t_end, line.w) : Eigen::Vector2d(line.w, t_end);
    const SurfaceDerivatives d = surface_derivatives(s, uv.x(), uv.y());
    const Eigen::Vector3d st = dir == PassDirection::U ? d.su : d.sv, sw = dir == PassDirection::U ? d.sv : d.su;
    // An edge collapsed to a point (|sw| ~ 0: rounding noise) has no length to cover.
    if (!(sw.norm() > 1e-9 * st.norm())) continue;
    if (st.cross(sw).norm() / (st.norm() * sw.norm()) < kEdgeSin) return true;
  }
  return false;
}

// Points of a straight zig-zag link from tip a to tip b, each raised to the drop-cutter height
// where the straight line would cut in; spaced so that the sag of each piece over a ball of
// radius r stays within the gouge tolerance: l = sqrt(8 r tol) / 2 (half the chord of sagitta tol).
std::vector<Eigen::Vector3d> link_points(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const DropCutter& drop,
                                         double tool_radius_mm, double gouge_tol_mm) {
  const double r = drop.ball_radius_mm();
  const double piece = 0.5 * std::sqrt(8 * r * gouge_tol_mm);
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).head<2>().norm() / piece)));
  std::vector<Eigen::Vector3d> out;
  for (int k = 1; k <= n; ++k) {
    Eigen::Vector3d q = a + (b - a) * (static_cast<double>(k) / n);
    if (k < n) {
      const DropCutter::Contact c = drop.drop(q.head<2>());
      if (c.hit) q.z() = std::max(q.z(), c.centre_z - tool_radius_mm);
    }
    out.push_back(q);
  }
  return out;
}

// The steps of generate_toolpath, in its order (defined after it).
std::vector<WorkItem> work_items(const BSplineSurface& surface, const ToolpathOptions& o, const std::vector<PassLine>& lines,
                                 std::size_t& edge_passes);
void side_step_stats(const std::vector<PassLine>& lines, ToolpathStats& st);
double collect_segments(const std::vector<WorkItem>& items, std::vector<MarchResult>& marched, ToolpathResult& result);
double safe_plane(const ToolpathOptions& o, double top);
void write_cl_moves(const DropCutter& drop, const ToolpathOptions& o, ToolpathResult& result);
void move_stats(const ClData& cl, ToolpathStats& st);

}  // namespace

void validate(const ToolpathOptions& o) {
  const auto finite_pos = [](double v) { return std::isfinite(v) && v > 0; };
  const auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0; };
  require(finite_pos(o.tool_radius_mm) && o.tool_radius_mm <= kMaxToolRadiusMm,
          "--tool-radius-mm must be > 0 and at most " + mm(kMaxToolRadiusMm));
  require(finite_pos(o.scallop_mm), "--scallop-mm must be > 0");
  require(o.scallop_mm < o.tool_radius_mm, "--scallop-mm must be below the tool radius");
  require(finite_pos(o.chord_tol_mm), "--chord-tol-mm must be > 0");
  require(o.chord_tol_mm < o.scallop_mm,
          "--chord-tol-mm (" + mm(o.chord_tol_mm) + ") must be below --scallop-mm (" + mm(o.scallop_mm) +
              "): in concave regions the chords leave up to e of material, and the side step uses what remains of h");
  require(finite_pos(o.gouge_tol_mm), "--gouge-tol-mm must be > 0");
  require(finite_nonneg(o.stock_mm), "--stock-mm must be >= 0");
  require(finite_pos(o.max_step_mm), "--max-step-mm must be > 0");
  require(finite_pos(o.feed_mm_per_min), "--feed-mm-per-min must be > 0");
  require(finite_pos(o.plunge_feed_mm_per_min), "--plunge-feed-mm-per-min must be > 0");
  require(!o.safe_z_mm || std::isfinite(*o.safe_z_mm), "--safe-z-mm must be a finite number");
  require(finite_nonneg(o.retract_mm), "--retract-mm must be >= 0");
  require(finite_nonneg(o.clearance_mm), "--clearance-mm must be >= 0");
  require(o.ramp_angle_deg >= 0 && o.ramp_angle_deg <= 45, "--ramp-angle-deg must be in [0, 45] (0: straight down)");
  require(finite_pos(o.drop_sample_mm), "--drop-sample-mm must be > 0");
  require(finite_pos(o.side_sample_mm), "--side-sample-mm must be > 0");
  require(o.threads >= 0, "--threads must be >= 0");
  require(o.max_cl_points > 0, "--max-cl-points must be > 0");
  require(!o.spindle_rpm || finite_pos(*o.spindle_rpm), "--spindle-rpm must be > 0");
  require(o.part_name.find_first_of("\r\n") == std::string::npos, "--part-name must be one line");
}

ToolpathResult generate_toolpath(const BSplineSurface& input, const ToolpathOptions& o) {
  validate(o);
  // One orientation for the whole surface: its normal points up where it faces up (a normal
  // flipped point by point would turn into the part at a vertical tangent plane).
  const SurfaceFacing facing = surface_facing(input);
  if (facing.up_mm2 + facing.down_mm2 < kWallShare * facing.area_mm2) {
    throw GeometryError("the surface is a vertical wall: its projection onto the xy plane is " +
                        mm(100 * (facing.up_mm2 + facing.down_mm2) / std::max(facing.area_mm2, 1e-300)) +
                        " % of its area, so a ball end from above cannot follow it (a STEP/IGES part machined with "
                        "--all-faces reports its walls)");
  }
  const BSplineSurface surface = upward_oriented(input);
  const auto start = std::chrono::steady_clock::now();
  ToolpathResult result;
  const double R = o.tool_radius_mm;
  const double r = R + o.stock_mm;  // radius of the ball the centres are computed for

  // Steps 1, 5, 6: the pass lines.
  PassPlanOptions plan;
  plan.direction = o.direction;
  plan.tool_radius_mm = R;
  plan.scallop_mm = o.scallop_mm;
  plan.chord_tol_mm = o.chord_tol_mm;
  plan.stock_mm = o.stock_mm;
  plan.max_step_mm = o.max_step_mm;
  plan.sample_mm = o.side_sample_mm;
  plan.threads = o.threads;
  result.lines = plan_passes(surface, plan);

  const DropCutter drop(surface, r, o.drop_sample_mm);
  CutterOptions cutter;
  cutter.tool_radius_mm = R;
  cutter.stock_mm = o.stock_mm;
  cutter.gouge_tol_mm = o.gouge_tol_mm;
  cutter.lift = o.lift;
  cutter.sample_mm = o.drop_sample_mm;
  ForwardStepOptions forward;
  forward.chord_tol_mm = o.chord_tol_mm;
  forward.gouge_tol_mm = o.gouge_tol_mm;
  forward.max_step_mm = o.max_step_mm;
  forward.enforce_gouge = o.lift;
  std::atomic<std::size_t> points_taken{0};
  forward.points_taken = &points_taken;
  forward.max_points = o.max_cl_points;
  const std::vector<WorkItem> items = work_items(surface, o, result.lines, result.stats.edge_passes);

  // Steps 2, 3, 4 (and 7) on every piece, in parallel: each writes only its own slot.
  std::vector<MarchResult> marched(items.size());
  geometry::parallel_for(items.size(), geometry::thread_count(o.threads), [&](std::size_t i) {
    const WorkItem& item = items[i];
    const IsoCurve curve(surface, item.direction, item.w);
    marched[i] = march_interval(curve, item.t_from, item.t_to, forward, r,
                                [&](const PassFrame& f) { return cc_to_cl(f, drop, cutter); });
  });

  ToolpathStats& st = result.stats;
  st.passes = result.lines.size();
  side_step_stats(result.lines, st);
  const double top_tip = collect_segments(items, marched, result);
  st.safe_z_mm = safe_plane(o, std::max(drop.top_z(), top_tip));
  write_cl_moves(drop, o, result);
  move_stats(result.cl, st);
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

// The pieces in machining order: zig-zag reverses every other line. Then the edge passes along
// slanted domain edges (without a boundary polygon, whose edges the passes overrun instead): the
// edge nearer to where the last pass ended first; `edge_passes` counts them.
std::vector<WorkItem> work_items(const BSplineSurface& surface, const ToolpathOptions& o, const std::vector<PassLine>& lines,
                                 std::size_t& edge_passes) {
  std::vector<WorkItem> items;
  for (std::size_t k = 0; k < lines.size(); ++k) {
    const auto& ivs = lines[k].intervals;
    const bool reverse = o.pattern == Pattern::ZigZag && k % 2 == 1;
    const double w = lines[k].w;
    if (!reverse) {
      for (const Interval& iv : ivs) items.push_back({k, o.direction, w, iv.t0, iv.t1});
    } else {
      for (auto it = ivs.rbegin(); it != ivs.rend(); ++it) items.push_back({k, o.direction, w, it->t1, it->t0});
    }
  }
  if (items.empty()) throw GeometryError("no pass crosses the inside of the boundary polygon");
  if (surface.boundary_uv.empty()) {
    const auto [t0, t1] = along_domain(surface, o.direction);
    const auto [w0, w1] = across_domain(surface, o.direction);
    const PassDirection other = o.direction == PassDirection::U ? PassDirection::V : PassDirection::U;
    const bool ended_high = items.back().t_to == t1;
    bool downwards = true;  // the last line lies at w1: the first edge pass runs back to w0
    for (const double t_end : ended_high ? std::array<double, 2>{t1, t0} : std::array<double, 2>{t0, t1}) {
      if (!edge_is_slanted(surface, o.direction, t_end, lines)) continue;
      const std::size_t index = lines.size() + edge_passes++;
      items.push_back({index, other, t_end, downwards ? w1 : w0, downwards ? w0 : w1});
      downwards = !downwards;
    }
  }
  return items;
}

// The smallest and largest side step between neighbouring lines (0, 0 without any).
void side_step_stats(const std::vector<PassLine>& lines, ToolpathStats& st) {
  st.min_side_step_mm = kInf;
  st.max_side_step_mm = 0;
  for (const PassLine& line : lines) {
    if (line.across_step <= 0) continue;
    st.min_side_step_mm = std::min(st.min_side_step_mm, line.side_step_mm);
    st.max_side_step_mm = std::max(st.max_side_step_mm, line.side_step_mm);
  }
  if (!std::isfinite(st.min_side_step_mm)) st.min_side_step_mm = 0;
}

// Point k of `seg`, a gouging one, into the gouge runs: it extends the last run when the point
// before it on the same pass gouged too, else starts one.
void add_to_gouge_runs(const PassSegment& seg, std::size_t k, std::vector<GougeRun>& gouges) {
  const CutterLocation& p = seg.points[k];
  const bool extend = k > 0 && seg.points[k - 1].gouge && !gouges.empty() && gouges.back().pass == seg.pass;
  if (!extend) {
    GougeRun run;
    run.pass = seg.pass;
    run.first_cc = p.cc;
    run.deepest_contact = p.contact;
    run.min_concave_radius_mm = kInf;
    gouges.push_back(run);
  }
  GougeRun& run = gouges.back();
  run.last_cc = p.cc;
  ++run.points;
  if (p.gouge_depth_mm >= run.max_depth_mm) run.max_depth_mm = p.gouge_depth_mm, run.deepest_contact = p.contact;
  run.min_concave_radius_mm = std::min(run.min_concave_radius_mm, p.concave_radius_mm);
  run.lifted = run.lifted || p.lifted;
}

// The marched pieces into result.segments (their points moved out of `marched`), with the
// statistics of their steps and gouges; returns the highest tip (-inf without points).
double collect_segments(const std::vector<WorkItem>& items, std::vector<MarchResult>& marched, ToolpathResult& result) {
  ToolpathStats& st = result.stats;
  st.min_forward_step_mm = kInf;
  double top_tip = -kInf;
  for (std::size_t i = 0; i < items.size(); ++i) {
    MarchResult& m = marched[i];
    st.max_chord_error_mm = std::max(st.max_chord_error_mm, m.max_chord_error_mm);
    st.max_ball_dip_mm = std::max(st.max_ball_dip_mm, m.max_penetration_mm);
    st.rejected_steps += static_cast<std::size_t>(m.rejected_steps);
    PassSegment seg;
    seg.pass = items[i].line;
    seg.direction = items[i].direction;
    seg.points = std::move(m.points);
    for (std::size_t k = 0; k < seg.points.size(); ++k) {
      const CutterLocation& p = seg.points[k];
      if (!p.tip.allFinite()) throw GeometryError("a CL point is not finite (degenerate surface)");
      top_tip = std::max(top_tip, p.tip.z());
      if (k > 0) {
        const double step = (p.cc - seg.points[k - 1].cc).norm();
        st.min_forward_step_mm = std::min(st.min_forward_step_mm, step);
        st.max_forward_step_mm = std::max(st.max_forward_step_mm, step);
      }
      if (p.gouge) {
        ++st.gouge_points;
        st.max_gouge_depth_mm = std::max(st.max_gouge_depth_mm, p.gouge_depth_mm);
        add_to_gouge_runs(seg, k, result.gouges);
      }
    }
    st.cl_points += seg.points.size();
    result.segments.push_back(std::move(seg));
  }
  if (!std::isfinite(st.min_forward_step_mm)) st.min_forward_step_mm = 0;
  st.segments = result.segments.size();
  return top_tip;
}

// Safe plane: above both the surface and the path (`top`, the higher of the two).
double safe_plane(const ToolpathOptions& o, double top) {
  if (o.safe_z_mm) {
    if (*o.safe_z_mm < top) {
      throw UsageError("--safe-z-mm " + mm(*o.safe_z_mm) + " is below the top of the surface and the path (" + mm(top) +
                       " mm)");
    }
    return *o.safe_z_mm;
  }
  return top + o.retract_mm;
}

// CL moves: rapid to the safe plane, rapid down to the clearance height, plunge at the plunge
// feed, cut; between pieces a zig-zag link at cutting feed (consecutive lines, shorter than the
// tool diameter) or retract - rapid - plunge.
void write_cl_moves(const DropCutter& drop, const ToolpathOptions& o, ToolpathResult& result) {
  const double R = o.tool_radius_mm;
  ToolpathStats& st = result.stats;
  ClData& cl = result.cl;
  cl.part_name = o.part_name;
  cl.tool_diameter_mm = 2 * R;
  cl.tool_corner_radius_mm = R;
  cl.spindle_rpm = o.spindle_rpm;
  cl.coolant = o.coolant;
  const double safe = st.safe_z_mm;
  const auto rapid = [&](const Eigen::Vector3d& p) {
    cl.moves.push_back({ClMove::Kind::Rapid, p, std::nullopt, 0.0});
  };
  const auto feed = [&](const Eigen::Vector3d& p, double f) { cl.moves.push_back({ClMove::Kind::Feed, p, std::nullopt, f}); };
  // Onto the start of a pass: straight down from the clearance height, or (ramp_angle_deg > 0)
  // a lead-in ramp: rapid down to the clearance height above the point of the pass a
  // horizontal length L = clearance / tan(angle) along it, then back along the pass to its start
  // at the pass's own CL points lifted by clearance * s / L (s: horizontal length from the
  // start), so the tool comes down at the ramp angle relative to the pass and never below it; the
  // pass then cuts that stretch at full depth. A pass shorter than L is ramped over its length.
  const auto approach = [&](const std::vector<CutterLocation>& pts) {
    const Eigen::Vector3d& p = pts.front().tip;
    if (o.ramp_angle_deg > 0 && pts.size() > 1 && o.clearance_mm > 0) {
      const double L = o.clearance_mm / std::tan(o.ramp_angle_deg * 3.14159265358979323846 / 180);
      std::vector<std::pair<Eigen::Vector3d, double>> lead{{p, 0.0}};  // (tip, s)
      for (std::size_t k = 1; k < pts.size() && lead.back().second < L; ++k) {
        const Eigen::Vector3d& a = pts[k - 1].tip;
        const Eigen::Vector3d& b = pts[k].tip;
        const double l = (b - a).head<2>().norm();
        const double s0 = lead.back().second;
        if (s0 + l > L && l > 0) {
          lead.push_back({a + (b - a) * ((L - s0) / l), L});
        } else {
          lead.push_back({b, s0 + l});
        }
      }
      const double span = lead.back().second;
      if (span > 0) {
        const Eigen::Vector3d& far = lead.back().first;
        rapid({far.x(), far.y(), safe});
        if (far.z() + o.clearance_mm < safe) rapid({far.x(), far.y(), far.z() + o.clearance_mm});
        for (std::size_t k = lead.size() - 1; k-- > 0;) {
          feed(lead[k].first + Eigen::Vector3d(0, 0, o.clearance_mm * lead[k].second / span), o.plunge_feed_mm_per_min);
        }
        return;
      }
    }
    rapid({p.x(), p.y(), safe});
    if (p.z() + o.clearance_mm < safe) rapid({p.x(), p.y(), p.z() + o.clearance_mm});
    feed(p, o.plunge_feed_mm_per_min);
  };
  for (std::size_t s = 0; s < result.segments.size(); ++s) {
    const auto& pts = result.segments[s].points;
    if (s == 0) approach(pts);
    for (std::size_t k = 1; k < pts.size(); ++k) feed(pts[k].tip, o.feed_mm_per_min);
    if (s + 1 == result.segments.size()) break;
    const auto& next = result.segments[s + 1];
    const Eigen::Vector3d a = pts.back().tip, b = next.points.front().tip;
    const bool link = o.pattern == Pattern::ZigZag && next.pass == result.segments[s].pass + 1 &&
                      (b - a).head<2>().norm() <= 2 * R;
    if (link) {
      for (const Eigen::Vector3d& q : link_points(a, b, drop, R, o.gouge_tol_mm)) feed(q, o.feed_mm_per_min);
    } else {
      ++st.retracts;
      rapid({a.x(), a.y(), safe});
      approach(next.points);
    }
  }
  const Eigen::Vector3d last = cl.moves.back().tip_mm;
  rapid({last.x(), last.y(), safe});
}

// The number of moves and the lengths of the feed and the rapid moves.
void move_stats(const ClData& cl, ToolpathStats& st) {
  st.moves = cl.moves.size();
  for (std::size_t k = 1; k < cl.moves.size(); ++k) {
    const double len = (cl.moves[k].tip_mm - cl.moves[k - 1].tip_mm).norm();
    (cl.moves[k].kind == ClMove::Kind::Feed ? st.feed_length_mm : st.rapid_length_mm) += len;
  }
}

}  // namespace

}  // namespace photomill::toolpath
