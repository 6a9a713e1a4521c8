// pick: click corresponding points in the photos, in a browser page served on 127.0.0.1 (issue
// 29). Prints the page's address (with this run's token) on stdout and serves until the page's
// Finish button (or Ctrl+C); every mark is saved to -o at once.
#include <iostream>

#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/option_checks.hpp"
#include "formats/tool.hpp"
#include "pick/server.hpp"

using namespace photomill;

int main(int argc, char** argv) {
  std::vector<std::string> photos;
  std::string camera, poses, output, refine = "auto";
  int port = 0;
  pick::SessionOptions o;
  return tool::run(
      argc, argv,
      {"pick", "Click corresponding points in the photos, in a browser page on this machine (127.0.0.1 only)",
       "pick part_*.jpg --camera camera.yaml --poses poses.csv -o clicked.csv"},
      [&](CLI::App& app) {
        app.add_option("photos", photos, "The photos (their names as given become the observations' image names)");
        app.add_option("-o,--output", output,
                       "The observations file, written after every change (loaded first if it exists)");
        app.add_option("--camera", camera, "camera.yaml of the photos (with --poses: epipolar curves, predictions, residuals)");
        app.add_option("--poses", poses, "The photos' poses (triangulate's poses.csv)");
        app.add_option("--port", port, "TCP port on 127.0.0.1 (0 = a free port)")->check(tool::finite_in(0, 65535))->capture_default_str();
        app.add_option("--refine", refine, "How a click is refined at first (the page can change it): none, corner, blob, match, or auto (corner below zoom 4, else none)")
            ->check(CLI::IsMember({"none", "corner", "blob", "match", "auto"}))->capture_default_str();
        app.add_option("--corner-half-window-px", o.corner_half_window_px, "Corner refinement's window half-width")
            ->check(tool::finite_in(2, 50))->capture_default_str();
        app.add_option("--blob-half-window-px", o.blob_half_window_px, "Blob centring's window half-width (a blob must fit in it)")
            ->check(tool::finite_in(3, 200))->capture_default_str();
        app.add_option("--lsm-half-window-px", o.lsm_half_window_px, "Least-squares matching's window half-width")
            ->check(tool::finite_in(3, 50))->capture_default_str();
        app.add_option("--max-refine-shift-px", o.max_refine_shift_px,
                       "A refinement that moves the click farther than this is refused (the click is kept)")
            ->check(tool::finite_in(0.01, 100))->capture_default_str();
        app.add_option("--first-id", o.first_id, "The id of the first new point (above detect's marker-corner ids)")
            ->check(tool::finite_in(0, 1e15))->capture_default_str();
        app.add_option("--thumbnail-px", o.thumbnail_px, "Thumbnails' longest side")->check(tool::finite_in(32, 2048))->capture_default_str();
        app.add_option("-j,--jobs", o.threads, "Photos read in parallel at start (0 = all cores)")->check(tool::non_negative_up_to(1024))->capture_default_str();
      },
      [&] {
        if (photos.empty()) throw UsageError("give the photos to mark points in");
        if (output.empty()) throw UsageError("give the observations file: -o FILE");
        if (output == "-") throw UsageError("-o must name a file (it is rewritten after every change)");
        const auto opt = [](const std::string& s) { return s.empty() ? std::nullopt : std::optional<std::string>(s); };
        pick::HttpServer server(port);  // first: a taken port is said before the photos are read
        pick::Session session(photos, opt(camera), opt(poses), output, o);
        pick::App app(session, pick::make_token(), server.port(), *pick::parse_refine(refine));
        std::cout << app.url() << std::endl;
        log::info("open " + app.url() + " in a browser on this machine; the page's Finish button (or Ctrl+C) ends");
        server.serve([&](const pick::HttpRequest& r, bool* stop) { return app.handle(r, stop); });
        session.flush();  // a save that failed last (a full disk) is tried again, or is this run's error: exit 1
        log::info(output + " holds " + std::to_string(session.observations().size()) + " observations");
      });
}
