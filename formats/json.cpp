#include "formats/json.hpp"

#include <cmath>
#include <cstdio>

#include "formats/text.hpp"

namespace photomill {

std::string json_escape(std::string_view s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += ch;
        }
    }
  }
  return out + "\"";
}

void JsonWriter::separator() {
  if (after_key_) {
    after_key_ = false;
    return;
  }
  if (!first_.empty()) {
    if (!first_.back()) out_ << ",";
    first_.back() = false;
  }
}

JsonWriter& JsonWriter::begin_object() { separator(); out_ << "{"; first_.push_back(true); return *this; }
JsonWriter& JsonWriter::end_object() { first_.pop_back(); out_ << "}"; if (first_.empty()) out_ << "\n"; return *this; }
JsonWriter& JsonWriter::begin_array() { separator(); out_ << "["; first_.push_back(true); return *this; }
JsonWriter& JsonWriter::end_array() { first_.pop_back(); out_ << "]"; if (first_.empty()) out_ << "\n"; return *this; }
JsonWriter& JsonWriter::key(std::string_view k) { separator(); out_ << json_escape(k) << ":"; after_key_ = true; return *this; }
JsonWriter& JsonWriter::value(std::string_view s) { separator(); out_ << json_escape(s); return *this; }
JsonWriter& JsonWriter::value(double d) {
  separator();
  if (std::isfinite(d)) out_ << format_double(d);
  else out_ << "null";
  return *this;
}
JsonWriter& JsonWriter::value(std::int64_t i) { separator(); out_ << i; return *this; }
JsonWriter& JsonWriter::value(bool b) { separator(); out_ << (b ? "true" : "false"); return *this; }
JsonWriter& JsonWriter::null() { separator(); out_ << "null"; return *this; }

}  // namespace photomill
