// pick's web application (issue 29): the routes of the page and its JSON API over a Session,
// and the checks every request passes first. Separate from the sockets (pick/http.hpp) so that
// tests call handle() directly.
//
// Security (the page can change a file on disk, so any web page the user has open must not be
// able to drive it): the server listens on 127.0.0.1 only; every request must carry the random
// token of this run (query parameter `token`, 128 bits); a request whose Host is not
// 127.0.0.1:PORT or localhost:PORT is refused (DNS rebinding), and so is one whose Origin is
// another origin or whose Sec-Fetch-Site says cross-site. The server reads no path from a request:
// photos are served by their index in the command line's list, the page and its script are
// compiled in, and any other path is 404. Responses forbid framing and other sources (CSP).
#pragma once

#include <string>

#include "pick/http.hpp"
#include "pick/session.hpp"

namespace photomill::pick {

class App {
public:
  App(Session& session, std::string token, int port, Refine default_refine = Refine::Auto);

  // Answers one request; sets *stop when the page asked to finish (POST /api/quit).
  HttpResponse handle(const HttpRequest& request, bool* stop);

  // The page's address: http://127.0.0.1:PORT/?token=TOKEN
  std::string url() const;

private:
  std::string refusal(const HttpRequest& request) const;  // why it is refused; empty: allowed
  HttpResponse state() const;
  HttpResponse guide(const HttpRequest& request) const;
  HttpResponse mark(const HttpRequest& request);
  HttpResponse remove(const HttpRequest& request);
  HttpResponse undo();

  Session& session_;
  std::string token_;
  int port_ = 0;
  Refine default_refine_ = Refine::Auto;
};

// 32 hexadecimal digits from the system's random source (std::random_device: /dev/urandom).
std::string make_token();

// The page, its script and its style, compiled in (pick/page.html, pick.js, pick.css).
const std::string& page_html();
const std::string& page_script();
const std::string& page_style();

}  // namespace photomill::pick
