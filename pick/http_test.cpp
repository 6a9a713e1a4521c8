// pick's request parsing (issue 29): percent-decoding, the request head, refusals.
#include <gtest/gtest.h>

#include "pick/http.hpp"

namespace photomill::pick {
namespace {

TEST(PercentDecode, DecodesEscapesAndRefusesMalformedOnes) {
  EXPECT_EQ(percent_decode("/photo/3"), "/photo/3");
  EXPECT_EQ(percent_decode("%2e%2E%2F"), "../");
  EXPECT_EQ(percent_decode("a+b"), "a+b");
  EXPECT_FALSE(percent_decode("%2"));
  EXPECT_FALSE(percent_decode("%zz"));
  EXPECT_FALSE(percent_decode("a%00b"));  // an encoded NUL could cut a name short
}

TEST(RequestHead, ParsesPathQueryAndHeaders) {
  HttpRequest r;
  ASSERT_FALSE(parse_request_head("GET /api/guide?point=56&photo=%31&token=ab HTTP/1.1\r\nHost: 127.0.0.1:80\r\n"
                                  "Origin:  http://127.0.0.1:80 \r\n", r));
  EXPECT_EQ(r.method, "GET");
  EXPECT_EQ(r.path, "/api/guide");
  EXPECT_EQ(r.query.at("point"), "56");
  EXPECT_EQ(r.query.at("photo"), "1");
  EXPECT_EQ(r.query.at("token"), "ab");
  EXPECT_EQ(r.header("host"), "127.0.0.1:80");
  EXPECT_EQ(r.header("origin"), "http://127.0.0.1:80");
  EXPECT_EQ(r.header("absent"), "");
}

TEST(RequestHead, RefusesMalformedRequests) {
  for (const std::string head : {"", "GET", "GET /", "GET / HTTP/2.0", "GET / HTTP/1.1 extra", "GET http://x/ HTTP/1.1",
                                 "GET /%zz HTTP/1.1", "GET /?a=%zz HTTP/1.1", "GET / HTTP/1.1\r\nno colon"}) {
    HttpRequest r;
    const auto e = parse_request_head(head, r);
    ASSERT_TRUE(e) << head;
    EXPECT_EQ(e->status, 400) << head;
    EXPECT_FALSE(e->reason.empty());
  }
}

TEST(Response, SerialisesStatusLengthAndHeaders) {
  const std::string wire = serialise({404, "text/plain; charset=utf-8", "not found\n", {{"X-Frame-Options", "DENY"}}});
  EXPECT_EQ(wire.rfind("HTTP/1.1 404 Not Found\r\n", 0), 0u) << wire;
  EXPECT_NE(wire.find("Content-Length: 10\r\n"), std::string::npos);
  EXPECT_NE(wire.find("Connection: close\r\n"), std::string::npos);
  EXPECT_NE(wire.find("X-Frame-Options: DENY\r\n"), std::string::npos);
  EXPECT_EQ(wire.substr(wire.size() - 14), "\r\n\r\nnot found\n");
}

}  // namespace
}  // namespace photomill::pick
