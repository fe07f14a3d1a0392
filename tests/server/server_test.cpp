// grotto-server over real sockets: a Server started in-process on 127.0.0.1, port 0, and Beast
// WebSocket/HTTP clients on loopback (tests/server/server_harness.hpp). Every wait is bounded
// (kWait), so a broken server fails a test instead of hanging it. Faults (out of descriptors,
// squatters, slow readers, floods, broken caches) are tests/faults/.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <span>
#include <thread>

#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/context.hpp"
#include "common/mesh/room_mesh.hpp"
#include "proto/messages.hpp"
#include "proto/room_frame.hpp"
#include "proto/room_path.hpp"
#include "proto/world_digest.hpp"
#include "server/config.hpp"
#include "server/server.hpp"
#include "tests/server/harness_plain.hpp"
#include "tests/server/server_harness.hpp"

namespace {

using namespace grotto::server_test;

// ---- session basics ----

TEST(ServerSession, hello_gets_welcome_with_the_servers_limits) {
  auto c = test_config();
  c.limits.max_rooms_in_flight = 77;
  c.limits.max_rooms_per_request = 33;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  auto w = client.hello();
  EXPECT_EQ(w.ref, 1u);
  EXPECT_EQ(w.version, grotto::proto::kProtocolVersion);
  EXPECT_EQ(w.seed, c.seed);
  EXPECT_EQ(w.limits, c.limits);
  EXPECT_EQ(w.server, grotto::server::product_version());
  EXPECT_TRUE(client.alive());
  // spawn and locate answer with the layout's own values.
  grotto::proto::Spawn sp;
  sp.ref = 5;
  ASSERT_FALSE(client.send(sp));
  auto in = client.next_text();
  ASSERT_TRUE(in && in->as<grotto::proto::SpawnPoint>());
  auto world = grotto::cave::World::create(c.seed, c.layout);
  EXPECT_EQ(in->as<grotto::proto::SpawnPoint>()->room, grotto::cave::spawn_room(*world));
  grotto::proto::Locate lo;
  lo.ref = 6;
  lo.point = in->as<grotto::proto::SpawnPoint>()->position;
  ASSERT_FALSE(client.send(lo));
  auto located = client.next_text();
  ASSERT_TRUE(located && located->as<grotto::proto::Located>());
  EXPECT_EQ(located->as<grotto::proto::Located>()->ref, 6u);
  EXPECT_TRUE(located->as<grotto::proto::Located>()->room.has_value());
}

TEST(ServerRooms, room_over_the_wire_decodes_to_the_in_process_mesh) {
  auto c = test_config();
  auto server = start(c);
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  auto rooms = sector_rooms(c.seed, {0, 0, 0});
  ASSERT_GE(rooms.size(), 3u);
  ASSERT_FALSE(client.send(request_of(rooms, 0, 3, 10)));
  std::map<uint64_t, std::string> got;
  while (got.size() < 3) {
    auto [ec, in] = client.read();
    ASSERT_FALSE(ec) << ec.message();
    ASSERT_FALSE(in.text) << in.data;
    got[frame_id(in.data).packed()] = in.data;
  }
  auto world = grotto::cave::World::create(c.seed, c.layout);
  auto ctx = grotto::mesh::MeshContext::create(*world, c.mesh);
  ASSERT_TRUE(ctx.ok());
  for (size_t i = 0; i < 3; ++i) {
    const std::string& bytes = got.at(rooms[i].id.packed());
    auto frame = grotto::proto::decode_room_frame(
        std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()),
        server->config().limits);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_EQ(frame->room.id, rooms[i].id);
    EXPECT_EQ(frame->room.portals.size(), rooms[i].portals.size());
    grotto::codec::DecodeLimits limits;
    limits.normals = grotto::proto::payload_has_normals(frame->version);
    auto wire = grotto::codec::decode_room(frame->payload, limits);
    ASSERT_TRUE(wire.ok()) << wire.error().message;
    auto local = grotto::mesh::build_room_mesh(*ctx, rooms[i], grotto::mesh::Lod::kPatch);
    ASSERT_TRUE(local.ok()) << local.error().message;
    EXPECT_EQ(frame->origin, local->origin);
    // The same mesh: the wire decodes exactly as the in-process mesh encoded and decoded again.
    grotto::codec::EncodeOptions options;
    options.normals = limits.normals;
    auto payload = grotto::codec::encode_room(*local, options);
    ASSERT_TRUE(payload.ok());
    EXPECT_EQ(frame->payload, *payload);
    auto again = grotto::codec::decode_room(*payload, limits);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(wire->vertex_count(), local->vertex_count());
    EXPECT_EQ(wire->triangle_count(), local->triangle_count());
    ASSERT_EQ(wire->positions.size(), again->positions.size());
    for (size_t v = 0; v < wire->positions.size(); ++v) {
      EXPECT_EQ(wire->positions[v].x, again->positions[v].x);
      EXPECT_EQ(wire->positions[v].y, again->positions[v].y);
      EXPECT_EQ(wire->positions[v].z, again->positions[v].z);
    }
    EXPECT_EQ(wire->indices, again->indices);
    EXPECT_EQ(wire->rim_index, again->rim_index);
  }
  EXPECT_GE(server->metrics().rooms_served.value(), 3u);
}

TEST(ServerRooms, many_clients_wanting_one_room_cause_one_build) {
  auto c = test_config();
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = sector_rooms(c.seed, {1, 0, 0});
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 4; ++i) {
    clients.push_back(std::make_unique<Client>(server->port()));
    ASSERT_FALSE(clients.back()->connect());
    clients.back()->hello();
  }
  for (auto& cl : clients)
    ASSERT_FALSE(cl->send(request_of(rooms, 5, 1, 1)));
  for (auto& cl : clients) {
    auto [ec, in] = cl->read();
    ASSERT_FALSE(ec);
    ASSERT_FALSE(in.text) << in.data;
    EXPECT_EQ(frame_id(in.data), rooms[5].id);
  }
  EXPECT_EQ(server->metrics().rooms_built.value(), 1u);
  EXPECT_EQ(server->metrics().rooms_served.value(), 4u);
}

TEST(ServerRooms, cancelled_rooms_are_not_sent) {
  auto c = test_config();
  c.generator.workers = 1;
  c.generator.max_batch_rooms = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(200);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  ASSERT_FALSE(client.send(request_of(rooms, 0, 200, 2)));
  grotto::proto::Cancel cancel;
  cancel.ref = 3;
  for (const auto& r : rooms)
    cancel.rooms.push_back(r.id);
  ASSERT_FALSE(client.send(cancel));
  grotto::proto::StatsQuery q;
  q.ref = 4;
  ASSERT_FALSE(client.send(q));
  auto in = client.next_text();
  ASSERT_TRUE(in && in->as<grotto::proto::Stats>()) << (in ? in->data : "");
  EXPECT_EQ(in->as<grotto::proto::Stats>()->in_flight, 0u);
  size_t before_stats = client.frames.size();
  // Nothing cancelled arrives after the cancel was processed: the next thing is the pong.
  EXPECT_TRUE(client.alive());
  EXPECT_EQ(client.frames.size(), before_stats);
  EXPECT_LT(before_stats, rooms.size());
  EXPECT_GT(server->metrics().rooms_cancelled.value(), 0u);
  EXPECT_LT(server->metrics().rooms_built.value(), rooms.size());
}

TEST(ServerRooms, a_greedy_client_does_not_starve_a_modest_one) {
  auto c = test_config();
  c.generator.workers = 1;
  c.generator.max_batch_rooms = 4;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(1001);
  Client greedy(server->port());
  Client modest(server->port());
  ASSERT_FALSE(greedy.connect());
  ASSERT_FALSE(modest.connect());
  greedy.hello("greedy");
  modest.hello("modest");
  for (size_t i = 0; i < 1000; i += 250)
    ASSERT_FALSE(greedy.send(request_of(rooms, i, 250, i)));
  std::this_thread::sleep_for(50ms);
  ASSERT_FALSE(modest.send(request_of(rooms, 1000, 1, 1)));
  auto [ec, in] = modest.read();
  ASSERT_FALSE(ec);
  ASSERT_FALSE(in.text) << in.data;
  EXPECT_EQ(frame_id(in.data), rooms[1000].id);
  // Round-robin across clients: the modest room went out long before the greedy client's 1,000.
  EXPECT_LT(server->metrics().rooms_served.value(), 500u);
}

TEST(ServerRooms, re_requesting_a_room_replaces_its_lod_and_priority) {
  auto c = test_config();
  c.generator.workers = 1;
  c.generator.max_batch_rooms = 2;
  c.limits.max_lod = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(301);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  // 300 rooms queue ahead of room X at lod 0 ...
  for (size_t i = 0; i < 300; i += 150) {
    ASSERT_FALSE(client.send(request_of(rooms, i, 150, i, 10)));
  }
  grotto::proto::Request x;
  x.ref = 1;
  x.rooms.push_back({rooms[300].id, 0, 20});
  ASSERT_FALSE(client.send(x));
  // ... then X again at lod 1, first in line: the lod and the priority are replaced.
  x.ref = 2;
  x.rooms[0] = {rooms[300].id, 1, 0};
  ASSERT_FALSE(client.send(x));
  int x_frames = 0;
  int lod = -1;
  for (int n = 0; n < 301 && x_frames == 0; ++n) {
    auto [ec, in] = client.read();
    ASSERT_FALSE(ec);
    if (in.text) continue;
    auto f = grotto::proto::decode_room_frame(
        std::span(reinterpret_cast<const uint8_t*>(in.data.data()), in.data.size()), c.limits);
    ASSERT_TRUE(f.ok()) << f.error().message;
    if (f->room.id == rooms[300].id) {
      ++x_frames;
      lod = f->lod;
    }
  }
  EXPECT_EQ(x_frames, 1);
  EXPECT_EQ(lod, 1);
  // X is no longer in flight: the lod-0 want is gone with it.
  grotto::proto::Cancel cancel;
  for (size_t i = 0; i < 300; i += 1) {
    cancel.rooms.push_back(rooms[i].id);
    if (cancel.rooms.size() == 256 || i == 299) {
      ASSERT_FALSE(client.send(cancel));
      cancel.rooms.clear();
    }
  }
  grotto::proto::StatsQuery q;
  q.ref = 3;
  ASSERT_FALSE(client.send(q));
  auto st = client.next_text();
  ASSERT_TRUE(st && st->as<grotto::proto::Stats>());
  EXPECT_EQ(st->as<grotto::proto::Stats>()->in_flight, 0u);
  EXPECT_TRUE(client.alive());
  for (const auto& frame : client.frames)
    EXPECT_NE(frame_id(frame), rooms[300].id);
}

// --max-kbps over real sockets: frames come no faster than the cap allows, and rooms asked for
// later at a smaller priority overtake the far ones still waiting for bandwidth.
TEST(ServerRooms, max_kbps_paces_frames_and_near_rooms_overtake_far_ones) {
  auto c = test_config();
  c.limits.max_kbps = 200;  // 25,000 bytes a second; the bucket holds as much
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(35);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  EXPECT_EQ(client.hello().limits.max_kbps, 200u);
  const auto t0 = Clock::now();
  ASSERT_FALSE(client.send(request_of(rooms, 0, 30, 1, 50)));  // far: ~80 KB, over 3 s of cap
  std::vector<RoomId> order;
  size_t bytes = 0, largest = 0;
  auto read_frame = [&] {
    auto [ec, in] = client.read();
    ASSERT_FALSE(ec) << ec.message();
    ASSERT_FALSE(in.text) << in.data;
    order.push_back(frame_id(in.data));
    bytes += in.data.size();
    largest = std::max(largest, in.data.size());
  };
  read_frame();
  ASSERT_FALSE(client.send(request_of(rooms, 30, 5, 2, 0)));  // near
  while (order.size() < 35 && !HasFatalFailure())
    read_frame();
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  // The bucket (25,000 bytes) and one overdrawing frame may go at once; the rest at the rate.
  const double floor_s =
      (static_cast<double>(bytes) - 25'000 - static_cast<double>(largest)) / 25'000;
  EXPECT_GE(elapsed, floor_s) << bytes << " bytes";
  EXPECT_GT(floor_s, 1.0);  // the test asks for well over the bucket
  // Every near room came before the last ten far ones.
  size_t last_near = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    for (size_t k = 30; k < 35; ++k)
      if (order[i] == rooms[k].id) last_near = i;
  }
  EXPECT_LT(last_near, order.size() - 10);
  EXPECT_GT(server->metrics().bandwidth_waits.value(), 0u);
}

// ---- bad input: each case gets its documented code; the server and other clients carry on ----

struct BadCase {
  const char* name;
  std::string text;
  ErrorCode code;
};

TEST(ServerBadInput, non_fatal_errors_leave_the_connection_working) {
  auto c = test_config();
  c.limits.max_rooms_per_request = 4;
  c.limits.max_rooms_in_flight = 3;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client bystander(server->port());
  ASSERT_FALSE(bystander.connect());
  bystander.hello("bystander");
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  auto rooms = sector_rooms(c.seed, {0, 0, 0});
  std::string id0 = rooms[0].id.to_string();
  std::vector<BadCase> cases = {
      {"invalid JSON", "{\"type\":\"ping\",", ErrorCode::kBadJson},
      {"not an object", "[1,2]", ErrorCode::kBadMessage},
      {"wrong type of field", "{\"type\":\"ping\",\"ref\":7,\"t\":\"soon\"}",
       ErrorCode::kBadMessage},
      {"unknown type", "{\"type\":\"teleport\",\"ref\":8}", ErrorCode::kUnknownType},
      {"malformed room id",
       "{\"type\":\"request\",\"ref\":9,\"rooms\":[{\"id\":\"0.0.0.q1\",\"lod\":0,\"priority\":0}]"
       "}",
       ErrorCode::kInvalidRoomId},
      {"out-of-range room id",
       "{\"type\":\"request\",\"ref\":10,\"rooms\":[{\"id\":\"70000.0.0.r1\",\"lod\":0,"
       "\"priority\":0}]}",
       ErrorCode::kInvalidRoomId},
      {"lod over max_lod",
       "{\"type\":\"request\",\"ref\":11,\"rooms\":[{\"id\":\"" + id0 +
           "\",\"lod\":1,\"priority\":0}]}",
       ErrorCode::kBadMessage},
      {"rooms over max_rooms_per_request",
       "{\"type\":\"cancel\",\"ref\":12,\"rooms\":[\"0.0.0.r1\",\"0.0.0.r2\",\"0.0.0.r3\","
       "\"0.0.0.r4\",\"0.0.0.r5\"]}",
       ErrorCode::kTooLarge},
  };
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.name);
    ASSERT_FALSE(client.send(bad.text));
    auto e = client.next_error();
    ASSERT_TRUE(e);
    EXPECT_EQ(e->code, bad.code) << e->message;
    EXPECT_FALSE(e->fatal);
    EXPECT_TRUE(client.alive());
  }
  // A well-formed id that names no room: not_found, naming the room.
  auto missing = RoomId::interior({0, 0, 0}, 4000);
  grotto::proto::Request r;
  r.ref = 20;
  r.rooms.push_back({missing, 0, 0});
  ASSERT_FALSE(client.send(r));
  auto e = client.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kNotFound) << e->message;
  EXPECT_EQ(e->room, missing);
  EXPECT_EQ(e->ref, 20u);  // PROTOCOL.md: an error about a message carries its ref
  EXPECT_FALSE(e->fatal);
  // A request flood: over max_rooms_in_flight refuses the whole request; nothing is queued.
  ASSERT_FALSE(client.send(request_of(rooms, 0, 4, 22, 1)));
  e = client.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kLimitExceeded) << e->message;
  EXPECT_EQ(e->ref, 22u);
  EXPECT_FALSE(e->room.has_value());
  grotto::proto::StatsQuery q;
  q.ref = 23;
  ASSERT_FALSE(client.send(q));
  auto stats = client.next_text();
  ASSERT_TRUE(stats && stats->as<grotto::proto::Stats>());
  EXPECT_EQ(stats->as<grotto::proto::Stats>()->in_flight, 0u);
  EXPECT_TRUE(client.frames.empty());
  EXPECT_TRUE(client.alive());
  EXPECT_TRUE(bystander.alive());
  EXPECT_GT(server->metrics().errors(ErrorCode::kBadJson), 0u);
  EXPECT_GT(server->metrics().errors(ErrorCode::kLimitExceeded), 0u);
}

struct FatalCase {
  const char* name;
  std::function<void(Client&)> act;
  ErrorCode code;  // the error expected before the close
  uint16_t close_code;
};

TEST(ServerBadInput, fatal_errors_close_only_that_connection) {
  auto c = test_config();
  c.limits.max_message_bytes = 2048;
  c.generator.max_worlds = 1;  // a server of one world: a hello for another is world_mismatch
  auto server = start(c);
  ASSERT_TRUE(server);
  Client bystander(server->port());
  ASSERT_FALSE(bystander.connect());
  bystander.hello("bystander");
  std::vector<FatalCase> cases = {
      {"binary frame",
       [](Client& cl) {
         cl.hello();
         cl.send_binary("GRTO\x01");
       },
       ErrorCode::kBadFrame, 1008},
      {"wrong protocol version",
       [](Client& cl) { cl.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[3,4]}"); },
       ErrorCode::kUnsupportedVersion, 1008},
      {"message before hello", [](Client& cl) { cl.send("{\"type\":\"spawn\",\"ref\":1}"); },
       ErrorCode::kOutOfOrder, 1008},
      {"hello twice",
       [](Client& cl) {
         cl.hello();
         cl.send("{\"type\":\"hello\",\"ref\":2,\"versions\":[1]}");
       },
       ErrorCode::kOutOfOrder, 1008},
      {"another world",
       [](Client& cl) {
         cl.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[1],\"seed\":\"8\"}");
       },
       ErrorCode::kWorldMismatch, 1008},
      {"another parameter digest",
       [](Client& cl) {
         cl.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[1],\"params\":\"0000000000000001\"}");
       },
       ErrorCode::kWorldMismatch, 1008},
      {"bad hello", [](Client& cl) { cl.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[]}"); },
       ErrorCode::kBadMessage, 1008},
      // PROTOCOL.md's order of checks: every error before welcome is fatal, and the order check
      // comes before the fields.
      {"invalid field before hello", [](Client& cl) { cl.send("{\"type\":\"ping\",\"t\":\"x\"}"); },
       ErrorCode::kOutOfOrder, 1008},
      {"unknown type before hello", [](Client& cl) { cl.send("{\"type\":\"teleport\"}"); },
       ErrorCode::kUnknownType, 1008},
      {"invalid JSON before hello", [](Client& cl) { cl.send("{\"type\":"); }, ErrorCode::kBadJson,
       1008},
      {"invalid second hello",
       [](Client& cl) {
         cl.hello();
         cl.send("{\"type\":\"hello\",\"versions\":\"1\"}");
       },
       ErrorCode::kOutOfOrder, 1008},
  };
  for (const auto& fatal : cases) {
    SCOPED_TRACE(fatal.name);
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    fatal.act(client);
    auto e = client.next_error();
    ASSERT_TRUE(e);
    EXPECT_EQ(e->code, fatal.code) << e->message;
    EXPECT_TRUE(e->fatal);
    if (fatal.code == ErrorCode::kUnsupportedVersion) {
      EXPECT_EQ(e->versions, (std::vector<uint32_t>{1, 2}));
    }
    auto reason = client.wait_close();
    EXPECT_EQ(reason.code, fatal.close_code);
    EXPECT_EQ(std::string(reason.reason.c_str()), grotto::proto::wire_code_name(fatal.code));
    EXPECT_TRUE(bystander.alive());
  }
  // A message over max_message_bytes: too_large, fatal, close 1009.
  Client big(server->port());
  ASSERT_FALSE(big.connect());
  big.hello();
  big.send("{\"type\":\"ping\",\"t\":1,\"pad\":\"" + std::string(3000, 'x') + "\"}");
  auto e = big.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kTooLarge);
  EXPECT_TRUE(e->fatal);
  EXPECT_EQ(big.wait_close().code, 1009) << big.last_error_.message();
  // Far bigger ones get the same answer: the server stops reading at the limit instead of
  // letting the WebSocket layer cut the connection without a reason (PROTOCOL.md, "Closing").
  for (size_t size : {70'000u, 100'000u, 1'000'000u}) {
    SCOPED_TRACE(size);
    Client huge(server->port());
    ASSERT_FALSE(huge.connect());
    huge.hello();
    huge.send("{\"type\":\"ping\",\"t\":1,\"pad\":\"" + std::string(size, 'x') + "\"}");
    auto error = huge.next_error();
    ASSERT_TRUE(error);
    EXPECT_EQ(error->code, ErrorCode::kTooLarge);
    EXPECT_TRUE(error->fatal);
    auto reason = huge.wait_close();
    EXPECT_EQ(reason.code, 1009);
    EXPECT_EQ(std::string(reason.reason.c_str()), "too_large");
  }
  EXPECT_TRUE(bystander.alive());
  EXPECT_GT(server->metrics().errors(ErrorCode::kTooLarge), 0u);
  // A text frame that is not UTF-8 fails the WebSocket connection (RFC 6455 8.1): close 1007,
  // no error message, before the JSON is read.
  Client latin1(server->port());
  ASSERT_FALSE(latin1.connect());
  latin1.hello();
  latin1.send("{\"type\":\"ping\",\"t\":1,\"x\":\"caf\xe9\"}");
  EXPECT_EQ(latin1.wait_close().code, 1007);
  EXPECT_TRUE(bystander.alive());
}

TEST(ServerHttp, endpoints_answer_and_plain_http_on_ws_is_426) {
  auto server = start(test_config());
  ASSERT_TRUE(server);
  EXPECT_EQ(http_get(server->port(), "/ws").status, 426);
  EXPECT_EQ(http_get(server->port(), "/nothing-here").status, 404);
  EXPECT_EQ(http_get(server->port(), "/healthz").status, 200);
  EXPECT_EQ(http_get(server->port(), "/readyz").status, 200);
  // Limits: 8 KiB of headers (431), 8 KiB of body (413).
  EXPECT_EQ(http_get(server->port(), "/healthz", 9000).status, 413);
  EXPECT_EQ(http_get(server->port(), "/healthz", 0, 9000).status, 431);
  auto v = http_get(server->port(), "/version");
  EXPECT_EQ(v.status, 200);
  EXPECT_NE(v.body.find("\"protocol\":2,\"protocols\":[1,2]"), std::string::npos) << v.body;
  // A WebSocket upgrade on another path is refused too.
  Client wrong(server->port());
  EXPECT_TRUE(wrong.connect("/elsewhere"));
  // The server and its WebSocket clients are unaffected.
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  EXPECT_TRUE(client.alive());
}

TEST(ServerHttp, metrics_scrape_parses_as_prometheus_text) {
  auto server = start(test_config());
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  EXPECT_TRUE(client.alive());
  client.send("nonsense");
  client.next_error();
  auto m = http_get(server->port(), "/metrics");
  ASSERT_EQ(m.status, 200);
  EXPECT_NE(m.content_type.find("text/plain; version=0.0.4"), std::string::npos);
  std::regex sample(R"(^[a-zA-Z_:][a-zA-Z0-9_:]*(\{[^}]*\})? [-+0-9.eEIinfNa]+$)");
  std::map<std::string, double> values;
  std::istringstream lines(m.body);
  std::string line;
  int samples = 0;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] == '#') continue;
    EXPECT_TRUE(std::regex_match(line, sample)) << line;
    auto space = line.rfind(' ');
    values[line.substr(0, space)] = std::stod(line.substr(space + 1));
    ++samples;
  }
  EXPECT_GT(samples, 10);
  EXPECT_EQ(values["grotto_connections_total"], 1);
  EXPECT_EQ(values["grotto_connections_open"], 1);
  EXPECT_GE(values["grotto_messages_total"], 3);
  EXPECT_EQ(values["grotto_errors_total{code=\"bad_json\"}"], 1);
}

// ---- limits and timeouts ----

TEST(ServerLimits, no_hello_within_the_handshake_timeout_closes_with_timeout) {
  auto c = test_config();
  c.limits.handshake_timeout_ms = 100;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  auto e = client.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kTimeout);
  EXPECT_TRUE(e->fatal);
  EXPECT_EQ(std::string(client.wait_close().reason.c_str()), "timeout");
}

TEST(ServerLimits, silence_past_the_idle_timeout_closes_with_timeout) {
  auto c = test_config();
  c.limits.idle_timeout_ms = 300;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  client.hello();
  // Pings keep it open past the timeout ...
  for (int i = 0; i < 4; ++i) {
    std::this_thread::sleep_for(100ms);
    EXPECT_TRUE(client.alive(i));
  }
  // ... silence closes it.
  auto e = client.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kTimeout);
  EXPECT_EQ(std::string(client.wait_close().reason.c_str()), "timeout");
}

TEST(ServerLimits, connections_over_max_connections_are_refused) {
  auto c = test_config();
  c.max_connections = 2;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client a(server->port()), b(server->port()), extra(server->port());
  ASSERT_FALSE(a.connect());
  ASSERT_FALSE(b.connect());
  a.hello();
  b.hello();
  ASSERT_FALSE(extra.connect());
  auto e = extra.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kOverloaded);
  EXPECT_TRUE(e->fatal);
  // Sent at once, before any hello (PROTOCOL.md, "Closing").
  auto reason = extra.wait_close();
  EXPECT_EQ(reason.code, 1008);
  EXPECT_EQ(std::string(reason.reason.c_str()), "overloaded");
  EXPECT_EQ(server->metrics().connections_rejected.value(), 1u);
  EXPECT_TRUE(a.alive());
  // A place frees up when a client leaves.
  a.close();
  auto deadline = Clock::now() + kWait;
  while (server->sessions() > 1 && Clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  Client later(server->port());
  ASSERT_FALSE(later.connect());
  later.hello();
  EXPECT_TRUE(later.alive());
}

// Past capacity (PROTOCOL.md, "Waiting to enter"): max_players 1 stands for a server whose
// players are no longer served in time.
TEST(ServerAdmission, past_capacity_a_client_that_can_wait_is_queued_then_welcomed) {
  auto c = test_config();
  c.admission.max_players = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client first(server->port()), second(server->port()), plain(server->port());
  ASSERT_FALSE(first.connect());
  first.hello();
  // One that says it can wait: its place, then nothing while the first plays.
  ASSERT_FALSE(second.connect());
  grotto::proto::Hello h;
  h.ref = 5;
  h.versions = {2, 1};
  h.queue = true;
  ASSERT_FALSE(second.send(grotto::proto::ClientMessage(h)));
  auto queued = second.next_text();
  ASSERT_TRUE(queued && queued->as<grotto::proto::Queued>()) << (queued ? queued->data : "none");
  EXPECT_EQ(queued->as<grotto::proto::Queued>()->position, 1u);
  EXPECT_EQ(queued->as<grotto::proto::Queued>()->queue, 1u);
  EXPECT_EQ(queued->as<grotto::proto::Queued>()->ref, grotto::proto::Ref{5});
  EXPECT_TRUE(second.alive());  // ping is answered while queued
  EXPECT_EQ(http_get(server->port(), "/readyz").status, 503);
  auto metrics = http_get(server->port(), "/metrics").body;
  EXPECT_EQ(metric(metrics, "grotto_sessions_queued"), 1.0);
  // One that cannot wait: refused with a time to come back, never left silent.
  ASSERT_FALSE(plain.connect());
  grotto::proto::Hello p;
  p.ref = 6;
  p.versions = {2, 1};
  ASSERT_FALSE(plain.send(grotto::proto::ClientMessage(p)));
  auto e = plain.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kOverloaded);
  EXPECT_TRUE(e->fatal);
  ASSERT_TRUE(e->retry_after_ms);
  EXPECT_GE(*e->retry_after_ms, 1000u);
  EXPECT_EQ(std::string(plain.wait_close().reason.c_str()), "overloaded");
  // The first leaves: the second is welcomed and plays.
  first.close();
  std::optional<Incoming> welcome;
  for (int i = 0; i < 10; ++i) {
    welcome = second.next_text();
    if (!welcome || !welcome->as<grotto::proto::Queued>()) break;
  }
  ASSERT_TRUE(welcome && welcome->as<grotto::proto::Welcome>())
      << (welcome ? welcome->data : "none");
  EXPECT_EQ(welcome->as<grotto::proto::Welcome>()->ref, grotto::proto::Ref{5});
  EXPECT_TRUE(second.alive());
  auto deadline = Clock::now() + kWait;
  while (http_get(server->port(), "/readyz").status != 200 && Clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  EXPECT_EQ(http_get(server->port(), "/readyz").status, 200);
}

// A balancer's mark (PROTOCOL.md, "Balancers"): a marked upgrade that would not get in at once is
// declined with 403 before the WebSocket, saying why, counted apart from connections and
// refusals; unmarked, the same newcomer is admitted or queued as before.
TEST(ServerAdmission, a_marked_newcomer_is_declined_before_the_upgrade_when_it_would_wait) {
  auto c = test_config();
  c.admission.max_players = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto marked = [&](Client& cl) { cl.set_upgrade_header("X-Grotto-Balancer", "try-others"); };
  // Room for one: the marked newcomer is upgraded and welcomed like any other.
  Client first(server->port());
  marked(first);
  ASSERT_FALSE(first.connect());
  first.hello();
  // Full: declined before the upgrade, with why and when to come back.
  Client second(server->port());
  marked(second);
  EXPECT_TRUE(second.connect());
  EXPECT_EQ(second.response().result_int(), 403);
  EXPECT_EQ(std::string(second.response()[beast::http::field::retry_after]), "1");
  EXPECT_NE(second.response().body().find("max_players"), std::string::npos)
      << second.response().body();
  // Unmarked, nothing changes: it waits in the queue.
  Client plain(server->port());
  ASSERT_FALSE(plain.connect());
  grotto::proto::Hello h;
  h.ref = 7;
  h.versions = {2, 1};
  h.queue = true;
  ASSERT_FALSE(plain.send(grotto::proto::ClientMessage(h)));
  auto queued = plain.next_text();
  ASSERT_TRUE(queued && queued->as<grotto::proto::Queued>()) << (queued ? queued->data : "none");
  // Somebody waits now: nobody passes the queue, and the reason says so. Any other value of the
  // header is no mark.
  Client third(server->port());
  marked(third);
  EXPECT_TRUE(third.connect());
  EXPECT_EQ(third.response().result_int(), 403);
  EXPECT_NE(third.response().body().find("queue"), std::string::npos) << third.response().body();
  Client other(server->port());
  other.set_upgrade_header("X-Grotto-Balancer", "something-else");
  EXPECT_FALSE(other.connect());
  // The upgrade's 101 can reach the client before the server counts the session: wait for it.
  std::string metrics;
  for (auto deadline = Clock::now() + kWait; Clock::now() < deadline;
       std::this_thread::sleep_for(5ms)) {
    metrics = http_get(server->port(), "/metrics").body;
    if (metric(metrics, "grotto_connections_total") >= 3.0) break;
  }
  EXPECT_EQ(metric(metrics, "grotto_admission_redirected_total{reason=\"max_players\"}"), 1.0);
  EXPECT_EQ(metric(metrics, "grotto_admission_redirected_total{reason=\"queue\"}"), 1.0);
  EXPECT_EQ(metric(metrics, "grotto_connections_total"), 3.0);  // first, plain, other
  EXPECT_EQ(metric(metrics, "grotto_connections_rejected_total"), 0.0);
  EXPECT_EQ(metric(metrics, "grotto_sessions_refused_total"), 0.0);
}

// ---- shutdown ----

TEST(ServerShutdown, stop_closes_every_session_with_service_restart_in_bounded_time) {
  auto c = test_config();
  c.generator.workers = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(300);
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < 3; ++i) {
    clients.push_back(std::make_unique<Client>(server->port()));
    ASSERT_FALSE(clients.back()->connect());
    clients.back()->hello();
    ASSERT_FALSE(clients.back()->send(request_of(rooms, 100 * i, 100, 1)));
  }
  std::thread reader([&] {
    for (auto& cl : clients) {
      auto e = cl->next_error();
      while (e && e->code != ErrorCode::kServiceRestart)
        e = cl->next_error();
      EXPECT_TRUE(e && e->fatal);
      auto reason = cl->wait_close();
      EXPECT_EQ(reason.code, 1001);
      EXPECT_EQ(std::string(reason.reason.c_str()), "service_restart");
    }
  });
  std::this_thread::sleep_for(50ms);
  auto t0 = Clock::now();
  server->stop(2000ms);
  EXPECT_LT(Clock::now() - t0, 4s);
  reader.join();
  EXPECT_EQ(http_get(server->port(), "/healthz").status, 0);  // no longer listening
}

// ---- what PROTOCOL.md's Closing section promises ----

// A client frame as the wire carries it (masked, as RFC 6455 requires of clients), or unmasked.
std::string client_frame(uint8_t first_byte, const std::string& payload, bool masked = true) {
  std::string f(1, static_cast<char>(first_byte));
  const char mask[4] = {0x11, 0x22, 0x33, 0x44};
  f += static_cast<char>((masked ? 0x80 : 0) | payload.size());  // payloads under 126 bytes here
  if (masked) f.append(mask, 4);
  for (size_t i = 0; i < payload.size(); ++i)
    f += masked ? static_cast<char>(payload[i] ^ mask[i % 4]) : payload[i];
  return f;
}

// Bytes written straight to the client's socket, behind Beast's back.
void send_raw(Client& client, const std::string& bytes) {
  int fd = beast::get_lowest_layer(client.ws()).socket().native_handle();
  ASSERT_EQ(::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL),
            static_cast<ssize_t>(bytes.size()));
}

// Everything the server sends until it ends the TCP connection; `eof` false if it had not within
// `timeout`.
struct RawRead {
  std::string bytes;
  bool eof = false;
};
RawRead read_raw_until_eof(Client& client, std::chrono::milliseconds timeout = kWait) {
  int fd = beast::get_lowest_layer(client.ws()).socket().native_handle();
  RawRead out;
  auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    char buf[4096];
    ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      out.eof = true;  // FIN, or a reset: either way the connection is over
      break;
    }
    out.bytes.append(buf, static_cast<size_t>(n));
  }
  return out;
}

// The close code of the first close frame among unmasked server frames; 0 if none.
int close_code_in(const std::string& bytes) {
  size_t at = 0;
  while (at + 2 <= bytes.size()) {
    auto op = static_cast<uint8_t>(bytes[at]) & 0x0f;
    size_t len = static_cast<uint8_t>(bytes[at + 1]) & 0x7f, head = 2;
    if (len == 126) {
      if (at + 4 > bytes.size()) return 0;
      len = (static_cast<uint8_t>(bytes[at + 2]) << 8) | static_cast<uint8_t>(bytes[at + 3]);
      head = 4;
    }
    if (op == 8 && len >= 2 && at + head + 2 <= bytes.size()) {
      return (static_cast<uint8_t>(bytes[at + head]) << 8) |
             static_cast<uint8_t>(bytes[at + head + 1]);
    }
    at += head + len;
  }
  return 0;
}

// A connection that arrives while the server drains is accepted and told service_restart (1001),
// not refused at TCP (which a client cannot tell from a dead server).
TEST(ServerShutdown, a_connection_arriving_during_the_drain_gets_service_restart) {
  auto server = start(test_config());
  ASSERT_TRUE(server);
  Client holder(server->port());  // does not answer its close frame yet: the drain goes on
  ASSERT_FALSE(holder.connect());
  holder.hello();
  std::thread stopper([&] { server->stop(kWait); });
  auto deadline = Clock::now() + kWait;
  while (!server->stopping() && Clock::now() < deadline)
    std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(server->stopping());
  EXPECT_EQ(http_get(server->port(), "/readyz").status, 503);
  Client late(server->port());
  ASSERT_FALSE(late.connect()) << "refused during the drain";
  auto e = late.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kServiceRestart);
  EXPECT_TRUE(e->fatal);
  EXPECT_FALSE(e->ref);  // before any hello
  auto reason = late.wait_close();
  EXPECT_EQ(reason.code, 1001);
  EXPECT_EQ(std::string(reason.reason.c_str()), "service_restart");
  // A room URL during the drain: 503 service_restart once the generator has stopped taking work
  // (until then it may still be served), answered, never refused at TCP (PROTOCOL.md, Rooms over
  // HTTP).
  const auto& c = server->config();
  grotto::proto::RoomPath path;
  path.seed = c.seed;
  path.params = grotto::proto::world_params_digest(c.layout, c.mesh);
  path.id = sector_rooms(c.seed, {0, 0, 0}).front().id;
  HttpAnswer room;
  while (Clock::now() < deadline) {
    auto answers = http_exchange(server->port(), {{"GET", grotto::proto::room_path(path), {}}});
    ASSERT_EQ(answers.size(), 1u);
    room = answers.front();
    if (room.status != 200) break;
  }
  EXPECT_EQ(room.status, 503);
  EXPECT_TRUE(room.body.starts_with("service_restart: ")) << room.body;
  EXPECT_EQ(room.header("retry-after"), "1");
  // The holder answers its close: the drain ends, and then the port is closed.
  EXPECT_EQ(holder.wait_close().code, 1001);
  stopper.join();
  EXPECT_EQ(http_get(server->port(), "/healthz").status, 0);
}

// A client stopped in the middle of a frame cannot answer a close frame (the server would read it
// as that frame's payload): after `timeout` the server ends the TCP connection within its short
// grace, not after its HTTP timeout (here far longer than the test waits).
TEST(ServerLimits, a_timeout_ends_the_connection_even_in_the_middle_of_a_frame) {
  auto c = test_config();
  c.limits.handshake_timeout_ms = 200;
  c.limits.idle_timeout_ms = 300;
  c.http_timeout = 600s;
  auto server = start(c);
  ASSERT_TRUE(server);
  const std::string partial = client_frame(0x81, R"({"type":"ping","t":1,"pad":"xxxxxxxx"})");
  for (bool welcomed : {false, true}) {
    SCOPED_TRACE(welcomed ? "idle timeout" : "handshake timeout");
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    if (welcomed) client.hello();
    send_raw(client, partial.substr(0, 10));  // header, mask and 4 of its payload bytes
    auto got = read_raw_until_eof(client);
    EXPECT_NE(got.bytes.find("\"code\":\"timeout\""), std::string::npos) << got.bytes;
    EXPECT_EQ(close_code_in(got.bytes.substr(got.bytes.find("\"fatal\":true}") + 13)), 1008);
    EXPECT_TRUE(got.eof) << "the server kept the connection open past the grace";
    // The client answers the close frame (behind its partial frame, so never read as one).
    send_raw(client, client_frame(0x88, std::string("\x03\xe8", 2)));
  }
}

// Every close code the server sends, over real connections, is one PROTOCOL.md's Closing table
// lists: its own closes, the WebSocket layer's (1002, 1007) and its echo of a client's close.
TEST(ServerSession, every_close_code_the_server_sends_is_in_the_closing_table) {
  std::set<int> documented;
  {
    std::ifstream in(GROTTO_PROTOCOL_MD);
    ASSERT_TRUE(in.good()) << GROTTO_PROTOCOL_MD;
    bool inside = false;
    for (std::string line; std::getline(in, line);) {
      if (line.starts_with("#")) inside = line == "### Closing";
      if (inside && line.starts_with("| 1")) documented.insert(std::stoi(line.substr(2, 4)));
    }
  }
  auto c = test_config();
  c.limits.max_message_bytes = 1024;
  auto server = start(c);
  ASSERT_TRUE(server);
  std::map<std::string, int> sent;  // what happened -> the close code the server sent
  for (auto code : {websocket::close_code::normal, websocket::close_code::going_away}) {
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    client.hello();
    client.close(code);  // the server's answer is the close reason Beast read
    sent["client closed " + std::to_string(static_cast<int>(code))] = client.ws().reason().code;
  }
  {
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    send_raw(client, client_frame(0x81, "hi", /*masked=*/false));
    sent["unmasked frame"] = close_code_in(read_raw_until_eof(client).bytes);
  }
  {
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    client.hello();
    client.send("{\"type\":\"ping\",\"t\":1,\"x\":\"caf\xe9\"}");
    sent["invalid UTF-8"] = client.wait_close().code;
  }
  {
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    client.send("nonsense");
    sent["bad_json before welcome"] = client.wait_close().code;
  }
  {
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    client.hello();
    client.send(std::string(2000, ' '));
    sent["message over max_message_bytes"] = client.wait_close().code;
  }
  Client player(server->port());
  ASSERT_FALSE(player.connect());
  player.hello();
  std::thread stopper([&] { server->stop(kWait); });
  sent["shutdown"] = player.wait_close().code;
  stopper.join();
  EXPECT_EQ(sent["client closed 1000"], 1000);
  EXPECT_EQ(sent["client closed 1001"], 1001);
  EXPECT_EQ(sent["unmasked frame"], 1002);
  EXPECT_EQ(sent["invalid UTF-8"], 1007);
  EXPECT_EQ(sent["bad_json before welcome"], 1008);
  EXPECT_EQ(sent["message over max_message_bytes"], 1009);
  EXPECT_EQ(sent["shutdown"], 1001);
  for (const auto& [what, code] : sent)
    EXPECT_TRUE(documented.contains(code)) << what << ": close " << code << " is not documented";
}

// ---- configuration ----

grotto::server::CommandLine parse(std::vector<std::string> args) {
  std::vector<const char*> argv{"grotto-server"};
  for (auto& a : args)
    argv.push_back(a.c_str());
  return grotto::server::parse_command_line(static_cast<int>(argv.size()), argv.data());
}

std::string write_temp(const std::string& name, const std::string& text) {
  auto path = std::filesystem::temp_directory_path() / ("grotto_server_test_" + name);
  std::ofstream(path) << text;
  return path.string();
}

TEST(ServerSettings, flags_override_the_file_which_overrides_defaults) {
  auto defaults = parse({});
  ASSERT_TRUE(defaults.run) << defaults.text;
  EXPECT_EQ(defaults.config.bind, "127.0.0.1");
  EXPECT_EQ(defaults.config.port, grotto::server::kDefaultPort);
  auto file = write_temp("ok.json",
                         R"({"port": 9000, "workers": 3, "seed": "18446744073709551615",
                             "max-rooms-in-flight": 50, "log-level": "debug",
                             "sector-size": 128.0, "opencl-device": "none"})");
  auto cl = parse({"--config", file, "--port", "9001", "--idle-timeout-ms", "1234"});
  ASSERT_TRUE(cl.run) << cl.text;
  EXPECT_EQ(cl.config.port, 9001);
  EXPECT_EQ(cl.config.generator.workers, 3);
  EXPECT_EQ(cl.config.seed, 18446744073709551615ull);
  EXPECT_EQ(cl.config.limits.max_rooms_in_flight, 50u);
  EXPECT_EQ(cl.config.limits.idle_timeout_ms, 1234u);
  EXPECT_EQ(cl.config.log_level, "debug");
  EXPECT_EQ(cl.config.layout.sector_size, 128.0);
  EXPECT_EQ(cl.config.generator.builder.device.device, "none");
}

TEST(ServerSettings, invalid_settings_are_refused_naming_the_setting) {
  struct Case {
    std::vector<std::string> args;
    std::string mention;
  };
  std::vector<Case> cases = {
      {{"--port", "70000"}, "--port"},
      {{"--port", "http"}, "--port"},
      {{"--max-rooms-in-flight", "0"}, "--max-rooms-in-flight"},
      {{"--max-worlds", "0"}, "--max-worlds"},
      {{"--config", write_temp("worlds.json", R"({"max-worlds": 5000})")}, "max-worlds"},
      {{"--log-level", "loud"}, "--log-level"},
      {{"--no-such-flag"}, "no-such-flag"},
      {{"--sector-size", "1"}, "sector_size"},
      {{"--config", "/nonexistent/grotto.json"}, "/nonexistent/grotto.json"},
      {{"--config", write_temp("unknown.json", R"({"prot": 1})")}, "prot"},
      {{"--config", write_temp("type.json", R"({"port": "7878"})")}, "port"},
      {{"--config", write_temp("range.json", R"({"max-message-bytes": 10})")}, "max-message-bytes"},
      {{"--config", write_temp("nested.json", R"({"limits": {"a": 1}})")}, "limits"},
      {{"--config", write_temp("broken.json", R"({"port": )")}, "broken.json"},
  };
  for (const auto& c : cases) {
    auto cl = parse(c.args);
    EXPECT_FALSE(cl.run) << c.args[0];
    EXPECT_EQ(cl.exit_code, 2) << cl.text;
    EXPECT_NE(cl.text.find(c.mention), std::string::npos) << cl.text;
  }
}

// ---- the program ----

TEST(ServerProgram, help_lists_every_option_and_exits_0) {
  auto p = spawn({"--help"});
  auto text = read_until(p.out, "log-level", 10s);
  text += read_until(p.out, "\x01", 500ms);
  EXPECT_EQ(wait_exit(p.pid, 10s), 0);
  close(p.out);
  for (const char* flag : {"--config", "--bind", "--port", "--io-threads", "--seed",
                           "--max-connections", "--send-queue-bytes", "--max-rooms-in-flight",
                           "--idle-timeout-ms", "--handshake-timeout-ms", "--workers",
                           "--cache-bytes", "--batch-rooms", "--batch-wait-ms", "--job-deadline-ms",
                           "--urgent-ms", "--opencl-device", "--drain-timeout-ms", "--log-level"}) {
    EXPECT_NE(text.find(flag), std::string::npos) << flag;
  }
  EXPECT_NE(text.find("--opencl-queue"), std::string::npos);
}

TEST(ServerProgram, starts_serves_healthz_and_exits_0_on_sigterm) {
  auto p = spawn({"--port", "0", "--opencl-device", "none", "--workers", "1", "--io-threads", "1",
                  "--log-level", "warn"});
  auto text = read_until(p.out, "/ws)", 30s);
  std::smatch m;
  std::regex address(R"(http://127\.0\.0\.1:(\d+))");
  ASSERT_TRUE(std::regex_search(text, m, address)) << text;
  uint16_t port = static_cast<uint16_t>(std::stoi(m[1]));
  EXPECT_EQ(http_get(port, "/healthz").status, 200);
  Client client(port);
  ASSERT_FALSE(client.connect());
  client.hello();
  kill(p.pid, SIGTERM);
  EXPECT_EQ(std::string(client.wait_close().reason.c_str()), "service_restart");
  EXPECT_EQ(wait_exit(p.pid, 15s), 0);
  close(p.out);
}

TEST(ServerProgram, invalid_flag_exits_2_naming_it) {
  auto p = spawn({"--max-lod", "9"});
  EXPECT_EQ(wait_exit(p.pid, 10s), 2);
  close(p.out);
}

}  // namespace

// ---- the shared-secret token (PROTOCOL.md, hello.token) ----

namespace token_tests {

grotto::proto::Hello hello_with_token(std::optional<std::string> token) {
  grotto::proto::Hello h;
  h.ref = 1;
  h.versions = {1};
  h.name = "token-test";
  h.token = std::move(token);
  return h;
}

TEST(ServerToken, hello_without_the_right_token_is_unauthorized_and_closed) {
  auto c = test_config();
  c.token = "fleet secret 42";
  auto server = start(c);
  ASSERT_TRUE(server);
  Client bystander(server->port());
  ASSERT_FALSE(bystander.connect());
  ASSERT_FALSE(bystander.send(hello_with_token(c.token)));
  auto welcome = bystander.next_text();
  ASSERT_TRUE(welcome && welcome->as<grotto::proto::Welcome>()) << welcome->data;

  struct Case {
    const char* name;
    std::optional<std::string> token;
    const char* message;
  };
  for (const Case& k : {Case{"missing", std::nullopt, "missing token"},
                        Case{"wrong", "fleet secret 43", "wrong token"},
                        Case{"a prefix", "fleet secret", "wrong token"},
                        Case{"twice over", "fleet secret 42fleet secret 42", "wrong token"}}) {
    SCOPED_TRACE(k.name);
    Client client(server->port());
    ASSERT_FALSE(client.connect());
    ASSERT_FALSE(client.send(hello_with_token(k.token)));
    auto e = client.next_error();
    ASSERT_TRUE(e);
    EXPECT_EQ(e->code, ErrorCode::kUnauthorized);
    EXPECT_TRUE(e->fatal);
    EXPECT_EQ(e->message, k.message);
    EXPECT_EQ(e->ref, 1u);
    auto reason = client.wait_close();
    EXPECT_EQ(reason.code, 1008);
    EXPECT_EQ(std::string(reason.reason.c_str()), "unauthorized");
    EXPECT_TRUE(bystander.alive());
  }
  EXPECT_EQ(server->metrics().errors(ErrorCode::kUnauthorized), 4u);
  // The right token: rooms arrive.
  auto rooms = sector_rooms(c.seed, {0, 0, 0});
  ASSERT_FALSE(bystander.send(request_of(rooms, 0, 2, 10)));
  for (int i = 0; i < 2; ++i) {
    auto [ec, in] = bystander.read();
    ASSERT_FALSE(ec) << ec.message();
    EXPECT_FALSE(in.text) << in.data;
  }
}

TEST(ServerToken, without_a_token_configured_a_token_in_hello_is_ignored) {
  auto server = start(test_config());
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect());
  ASSERT_FALSE(client.send(hello_with_token("anything")));
  auto welcome = client.next_text();
  ASSERT_TRUE(welcome && welcome->as<grotto::proto::Welcome>()) << welcome->data;
}

TEST(ServerToken, token_comes_from_the_file_then_the_environment_and_bad_files_exit_2) {
  auto file = write_temp("token.txt", "  file-token \nignored\n");
  ::setenv("GROTTO_TOKEN", "env-token", 1);
  auto from_file = parse({"--token-file", file});
  auto from_env = parse({});
  auto from_config =
      parse({"--config", write_temp("token.json", "{\"token-file\": \"" + file + "\"}")});
  ::unsetenv("GROTTO_TOKEN");
  auto none = parse({});
  ASSERT_TRUE(from_file.run) << from_file.text;
  EXPECT_EQ(from_file.config.token, "file-token");
  ASSERT_TRUE(from_env.run) << from_env.text;
  EXPECT_EQ(from_env.config.token, "env-token");
  ASSERT_TRUE(from_config.run) << from_config.text;
  EXPECT_EQ(from_config.config.token, "file-token");
  ASSERT_TRUE(none.run);
  EXPECT_EQ(none.config.token, "");
  for (const auto& [content, mention] : std::vector<std::pair<std::string, std::string>>{
           {"\n", "the first line is empty"},
           {std::string(300, 'k'), "at most 256 bytes"},
           {"secret\x7f", "printable ASCII"}}) {
    auto bad = parse({"--token-file", write_temp("bad_token.txt", content)});
    EXPECT_FALSE(bad.run);
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.text.find("token-file"), std::string::npos) << bad.text;
    EXPECT_NE(bad.text.find(mention), std::string::npos) << bad.text;
  }
  auto p = spawn({"--token-file", "/nonexistent/grotto-token", "--log-level", "off"});
  EXPECT_EQ(wait_exit(p.pid, 10s), 2);
  close(p.out);
}

}  // namespace token_tests

// ---- the seed routing hint (PROTOCOL.md, Transport) ----

TEST(ServerSession, a_query_string_on_ws_is_accepted_and_ignored) {
  auto server = start(test_config());
  ASSERT_TRUE(server);
  Client client(server->port());
  ASSERT_FALSE(client.connect("/ws?seed=12345&x=y"));
  auto w = client.hello();
  EXPECT_EQ(w.seed, server->config().seed);  // the hint does not choose the world
  Client other(server->port());
  EXPECT_TRUE(other.connect("/wsx?seed=1")) << "only the path before '?' is matched";
}

// --max-worlds: a hello that names another seed opens that world (its rooms are the bytes a
// server of that seed sends); with every world in use a new seed is refused with a fatal
// `overloaded`, and the server's own world (no seed named) always answers.
TEST(ServerWorlds, a_named_world_opens_and_with_all_in_use_another_is_overloaded) {
  auto rooms_from = [](Client& client, const std::vector<grotto::cave::Room>& rooms) {
    std::map<uint64_t, std::string> got;
    EXPECT_FALSE(client.send(request_of(rooms, 0, 4, 10)));
    while (got.size() < 4) {
      auto [ec, in] = client.read();
      if (ec || in.text) {
        ADD_FAILURE() << (ec ? ec.message() : in.data);
        break;
      }
      got[frame_id(in.data).packed()] = in.data;
    }
    return got;
  };
  const std::string hello8 = "{\"type\":\"hello\",\"ref\":1,\"versions\":[2,1],\"seed\":\"8\"}";
  auto rooms8 = sector_rooms(8, {0, 0, 0});
  ASSERT_GE(rooms8.size(), 4u);

  auto c = test_config();
  c.generator.max_worlds = 2;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client player8(server->port());
  ASSERT_FALSE(player8.connect("/ws?seed=8"));
  ASSERT_FALSE(player8.send(hello8));
  auto welcome = player8.next_text();
  ASSERT_TRUE(welcome && welcome->as<grotto::proto::Welcome>()) << welcome->data;
  EXPECT_EQ(welcome->as<grotto::proto::Welcome>()->seed, 8u);
  grotto::proto::Spawn sp;
  sp.ref = 2;
  ASSERT_FALSE(player8.send(sp));
  auto spawn = player8.next_text();
  ASSERT_TRUE(spawn && spawn->as<grotto::proto::SpawnPoint>());
  EXPECT_EQ(spawn->as<grotto::proto::SpawnPoint>()->room,
            grotto::cave::spawn_room(*grotto::cave::World::create(8, c.layout)));
  auto got = rooms_from(player8, rooms8);

  auto c8 = test_config();
  c8.seed = 8;
  auto server8 = start(c8);
  ASSERT_TRUE(server8);
  Client direct(server8->port());
  ASSERT_FALSE(direct.connect());
  direct.hello();
  EXPECT_EQ(got, rooms_from(direct, rooms8)) << "world 8 differs from a server of seed 8";

  Client player9(server->port());
  ASSERT_FALSE(player9.connect());
  ASSERT_FALSE(player9.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[1],\"seed\":\"9\"}"));
  auto e = player9.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kOverloaded);
  EXPECT_TRUE(e->fatal);
  EXPECT_NE(e->message.find("max_worlds"), std::string::npos) << e->message;
  auto reason = player9.wait_close();
  EXPECT_EQ(reason.code, 1008);
  EXPECT_EQ(std::string(reason.reason.c_str()), "overloaded");
  EXPECT_TRUE(player8.alive());

  Client home(server->port());
  ASSERT_FALSE(home.connect());
  EXPECT_EQ(home.hello().seed, c.seed);  // the server's own world is never closed
  auto metrics = http_get(server->port(), "/metrics");
  EXPECT_NE(metrics.body.find("grotto_worlds_open 2\n"), std::string::npos);
  EXPECT_NE(metrics.body.find("grotto_worlds_refused_total 1\n"), std::string::npos);

  // Once world 8's player leaves, world 9 opens in its place.
  player8.close_tcp();
  bool welcomed = false;
  for (int attempt = 0; attempt < 100 && !welcomed; ++attempt) {
    Client try9(server->port());
    ASSERT_FALSE(try9.connect());
    ASSERT_FALSE(try9.send("{\"type\":\"hello\",\"ref\":1,\"versions\":[1],\"seed\":\"9\"}"));
    auto in = try9.next_text();
    welcomed = in && in->as<grotto::proto::Welcome>();
    if (!welcomed) std::this_thread::sleep_for(50ms);  // the server has not seen the close yet
  }
  EXPECT_TRUE(welcomed);
}
