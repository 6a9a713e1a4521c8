#include "pick/http.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <sstream>

#include "formats/error.hpp"

namespace photomill::pick {
namespace {

const std::string kServerName = "127.0.0.1";

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

const char* reason_phrase(int status) {
  switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 408: return "Request Timeout";
    case 409: return "Conflict";
    case 413: return "Content Too Large";
    case 422: return "Unprocessable Content";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    case 500: return "Internal Server Error";
    default: return "Status";
  }
}

void send_all(int fd, const std::string& bytes) {
  std::size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // the client went away: nothing to tell it
    sent += static_cast<std::size_t>(n);
  }
}

HttpResponse refuse(int status, const std::string& reason) { return {status, "text/plain; charset=utf-8", reason + "\n", {}}; }

// The request in the bytes received so far: nullopt while it is incomplete (*ready false), or
// with *ready true either nullopt (`request` holds it) or the refusal to send instead.
std::optional<HttpResponse> parse_received(const std::string& data, HttpRequest& request, bool* ready) {
  *ready = false;
  const std::size_t head_end = data.find("\r\n\r\n");
  if (head_end == std::string::npos) {
    if (data.size() > kMaxHeaderBytes) {
      *ready = true;
      return refuse(431, "request head too large");
    }
    return std::nullopt;
  }
  *ready = true;
  if (head_end > kMaxHeaderBytes) return refuse(431, "request head too large");
  request = HttpRequest{};
  if (auto e = parse_request_head(data.substr(0, head_end), request)) return refuse(e->status, e->reason);
  if (!request.header("transfer-encoding").empty()) return refuse(400, "chunked bodies are not accepted");
  std::size_t length = 0;
  const std::string cl = request.header("content-length");
  if (!cl.empty()) {
    if (cl.find_first_not_of("0123456789") != std::string::npos || cl.size() > 9) return refuse(400, "bad Content-Length");
    length = std::stoul(cl);
    if (length > kMaxBodyBytes) return refuse(413, "body too large");
  }
  if (data.size() - head_end - 4 < length) {
    *ready = false;
    return std::nullopt;
  }
  request.body = data.substr(head_end + 4, length);
  return std::nullopt;
}

}  // namespace

std::string HttpRequest::header(const std::string& name) const {
  const auto it = headers.find(name);
  return it == headers.end() ? std::string() : it->second;
}

std::optional<std::string> percent_decode(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '%') {
      out += s[i];
      continue;
    }
    if (i + 2 >= s.size()) return std::nullopt;
    const int hi = hex_digit(s[i + 1]), lo = hex_digit(s[i + 2]);
    if (hi < 0 || lo < 0) return std::nullopt;
    const char c = static_cast<char>(hi * 16 + lo);
    if (c == '\0') return std::nullopt;
    out += c;
    i += 2;
  }
  return out;
}

std::optional<HttpParseError> parse_request_head(const std::string& head, HttpRequest& request) {
  std::istringstream in(head);
  std::string line;
  if (!std::getline(in, line)) return HttpParseError{400, "empty request"};
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::istringstream first(line);
  std::string version, extra;
  if (!(first >> request.method >> request.target >> version) || (first >> extra)) {
    return HttpParseError{400, "malformed request line"};
  }
  if (version != "HTTP/1.1" && version != "HTTP/1.0") return HttpParseError{400, "unsupported HTTP version"};
  if (request.target.empty() || request.target[0] != '/') return HttpParseError{400, "the target must be a path"};
  const auto q = request.target.find('?');
  const auto path = percent_decode(request.target.substr(0, q));
  if (!path) return HttpParseError{400, "malformed escape in the path"};
  request.path = *path;
  if (q != std::string::npos) {
    std::istringstream query(request.target.substr(q + 1));
    std::string pair;
    while (std::getline(query, pair, '&')) {
      if (pair.empty()) continue;
      const auto eq = pair.find('=');
      const auto key = percent_decode(pair.substr(0, eq));
      const auto value = percent_decode(eq == std::string::npos ? "" : pair.substr(eq + 1));
      if (!key || !value) return HttpParseError{400, "malformed escape in the query"};
      request.query[*key] = *value;
    }
  }
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto colon = line.find(':');
    if (colon == std::string::npos || colon == 0) return HttpParseError{400, "malformed header line"};
    request.headers[lower(trim(line.substr(0, colon)))] = trim(line.substr(colon + 1));
  }
  return std::nullopt;
}

std::string serialise(const HttpResponse& r) {
  std::ostringstream out;
  out << "HTTP/1.1 " << r.status << ' ' << reason_phrase(r.status) << "\r\n"
      << "Content-Type: " << r.content_type << "\r\n"
      << "Content-Length: " << r.body.size() << "\r\n"
      << "Connection: close\r\n";
  for (const auto& [name, value] : r.headers) out << name << ": " << value << "\r\n";
  out << "\r\n";
  out << r.body;
  return out.str();
}

HttpServer::HttpServer(int port) {
  const std::string where = kServerName + ":" + std::to_string(port);
  if (port < 0 || port > 65535) throw UsageError("--port must be 0-65535, got " + std::to_string(port));
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw InputError(where, 0, std::string("cannot open a socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);  // loopback only: nothing else can connect
  if (::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || ::listen(fd_, 16) != 0) {
    const std::string reason = std::strerror(errno);
    ::close(fd_);
    throw InputError(where, 0, "cannot listen: " + reason);
  }
  socklen_t size = sizeof address;
  ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size);
  port_ = ntohs(address.sin_port);
}

HttpServer::~HttpServer() {
  if (fd_ >= 0) ::close(fd_);
}

void HttpServer::serve(const std::function<HttpResponse(const HttpRequest&, bool* stop)>& handler) {
  // Connections are read side by side (poll), so that one that sends nothing (a browser's
  // speculative preconnect) does not hold up the others; each is answered as soon as its request
  // is complete, one at a time, and dropped after kSocketTimeoutS of silence.
  struct Client {
    int fd;
    std::string data;
    std::chrono::steady_clock::time_point deadline;
  };
  std::vector<Client> clients;
  bool stop = false;
  const auto finish = [](Client& c, const HttpResponse& response) {
    timeval timeout{kSocketTimeoutS, 0};
    ::setsockopt(c.fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
    send_all(c.fd, serialise(response));
    ::shutdown(c.fd, SHUT_WR);
    ::close(c.fd);
    c.fd = -1;
  };
  while (!stop) {
    std::vector<pollfd> fds{{fd_, POLLIN, 0}};
    for (const auto& c : clients) fds.push_back({c.fd, POLLIN, 0});
    const int n = ::poll(fds.data(), fds.size(), 1000);
    if (n < 0 && errno != EINTR) {
      throw InputError(kServerName + ":" + std::to_string(port_), 0, std::string("poll: ") + std::strerror(errno));
    }
    const auto now = std::chrono::steady_clock::now();
    for (std::size_t i = 1; n > 0 && i < fds.size(); ++i) {
      Client& c = clients[i - 1];
      if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      char buffer[8192];
      const ssize_t got = ::recv(c.fd, buffer, sizeof buffer, 0);
      if (got <= 0) {
        if (got < 0 && errno == EINTR) continue;
        ::close(c.fd);  // closed or failed before a whole request: nothing to answer
        c.fd = -1;
        continue;
      }
      c.data.append(buffer, static_cast<std::size_t>(got));
      HttpRequest request;
      bool ready = false;
      auto refusal = parse_received(c.data, request, &ready);
      if (!ready) continue;
      finish(c, refusal ? *refusal : handler(request, &stop));
      if (stop) break;
    }
    for (auto& c : clients) {
      if (c.fd >= 0 && now > c.deadline) finish(c, refuse(408, "request timeout"));
    }
    clients.erase(std::remove_if(clients.begin(), clients.end(), [](const Client& c) { return c.fd < 0; }), clients.end());
    if (!stop && n > 0 && (fds[0].revents & POLLIN)) {
      const int client = ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (client >= 0) {
        if (clients.size() >= kMaxConnections) {
          Client c{client, {}, now};
          finish(c, refuse(503, "too many connections"));
        } else {
          clients.push_back({client, {}, now + std::chrono::seconds(kSocketTimeoutS)});
        }
      } else if (errno != EINTR && errno != ECONNABORTED && errno != EAGAIN) {
        throw InputError(kServerName + ":" + std::to_string(port_), 0, std::string("accept: ") + std::strerror(errno));
      }
    }
  }
  for (auto& c : clients) ::close(c.fd);
}

}  // namespace photomill::pick
