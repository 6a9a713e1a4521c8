// Report output (see report.hpp).
#include "triangulate/report.hpp"

#include <cmath>
#include <sstream>

#include "formats/run.hpp"
#include "formats/json.hpp"
#include "formats/log.hpp"

namespace photomill::triangulate {
namespace {

std::string fmt(double v, int precision = 4) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

}  // namespace

void write_report_json(std::ostream& out, const Report& r) {
  JsonWriter j(out);
  j.begin_object();
  j.field("tool", "triangulate");
  j.field("run_id", run_id());
  j.key("datum").begin_object();
  j.field("type", r.datum);
  j.key("reference_image");
  if (r.reference_image) {
    j.value(*r.reference_image);
  } else {
    j.null();
  }
  j.field("known_poses", r.known_poses);
  for (const auto& [key, v] : {std::pair{"pose_sigma_mm", r.pose_sigma_mm}, std::pair{"pose_sigma_deg", r.pose_sigma_deg}}) {
    j.key(key);
    if (v) {
      j.value(*v);
    } else {
      j.null();
    }
  }
  j.end_object();
  j.field("pose_initialisation", r.pose_initialisation);
  j.field("images", r.images);
  j.field("registered_images", r.registered_images);
  j.field("tracks", r.tracks);
  j.field("points", r.points);
  j.field("observations_used", r.observations_used);
  j.key("observation_classes").begin_object();
  for (const auto& [name, c] : r.observation_classes) {
    j.key(name).begin_object();
    j.field("observations", c.observations);
    j.field("sigma_px", c.sigma_px);
    j.end_object();
  }
  j.end_object();
  j.field("observation_sigma_estimated", r.observation_sigma_estimated);
  j.field("initial_rms_px", r.initial_rms_px);
  j.field("final_rms_px", r.final_rms_px);
  j.key("bundle_adjustment").begin_object();
  j.field("runs", r.adjustments);
  j.field("final_iterations", r.final_iterations);
  j.field("total_iterations", r.total_iterations);
  j.field("seconds", r.adjustment_seconds);
  j.field("solver", r.solver);
  j.field("loss", r.loss);
  j.field("loss_scale_px", r.loss_scale_px);
  j.field("refine_intrinsics", r.refine_intrinsics);
  j.field("threads", r.threads);
  j.end_object();
  j.field("total_seconds", r.total_seconds);
  j.key("uncertainty").begin_object();
  j.field("method", r.sigma_method);
  j.field("variance_factor", r.variance_factor);
  j.end_object();
  if (!r.refined_camera.empty()) {
    j.key("refined_camera").begin_array();
    for (double v : r.refined_camera) j.value(v);
    j.end_array();
  }
  if (r.rig) {
    j.key("rig").begin_object();
    j.field("frames", r.rig->frames);
    j.field("frames_placed", r.rig->frames_placed);
    j.field("reference_frame", r.rig->reference_frame);
    j.key("cameras").begin_array();
    for (const RigCameraReport& c : r.rig->cameras) {
      j.begin_object();
      j.field("prefix", c.prefix);
      j.field("refined", c.refined);
      j.field("rotation_change_deg", c.rotation_change_deg);
      j.field("translation_change_mm", c.translation_change_mm);
      j.key("translation_mm").begin_array();
      for (double v : c.translation_mm) j.value(v);
      j.end_array();
      j.field("baseline_mm", c.baseline_mm);
      j.end_object();
    }
    j.end_array();
    j.end_object();
  }
  if (!r.refined_cameras.empty()) {
    j.key("refined_cameras").begin_array();
    for (const auto& [prefix, values] : r.refined_cameras) {
      j.begin_object();
      j.field("prefix", prefix);
      j.key("camera").begin_array();
      for (double v : values) j.value(v);
      j.end_array();
      j.end_object();
    }
    j.end_array();
  }
  j.key("per_image").begin_array();
  for (const ImageReport& im : r.per_image) {
    j.begin_object();
    j.field("image", im.image);
    j.field("registered", im.registered);
    j.field("registered_by", im.registered_by);
    j.field("observations", im.observations);
    j.field("rms_px", im.rms_px);
    j.end_object();
  }
  j.end_array();
  j.key("removed_observations").begin_array();
  for (const RemovedObservation& o : r.removed) {
    j.begin_object();
    j.field("track_id", static_cast<std::int64_t>(o.track_id));
    j.field("image", o.image);
    j.field("residual_px", o.residual_px);
    j.field("round", o.round);
    j.end_object();
  }
  j.end_array();
  j.key("tracks_dropped").begin_object();
  for (const auto& [why, n] : r.tracks_dropped) j.field(why, n);
  j.end_object();
  {
    const TwoViewReport& t = r.two_view;
    j.key("two_view_check").begin_object();
    j.field("enabled", t.enabled);
    j.field("ran", t.ran);
    j.field("reference_points", t.reference_points);
    j.field("spacing_mm", t.spacing_mm);
    j.field("checked", t.checked);
    j.field("kept", t.checked - t.removed_unsupported - t.removed_off_neighbours);
    j.field("removed_unsupported", t.removed_unsupported);
    j.field("removed_off_neighbours", t.removed_off_neighbours);
    j.field("neighbours", t.neighbours);
    j.field("reach", t.reach);
    j.field("sigmas", t.sigmas);
    j.field("tolerance_mm", t.tolerance_mm);
    j.key("removed").begin_array();
    for (const RemovedPoint& p : t.removed) {
      j.begin_object();
      j.field("track_id", static_cast<std::int64_t>(p.track_id));
      j.key("xyz_mm").begin_array();
      for (double v : p.xyz_mm) j.value(v);
      j.end_array();
      j.field("reason", p.reason);
      j.key("distance_mm");
      std::isfinite(p.distance_mm) ? j.value(p.distance_mm) : j.null();
      j.key("allowed_mm");
      std::isfinite(p.allowed_mm) ? j.value(p.allowed_mm) : j.null();
      j.end_object();
    }
    j.end_array();
    j.end_object();
  }
  j.key("scale_bars").begin_array();
  for (const ScaleBarReport& b : r.scale_bars) {
    j.begin_object();
    j.field("point_a", static_cast<std::int64_t>(b.point_a));
    j.field("point_b", static_cast<std::int64_t>(b.point_b));
    j.field("origin", b.origin);
    j.field("distance_mm", b.distance_mm);
    j.field("sigma_mm", b.sigma_mm);
    j.field("used", b.used);
    j.key("measured_mm");
    b.used ? j.value(b.measured_mm) : j.null();
    j.key("residual_mm");
    b.used ? j.value(b.measured_mm - b.distance_mm) : j.null();
    j.end_object();
  }
  j.end_array();
  j.key("control_points").begin_array();
  for (const ControlReport& c : r.control_points) {
    j.begin_object();
    j.field("point_id", static_cast<std::int64_t>(c.point_id));
    j.field("fixed", c.fixed);
    j.field("sigma_mm", c.sigma_mm);
    j.field("residual_mm", c.residual_mm);
    j.field("observations", c.observations);
    j.end_object();
  }
  j.end_array();
  j.key("warnings").begin_array();
  for (const std::string& w : r.warnings) j.value(w);
  j.end_array();
  j.end_object();
  out << "\n";
}

void log_report(const Report& r) {
  for (const std::string& w : r.warnings) log::warn(w);
  std::string datum = "datum: " + r.datum;
  if (r.reference_image) datum += " (reference image " + *r.reference_image + ")";
  log::info(datum + "; poses from " + r.pose_initialisation);
  log::info(std::to_string(r.registered_images) + " of " + std::to_string(r.images) + " images, " +
            std::to_string(r.points) + " points, " + std::to_string(r.observations_used) + " observations");
  std::string sigmas;
  for (const auto& [name, c] : r.observation_classes) {
    sigmas += (sigmas.empty() ? "" : ", ") + name + " " + fmt(c.sigma_px) + " px (" + std::to_string(c.observations) + ")";
  }
  log::info("reprojection RMS " + fmt(r.final_rms_px) + " px (before the final adjustment " + fmt(r.initial_rms_px) +
            " px); sigma " + (r.observation_sigma_estimated ? "estimated" : "given") + ": " + sigmas);
  if (r.rig) {
    std::string cams;
    for (const RigCameraReport& c : r.rig->cameras) {
      if (!c.refined) continue;
      cams += (cams.empty() ? "" : ", ") + c.prefix + " moved " + fmt(c.rotation_change_deg) + " deg, " +
              fmt(c.translation_change_mm) + " mm (baseline " + fmt(c.baseline_mm) + " mm)";
    }
    log::info("rig: " + std::to_string(r.rig->frames_placed) + " of " + std::to_string(r.rig->frames) +
              " frames placed, frame " + r.rig->reference_frame + " is the world; " +
              (cams.empty() ? "the cameras' poses in the rig held as given (no sigma in the rig file)"
                            : "poses in the rig adjusted: " + cams));
  }
  log::info("bundle adjustment: " + std::to_string(r.adjustments) + " runs, " + fmt(r.adjustment_seconds) + " s (" +
            r.solver + ", " + std::to_string(r.threads) + " threads); total " + fmt(r.total_seconds) + " s");
  std::size_t dropped = 0;
  std::string reasons;
  for (const auto& [why, n] : r.tracks_dropped) {
    dropped += n;
    reasons += (reasons.empty() ? "" : ", ") + why + " " + std::to_string(n);
  }
  log::info(std::to_string(r.removed.size()) + " observations removed as outliers; " + std::to_string(dropped) +
            " tracks not reconstructed" + (reasons.empty() ? "" : " (" + reasons + ")"));
  std::size_t used = 0;
  double worst = 0;
  for (const ScaleBarReport& b : r.scale_bars) {
    if (!b.used) continue;
    ++used;
    worst = std::max(worst, std::abs(b.measured_mm - b.distance_mm));
  }
  if (!r.scale_bars.empty()) {
    log::info("scale bars: " + std::to_string(used) + " of " + std::to_string(r.scale_bars.size()) +
              " used, largest residual " + fmt(worst) + " mm");
  }
  for (const ScaleBarReport& b : r.scale_bars) {
    if (!b.used) continue;
    log::debug("scale bar " + std::to_string(b.point_a) + "-" + std::to_string(b.point_b) + " (" + b.origin + "): " +
               fmt(b.measured_mm, 10) + " mm for " + fmt(b.distance_mm, 10) + " mm, residual " +
               fmt(b.measured_mm - b.distance_mm) + " mm");
  }
  for (const ImageReport& im : r.per_image) {
    log::debug(im.image + ": " + (im.registered ? im.registered_by : "not registered") + ", " +
               std::to_string(im.observations) + " observations, RMS " + fmt(im.rms_px) + " px");
  }
  for (const RemovedObservation& o : r.removed) {
    log::debug("removed: track " + std::to_string(o.track_id) + " in " + o.image + ", " + fmt(o.residual_px) +
               " px (round " + std::to_string(o.round) + ")");
  }
  log::info("point sigma: " + r.sigma_method + ", variance factor " + fmt(r.variance_factor));
  for (const RemovedPoint& p : r.two_view.removed) {
    log::debug("two-view point removed: track " + std::to_string(p.track_id) + " at (" + fmt(p.xyz_mm[0]) + ", " +
               fmt(p.xyz_mm[1]) + ", " + fmt(p.xyz_mm[2]) + ") " +
               (p.reason == "unsupported" ? std::string("has no neighbour seen in three views")
                                          : fmt(p.distance_mm) + " mm off its neighbours' surface (allowed " + fmt(p.allowed_mm) + " mm)"));
  }
}

}  // namespace photomill::triangulate
