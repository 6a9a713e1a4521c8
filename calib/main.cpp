// calib: observations (image,point_id,u_px,v_px) + control points (a CSV or a board) -> camera.yaml.
// The report goes to stderr; --report FILE adds JSON, --plot FILE.png the residual vectors.
// Outputs are written only when the calibration succeeded (temporary names, renamed at the end).
#include <optional>
#include <sstream>

#include "calib/cli.hpp"
#include "calib/report.hpp"
#include "calib/rig.hpp"
#include "formats/camera.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"

int main(int argc, char** argv) {
  using namespace photomill;
  calib::CalibCli cli;
  return tool::run(
      argc, argv,
      {"calib", "camera calibration from boards and 3D control points: observations -> camera.yaml",
       "detect --chessboard 9x6 left*.jpg | calib --chessboard 9x6 --square-mm 25 --plot res.png > cam.yaml"},
      [&](CLI::App& app) { calib::add_options(app, cli); },
      [&] {
        const calib::CalibOptions options = calib::to_options(cli);
        const std::vector<ControlPoint> control = calib::load_control(cli);
        std::vector<Observation> observations;
        for (const auto& path : cli.observations) {
          auto in = tool::open_input(path);
          auto part = read_observations(*in, tool::source_name(path));
          observations.insert(observations.end(), part.begin(), part.end());
        }
        calib::check_observations(cli, observations, control);
        if (!cli.rig.empty()) {
          calib::RigCalibOptions rig_options;
          rig_options.camera = options;
          rig_options.lm = options.lm;
          rig_options.fix_intrinsics = cli.rig_fix_intrinsics;
          const calib::RigResult rig = calib::calibrate_rig(observations, control, cli.rig,
                                                            calib::resolve_rig_image_sizes(cli, observations),
                                                            rig_options, calib::observation_sources(cli));
          tool::OutputFile rig_out(cli.output);
          write_rig_yaml(rig_out.stream(), rig.rig);
          std::optional<tool::OutputFile> report_out;
          if (!cli.report.empty()) {
            report_out.emplace(cli.report);
            calib::write_rig_json_report(report_out->stream(), rig);
          }
          for (const auto& line : calib::rig_text_report(rig)) log::info(line);
          for (const auto& w : rig.warnings) log::warn(w);
          if (report_out) report_out->commit();
          rig_out.commit();
          return;
        }
        const cv::Size size = calib::resolve_image_size(cli, observations);

        const calib::CalibResult result = calib::calibrate(observations, control, size, options);

        tool::OutputFile camera_out(cli.output);
        write_camera_yaml(camera_out.stream(), result.camera);
        std::optional<tool::OutputFile> report_out;
        if (!cli.report.empty()) {
          report_out.emplace(cli.report);
          calib::write_json_report(report_out->stream(), result, options);
        }
        std::optional<tool::OutputFile> plot_out;
        calib::ResidualPlot plot;
        if (!cli.plot.empty()) {
          plot = calib::residual_plot(result);
          plot_out.emplace(cli.plot);
          plot_out->stream().write(reinterpret_cast<const char*>(plot.png.data()),
                                   static_cast<std::streamsize>(plot.png.size()));
        }
        for (const auto& line : calib::text_report(result)) log::info(line);
        for (const auto& w : result.warnings) log::warn(w);
        if (plot_out) {
          std::ostringstream msg;
          msg << cli.plot << ": residual vectors drawn x" << plot.magnification << " (legend bar = " << plot.bar_px
              << " px of residual)";
          log::info(msg.str());
          plot_out->commit();
        }
        if (report_out) report_out->commit();
        camera_out.commit();
      });
}
