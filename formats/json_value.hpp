// A small JSON reader (RFC 8259) for the stages' reports (--report FILE), which the job report
// (report) reads back: objects keep their key order, numbers are doubles, nesting is limited.
// Errors are InputError(source, line, what is wrong). Standard library only.
#pragma once

#include <istream>
#include <string>
#include <string_view>
#include <vector>

namespace photomill {

struct JsonValue {
  enum class Type { Null, Boolean, Number, String, Array, Object };
  struct Member;  // an object's key and value (defined below: JsonValue is incomplete here)
  Type type = Type::Null;
  bool boolean = false;
  double number = 0;
  std::string string;
  std::vector<JsonValue> array;
  std::vector<Member> object;  // in the file's order

  bool is_number() const { return type == Type::Number; }
  // The member `key` of an object; null for a missing key or a value that is not an object.
  const JsonValue* find(std::string_view key) const;
  // The value at a dotted path of object keys ("residuals.rms_mm"); null if any step is missing.
  const JsonValue* at(std::string_view dotted_path) const;
};

struct JsonValue::Member {
  std::string key;
  JsonValue value;
};

// The deepest nesting of arrays and objects read (a hostile file cannot exhaust the stack).
inline constexpr int kMaxJsonDepth = 200;

// Reads one JSON value and nothing after it but white space. Throws InputError(source_name,
// line, reason) for anything else: `x.json:3: expected ',' or '}' after an object member`.
JsonValue read_json(std::istream& in, const std::string& source_name);
JsonValue parse_json(std::string_view text, const std::string& source_name);

}  // namespace photomill
