// A minimal HTTP/1.1 server for pick's page (issue 29): connections read side by side, requests
// answered one at a time, one request per connection (Connection: close), bound to the IPv4
// loopback address only. The parsing is
// separate from the sockets so that tests can feed it text. Standard library and POSIX only.
// Limits (named below) turn an oversized or slow request into a refusal instead of unbounded
// memory or a blocked server.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace photomill::pick {

inline constexpr std::size_t kMaxHeaderBytes = 16 * 1024;   // request line and headers
inline constexpr std::size_t kMaxBodyBytes = 1024 * 1024;   // a POST's body (JSON)
inline constexpr int kSocketTimeoutS = 10;                  // a client silent this long is dropped
inline constexpr std::size_t kMaxConnections = 64;         // open at once; more are answered 503

// A request the application cannot carry out as asked (a click outside the photo, a body that is
// not the JSON expected): answered 422 with the message; the server goes on.
class RequestError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

struct HttpRequest {
  std::string method;                          // "GET", "POST"
  std::string target;                          // as sent: "/photo/3?token=..."
  std::string path;                            // percent-decoded path: "/photo/3"
  std::map<std::string, std::string> query;    // percent-decoded query parameters
  std::map<std::string, std::string> headers;  // names in lower case
  std::string body;

  // The header `name` (lower case), or "" if absent.
  std::string header(const std::string& name) const;
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // extra headers
};

// Why a request could not be parsed: the status to answer with (400, 413, 431) and a reason.
struct HttpParseError {
  int status = 400;
  std::string reason;
};

// Percent-decodes `s` ('+' stays '+'); nullopt for a malformed escape or an encoded NUL.
std::optional<std::string> percent_decode(const std::string& s);

// Parses the request head (everything before the blank line, without it) into `request`
// (method, target, path, query, headers); `body` is left empty. nullopt on success.
std::optional<HttpParseError> parse_request_head(const std::string& head, HttpRequest& request);

// The response as bytes on the wire (status line, Content-Type, Content-Length, Connection:
// close, the extra headers, the body).
std::string serialise(const HttpResponse& response);

// A listening socket on 127.0.0.1:port (0 = a free port the system chooses).
class HttpServer {
public:
  explicit HttpServer(int port = 0);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const { return port_; }

  // Accepts connections and answers each complete request with `handler` until `handler` sets
  // *stop (after its response is sent). Requests that cannot be parsed are answered here (400,
  // 413, 431) without calling the handler.
  void serve(const std::function<HttpResponse(const HttpRequest&, bool* stop)>& handler);

private:
  int fd_ = -1;
  int port_ = 0;
};

}  // namespace photomill::pick
