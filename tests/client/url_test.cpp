// client/stream's server address: ws://host:port[/path], and every malformed form refused by name.
#include "client/stream/url.hpp"

#include <gtest/gtest.h>

namespace grotto::stream {
namespace {

TEST(Url, parses_host_port_and_path_with_defaults) {
  struct Row {
    const char* text;
    const char* host;
    uint16_t port;
    const char* path;
  };
  const Row rows[] = {
      {"ws://example.org:8080/caves/ws", "example.org", 8080, "/caves/ws"},
      {"ws://h", "h", 80, "/ws"},
      {"ws://127.0.0.1:1/ws", "127.0.0.1", 1, "/ws"},
      {"ws://h:65535/ws?seed=7", "h", 65535, "/ws?seed=7"},
  };
  for (const Row& r : rows) {
    auto url = parse_url(r.text);
    ASSERT_TRUE(url.ok()) << r.text << ": " << url.error().message;
    EXPECT_EQ(url->host, r.host) << r.text;
    EXPECT_EQ(url->port, r.port) << r.text;
    EXPECT_EQ(url->path, r.path) << r.text;
  }
}

TEST(Url, refuses_what_is_not_a_ws_url_and_says_why) {
  struct Row {
    const char* text;
    const char* why;
  };
  const Row rows[] = {
      {"", "must start with ws://"},
      {"http://x:1/ws", "must start with ws://"},
      {"wss://host:443/ws", "wss is not supported"},
      {"ws://", "no host"},
      {"ws://:80", "no host"},
      {"ws://host:0", "port must be"},
      {"ws://host:99999", "port must be"},
      {"ws://host:12x", "port must be"},
      {"ws://host:", "port must be"},
      {"ws://a b:1/ws", "invalid host"},
      {"ws://user@h:1/ws", "invalid host"},
  };
  for (const Row& r : rows) {
    auto url = parse_url(r.text);
    ASSERT_FALSE(url.ok()) << r.text;
    EXPECT_EQ(url.error().code, ErrorCode::kInvalidArgument) << r.text;
    EXPECT_NE(url.error().message.find(r.why), std::string::npos) << url.error().message;
    EXPECT_NE(url.error().message.find("url"), std::string::npos) << url.error().message;
  }
}

}  // namespace
}  // namespace grotto::stream
