#include "pick/server.hpp"

#include <cmath>
#include <limits>
#include <random>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "formats/error.hpp"
#include "formats/image.hpp"
#include "formats/image_decode.hpp"
#include "formats/json.hpp"
#include "formats/json_value.hpp"
#include "formats/log.hpp"
#include "pick/page_assets.hpp"

namespace photomill::pick {
namespace {

HttpResponse text(int status, const std::string& message) {
  return {status, "text/plain; charset=utf-8", message + "\n", {}};
}

HttpResponse json(const std::string& body) { return {200, "application/json", body, {}}; }

// Equal strings in a time that does not depend on where they differ.
bool same_secret(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

// A non-negative integer made of digits only ("3", not "+3", "3.0" or "03x"); nullopt otherwise.
std::optional<std::size_t> index_of(const std::string& s) {
  if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos) return std::nullopt;
  return static_cast<std::size_t>(std::stoul(s));
}

const JsonValue& member(const JsonValue& body, const char* key) {
  const JsonValue* v = body.find(key);
  if (!v) throw RequestError(std::string("missing \"") + key + "\"");
  return *v;
}

double number(const JsonValue& body, const char* key) {
  const JsonValue& v = member(body, key);
  if (!v.is_number() || !std::isfinite(v.number)) throw RequestError(std::string("\"") + key + "\" must be a number");
  return v.number;
}

std::int64_t integer(const JsonValue& body, const char* key, std::int64_t max) {
  const double d = number(body, key);
  if (d < 0 || d > static_cast<double>(max) || d != std::floor(d)) {
    throw RequestError(std::string("\"") + key + "\" must be an integer from 0 to " + std::to_string(max));
  }
  return static_cast<std::int64_t>(d);
}

JsonValue request_json(const std::string& body) {
  try {
    JsonValue v = parse_json(body, "request");
    if (v.type != JsonValue::Type::Object) throw RequestError("the request's body must be a JSON object");
    return v;
  } catch (const InputError& e) {
    throw RequestError(e.what());
  }
}

void write_point(JsonWriter& w, const Eigen::Vector2d& uv) { w.begin_array().value(uv.x()).value(uv.y()).end_array(); }

std::string image_type(const std::string& bytes) {
  if (bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xFF && static_cast<unsigned char>(bytes[1]) == 0xD8) return "image/jpeg";
  if (bytes.size() >= 8 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) return "image/png";
  return "";
}

}  // namespace

std::string make_token() {
  std::random_device device;
  std::ostringstream out;
  static const char* hex = "0123456789abcdef";
  for (int i = 0; i < 8; ++i) {
    const unsigned v = device();
    for (int k = 0; k < 4; ++k) out << hex[(v >> (8 * k + 4)) & 15] << hex[(v >> (8 * k)) & 15];
  }
  return out.str().substr(0, 32);
}

const std::string& page_html() {
  static const std::string s(kPageHtml);
  return s;
}
const std::string& page_script() {
  static const std::string s(kPageScript);
  return s;
}
const std::string& page_style() {
  static const std::string s(kPageStyle);
  return s;
}

App::App(Session& session, std::string token, int port, Refine default_refine)
    : session_(session), token_(std::move(token)), port_(port), default_refine_(default_refine) {}

std::string App::url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/?token=" + token_; }

std::string App::refusal(const HttpRequest& r) const {
  const std::string port = std::to_string(port_);
  const std::string host = r.header("host");
  if (host != "127.0.0.1:" + port && host != "localhost:" + port) return "wrong Host: " + host;
  const std::string origin = r.header("origin");
  if (!origin.empty() && origin != "http://127.0.0.1:" + port && origin != "http://localhost:" + port) {
    return "request from another origin: " + origin;
  }
  const std::string site = r.header("sec-fetch-site");
  if (site == "cross-site" || site == "same-site") return "request from another site";
  const auto t = r.query.find("token");
  if (t == r.query.end() || !same_secret(t->second, token_)) return "missing or wrong token";
  return "";
}

HttpResponse App::handle(const HttpRequest& r, bool* stop) {
  if (const std::string why = refusal(r); !why.empty()) {
    log::debug("refused " + r.method + " " + r.path + ": " + why);
    return text(403, "refused: " + why);
  }
  const bool get = r.method == "GET", post = r.method == "POST";
  if (post && r.header("content-type").rfind("application/json", 0) != 0) return text(400, "POST needs Content-Type: application/json");
  HttpResponse response;
  try {
    if (get && r.path == "/") {
      std::string page = page_html();  // the token goes into the script's and style's addresses
      for (auto at = page.find("__TOKEN__"); at != std::string::npos; at = page.find("__TOKEN__", at)) page.replace(at, 9, token_);
      response = {200, "text/html; charset=utf-8", std::move(page), {}};
    } else if (get && r.path == "/pick.js") {
      response = {200, "text/javascript; charset=utf-8", page_script(), {}};
    } else if (get && r.path == "/pick.css") {
      response = {200, "text/css; charset=utf-8", page_style(), {}};
    } else if (get && r.path == "/api/state") {
      response = state();
    } else if (get && r.path == "/api/guide") {
      response = guide(r);
    } else if (get && (r.path.rfind("/photo/", 0) == 0 || r.path.rfind("/thumb/", 0) == 0)) {
      const bool thumb = r.path[1] == 't';
      const auto i = index_of(r.path.substr(7));
      if (!i || *i >= session_.photos().size()) return text(404, "no such photo");
      const Photo& p = session_.photos()[*i];
      if (thumb) {
        response = {200, "image/jpeg", p.thumbnail_jpeg, {}};
      } else {
        std::string bytes = read_image_file(p.path);
        std::string type = image_type(bytes);
        if (type.empty()) {  // a format browsers may not show (TIFF, ...): as PNG
          std::vector<unsigned char> png;
          cv::imencode(".png", read_image(p.path, cv::IMREAD_UNCHANGED), png);
          bytes.assign(png.begin(), png.end());
          type = "image/png";
        }
        response = {200, type, std::move(bytes), {}};
      }
    } else if (post && r.path == "/api/mark") {
      response = mark(r);
    } else if (post && r.path == "/api/delete") {
      response = remove(r);
    } else if (post && r.path == "/api/undo") {
      response = undo();
    } else if (post && r.path == "/api/quit") {
      *stop = true;  // main() saves again if the last save failed, and fails naming the file if it cannot
      response = session_.saved() ? text(200, "pick: finished; " + session_.observations_path() + " holds every mark")
                                  : text(500, "pick: the last marks are not saved in " + session_.observations_path() +
                                                  ": pick tries once more and says on its stderr whether it could");
    } else if (r.path == "/" || r.path == "/pick.js" || r.path == "/pick.css" || r.path.rfind("/api/", 0) == 0) {
      return text(405, "method not allowed");
    } else {
      return text(404, "not found");
    }
  } catch (const RequestError& e) {
    return text(422, e.what());
  } catch (const std::exception& e) {
    // A failed save (a full disk) or an unreadable photo: the page shows the message, and it is
    // logged, since the marks since the last save are at risk.
    log::warn(e.what());
    return text(500, e.what());
  }
  response.headers.emplace_back("Cache-Control", r.path.rfind("/thumb/", 0) == 0 || r.path.rfind("/photo/", 0) == 0 ? "private, max-age=3600" : "no-store");
  response.headers.emplace_back("X-Content-Type-Options", "nosniff");
  response.headers.emplace_back("X-Frame-Options", "DENY");
  response.headers.emplace_back("Referrer-Policy", "no-referrer");
  response.headers.emplace_back("Content-Security-Policy",
                                "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; connect-src 'self'; "
                                "frame-ancestors 'none'; base-uri 'none'; form-action 'none'");
  return response;
}

HttpResponse App::state() const {
  std::ostringstream out;
  JsonWriter w(out);
  w.begin_object();
  w.field("observations_file", session_.observations_path());
  w.field("oriented", session_.oriented());
  w.field("undo_depth", session_.undo_depth());
  w.field("default_refine", to_string(default_refine_));
  w.key("photos").begin_array();
  for (const auto& p : session_.photos()) {
    w.begin_object().field("name", p.path).field("width_px", p.width_px).field("height_px", p.height_px)
        .field("oriented", p.oriented).end_object();
  }
  w.end_array();
  w.key("points").begin_array();
  for (const auto& s : session_.points()) {
    w.begin_object().field("point_id", static_cast<std::int64_t>(s.point_id));
    w.key("observations").begin_array();
    for (const auto& o : s.observations) {
      w.begin_object().field("image", o.image).field("u_px", o.u_px).field("v_px", o.v_px);
      for (const auto& res : s.residuals) {
        if (res.image == o.image) w.field("residual_px", res.residual_px);
      }
      w.end_object();
    }
    w.end_array();
    if (s.xyz) {
      w.key("xyz").begin_array().value(s.xyz->x()).value(s.xyz->y()).value(s.xyz->z()).end_array();
    } else {
      w.field("triangulation_note", s.triangulation_note);
    }
    w.end_object();
  }
  w.end_array();
  w.field("next_free_id", static_cast<std::int64_t>(session_.next_free_id()));
  w.end_object();
  return json(out.str());
}

HttpResponse App::guide(const HttpRequest& r) const {
  const auto point = r.query.find("point"), photo = r.query.find("photo");
  const std::size_t none = std::numeric_limits<std::size_t>::max();
  const std::size_t point_id = point == r.query.end() ? none : index_of(point->second).value_or(none);
  const std::size_t photo_index = photo == r.query.end() ? none : index_of(photo->second).value_or(none);
  if (point_id == none || photo_index >= session_.photos().size()) return text(422, "guide needs point=ID and photo=INDEX");
  const Guide g = session_.guide(static_cast<PointId>(point_id), photo_index);
  std::ostringstream out;
  JsonWriter w(out);
  w.begin_object().key("curves").begin_array();
  for (const auto& c : g.curves) {
    w.begin_object().field("from_image", c.from_image).key("polylines").begin_array();
    for (const auto& line : c.polylines) {
      w.begin_array();
      for (const auto& uv : line) write_point(w, uv);
      w.end_array();
    }
    w.end_array().end_object();
  }
  w.end_array();
  w.key("predicted_px");
  if (g.predicted_px) {
    write_point(w, *g.predicted_px);
  } else {
    w.null();
  }
  w.end_object();
  return json(out.str());
}

HttpResponse App::mark(const HttpRequest& r) {
  const JsonValue body = request_json(r.body);
  const auto photo = static_cast<std::size_t>(integer(body, "photo", static_cast<std::int64_t>(session_.photos().size()) - 1));
  const PointId id = integer(body, "point_id", std::int64_t{1} << 52);
  const Eigen::Vector2d click(number(body, "u_px"), number(body, "v_px"));
  Refine refine = default_refine_;  // what the page was started with
  if (const JsonValue* v = body.find("refine")) {
    const auto parsed = parse_refine(v->string);
    if (v->type != JsonValue::Type::String || !parsed) throw RequestError("\"refine\" must be none, corner, blob, match or auto");
    refine = *parsed;
  }
  double zoom = 1;
  if (body.find("zoom")) {
    zoom = number(body, "zoom");
    if (!(zoom > 0)) throw RequestError("\"zoom\" must be positive");
  }
  const MarkResult m = session_.mark(photo, id, click, refine, zoom);
  std::ostringstream out;
  JsonWriter w(out);
  w.begin_object().field("image", m.observation.image).field("point_id", static_cast<std::int64_t>(m.observation.point_id))
      .field("u_px", m.observation.u_px).field("v_px", m.observation.v_px).field("refine", to_string(m.refine))
      .field("refined", m.refined).field("shift_px", m.shift_px).field("note", m.note).end_object();
  return json(out.str());
}

HttpResponse App::remove(const HttpRequest& r) {
  const JsonValue body = request_json(r.body);
  const auto photo = static_cast<std::size_t>(integer(body, "photo", static_cast<std::int64_t>(session_.photos().size()) - 1));
  const PointId id = integer(body, "point_id", std::int64_t{1} << 52);
  const bool removed = session_.remove(photo, id);
  return json(std::string("{\"removed\":") + (removed ? "true" : "false") + "}");
}

HttpResponse App::undo() {
  const bool undone = session_.undo();
  return json(std::string("{\"undone\":") + (undone ? "true" : "false") + "}");
}

}  // namespace photomill::pick
