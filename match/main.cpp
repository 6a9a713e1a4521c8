// match: observations CSV (coded points) and .feat files (natural features) -> tracks CSV
// (track_id,image,u_px,v_px) of verified correspondences. Summary on stderr: pairs, inliers per
// pair, dropped observations, track length histogram.
#include <string>
#include <vector>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/tool.hpp"
#include "match/cli.hpp"

int main(int argc, char** argv) {
  photomill::match::Cli cli;
  return photomill::tool::run(
      argc, argv,
      {"match", "correspondences between images: observations and features to verified tracks",
       "detect --aruco DICT_4X4_100 --features feat part*.jpg | match - --features feat --camera cam.yaml > tracks.csv"},
      [&](CLI::App& app) { photomill::match::add_options(app, cli); },
      [&] {
        const auto inputs = photomill::match::read_inputs(cli);
        photomill::log::Step step("matching");
        const auto result = photomill::match::match(inputs, cli.options, [&step](const std::string& m) {
          photomill::log::debug(m);
          step.set("matching: " + m);
        });
        photomill::match::report(result, cli);
        photomill::match::require_tracks(result, cli);
        photomill::tool::OutputFile out(cli.output);
        photomill::write_tracks(out.stream(), result.tracks);
        out.commit();
      });
}
