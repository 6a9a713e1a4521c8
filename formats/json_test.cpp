#include "formats/json.hpp"

#include <cmath>
#include <sstream>

#include <gtest/gtest.h>

namespace photomill {
namespace {

TEST(Json, WritesNestedValuesWithEscapesAndNullForNonFinite) {
  std::ostringstream out;
  JsonWriter j(out);
  j.begin_object().field("name", "a \"b\"\n").field("rms_px", 0.1).field("n", 3).field("ok", true);
  j.key("bad").value(std::nan("")).key("list").begin_array().value(1.5).value(std::int64_t{-2}).begin_object().end_object().end_array();
  j.end_object();
  EXPECT_EQ(out.str(), "{\"name\":\"a \\\"b\\\"\\n\",\"rms_px\":0.1,\"n\":3,\"ok\":true,\"bad\":null,\"list\":[1.5,-2,{}]}\n");
}

TEST(Json, EscapesControlCharacters) { EXPECT_EQ(json_escape(std::string("\x01", 1)), "\"\\u0001\""); }

}  // namespace
}  // namespace photomill
