// Rooms as immutable HTTP resources (PROTOCOL.md, "Rooms over HTTP"), over real
// loopback sockets: a Server started in-process on 127.0.0.1, port 0. A room URL answers the
// WebSocket room frame's bytes with the cache headers, 304 to its ETag, each bad URL its status
// and a one-line reason, and the token and rate rules of the WebSocket.
#include <gtest/gtest.h>

#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "proto/room_path.hpp"
#include "proto/world_digest.hpp"
#include "server/config.hpp"
#include "server/server.hpp"
#include "tests/server/harness_plain.hpp"

namespace {

using namespace grotto::server_test;
using grotto::cave::RoomId;
using grotto::server::Server;
using grotto::server::ServerConfig;

// As server_harness.hpp's test_config: port 0, the CPU reference, two threads.
ServerConfig config() {
  ServerConfig c;
  c.port = 0;
  c.io_threads = 2;
  c.generator.workers = 2;
  c.generator.builder.device.device = "none";
  c.log_level = "warn";
  return c;
}

std::unique_ptr<Server> start(const ServerConfig& c) {
  auto s = Server::start(c);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  return s.ok() ? std::move(s).value() : nullptr;
}

std::vector<RoomId> spawn_sector_rooms(const ServerConfig& c, size_t count) {
  auto world = grotto::cave::World::create(c.seed, c.layout);
  std::vector<RoomId> out;
  for (const auto& r : grotto::cave::generate_sector(*world, {0, 0, 0}).rooms) {
    if (out.size() < count) out.push_back(r.id);
  }
  return out;
}

std::string url(const ServerConfig& c, RoomId id, uint32_t version = 2, uint32_t lod = 0) {
  grotto::proto::RoomPath p;
  p.version = version;
  p.seed = c.seed;
  p.params = grotto::proto::world_params_digest(c.layout, c.mesh);
  p.lod = lod;
  p.id = id;
  return grotto::proto::room_path(p);
}

HttpAnswer get(uint16_t port, const std::string& target,
               std::vector<std::pair<std::string, std::string>> headers = {},
               const std::string& method = "GET") {
  auto answers = http_exchange(port, {{method, target, std::move(headers)}});
  return answers.empty() ? HttpAnswer{} : answers.front();
}

TEST(RoomsOverHttp, a_room_url_answers_the_websocket_frames_bytes_with_cache_headers) {
  auto c = config();
  auto server = start(c);
  ASSERT_TRUE(server);
  const std::regex strong_etag(R"re("[0-9a-f]{16}")re");
  for (uint32_t version : {1u, 2u}) {
    for (RoomId id : spawn_sector_rooms(c, 3)) {
      SCOPED_TRACE(url(c, id, version));
      std::string frame = websocket_room_frame(server->port(), id, 0, version);
      ASSERT_FALSE(frame.empty());
      const uint64_t built = server->metrics().rooms_built.value();
      auto a = get(server->port(), url(c, id, version));
      ASSERT_EQ(a.status, 200) << a.body;
      EXPECT_EQ(a.body, frame) << "not the WebSocket room frame's bytes";
      EXPECT_EQ(server->metrics().rooms_built.value(), built) << "not from the generator's cache";
      EXPECT_EQ(a.header("cache-control"), "public, max-age=31536000, immutable");
      EXPECT_EQ(a.header("content-type"), "application/octet-stream");
      EXPECT_EQ(a.header("content-length"), std::to_string(frame.size()));
      EXPECT_TRUE(std::regex_match(a.header("etag"), strong_etag)) << a.header("etag");
      // HEAD: the same headers, no body.
      auto h = get(server->port(), url(c, id, version), {}, "HEAD");
      ASSERT_EQ(h.status, 200);
      EXPECT_TRUE(h.body.empty());
      EXPECT_EQ(h.header("content-length"), std::to_string(frame.size()));
      EXPECT_EQ(h.header("etag"), a.header("etag"));
      EXPECT_EQ(h.header("cache-control"), a.header("cache-control"));
    }
  }
  // The same room in two versions is two resources with two tags.
  auto id = spawn_sector_rooms(c, 1).front();
  EXPECT_NE(get(server->port(), url(c, id, 1)).header("etag"),
            get(server->port(), url(c, id, 2)).header("etag"));
  EXPECT_EQ(server->metrics().rooms_http_served.value(), 14u);  // 12 above and these 2
  // /version names what a room URL needs: the seed and the parameter digest.
  auto v = get(server->port(), "/version");
  EXPECT_NE(
      v.body.find("\"seed\":\"7\",\"params\":\"" +
                  grotto::proto::digest_text(grotto::proto::world_params_digest(c.layout, c.mesh)) +
                  "\""),
      std::string::npos)
      << v.body;
  // So does /metrics.
  auto m = get(server->port(), "/metrics");
  EXPECT_NE(m.body.find("grotto_rooms_http_served_total 14\n"), std::string::npos);
  EXPECT_NE(m.body.find("grotto_rooms_http_refused_total{status=\"404\"} 0\n"), std::string::npos);
}

TEST(RoomsOverHttp, a_room_not_yet_built_is_built_through_the_generator) {
  auto c = config();
  auto server = start(c);
  ASSERT_TRUE(server);
  auto id = spawn_sector_rooms(c, 2).back();
  auto a = get(server->port(), url(c, id));
  ASSERT_EQ(a.status, 200) << a.body;
  EXPECT_EQ(server->metrics().rooms_built.value(), 1u);
  EXPECT_EQ(a.body, websocket_room_frame(server->port(), id, 0, 2));
  EXPECT_EQ(server->metrics().rooms_built.value(), 1u) << "the player's want was a cache hit";
}

TEST(RoomsOverHttp, if_none_match_with_the_etag_gets_304) {
  auto c = config();
  auto server = start(c);
  ASSERT_TRUE(server);
  const std::string target = url(c, spawn_sector_rooms(c, 1).front());
  auto first = get(server->port(), target);
  ASSERT_EQ(first.status, 200);
  const std::string etag = first.header("etag");
  struct Case {
    std::string if_none_match;
    int status;
  };
  for (const Case& k :
       {Case{etag, 304}, Case{"W/" + etag, 304}, Case{"*", 304},
        Case{"\"0123456789abcdef\", " + etag, 304}, Case{"\"0123456789abcdef\"", 200}}) {
    SCOPED_TRACE(k.if_none_match);
    auto a = get(server->port(), target, {{"If-None-Match", k.if_none_match}});
    EXPECT_EQ(a.status, k.status);
    EXPECT_EQ(a.header("etag"), etag);
    EXPECT_EQ(a.header("cache-control"), "public, max-age=31536000, immutable");
    if (k.status == 304) {
      EXPECT_TRUE(a.body.empty());
    } else {
      EXPECT_EQ(a.body, first.body);
    }
  }
  EXPECT_EQ(server->metrics().rooms_http_not_modified.value(), 4u);
}

TEST(RoomsOverHttp, bad_room_urls_get_their_status_and_a_one_line_reason) {
  auto c = config();
  c.generator.max_worlds = 1;  // a server of one world: another seed's room is not found
  auto server = start(c);
  ASSERT_TRUE(server);
  const RoomId id = spawn_sector_rooms(c, 1).front();
  const std::string good = url(c, id);
  const std::string digest =
      grotto::proto::digest_text(grotto::proto::world_params_digest(c.layout, c.mesh));
  struct Case {
    std::string method;
    std::string target;
    int status;
    std::string reason;  // a part of the one-line body
  };
  for (const Case& k : {
           Case{"POST", good, 405, "GET and HEAD only"},
           Case{"DELETE", good, 405, "GET and HEAD only"},
           Case{"GET", "/rooms/v2/7", 400, "parts after /rooms/"},
           Case{"GET", "/rooms/2/7/" + digest + "/0/0.0.0.r0", 400, "version"},
           Case{"GET", "/rooms/v2/07/" + digest + "/0/0.0.0.r0", 400, "'seed'"},
           Case{"GET", "/rooms/v2/7/ABC/0/0.0.0.r0", 400, "'params'"},
           Case{"GET", "/rooms/v2/7/" + digest + "/x/0.0.0.r0", 400, "lod"},
           Case{"GET", "/rooms/v2/7/" + digest + "/0/0.0.0.r9999", 400, "interior index"},
           Case{"GET", "/rooms/v3/7/" + digest + "/0/0.0.0.r0", 404, "protocol version 3"},
           Case{"GET", "/rooms/v2/7/0000000000000001/0/0.0.0.r0", 404,
                "world parameters 0000000000000001 are not this server's (" + digest + ")"},
           Case{"GET", "/rooms/v2/7/" + digest + "/1/0.0.0.r0", 404, "max_lod 0"},
           Case{"GET", "/rooms/v2/8/" + digest + "/0/0.0.0.r0", 404, "serves seed 7, not 8"},
           Case{"GET", "/rooms/v2/7/" + digest + "/0/0.0.0.r4000", 404, "does not exist"},
       }) {
    SCOPED_TRACE(k.method + " " + k.target);
    auto a = get(server->port(), k.target, {}, k.method);
    EXPECT_EQ(a.status, k.status);
    EXPECT_NE(a.body.find(k.reason), std::string::npos) << a.body;
    ASSERT_FALSE(a.body.empty());
    EXPECT_EQ(a.body.find('\n'), a.body.size() - 1) << "one line: " << a.body;
    EXPECT_EQ(a.header("content-type"), "text/plain");
    EXPECT_EQ(a.header("cache-control"), "no-store");
    if (k.status == 405) {
      EXPECT_EQ(a.header("allow"), "GET, HEAD");
    }
  }
  EXPECT_EQ(server->metrics().room_http_refusals(405), 2u);
  EXPECT_EQ(server->metrics().room_http_refusals(400), 6u);
  EXPECT_EQ(server->metrics().room_http_refusals(404), 5u);
  EXPECT_EQ(get(server->port(), good).status, 200) << "the server still serves";
}

// Grotto-Priority (how soon the room is needed; a replica's owner fetch passes its player's)
// takes whole milliseconds up to an hour; anything else is refused, naming the header.
TEST(RoomsOverHttp, grotto_priority_is_whole_milliseconds_or_refused) {
  auto c = config();
  auto server = start(c);
  ASSERT_TRUE(server);
  const std::string good = url(c, spawn_sector_rooms(c, 1).front());
  for (const char* bad : {"soon", "-1", "1.5", "3600001", "99999999999"}) {
    auto a = get(server->port(), good, {{"Grotto-Priority", bad}});
    EXPECT_EQ(a.status, 400) << bad;
    EXPECT_NE(a.body.find("Grotto-Priority must be whole milliseconds from 0 to 3600000"),
              std::string::npos)
        << bad << ": " << a.body;
  }
  for (const char* ok : {"0", "250", "3600000"})
    EXPECT_EQ(get(server->port(), good, {{"Grotto-Priority", ok}}).status, 200) << ok;
}

// A server with a token serves rooms only to requests that carry it, as it serves players only
// after a hello with it (PROTOCOL.md, "Rooms over HTTP").
TEST(RoomsOverHttp, with_a_token_room_urls_need_it) {
  auto c = config();
  c.token = "fleet secret 42";
  auto server = start(c);
  ASSERT_TRUE(server);
  const RoomId id = spawn_sector_rooms(c, 1).front();
  struct Case {
    std::vector<std::pair<std::string, std::string>> headers;
    int status;
    std::string reason;
  };
  for (const Case& k : {Case{{}, 401, "missing token"},
                        Case{{{"Authorization", "Bearer fleet secret 43"}}, 401, "wrong token"},
                        Case{{{"Authorization", "Bearer fleet secret"}}, 401, "wrong token"},
                        Case{{{"Authorization", "Basic fleet secret 42"}}, 401, "wrong token"},
                        Case{{{"Authorization", "Bearer fleet secret 42"}}, 200, ""}}) {
    SCOPED_TRACE(k.headers.empty() ? "none" : k.headers[0].second);
    auto a = get(server->port(), url(c, id), k.headers);
    EXPECT_EQ(a.status, k.status);
    EXPECT_NE(a.body.find(k.reason), std::string::npos) << a.body;
    EXPECT_EQ(a.body.find("fleet"), std::string::npos) << "the token is never quoted";
    if (k.status == 401) {
      EXPECT_EQ(a.header("www-authenticate"), "Bearer realm=\"grotto\"");
    } else {
      EXPECT_EQ(a.body, websocket_room_frame(server->port(), id, 0, 2, c.token));
    }
  }
  // The token goes before what the URL asks: another world's parameters still get 401.
  auto other = get(server->port(), "/rooms/v2/7/0000000000000001/0/0.0.0.r0");
  EXPECT_EQ(other.status, 401);
}

// The WebSocket's request rate, per HTTP connection: request_burst rooms at once, then
// request_rate a second; over it, 429 with Retry-After, and the connection stays usable.
TEST(RoomsOverHttp, the_request_rate_holds_per_connection) {
  auto c = config();
  c.limits.request_rate = 1;
  c.limits.request_burst = 2;
  auto server = start(c);
  ASSERT_TRUE(server);
  const std::string target = url(c, spawn_sector_rooms(c, 1).front());
  std::vector<HttpRequest> requests(20, HttpRequest{"GET", target, {}});
  auto answers = http_exchange(server->port(), requests);
  ASSERT_EQ(answers.size(), requests.size()) << "the connection was closed";
  EXPECT_EQ(answers[0].status, 200);
  EXPECT_EQ(answers[1].status, 200);
  size_t refused = 0;
  for (const auto& a : answers) {
    if (a.status != 429) continue;
    ++refused;
    EXPECT_EQ(a.header("retry-after"), "1");
    EXPECT_NE(a.body.find("request_rate (1 rooms/s"), std::string::npos) << a.body;
  }
  EXPECT_GT(refused, 0u);
  // Another connection has its own bucket.
  EXPECT_EQ(get(server->port(), target).status, 200);
}

}  // namespace
