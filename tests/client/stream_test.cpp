// client/stream against real servers on loopback: a grotto Server started in-process (port 0 or a
// fixed port for restarts), and a misbehaving server written here with Beast that speaks the
// protocol wrongly on purpose (another version, corrupt rooms, a connection cut mid-frame). Every
// wait is bounded (kWait), so a broken client fails a test instead of hanging it.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <thread>
#include <vector>

#include "client/stream/stream.hpp"
#include "client/stream/verify.hpp"
#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/context.hpp"
#include "common/mesh/room_mesh.hpp"
#include "proto/room_frame.hpp"
#include "server/server.hpp"

namespace {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using grotto::cave::RoomId;
using grotto::server::Server;
using grotto::server::ServerConfig;
using grotto::stream::Pose;
using grotto::stream::Runtime;
using grotto::stream::Stream;
using grotto::stream::StreamOptions;
using grotto::stream::StreamState;

constexpr auto kWait = 30s;

ServerConfig test_config(uint16_t port = 0) {
  ServerConfig c;
  c.port = port;
  c.io_threads = 1;
  c.generator.workers = 2;
  c.generator.builder.device.device = "none";  // the CPU reference: no OpenCL start-up in tests
  c.drain_timeout = 2000ms;
  c.log_level = "warn";
  return c;
}

std::unique_ptr<Server> start_server(const ServerConfig& c) {
  auto s = Server::start(c);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  return s.ok() ? std::move(s).value() : nullptr;
}

std::string url_of(uint16_t port) {
  return "ws://127.0.0.1:" + std::to_string(port) + "/ws";
}

// For failure messages: what the Stream did.
std::string describe(const grotto::stream::StreamStats& s) {
  std::string text = std::string("state=") + grotto::stream::state_name(s.state) +
                     " requests=" + std::to_string(s.requests_sent) +
                     " cancels=" + std::to_string(s.cancels_sent) +
                     " received=" + std::to_string(s.rooms_received) +
                     " ready=" + std::to_string(s.rooms_ready) +
                     " rejected=" + std::to_string(s.rooms_rejected) +
                     " in_flight=" + std::to_string(s.in_flight) +
                     " drops=" + std::to_string(s.drops) + " last_error=\"" + s.last_error + "\"";
  for (const auto& [code, n] : s.errors)
    text += " " + code + "=" + std::to_string(n);
  return text;
}

std::unique_ptr<Stream> start_stream(const StreamOptions& o, Runtime& rt) {
  auto s = Stream::start(o, rt);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  return s.ok() ? std::move(s).value() : nullptr;
}

// Polls `done` every 20 ms until it holds or kWait passes.
bool wait_for(const std::function<bool()>& done, std::chrono::milliseconds limit = kWait) {
  auto deadline = Clock::now() + limit;
  while (Clock::now() < deadline) {
    if (done()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return done();
}

// The whole portal graph of the sectors around the origin, from the layout itself: what the
// client should end up knowing.
grotto::stream::PortalGraph layout_graph(uint64_t seed) {
  auto world = grotto::cave::World::create(seed, {});
  grotto::stream::PortalGraph graph;
  std::vector<grotto::cave::Room> all;
  for (int x = -1; x <= 1; ++x) {
    for (int y = -1; y <= 1; ++y) {
      for (int z = -1; z <= 1; ++z) {
        auto sector = grotto::cave::generate_sector(*world, {x, y, z});
        all.insert(all.end(), sector.rooms.begin(), sector.rooms.end());
      }
    }
  }
  // Add in two passes: a room is consistent once its neighbours are there or absent.
  for (const auto& r : all)
    (void)graph.add(r);
  for (const auto& r : all)
    (void)graph.add(r);
  return graph;
}

// The rooms within the horizon of the spawn pose, computed locally from the layout.
std::set<RoomId> expected_rooms(uint64_t seed, const grotto::proto::SpawnPoint& spawn,
                                double horizon_s) {
  auto graph = layout_graph(seed);
  Pose pose;
  pose.position = spawn.position;
  pose.room = spawn.room;
  grotto::stream::PlanOptions plan;
  plan.horizon_s = horizon_s;
  std::set<RoomId> ids;
  for (const auto& p : graph.plan(spawn.room, pose, plan))
    ids.insert(p.id);
  return ids;
}

// Whether every room of `ids` is decoded and stored.
bool all_ready(const Stream& stream, const std::set<RoomId>& ids) {
  for (auto id : ids) {
    if (!stream.ready(id)) return false;
  }
  return true;
}

// Most tests here were worked out for a fixed horizon (every room within it is asked for at
// once); the adaptive one, the default, has a test of its own below.
StreamOptions fixed_horizon() {
  StreamOptions o;
  o.min_horizon_s = 0;
  return o;
}

// The default: the horizon adapts, from the floor. Against a quick server it stays there, and the
// rooms within it arrive.
TEST(Stream, the_default_adaptive_horizon_fetches_the_rooms_within_its_floor) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o;
  o.url = url_of(server->port());
  ASSERT_EQ(o.min_horizon_s, grotto::stream::kDefaultMinHorizonS);
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }))
      << describe(stream->stats());
  auto expected = expected_rooms(7, *stream->spawn_point(), grotto::stream::kDefaultMinHorizonS);
  ASSERT_FALSE(expected.empty());
  EXPECT_TRUE(wait_for([&] { return all_ready(*stream, expected); })) << describe(stream->stats());
  EXPECT_GE(stream->stats().horizon_s, grotto::stream::kDefaultMinHorizonS);
  EXPECT_LT(stream->stats().horizon_s, o.plan.horizon_s) << "a quick server: near the floor";
}

TEST(Stream, spawns_and_prefetches_every_room_within_the_horizon) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 3.0;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }))
      << describe(stream->stats());
  auto spawn = *stream->spawn_point();
  auto expected = expected_rooms(7, spawn, o.plan.horizon_s);
  ASSERT_GT(expected.size(), 3u);
  ASSERT_TRUE(wait_for([&] { return all_ready(*stream, expected); }))
      << "rooms ready: " << stream->stats().rooms_ready << " of " << expected.size();
  auto stats = stream->stats();
  EXPECT_EQ(stats.state, StreamState::kReady);
  EXPECT_EQ(stats.rooms_rejected, 0u);
  EXPECT_TRUE(stats.errors.empty());
  EXPECT_EQ(stats.connects, 1u);
  EXPECT_EQ(stats.server, "grotto-server 0.3.0");
  auto fresh = stream->take_new_rooms();
  EXPECT_GE(fresh.size(), expected.size());
  for (const auto& r : fresh)
    EXPECT_GT(r->mesh.triangle_count(), 0u);
  auto samples = stream->take_samples();
  EXPECT_EQ(samples.size(), fresh.size());
  for (const auto& s : samples)
    EXPECT_GT(s.latency_ms, 0.0);
  EXPECT_TRUE(stream->take_new_rooms().empty());
}

// Both protocol versions against one server: version 1's rooms carry normals, version 2's come
// without and the client derives them; either way the same rooms arrive, every vertex has a unit
// normal, and the rims of neighbours held by one Stream agree bit for bit, normals included
// (verify_seam). Version 2's payloads are smaller.
TEST(Stream, both_protocol_versions_stream_rooms_whose_seams_agree) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  std::map<uint32_t, size_t> payload_bytes, seams;
  std::map<uint32_t, std::set<RoomId>> received;
  for (uint32_t version : {1u, 2u}) {
    SCOPED_TRACE("protocol " + std::to_string(version));
    StreamOptions o = fixed_horizon();
    o.url = url_of(server->port());
    o.plan.horizon_s = 5.0;
    o.protocol_version = version;
    auto stream = start_stream(o, rt);
    ASSERT_TRUE(stream);
    ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }))
        << describe(stream->stats());
    auto expected = expected_rooms(7, *stream->spawn_point(), o.plan.horizon_s);
    ASSERT_TRUE(wait_for([&] { return all_ready(*stream, expected); }))
        << describe(stream->stats());
    EXPECT_EQ(stream->stats().rooms_rejected, 0u);
    std::map<RoomId, std::shared_ptr<const grotto::stream::ReadyRoom>> rooms;
    for (const auto& r : stream->take_new_rooms()) {
      rooms[r->room.id] = r;
      received[version].insert(r->room.id);
      payload_bytes[version] += r->payload_bytes;
      ASSERT_EQ(r->mesh.normals.size(), r->mesh.vertex_count());
      for (const auto& n : r->mesh.normals)
        ASSERT_NEAR(std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z), 1.0, 1e-3);
      EXPECT_TRUE(grotto::stream::verify_room(*r).ok()) << r->room.id.to_string();
    }
    for (const auto& [id, r] : rooms) {
      for (const auto& portal : r->room.portals) {
        auto other = rooms.find(portal.neighbour);
        if (other == rooms.end() || !(id < portal.neighbour)) continue;
        grotto::Status s = grotto::stream::verify_seam(*r, *other->second);
        EXPECT_TRUE(s.ok()) << s.error().message;
        ++seams[version];
      }
    }
    EXPECT_GT(seams[version], 3u);
  }
  EXPECT_EQ(received[1], received[2]) << "the same rooms either way";
  EXPECT_LT(payload_bytes[2] * 10, payload_bytes[1] * 9) << "version 2 saves over a tenth";
}

// A server with tight limits: the Stream never asks for more in flight, or puts more in one
// request or one message, than welcome announced, so no request is refused, and everything still
// arrives.
TEST(Stream, stays_within_the_limits_the_server_announces) {
  auto config = test_config();
  config.limits.max_rooms_in_flight = 3;
  config.limits.max_rooms_per_request = 2;
  config.limits.max_message_bytes = 1024;
  auto server = start_server(config);
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 8.0;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  auto expected = expected_rooms(7, *stream->spawn_point(), o.plan.horizon_s);
  ASSERT_GT(expected.size(), 6u) << "enough rooms to need several rounds of requests";
  uint64_t most_in_flight = 0;
  ASSERT_TRUE(wait_for([&] {
    most_in_flight = std::max(most_in_flight, stream->stats().in_flight);
    return all_ready(*stream, expected);
  })) << describe(stream->stats());
  auto stats = stream->stats();
  EXPECT_TRUE(stats.errors.empty()) << describe(stats);
  EXPECT_EQ(stats.limits.max_rooms_in_flight, 3u);
  EXPECT_LE(most_in_flight, 3u);
  EXPECT_EQ(server->metrics().errors(grotto::ErrorCode::kLimitExceeded), 0u);
  EXPECT_EQ(server->metrics().errors(grotto::ErrorCode::kTooLarge), 0u);
}

TEST(Stream, cancels_what_falls_out_of_the_horizon_when_the_player_moves_away) {
  auto config = test_config();
  config.generator.workers = 1;  // slow enough that rooms are still in flight when we move
  auto server = start_server(config);
  ASSERT_TRUE(server);
  Runtime rt(1, 1);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 60.0;  // a wide horizon: hundreds of rooms wanted around the spawn
  o.max_in_flight = 512;
  o.spawn = false;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  Pose here;
  here.room = RoomId::interior({0, 0, 0}, 0);
  stream->set_pose(here);
  // The graph unfolds as frames arrive (each brings its portals), so the frontier in flight grows
  // with the rooms received.
  ASSERT_TRUE(wait_for([&] { return stream->stats().in_flight >= 8; }))
      << describe(stream->stats());
  Pose far;
  far.room = RoomId::interior({40, 0, 0}, 0);
  far.position = {40 * 256.0, 0, 0};
  stream->set_pose(far);
  ASSERT_TRUE(wait_for([&] { return stream->stats().cancels_sent >= 4; }))
      << describe(stream->stats());
  ASSERT_TRUE(wait_for([&] { return stream->ready(far.room.value()); }))
      << describe(stream->stats());
  EXPECT_EQ(stream->stats().rooms_rejected, 0u);
  // The server may have sent them already (it builds a patch room in milliseconds): rooms that
  // arrive after their cancel are dropped quietly, not counted as rejected.
}

TEST(Stream, reconnects_after_a_server_restart_and_every_wanted_room_arrives) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  const uint16_t port = server->port();
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(port);
  o.plan.horizon_s = 6.0;
  o.backoff_initial = 50ms;
  o.backoff_max = 400ms;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->stats().rooms_ready >= 3; }))
      << describe(stream->stats());
  server->stop(2000ms);  // mid-run: rooms are still in flight
  server.reset();
  ASSERT_TRUE(wait_for([&] { return stream->state() == StreamState::kBackoff; }))
      << describe(stream->stats());
  std::this_thread::sleep_for(300ms);  // a few refused reconnects while nothing listens
  server = start_server(test_config(port));
  ASSERT_TRUE(server);
  auto spawn = *stream->spawn_point();
  auto expected = expected_rooms(7, spawn, o.plan.horizon_s);
  // The rooms may all have arrived before the drain: wait for the reconnect as well.
  ASSERT_TRUE(wait_for([&] {
    return all_ready(*stream, expected) && stream->stats().reconnects >= 1 &&
           stream->state() == StreamState::kReady;
  })) << "rooms ready: "
      << stream->stats().rooms_ready << " of " << expected.size() << "; "
      << describe(stream->stats());
  auto stats = stream->stats();
  EXPECT_GE(stats.reconnects, 1u);
  EXPECT_GE(stats.drops, 1u);
  // The drain's service_restart is a notice (the server said it would go), not an error.
  EXPECT_GE(stats.restart_notices, 1u);
  EXPECT_TRUE(stats.errors.empty()) << describe(stats);
  EXPECT_EQ(stats.state, StreamState::kReady);
  EXPECT_EQ(stats.rooms_rejected, 0u);
  EXPECT_EQ(stats.rooms_given_up, 0u);
}

// Rooms of lod 0 and lod 1 do not share rims (PROTOCOL.md "Levels of detail"), so a Stream keeps
// neighbours at one lod: asked for lod 1, it holds lod-1 rooms from a server that serves them, and
// when the server comes back serving lod 0 only, it lets every lod-1 room go and holds the same
// neighbourhood at lod 0, never the two side by side.
TEST(Stream, a_server_back_with_another_max_lod_never_leaves_neighbours_at_two_lods) {
  auto detail = test_config();
  detail.limits.max_lod = 1;
  auto server = start_server(detail);
  ASSERT_TRUE(server);
  const uint16_t port = server->port();
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(port);
  o.lod = 1;
  o.plan.horizon_s = 3.0;
  o.backoff_initial = 50ms;
  o.backoff_max = 400ms;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  auto neighbours_at_one_lod = [&](std::set<RoomId> ids) {
    std::map<RoomId, uint8_t> lods;
    for (auto id : ids)
      if (auto r = stream->room(id)) lods[id] = r->lod;
    for (const auto& [id, lod] : lods) {
      auto r = stream->room(id);
      if (!r) continue;
      for (const auto& p : r->room.portals) {
        auto it = lods.find(p.neighbour);
        if (it != lods.end() && it->second != lod) return false;
      }
    }
    return true;
  };
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }))
      << describe(stream->stats());
  auto spawn = *stream->spawn_point();
  auto expected = expected_rooms(7, spawn, o.plan.horizon_s);
  ASSERT_TRUE(wait_for([&] { return all_ready(*stream, expected); })) << describe(stream->stats());
  for (auto id : expected)
    EXPECT_EQ(stream->room(id)->lod, 1) << id.to_string();
  server->stop(2000ms);
  server.reset();
  ASSERT_TRUE(wait_for([&] { return stream->state() == StreamState::kBackoff; }))
      << describe(stream->stats());
  server = start_server(test_config(port));  // max_lod 0
  ASSERT_TRUE(server);
  auto all_at_lod0 = [&] {
    for (auto id : expected) {
      auto r = stream->room(id);
      if (!r || r->lod != 0) return false;
    }
    return true;
  };
  bool mixed = false;
  ASSERT_TRUE(wait_for([&] {
    mixed = mixed || !neighbours_at_one_lod(expected);
    return all_at_lod0();
  })) << describe(stream->stats());
  EXPECT_FALSE(mixed) << "two neighbouring rooms were held at two lods at once";
  auto evicted = stream->take_evicted();
  for (auto id : expected)
    EXPECT_NE(std::find(evicted.begin(), evicted.end(), id), evicted.end()) << id.to_string();
  EXPECT_EQ(stream->stats().rooms_rejected, 0u) << describe(stream->stats());
}

// A multi-world server whose world slots all have players refuses a new world with a fatal
// `overloaded`: the Stream keeps the server's reason, backs off and tries again (it is not a
// refusal for good), and gets its world once a slot frees up.
TEST(Stream, a_world_refused_for_want_of_a_slot_is_retried_until_one_frees_up) {
  auto c = test_config();
  c.generator.max_worlds = 2;  // the server's own (7) and one more
  auto server = start_server(c);
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 2.0;
  o.backoff_initial = 20ms;
  o.backoff_max = 100ms;
  o.seed = 8;
  auto first = start_stream(o, rt);
  ASSERT_TRUE(first);
  ASSERT_TRUE(wait_for([&] { return first->stats().rooms_ready > 0; })) << describe(first->stats());
  o.seed = 9;
  auto second = start_stream(o, rt);
  ASSERT_TRUE(second);
  ASSERT_TRUE(wait_for([&] {
    auto s = second->stats();
    return s.errors.contains("overloaded") && s.drops > 0;  // refused and closed
  })) << describe(second->stats());
  auto refused = second->stats();
  EXPECT_NE(refused.last_error.find("max_worlds"), std::string::npos) << refused.last_error;
  EXPECT_NE(refused.state, StreamState::kFailed);
  EXPECT_EQ(refused.rooms_ready, 0u);
  first->stop();
  first.reset();
  ASSERT_TRUE(wait_for([&] { return second->stats().rooms_ready > 0; }))
      << describe(second->stats());
  EXPECT_EQ(second->stats().state, StreamState::kReady);
}

TEST(Stream, a_server_back_with_another_world_clears_what_was_held_and_spawns_again) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  const uint16_t port = server->port();
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(port);
  o.plan.horizon_s = 2.0;
  o.backoff_initial = 20ms;
  o.backoff_max = 100ms;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] {
    auto s = stream->spawn_point();
    return s && stream->ready(s->room);
  })) << describe(stream->stats());
  const auto old_spawn = *stream->spawn_point();
  const auto old_room = stream->room(old_spawn.room);
  const size_t held = stream->take_new_rooms().size();
  server->stop(1000ms);
  server.reset();
  auto other = test_config(port);
  other.seed = 8;  // a redeploy with another world behind the same address
  server = start_server(other);
  ASSERT_TRUE(server);
  ASSERT_TRUE(wait_for([&] {
    auto s = stream->spawn_point();
    return stream->stats().connects == 2 && s && stream->ready(s->room);
  })) << describe(stream->stats());
  auto evicted = stream->take_evicted();
  EXPECT_GE(evicted.size(), held) << "every room of the old world is reported gone";
  const auto new_spawn = *stream->spawn_point();
  const auto new_room = stream->room(new_spawn.room);
  ASSERT_TRUE(new_room);
  EXPECT_FALSE(new_spawn.position == old_spawn.position) << "a new spawn point was asked for";
  if (new_spawn.room == old_spawn.room) {
    EXPECT_FALSE(new_room->room.sphere.centre == old_room->room.sphere.centre);
  }
  EXPECT_EQ(stream->stats().rooms_rejected, 0u);
}

TEST(Stream, keeps_its_store_within_budget_by_evicting_the_farthest_rooms) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 2.0;
  // Room for a handful of patch rooms: most decode to 20-100 KB, the hall each stop stands in (the
  // hub room r0) with its neighbours to ~0.45 MB, which the store keeps whatever the
  // budget.
  o.store_bytes = 512 << 10;
  o.spawn = false;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  // Walk far along +x, a sector at a time: each stop wants rooms the store has no room for.
  for (int x = 0; x < 6; ++x) {
    Pose pose;
    pose.room = RoomId::interior({x * 2, 0, 0}, 0);
    auto d = [&] { return stream->descriptor(*pose.room); };
    stream->set_pose(pose);
    ASSERT_TRUE(wait_for([&] { return stream->ready(*pose.room); })) << describe(stream->stats());
    pose.position = d()->sphere.centre;
    stream->set_pose(pose);
    std::this_thread::sleep_for(300ms);
  }
  auto stats = stream->stats();
  EXPECT_GT(stats.rooms_evicted, 0u) << describe(stats);
  EXPECT_LE(stats.store_bytes, o.store_bytes);
  auto evicted = stream->take_evicted();
  EXPECT_EQ(evicted.size(), stats.rooms_evicted);
  // The first stop is the farthest from the last: its room went first.
  EXPECT_FALSE(stream->ready(RoomId::interior({0, 0, 0}, 0)));
  EXPECT_TRUE(stream->ready(RoomId::interior({10, 0, 0}, 0)));
  for (auto id : evicted)
    EXPECT_FALSE(stream->ready(id));
}

// A game holds its spawn on wait_area_ready: it returns true once every room within 8 m of the
// spawn point along the portal graph is held, and those are the rooms the layout itself puts
// there.
TEST(Stream, wait_area_ready_holds_until_the_ground_around_the_spawn_exists) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.plan.horizon_s = 6.0;  // 8 m is within 6 s at 4 m/s, behind the view too (x2)
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  const auto spawn = *stream->spawn_point();
  ASSERT_TRUE(stream->wait_area_ready(spawn.position, 8.0, 0, kWait)) << describe(stream->stats());
  // The area by the layout's own graph (the plan at 1 m/s with no view weighting, as area.hpp
  // measures): every room of it is held.
  auto graph = layout_graph(7);
  Pose pose;
  pose.position = spawn.position;
  pose.forward = {};
  pose.speed = 1.0;
  grotto::stream::PlanOptions plan;
  plan.horizon_s = 8.0;
  plan.behind_weight = 0;
  ASSERT_GT(graph.plan(spawn.room, pose, plan).size(), 1u);
  for (const auto& room : graph.plan(spawn.room, pose, plan))
    EXPECT_TRUE(stream->ready(room.id)) << room.id.to_string() << " at " << room.seconds << " m";
  EXPECT_FALSE(stream->area_status(spawn.position, 8.0, 0).first_missing.has_value());
}

// A room of sector (1,0,0) about 100 m from the spawn point (seed 7), and a point well inside it.
struct FarRoom {
  RoomId id = RoomId::interior({}, 0);
  grotto::Vec3 point;
};
FarRoom far_room(const grotto::Vec3& spawn) {
  auto world = grotto::cave::World::create(7, {});
  EXPECT_TRUE(world.ok());
  const auto sector = grotto::cave::generate_sector(*world, {1, 0, 0});
  FarRoom best;
  double best_error = 1e9;
  for (const auto& room : sector.rooms) {
    // A passage (a small room), not a hall: 8 m around a big room's centre may reach no portal.
    if (room.sphere.radius >= 6.0) continue;
    const grotto::Vec3 p = grotto::cave::interior_point(room);
    const double error = std::abs(grotto::distance(p, spawn) - 100.0);
    if (error < best_error) {
      best_error = error;
      best = {room.id, p};
    }
  }
  EXPECT_LT(best_error, 20.0);
  return best;
}

// The rooms of the area around `point` by the layout's own graph (area.hpp's walk).
std::vector<RoomId> layout_area(const grotto::stream::PortalGraph& graph, grotto::Vec3 point,
                                double radius_m) {
  std::vector<RoomId> ids;
  const auto start = graph.room_at(point);
  EXPECT_TRUE(start.has_value());
  if (!start) return ids;
  for (const auto& p : grotto::stream::area_rooms(graph, *start, point, radius_m))
    ids.push_back(p.id);
  return ids;
}

// A game waiting for the ground somewhere else (a teleport target, another player's spawn): the
// point lies in another sector, ~100 m from the player, who stays at the spawn point and whose
// plan (16 m at most) never reaches it. The wait itself locates the point and requests its area.
TEST(Stream, wait_area_ready_fetches_an_area_far_from_the_pose) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  const auto spawn = *stream->spawn_point();
  Pose pose;
  pose.position = spawn.position;
  pose.room = spawn.room;
  stream->set_pose(pose);
  const FarRoom far = far_room(spawn.position);
  ASSERT_FALSE(stream->area_status(far.point, 8.0, 0).located);
  ASSERT_TRUE(stream->wait_area_ready(far.point, 8.0, 0, kWait)) << describe(stream->stats());
  const auto area = layout_area(layout_graph(7), far.point, 8.0);
  ASSERT_GT(area.size(), 1u);
  EXPECT_EQ(area.front(), far.id);
  for (auto id : area)
    EXPECT_TRUE(stream->ready(id)) << id.to_string();
  EXPECT_EQ(stream->stats().state, StreamState::kReady);
}

// While a wait pins its area the store keeps those rooms, however far from the player and however
// small the budget; once it returned they are ordinary rooms, evicted like any other. With a
// budget of one byte every room that no plan keeps is evicted as the next one arrives, so the
// area completes only if its rooms are kept together.
TEST(Stream, a_waited_for_area_is_not_evicted_until_the_wait_returns) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.store_bytes = 1;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  const auto spawn = *stream->spawn_point();
  Pose pose;
  pose.position = spawn.position;
  pose.room = spawn.room;
  stream->set_pose(pose);
  const FarRoom far = far_room(spawn.position);
  ASSERT_TRUE(stream->wait_area_ready(far.point, 8.0, 0, kWait)) << describe(stream->stats());
  // A second wait, around the spawn and wider than the pose's plan, brings rooms that push the
  // first area's out: they are the farthest from the player and nothing keeps them now.
  ASSERT_TRUE(stream->wait_area_ready(spawn.position, 30.0, 0, kWait)) << describe(stream->stats());
  for (auto id : layout_area(layout_graph(7), far.point, 8.0))
    EXPECT_FALSE(stream->ready(id)) << id.to_string();
  EXPECT_GT(stream->stats().rooms_evicted, 0u);
}

// One lod a session: a stream of detail rooms (lod 1) never holds an area at lod 0, so a wait for
// one answers false at once instead of running to its timeout.
TEST(Stream, wait_area_ready_below_the_sessions_lod_returns_false_at_once) {
  auto config = test_config();
  config.limits.max_lod = 1;
  auto server = start_server(config);
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  o.lod = 1;
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  const auto t0 = Clock::now();
  EXPECT_FALSE(stream->wait_area_ready(stream->spawn_point()->position, 8.0, 0, kWait));
  EXPECT_LT(Clock::now() - t0, 10s) << describe(stream->stats());
}

TEST(Stream, wait_area_ready_returns_false_at_its_timeout_and_at_once_after_stop) {
  auto server = start_server(test_config());
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions o = fixed_horizon();
  o.url = url_of(server->port());
  auto stream = start_stream(o, rt);
  ASSERT_TRUE(stream);
  // A point no room holds, whatever the stream fetches: beyond the sector range (65,535 sectors
  // of 96 m), within the protocol's coordinates (2^24 m), so the server locates it nowhere.
  const grotto::Vec3 far{16'000'000, 0, 0};
  auto t0 = Clock::now();
  EXPECT_FALSE(stream->wait_area_ready(far, 1.0, 0, 300ms));
  auto waited = Clock::now() - t0;
  EXPECT_GE(waited, 300ms);
  EXPECT_LT(waited, 10s) << "bounded by the timeout, not by the network";
  stream->stop();
  t0 = Clock::now();
  EXPECT_FALSE(stream->wait_area_ready(far, 1.0, 0, kWait));
  EXPECT_LT(Clock::now() - t0, 10s) << "a stopped stream answers at once";
}

TEST(Stream, refuses_bad_urls_and_options_by_name) {
  Runtime rt(1, 1);
  for (const char* url : {"http://x:1/ws", "ws://", "ws://:80", "ws://host:0", "ws://host:99999",
                          "ws://host:12x", "wss://host:443/ws", ""}) {
    StreamOptions o = fixed_horizon();
    o.url = url;
    auto s = Stream::start(o, rt);
    ASSERT_FALSE(s.ok()) << url;
    EXPECT_NE(s.error().message.find("url"), std::string::npos) << s.error().message;
  }
  StreamOptions o = fixed_horizon();
  o.url = "ws://127.0.0.1:1/ws";
  o.plan.horizon_s = 0;
  auto s = Stream::start(o, rt);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("horizon"), std::string::npos);
  auto url = grotto::stream::parse_url("ws://example.org:8080/caves/ws");
  ASSERT_TRUE(url.ok());
  EXPECT_EQ(url->host, "example.org");
  EXPECT_EQ(url->port, 8080);
  EXPECT_EQ(url->path, "/caves/ws");
  EXPECT_EQ(grotto::stream::parse_url("ws://h")->path, "/ws");
}

// ---- a server that misbehaves on purpose ----

enum class Misbehaviour {
  kOtherVersion,     // welcome names protocol version 3
  kRefuseVersion,    // error unsupported_version (fatal), then close
  kCorruptRoom,      // every frame of one room has a payload byte flipped
  kCutMidFrameOnce,  // the first connection's first room frame is cut off halfway
  kGarbageControl,   // a text frame that is no JSON between good messages
  kHoldLater,        // serves the rooms of the first request only; later ones stay in flight
};

// One connection at a time, synchronous Beast on a thread of its own; rooms are built with the CPU
// reference mesher, as grotto-server builds them.
class BadServer {
 public:
  explicit BadServer(Misbehaviour how)
      : how_(how), acceptor_(ioc_, {net::ip::make_address("127.0.0.1"), 0}) {
    world_ = grotto::cave::World::create(7, {}).value();
    auto ctx = grotto::mesh::MeshContext::create(*world_, {});
    ctx_ = std::make_unique<grotto::mesh::MeshContext>(std::move(ctx).value());
    rooms_ = grotto::cave::generate_sector(*world_, {0, 0, 0}).rooms;
    acceptor_.non_blocking(true);
    thread_ = std::thread([this] { run(); });
  }
  ~BadServer() {
    stop_ = true;
    thread_.join();
  }
  uint16_t port() const { return acceptor_.local_endpoint().port(); }
  int connections() const { return connections_; }
  int frames_sent(RoomId id) const {
    std::lock_guard lock(mu_);
    auto it = sent_.find(id);
    return it == sent_.end() ? 0 : it->second;
  }
  RoomId corrupt_room() const { return rooms_[0].id; }
  const grotto::cave::Room& first_room() const { return rooms_[0]; }
  std::set<RoomId> cancelled() const {
    std::lock_guard lock(mu_);
    return cancelled_;
  }
  std::string target() const {  // the last upgrade request's target
    std::lock_guard lock(mu_);
    return target_;
  }

 private:
  void run() {
    while (!stop_) {
      tcp::socket socket(ioc_);
      beast::error_code ec;
      acceptor_.accept(socket, ec);
      if (ec) {
        std::this_thread::sleep_for(5ms);
        continue;
      }
      socket.non_blocking(false);
      ++connections_;
      serve(std::move(socket));
    }
  }

  void serve(tcp::socket socket) {
    websocket::stream<tcp::socket> ws(std::move(socket));
    beast::error_code ec;
    beast::flat_buffer upgrade_buffer;
    http::request<http::string_body> upgrade;
    http::read(ws.next_layer(), upgrade_buffer, upgrade, ec);
    if (ec) return;
    {
      std::lock_guard lock(mu_);
      target_ = std::string(upgrade.target());
    }
    ws.accept(upgrade, ec);
    if (ec) return;
    beast::flat_buffer buffer;
    ws.read(buffer, ec);  // hello
    if (ec) return;
    auto hello = grotto::proto::parse_client_message(beast::buffers_to_string(buffer.data()), {});
    buffer.clear();
    grotto::proto::Ref ref = hello.ok() ? std::get<grotto::proto::Hello>(*hello).ref : std::nullopt;
    ws.text(true);
    if (how_ == Misbehaviour::kRefuseVersion) {
      grotto::proto::ErrorMessage e;
      e.ref = ref;
      e.code = grotto::ErrorCode::kUnsupportedVersion;
      e.message = "this server speaks only version 7";
      e.versions = {7};
      e.fatal = true;
      ws.write(net::buffer(grotto::proto::serialize(grotto::proto::ServerMessage{e})), ec);
      ws.close(websocket::close_code::policy_error, ec);
      return;
    }
    grotto::proto::Welcome w;
    w.ref = ref;
    w.version = how_ == Misbehaviour::kOtherVersion ? 3 : 2;
    w.server = "bad-server 0";
    w.seed = 7;
    w.params = 1;
    ws.write(net::buffer(grotto::proto::serialize(grotto::proto::ServerMessage{w})), ec);
    const bool cut_now = how_ == Misbehaviour::kCutMidFrameOnce && connections_ == 1;
    while (!stop_ && !ec) {
      // Blocking: the Stream closes its end when the test stops it, which ends this read.
      ws.read(buffer, ec);
      if (ec) break;
      auto msg = grotto::proto::parse_client_message(beast::buffers_to_string(buffer.data()), {});
      buffer.clear();
      if (!msg.ok()) continue;
      if (auto* s = std::get_if<grotto::proto::Spawn>(&*msg)) {
        grotto::proto::SpawnPoint p;
        p.ref = s->ref;
        p.room = rooms_[0].id;
        p.position = rooms_[0].sphere.centre;
        ws.text(true);
        ws.write(net::buffer(grotto::proto::serialize(grotto::proto::ServerMessage{p})), ec);
        if (how_ == Misbehaviour::kGarbageControl) {
          ws.write(net::buffer(std::string("{this is not json")), ec);
        }
      } else if (auto* c = std::get_if<grotto::proto::Cancel>(&*msg)) {
        std::lock_guard lock(mu_);
        cancelled_.insert(c->rooms.begin(), c->rooms.end());
      } else if (auto* r = std::get_if<grotto::proto::Request>(&*msg)) {
        if (how_ == Misbehaviour::kHoldLater && requests_++ > 0) continue;
        for (const auto& want : r->rooms) {
          auto frame = frame_of(want.id);
          if (frame.empty()) continue;
          {
            std::lock_guard lock(mu_);
            ++sent_[want.id];
          }
          if (cut_now) {
            // A binary frame header announcing the whole frame, half of it, then the socket
            // closes without a WebSocket close.
            std::vector<uint8_t> raw = {0x82, 127};
            for (int i = 7; i >= 0; --i)
              raw.push_back(uint8_t(uint64_t(frame.size()) >> (8 * i)));
            raw.insert(raw.end(), frame.begin(), frame.begin() + frame.size() / 2);
            net::write(ws.next_layer(), net::buffer(raw), ec);
            ws.next_layer().close(ec);
            return;
          }
          if (how_ == Misbehaviour::kCorruptRoom && want.id == corrupt_room()) {
            // The payload's Draco magic, right after the header and portal records: the frame
            // is valid, the mesh is not (caught by the decode on a worker).
            frame[grotto::proto::room_frame_size(rooms_[0].portals.size(), 0) + 4] ^= 0x5a;
          }
          ws.binary(true);
          ws.write(net::buffer(frame), ec);
          if (ec) break;
        }
      }
    }
  }

  std::vector<uint8_t> frame_of(RoomId id) {
    for (const auto& room : rooms_) {
      if (room.id != id) continue;
      auto mesh = grotto::mesh::build_room_mesh(*ctx_, room, grotto::mesh::Lod::kPatch);
      grotto::codec::EncodeOptions options;
      options.normals = false;  // version 2's payload, the version this server's welcome names
      auto payload = grotto::codec::encode_room(*mesh, options);
      return grotto::proto::encode_room_frame(room, 0, mesh->origin, *payload, 2);
    }
    return {};
  }

  Misbehaviour how_;
  net::io_context ioc_;
  tcp::acceptor acceptor_;
  std::optional<grotto::cave::World> world_;
  std::unique_ptr<grotto::mesh::MeshContext> ctx_;
  std::vector<grotto::cave::Room> rooms_;
  std::atomic<bool> stop_{false};
  std::atomic<int> connections_{0};
  mutable std::mutex mu_;
  std::map<RoomId, int> sent_;
  std::set<RoomId> cancelled_;
  std::string target_;
  int requests_ = 0;
  std::thread thread_;
};

StreamOptions bad_server_options(uint16_t port) {
  StreamOptions o = fixed_horizon();
  o.url = url_of(port);
  o.seed = 7;
  o.plan.horizon_s = 10.0;  // the spawn room and a few rings of neighbours
  o.backoff_initial = 20ms;
  o.backoff_max = 100ms;
  return o;
}

// Turning round makes the rooms ahead more expensive (the first hop is stretched for portals
// behind the view): one whose cost passes cancel_factor x horizon is cancelled. The server holds
// every room after the first, so the room is certainly still in flight when the player turns.
TEST(StreamAgainstABadServer, turning_back_cancels_the_rooms_ahead_that_leave_the_horizon) {
  BadServer bad(Misbehaviour::kHoldLater);
  Runtime rt(1, 1);
  const auto& room = bad.first_room();
  ASSERT_FALSE(room.portals.empty());
  // The portal farthest from the centre, at 0.8 of the horizon straight ahead: wanted; behind
  // (cost x2 = 1.6 horizons) past the cancel line at 1.5.
  const grotto::cave::Portal* ahead = &room.portals[0];
  for (const auto& p : room.portals) {
    if (distance(p.centre, room.sphere.centre) > distance(ahead->centre, room.sphere.centre)) {
      ahead = &p;
    }
  }
  const double d = distance(ahead->centre, room.sphere.centre);
  StreamOptions o = bad_server_options(bad.port());
  o.spawn = false;
  o.plan.horizon_s = d / 0.8;
  o.cancel_factor = 1.5;
  o.replan_interval = 20ms;
  auto stream = start_stream(o, rt);
  Pose pose;
  pose.room = room.id;
  pose.position = room.sphere.centre;
  pose.forward = ahead->centre - room.sphere.centre;
  pose.speed = 1.0;
  stream->set_pose(pose);
  ASSERT_TRUE(wait_for([&] { return stream->ready(room.id) && stream->stats().in_flight > 0; }))
      << describe(stream->stats());
  EXPECT_TRUE(bad.cancelled().empty());
  pose.forward = -pose.forward;
  stream->set_pose(pose);
  ASSERT_TRUE(wait_for([&] { return bad.cancelled().count(ahead->neighbour) == 1; }))
      << describe(stream->stats());
  EXPECT_GE(stream->stats().cancels_sent, 1u);
}

TEST(StreamAgainstABadServer, stops_with_a_clear_error_when_the_server_picks_another_version) {
  BadServer bad(Misbehaviour::kOtherVersion);
  Runtime rt(1, 1);
  auto stream = start_stream(bad_server_options(bad.port()), rt);
  ASSERT_TRUE(wait_for([&] { return stream->state() == StreamState::kFailed; }))
      << describe(stream->stats());
  auto stats = stream->stats();
  EXPECT_NE(stats.last_error.find("version 3"), std::string::npos) << stats.last_error;
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(bad.connections(), 1) << "a refused version must not be retried";
}

TEST(StreamAgainstABadServer, the_upgrade_carries_the_seed_as_a_routing_hint) {
  Runtime rt(1, 1);
  for (std::optional<uint64_t> seed :
       {std::optional<uint64_t>(18446744073709551615ull), std::optional<uint64_t>()}) {
    BadServer bad(Misbehaviour::kRefuseVersion);
    auto o = bad_server_options(bad.port());
    o.seed = seed;
    auto stream = start_stream(o, rt);
    ASSERT_TRUE(wait_for([&] { return stream->state() == StreamState::kFailed; }))
        << describe(stream->stats());
    EXPECT_EQ(bad.target(), seed ? "/ws?seed=18446744073709551615" : "/ws");
  }
}

TEST(StreamAgainstABadServer, stops_when_the_server_refuses_our_version) {
  BadServer bad(Misbehaviour::kRefuseVersion);
  Runtime rt(1, 1);
  auto stream = start_stream(bad_server_options(bad.port()), rt);
  ASSERT_TRUE(wait_for([&] { return stream->state() == StreamState::kFailed; }))
      << describe(stream->stats());
  auto stats = stream->stats();
  EXPECT_NE(stats.last_error.find("unsupported_version"), std::string::npos) << stats.last_error;
  EXPECT_EQ(stats.errors["unsupported_version"], 1u);
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(bad.connections(), 1);
}

TEST(StreamAgainstABadServer, rejects_a_corrupt_room_asks_again_and_gives_up_after_three) {
  BadServer bad(Misbehaviour::kCorruptRoom);
  Runtime rt(1, 1);
  auto stream = start_stream(bad_server_options(bad.port()), rt);
  ASSERT_TRUE(wait_for([&] { return stream->stats().rooms_given_up == 1; }))
      << stream->stats().last_error;
  EXPECT_EQ(bad.frames_sent(bad.corrupt_room()), 3);
  ASSERT_TRUE(wait_for([&] { return stream->stats().rooms_ready >= 1; }))
      << "the other rooms still arrive";
  auto stats = stream->stats();
  EXPECT_EQ(stats.rooms_rejected, 3u);
  EXPECT_FALSE(stream->ready(bad.corrupt_room()));
  EXPECT_EQ(stats.state, StreamState::kReady) << "one bad room does not end the connection";
  EXPECT_EQ(bad.connections(), 1);
}

TEST(StreamAgainstABadServer, a_connection_cut_mid_frame_reconnects_and_the_room_arrives) {
  BadServer bad(Misbehaviour::kCutMidFrameOnce);
  Runtime rt(1, 1);
  auto stream = start_stream(bad_server_options(bad.port()), rt);
  ASSERT_TRUE(wait_for([&] { return stream->ready(bad.corrupt_room()); }))
      << stream->stats().last_error;
  auto stats = stream->stats();
  EXPECT_EQ(bad.connections(), 2);
  EXPECT_EQ(stats.drops, 1u);
  EXPECT_EQ(stats.reconnects, 1u);
  EXPECT_EQ(stats.rooms_rejected, 0u);
}

TEST(StreamAgainstABadServer, an_invalid_control_message_is_counted_and_the_stream_goes_on) {
  BadServer bad(Misbehaviour::kGarbageControl);
  Runtime rt(1, 1);
  auto stream = start_stream(bad_server_options(bad.port()), rt);
  ASSERT_TRUE(wait_for([&] { return stream->stats().rooms_ready >= 2; }))
      << describe(stream->stats());
  auto stats = stream->stats();
  EXPECT_EQ(stats.errors["bad_message"], 1u);
  EXPECT_NE(stats.last_error.find("invalid message"), std::string::npos) << stats.last_error;
  EXPECT_EQ(bad.connections(), 1);
}

}  // namespace

// ---- the shared-secret token ----

namespace token_tests {

TEST(StreamToken, the_right_token_streams_and_a_wrong_one_fails_for_good) {
  auto c = test_config();
  c.token = "stream-secret";
  auto server = start_server(c);
  ASSERT_TRUE(server);
  Runtime rt(1, 2);
  StreamOptions good;
  good.url = url_of(server->port());
  good.token = "stream-secret";
  good.plan.horizon_s = 1.0;
  auto stream = start_stream(good, rt);
  ASSERT_TRUE(stream);
  ASSERT_TRUE(wait_for([&] { return stream->stats().rooms_ready > 0; }))
      << describe(stream->stats());
  for (const std::string& token : {std::string("stream-secreT"), std::string()}) {
    SCOPED_TRACE(token.empty() ? "no token" : "wrong token");
    StreamOptions bad = good;
    bad.token = token;
    auto refused = start_stream(bad, rt);
    ASSERT_TRUE(refused);
    ASSERT_TRUE(wait_for([&] { return refused->state() == StreamState::kFailed; }))
        << describe(refused->stats());
    auto stats = refused->stats();
    EXPECT_EQ(stats.errors["unauthorized"], 1u);
    EXPECT_NE(stats.last_error.find(token.empty() ? "missing token" : "wrong token"),
              std::string::npos)
        << stats.last_error;
    EXPECT_EQ(stats.connects, 0u);
  }
  EXPECT_EQ(stream->state(), StreamState::kReady) << describe(stream->stats());
  StreamOptions invalid = good;
  invalid.token = "tab\there";
  auto refused = Stream::start(invalid, rt);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("token must be printable ASCII"), std::string::npos)
      << refused.error().message;
}

}  // namespace token_tests
