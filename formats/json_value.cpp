// A small JSON reader (see json_value.hpp): recursive descent over RFC 8259's grammar.
#include "formats/json_value.hpp"

#include <cmath>
#include <iterator>
#include <locale>
#include <sstream>
#include <tuple>

#include "formats/error.hpp"

namespace photomill {

const JsonValue* JsonValue::find(std::string_view key) const {
  if (type != Type::Object) return nullptr;
  for (const auto& [k, v] : object) {
    if (k == key) return &v;
  }
  return nullptr;
}

const JsonValue* JsonValue::at(std::string_view path) const {
  const JsonValue* v = this;
  while (v) {
    const std::size_t dot = path.find('.');
    v = v->find(path.substr(0, dot));
    if (dot == std::string_view::npos) return v;
    path.remove_prefix(dot + 1);
  }
  return nullptr;
}

namespace {

class Parser {
public:
  Parser(std::string_view text, const std::string& source) : s_(text), source_(source) {}

  JsonValue document() {
    space();
    if (pos_ == s_.size()) fail("empty file, not JSON");
    JsonValue v = value(0);
    space();
    if (pos_ != s_.size()) fail(std::string("unexpected '") + s_[pos_] + "' after the JSON value");
    return v;
  }

private:
  [[noreturn]] void fail(const std::string& what) const {
    std::size_t line = 1;
    for (std::size_t k = 0; k < pos_ && k < s_.size(); ++k) line += s_[k] == '\n';
    throw InputError(source_, line, what);
  }
  void space() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
  }
  bool take(char c) {
    if (pos_ < s_.size() && s_[pos_] == c) return ++pos_, true;
    return false;
  }
  std::string where() const { return pos_ < s_.size() ? std::string("'") + s_[pos_] + "'" : "the end of the file"; }

  JsonValue value(int depth) {
    if (depth > kMaxJsonDepth) fail("nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    space();
    if (pos_ >= s_.size()) fail("the file ends where a value was expected");
    JsonValue v;
    const char c = s_[pos_];
    if (c == '{') {
      ++pos_;
      v.type = JsonValue::Type::Object;
      space();
      if (take('}')) return v;
      for (;;) {
        space();
        if (pos_ >= s_.size() || s_[pos_] != '"') fail("expected a string key in an object, found " + where());
        std::string key = string();
        space();
        if (!take(':')) fail("expected ':' after the key \"" + key + "\", found " + where());
        v.object.push_back({std::move(key), value(depth + 1)});
        space();
        if (take('}')) return v;
        if (!take(',')) fail("expected ',' or '}' after an object member, found " + where());
      }
    }
    if (c == '[') {
      ++pos_;
      v.type = JsonValue::Type::Array;
      space();
      if (take(']')) return v;
      for (;;) {
        v.array.push_back(value(depth + 1));
        space();
        if (take(']')) return v;
        if (!take(',')) fail("expected ',' or ']' after an array element, found " + where());
      }
    }
    if (c == '"') {
      v.type = JsonValue::Type::String;
      v.string = string();
      return v;
    }
    for (const auto& [word, type, flag] : {std::tuple{"true", JsonValue::Type::Boolean, true},
                                           std::tuple{"false", JsonValue::Type::Boolean, false},
                                           std::tuple{"null", JsonValue::Type::Null, false}}) {
      if (s_.substr(pos_, std::string_view(word).size()) == word) {
        pos_ += std::string_view(word).size();
        v.type = type, v.boolean = flag;
        return v;
      }
    }
    if (c == '-' || (c >= '0' && c <= '9')) {
      v.type = JsonValue::Type::Number;
      v.number = number();
      return v;
    }
    fail("expected a value, found " + where());
  }

  // number = [ minus ] int [ frac ] [ exp ] (RFC 8259, 6), read in the C locale by std::istringstream.
  double number() {
    const std::size_t start = pos_;
    const auto digits = [&] {
      const std::size_t from = pos_;
      while (pos_ < s_.size() && s_[pos_] >= '0' && s_[pos_] <= '9') ++pos_;
      return pos_ > from;
    };
    take('-');
    if (take('0')) {
      if (pos_ < s_.size() && s_[pos_] >= '0' && s_[pos_] <= '9') fail("a number with a leading zero");
    } else if (!digits()) {
      fail("expected digits in a number");
    }
    if (take('.') && !digits()) fail("expected digits after the decimal point");
    if (pos_ < s_.size() && (s_[pos_] == 'e' || s_[pos_] == 'E')) {
      ++pos_;
      if (!take('+')) take('-');
      if (!digits()) fail("expected digits in the exponent");
    }
    std::istringstream in(std::string(s_.substr(start, pos_ - start)));
    in.imbue(std::locale::classic());
    double d = 0;
    in >> d;
    if (in.fail() || !std::isfinite(d)) fail("a number beyond the range of a double");
    return d;
  }

  std::string string() {
    ++pos_;  // the opening quote
    std::string out;
    for (;;) {
      if (pos_ >= s_.size()) fail("the file ends inside a string");
      const char c = s_[pos_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) fail("a control character inside a string");
      if (c != '\\') {
        out += c;
        continue;
      }
      if (pos_ >= s_.size()) fail("the file ends inside a string");
      const char e = s_[pos_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xD800 && cp < 0xDC00) {  // a surrogate pair
            if (!(take('\\') && take('u'))) fail("a lone UTF-16 surrogate in a string");
            const unsigned low = hex4();
            if (low < 0xDC00 || low >= 0xE000) fail("a lone UTF-16 surrogate in a string");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (low - 0xDC00);
          }
          utf8(out, cp);
          break;
        }
        default: fail(std::string("an unknown escape '\\") + e + "' in a string");
      }
    }
  }
  unsigned hex4() {
    unsigned v = 0;
    for (int k = 0; k < 4; ++k) {
      if (pos_ >= s_.size()) fail("the file ends inside a \\u escape");
      const char c = s_[pos_++];
      v <<= 4;
      if (c >= '0' && c <= '9') v |= static_cast<unsigned>(c - '0');
      else if (c >= 'a' && c <= 'f') v |= static_cast<unsigned>(c - 'a' + 10);
      else if (c >= 'A' && c <= 'F') v |= static_cast<unsigned>(c - 'A' + 10);
      else fail("expected 4 hex digits after \\u");
    }
    return v;
  }
  static void utf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += static_cast<char>(cp);
    } else if (cp < 0x800) {
      out += static_cast<char>(0xC0 | (cp >> 6)), out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xE0 | (cp >> 12)), out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (cp >> 18)), out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F)), out += static_cast<char>(0x80 | (cp & 0x3F));
    }
  }

  std::string_view s_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

}  // namespace

JsonValue parse_json(std::string_view text, const std::string& source_name) { return Parser(text, source_name).document(); }

JsonValue read_json(std::istream& in, const std::string& source_name) {
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(source_name, 0, "read error");
  return parse_json(text, source_name);
}

}  // namespace photomill
