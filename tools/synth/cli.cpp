// synth's options (see cli.hpp).
#include "tools/synth/cli.hpp"

#include <stdexcept>

#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "tools/synth/camera_model.hpp"

namespace photomill::synth {

void add_options(CLI::App& app, SynthCli& c) {
  SynthOptions& o = c.options;
  app.add_option("-o,--output-dir", c.output_dir, "Folder for images and truth (created)")->required();

  const std::string part = "Part";
  app.add_option("--shape", o.shape, "Shape of the part")
      ->check(CLI::IsMember(shape_names()))->capture_default_str()->group(part);
  app.add_option("--part-x-mm", o.part_x_mm, "Part length along x")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--part-y-mm", o.part_y_mm, "Part width along y")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--part-height-mm", o.part_height_mm, "Highest point of the part")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--edge-blend-mm", o.edge_blend_mm, "Width of the ramp from the plate up to the part (0: vertical walls)")->check(CLI::NonNegativeNumber)->capture_default_str()->group(part);
  app.add_option("--dictionary", o.dictionary, "ArUco dictionary of the plate and part markers")
      ->check(CLI::IsMember(dictionary_names()))->capture_default_str()->group(part);
  app.add_option("--plate-marker-mm", o.layout.plate_marker_mm, "Side of the plate markers (black border included)")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--part-marker-mm", o.layout.part_marker_mm, "Side of the markers on the part")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--part-markers-x", o.layout.part_markers_x, "Part markers along x")->check(CLI::Range(0, 20))->capture_default_str()->group(part);
  app.add_option("--part-markers-y", o.layout.part_markers_y, "Part markers along y")->check(CLI::Range(0, 20))->capture_default_str()->group(part);
  app.add_option("--speckle-mm", o.speckle_mm, "Grain size of the speckle texture")->check(CLI::PositiveNumber)->capture_default_str()->group(part);
  app.add_option("--surface-step-mm", o.surface_step_mm, "Grid spacing of surface.ply")->check(CLI::PositiveNumber)->capture_default_str()->group(part);

  const std::string cam = "Camera";
  app.add_option("--width", c.width_px, "Image width, pixels")->check(CLI::Range(16, 20000))->capture_default_str()->group(cam);
  app.add_option("--height", c.height_px, "Image height, pixels")->check(CLI::Range(16, 20000))->capture_default_str()->group(cam);
  app.add_option("--fx", c.fx, "Focal length along x, pixels")->check(CLI::PositiveNumber)->capture_default_str()->group(cam);
  app.add_option("--fy", c.fy, "Focal length along y, pixels [default: fx]")->check(CLI::PositiveNumber)->group(cam);
  app.add_option("--cx", c.cx, "Principal point column, pixels [default: (width-1)/2]")->group(cam);
  app.add_option("--cy", c.cy, "Principal point row, pixels [default: (height-1)/2]")->group(cam);
  app.add_option("--k1", c.k1, "Radial distortion k1")->capture_default_str()->group(cam);
  app.add_option("--k2", c.k2, "Radial distortion k2")->capture_default_str()->group(cam);
  app.add_option("--p1", c.p1, "Tangential distortion p1")->capture_default_str()->group(cam);
  app.add_option("--p2", c.p2, "Tangential distortion p2")->capture_default_str()->group(cam);
  app.add_option("--k3", c.k3, "Radial distortion k3")->capture_default_str()->group(cam);

  const std::string views = "Views";
  app.add_option("--views", o.views.count, "Number of part views")->check(CLI::Range(0, 1000))->capture_default_str()->group(views);
  app.add_option("--elevation-deg", o.views.elevations_deg, "Elevations above the plate, cycled through the views")
      ->delimiter(',')->check(CLI::Range(1.0, 88.0))->capture_default_str()->group(views);
  app.add_option("--distance-mm", o.views.distance_mm, "Camera distance to the part")->check(CLI::PositiveNumber)->capture_default_str()->group(views);
  app.add_option("--azimuth-offset-deg", o.views.azimuth_offset_deg, "Azimuth of the first view")->capture_default_str()->group(views);
  app.add_option("--jitter", o.views.jitter, "Scale of random pose perturbations (0: exact ring)")->check(CLI::Range(0.0, 10.0))->capture_default_str()->group(views);
  app.add_option("--calib-views", o.calibration.count, "Number of ChArUco board views")->check(CLI::Range(0, 1000))->capture_default_str()->group(views);
  app.add_option("--board-squares-x", o.calibration.board.squares_x, "Board squares along x")->check(CLI::Range(2, 100))->capture_default_str()->group(views);
  app.add_option("--board-squares-y", o.calibration.board.squares_y, "Board squares along y")->check(CLI::Range(2, 100))->capture_default_str()->group(views);
  app.add_option("--board-square-mm", o.calibration.board.square_mm, "Board square side")->check(CLI::PositiveNumber)->capture_default_str()->group(views);
  app.add_option("--board-marker-mm", o.calibration.board.marker_mm, "Board marker side")->check(CLI::PositiveNumber)->capture_default_str()->group(views);
  app.add_option("--board-dictionary", o.calibration.board.dictionary, "ArUco dictionary of the board")
      ->check(CLI::IsMember(dictionary_names()))->capture_default_str()->group(views);
  app.add_option("--board-max-tilt-deg", o.calibration.max_tilt_deg, "Largest board tilt")->check(CLI::Range(0.0, 75.0))->capture_default_str()->group(views);

  const std::string render = "Rendering";
  app.add_option("--supersampling", o.render.supersampling, "n: n x n samples per pixel")->check(CLI::Range(1, 16))->capture_default_str()->group(render);
  app.add_option("--noise-sigma", o.render.noise_sigma, "Gaussian noise, grey levels")->check(CLI::Range(0.0, 100.0))->capture_default_str()->group(render);
  app.add_option("--image-format", o.image_format, "Image file format")->check(CLI::IsMember({"jpg", "png"}))->capture_default_str()->group(render);
  app.add_option("--jpeg-quality", o.jpeg_quality, "JPEG quality")->check(CLI::Range(1, 100))->capture_default_str()->group(render);
  app.add_option("--seed", o.seed, "Seed of every random choice (speckle, poses, noise)")->capture_default_str()->group(render);
  app.add_option("--threads", o.render.threads, "Render threads (0: all cores)")->check(CLI::Range(0, 256))->capture_default_str()->group(render);
}

SynthOptions to_options(const SynthCli& c, const std::string& command_line) {
  SynthOptions o = c.options;
  o.command_line = command_line;
  o.seed = c.options.seed;
  Camera& cam = o.camera;
  cam.image_width_px = c.width_px;
  cam.image_height_px = c.height_px;
  cam.camera_matrix = Eigen::Matrix3d::Identity();
  cam.camera_matrix(0, 0) = c.fx;
  cam.camera_matrix(1, 1) = c.fy.value_or(c.fx);
  cam.camera_matrix(0, 2) = c.cx.value_or((c.width_px - 1) / 2.0);
  cam.camera_matrix(1, 2) = c.cy.value_or((c.height_px - 1) / 2.0);
  cam.distortion = {c.k1, c.k2, c.p1, c.p2, c.k3};
  try {
    validate_synth_camera(cam);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return o;
}

}  // namespace photomill::synth
