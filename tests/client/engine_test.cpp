// Grotto::stream's public interfaces (include/grotto/stream.hpp and grotto_stream.h) against an
// embedded server, through the shared library itself: what the headers promise about errors,
// ownership (rooms outlive the Stream; C pointers live until the next poll) and the rooms'
// arrays. tests/client/install_test.sh checks the same library installed and used from outside.
#include <gtest/gtest.h>

#include <grotto/grotto_stream.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <grotto/stream.hpp>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/cave/layout.hpp"
#include "server/embedded.hpp"

namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr auto kWait = 30s;

bool wait_for(const std::function<bool()>& done) {
  const auto deadline = Clock::now() + kWait;
  while (Clock::now() < deadline) {
    if (done()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return done();
}

// A grotto-server in-process on loopback, the CPU reference. max_players > 0 stands for a server
// past its capacity from that many players on: the next ones wait in its admission queue.
struct Server {
  grotto::server::EmbeddedServer embedded;
  explicit Server(size_t max_players = 0) {
    auto config = grotto::server::embedded_config();
    config.generator.workers = 2;
    config.generator.builder.device.device = "none";
    config.log_level = "warn";
    config.admission.max_players = max_players;
    auto started = grotto::server::start_embedded(config);
    EXPECT_TRUE(started.ok()) << (started.ok() ? "" : started.error().message);
    if (started.ok()) embedded = std::move(started).value();
  }
  const std::string& url() const { return embedded.url; }
};

// A point well inside a room of sector (1,0,0) about 100 m from `spawn` (the default world, seed
// 7), and that room's key: another sector, far beyond the pose's fetch plan.
std::pair<grotto::Vec3d, grotto::RoomKey> far_point(const double spawn[3]) {
  auto world = grotto::cave::World::create(grotto::cave::kDefaultSeed, {});
  EXPECT_TRUE(world.ok());
  const auto sector = grotto::cave::generate_sector(*world, {1, 0, 0});
  const grotto::Vec3 from{spawn[0], spawn[1], spawn[2]};
  std::pair<grotto::Vec3d, grotto::RoomKey> best{};
  double best_error = 1e9;
  for (const auto& room : sector.rooms) {
    const grotto::Vec3 p = grotto::cave::interior_point(room);
    const double error = std::abs(grotto::distance(p, from) - 100.0);
    if (error < best_error) {
      best_error = error;
      best = {{p.x, p.y, p.z}, room.id.packed()};
    }
  }
  EXPECT_LT(best_error, 20.0);
  return best;
}

// The contract of a room's arrays (stream.hpp, Room).
void expect_well_formed(const grotto::Room& r) {
  EXPECT_EQ(grotto::room_name(r.key), r.id);
  ASSERT_GT(r.vertex_count(), 0u) << r.id;
  EXPECT_EQ(r.positions.size(), 3 * r.vertex_count()) << r.id;
  EXPECT_EQ(r.normals.size(), 3 * r.vertex_count()) << r.id;
  EXPECT_EQ(r.roughness.size(), r.vertex_count()) << r.id;
  EXPECT_EQ(r.mineral.size(), r.vertex_count()) << r.id;
  ASSERT_EQ(r.indices.size() % 3, 0u) << r.id;
  EXPECT_GT(r.triangle_count(), 0u) << r.id;
  for (uint32_t i : r.indices)
    ASSERT_LT(i, r.vertex_count()) << r.id;
  for (size_t v = 0; v < r.vertex_count(); ++v) {
    // Every vertex lies within the room's sphere, plus the noise margin of verify.hpp (generous).
    const double dx = r.origin.x + r.positions[3 * v] - r.centre.x;
    const double dy = r.origin.y + r.positions[3 * v + 1] - r.centre.y;
    const double dz = r.origin.z + r.positions[3 * v + 2] - r.centre.z;
    ASSERT_LT(std::sqrt(dx * dx + dy * dy + dz * dz), r.radius + 2.0) << r.id << " vertex " << v;
    const float* n = &r.normals[3 * v];
    ASSERT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 0.01) << r.id << " vertex " << v;
  }
  ASSERT_FALSE(r.portals.empty()) << r.id;
  for (const grotto::Portal& p : r.portals)
    EXPECT_FALSE(grotto::room_name(p.neighbour).empty()) << r.id;
}

TEST(PublicStream, start_refuses_a_bad_configuration_with_the_reason) {
  std::string error;
  grotto::StreamConfig config;
  config.url = "http://127.0.0.1:1/ws";
  EXPECT_EQ(grotto::Stream::start(config, &error), nullptr);
  EXPECT_NE(error.find("ws://"), std::string::npos) << error;
  EXPECT_EQ(grotto::Stream::start(config), nullptr) << "error may be null";
  config.url = "ws://127.0.0.1:1/ws";
  config.horizon_s = -1;
  EXPECT_EQ(grotto::Stream::start(config, &error), nullptr);
  EXPECT_NE(error.find("horizon"), std::string::npos) << error;
  config.horizon_s = 4;
  config.decode_threads = -1;
  EXPECT_EQ(grotto::Stream::start(config, &error), nullptr);
  EXPECT_NE(error.find("decode_threads"), std::string::npos) << error;
  config.decode_threads = 0;
  config.min_horizon_s = -1;
  EXPECT_EQ(grotto::Stream::start(config, &error), nullptr);
  EXPECT_NE(error.find("min_horizon_s"), std::string::npos) << error;
  config.min_horizon_s = std::nan("");
  EXPECT_EQ(grotto::Stream::start(config, &error), nullptr);
  EXPECT_NE(error.find("min_horizon_s"), std::string::npos) << error;
}

TEST(PublicStream, an_unreachable_server_is_no_error_at_start_and_shows_in_stats) {
  grotto::StreamConfig config;
  config.url = "ws://127.0.0.1:1/ws";
  auto stream = grotto::Stream::start(config);
  ASSERT_NE(stream, nullptr);
  ASSERT_TRUE(wait_for([&] { return !stream->stats().last_error.empty(); }));
  EXPECT_NE(stream->stats().last_error.find("127.0.0.1:1"), std::string::npos)
      << stream->stats().last_error;
  stream->stop();
  EXPECT_EQ(stream->stats().state, grotto::StreamState::kStopped);
  EXPECT_STREQ(grotto::state_name(grotto::StreamState::kStopped), "stopped");
}

TEST(PublicStream, rooms_are_well_formed_and_outlive_their_stream) {
  Server server;
  ASSERT_FALSE(server.url().empty());
  grotto::StreamConfig config;
  config.url = server.url();
  auto stream = grotto::Stream::start(config);
  ASSERT_NE(stream, nullptr);
  ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
  const grotto::SpawnPoint spawn = *stream->spawn_point();
  ASSERT_TRUE(stream->wait_area_ready(spawn.position, 8.0, 0, kWait));
  EXPECT_TRUE(stream->area_ready(spawn.position, 8.0));
  std::vector<grotto::RoomPtr> rooms = stream->poll_rooms();
  ASSERT_GE(rooms.size(), 2u);
  std::set<grotto::RoomKey> keys;
  for (const auto& r : rooms) {
    keys.insert(r->key);
    ASSERT_NE(stream->room(r->key), nullptr) << r->id;
    EXPECT_EQ(stream->room(r->key)->positions.data(), r->positions.data())
        << "room() shares the decoded arrays, it does not copy them";
  }
  EXPECT_TRUE(keys.count(spawn.room)) << grotto::room_name(spawn.room);
  EXPECT_EQ(stream->room(0xffff'ffff'ffff'ffffull), nullptr);
  EXPECT_EQ(grotto::room_name(0xffff'ffff'ffff'ffffull), "");
  const auto stats = stream->stats();
  EXPECT_EQ(stats.state, grotto::StreamState::kReady);
  EXPECT_GE(stats.rooms_held, rooms.size());
  EXPECT_GT(stats.memory_bytes, 0u);
  stream.reset();  // the Stream and its store are gone; the rooms the caller holds are not
  for (const auto& r : rooms)
    expect_well_formed(*r);
}

// The horizon adapts by default: against a quick server it stays near its floor;
// min_horizon_s 0 keeps the fixed horizon.
TEST(PublicStream, the_default_horizon_adapts_and_zero_keeps_it_fixed) {
  Server server;
  ASSERT_FALSE(server.url().empty());
  for (double floor : {grotto::StreamConfig{}.min_horizon_s, 0.0}) {
    SCOPED_TRACE("min_horizon_s " + std::to_string(floor));
    grotto::StreamConfig config;
    config.url = server.url();
    config.min_horizon_s = floor;
    auto stream = grotto::Stream::start(config);
    ASSERT_NE(stream, nullptr);
    ASSERT_TRUE(wait_for([&] { return stream->spawn_point().has_value(); }));
    ASSERT_TRUE(stream->wait_area_ready(stream->spawn_point()->position, 8.0, 0, kWait));
    const double horizon = stream->stats().horizon_s;
    if (floor > 0) {
      EXPECT_GE(horizon, floor);
      EXPECT_LT(horizon, config.horizon_s);
    } else {
      EXPECT_EQ(horizon, config.horizon_s);
    }
  }
}

// Past its capacity a server queues a newcomer (proto/PROTOCOL.md "Waiting to enter"): the
// Stream offers to wait, says where it stands, and plays once the player ahead leaves.
TEST(PublicStream, waits_in_the_admission_queue_and_plays_when_its_turn_comes) {
  Server server(1);
  ASSERT_FALSE(server.url().empty());
  grotto::StreamConfig config;
  config.url = server.url();
  auto first = grotto::Stream::start(config);
  ASSERT_NE(first, nullptr);
  ASSERT_TRUE(wait_for([&] { return first->stats().state == grotto::StreamState::kReady; }))
      << grotto::state_name(first->stats().state) << ": " << first->stats().last_error;
  EXPECT_FALSE(first->stats().queued);
  EXPECT_EQ(first->stats().times_queued, 0u);

  auto second = grotto::Stream::start(config);
  ASSERT_NE(second, nullptr);
  ASSERT_TRUE(wait_for([&] { return second->stats().state == grotto::StreamState::kQueued; }))
      << grotto::state_name(second->stats().state) << ": " << second->stats().last_error;
  EXPECT_STREQ(grotto::state_name(grotto::StreamState::kQueued), "queued");
  grotto::StreamStats s = second->stats();
  ASSERT_TRUE(s.queued);
  EXPECT_EQ(s.queued->position, 1u);
  EXPECT_EQ(s.queued->length, 1u);
  EXPECT_EQ(s.times_queued, 1u);
  EXPECT_EQ(s.connects, 0u);
  EXPECT_FALSE(second->spawn_point()) << "no spawn point before the welcome";
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(second->stats().state, grotto::StreamState::kQueued) << "it waits: no retries";
  EXPECT_GT(second->stats().queued_ms, 0.0) << "the current wait counts";

  first.reset();  // the player ahead leaves: its place goes to the head of the queue at once
  ASSERT_TRUE(wait_for([&] { return second->stats().state == grotto::StreamState::kReady; }))
      << grotto::state_name(second->stats().state) << ": " << second->stats().last_error;
  s = second->stats();
  EXPECT_FALSE(s.queued);
  EXPECT_EQ(s.times_queued, 1u);
  EXPECT_GE(s.queued_ms, 300.0);
  EXPECT_EQ(s.connects, 1u);
  ASSERT_TRUE(wait_for([&] { return second->spawn_point().has_value(); }));
  EXPECT_TRUE(second->wait_area_ready(second->spawn_point()->position, 4.0, 0, kWait));
}

TEST(CStream, create_refuses_null_and_bad_configurations_into_the_callers_buffer) {
  char error[64];
  EXPECT_EQ(grotto_stream_create(nullptr, error, sizeof error), nullptr);
  EXPECT_STREQ(error, "config is NULL");
  grotto_stream_config config{};
  EXPECT_EQ(grotto_stream_create(&config, error, sizeof error), nullptr);
  EXPECT_STREQ(error, "config.url is NULL");
  config.url = "http://x/ws";
  EXPECT_EQ(grotto_stream_create(&config, error, sizeof error), nullptr);
  EXPECT_NE(std::strstr(error, "ws://"), nullptr) << error;
  // Cut to the buffer, NUL-terminated; a zero-size or null buffer is left alone.
  char small[8];
  std::memset(small, 'x', sizeof small);
  EXPECT_EQ(grotto_stream_create(&config, small, sizeof small), nullptr);
  EXPECT_EQ(std::strlen(small), 7u);
  small[0] = 'x';
  EXPECT_EQ(grotto_stream_create(&config, small, 0), nullptr);
  EXPECT_EQ(small[0], 'x');
  EXPECT_EQ(grotto_stream_create(&config, nullptr, 64), nullptr);
}

TEST(CStream, a_null_stream_is_harmless) {
  grotto_room room;
  uint64_t key;
  double p[3] = {0, 0, 0};
  grotto_stream_destroy(nullptr);
  grotto_stream_stop(nullptr);
  grotto_stream_set_pose(nullptr, nullptr);
  EXPECT_EQ(grotto_stream_spawn_point(nullptr, p, &key), 0);
  EXPECT_EQ(grotto_stream_poll_rooms(nullptr, &room, 1), 0u);
  EXPECT_EQ(grotto_stream_poll_evicted(nullptr, &key, 1), 0u);
  EXPECT_EQ(grotto_stream_area_ready(nullptr, p, 1, 0, 0), 0);
  EXPECT_STREQ(grotto_stream_last_error(nullptr), "");
  EXPECT_STREQ(grotto_stream_state_name(GROTTO_STATE_READY), "ready");
  EXPECT_STREQ(grotto_stream_state_name(GROTTO_STATE_QUEUED), "queued");
  EXPECT_STREQ(grotto_stream_state_name(GROTTO_STATE_QUEUED + 1), "unknown");
  EXPECT_STREQ(grotto_stream_state_name(-1), "unknown");
  EXPECT_STREQ(grotto_stream_state_name(99), "unknown");
  EXPECT_EQ(grotto_set_log_level(nullptr), 0);
  EXPECT_EQ(grotto_set_log_level("loud"), 0);
  EXPECT_EQ(grotto_set_log_level("warn"), 1);
  EXPECT_FALSE(grotto::set_log_level("Warn"));
  EXPECT_TRUE(grotto::set_log_level("info"));
}

// Polled one room at a time, each room's pointers stay readable until the next poll and carry
// what the C++ interface holds for that room.
TEST(CStream, polls_rooms_into_the_callers_array_a_few_at_a_time) {
  Server server;
  ASSERT_FALSE(server.url().empty());
  grotto_stream_config config{};
  config.url = server.url().c_str();
  config.decode_threads = 1;
  char error[128] = "";
  grotto_stream* stream = grotto_stream_create(&config, error, sizeof error);
  ASSERT_NE(stream, nullptr) << error;
  grotto_pose pose{};
  uint64_t spawn_room = 0;
  ASSERT_TRUE(
      wait_for([&] { return grotto_stream_spawn_point(stream, pose.position, &spawn_room); }));
  grotto_stream_set_pose(stream, &pose);
  ASSERT_EQ(grotto_stream_area_ready(stream, pose.position, 8.0, 0, 30'000), 1);
  // No room holds it: beyond the sector range (65,535 sectors of 96 m), within the protocol's
  // coordinates, so the server locates it nowhere and the waits below run to their timeouts.
  const double far[3] = {16'000'000, 0, 0};
  const auto t0 = Clock::now();
  EXPECT_EQ(grotto_stream_area_ready(stream, far, 1.0, 0, 0), 0);
  EXPECT_EQ(grotto_stream_area_ready(stream, far, 1.0, 0, 200), 0);
  EXPECT_LT(Clock::now() - t0, 10s) << "timeout 0 answers now, 200 waits 200 ms";
  grotto_stream_stats stats;
  grotto_stream_get_stats(stream, &stats);
  EXPECT_EQ(stats.state, GROTTO_STATE_READY);
  ASSERT_GE(stats.rooms_ready, 2u);

  std::set<uint64_t> seen;
  grotto_room rooms[2];
  for (size_t polled; (polled = grotto_stream_poll_rooms(stream, rooms, 1)) != 0;) {
    ASSERT_EQ(polled, 1u);
    const grotto_room& r = rooms[0];
    EXPECT_TRUE(seen.insert(r.key).second) << r.id << " handed out twice";
    EXPECT_EQ(grotto_stream_last_error(stream), std::string());
    ASSERT_GT(r.vertex_count, 0u);
    ASSERT_GT(r.portal_count, 0u);
    EXPECT_EQ(r.index_count % 3, 0u);
    for (size_t i = 0; i < r.index_count; ++i)
      ASSERT_LT(r.indices[i], r.vertex_count) << r.id;
    float sum = 0;  // every array readable to its end
    for (size_t v = 0; v < r.vertex_count; ++v) {
      sum += r.positions[3 * v + 2] + r.normals[3 * v + 2] + r.roughness[v] + r.mineral[v];
    }
    EXPECT_TRUE(std::isfinite(sum)) << r.id;
    EXPECT_FALSE(grotto::room_name(r.portals[r.portal_count - 1].neighbour).empty());
    EXPECT_EQ(grotto::room_name(r.key), r.id);
  }
  EXPECT_GE(seen.size(), stats.rooms_ready);
  EXPECT_TRUE(seen.count(spawn_room));
  EXPECT_EQ(grotto_stream_poll_rooms(stream, rooms, 2), 0u) << "every room is handed out once";
  uint64_t evicted[4];
  EXPECT_EQ(grotto_stream_poll_evicted(stream, evicted, 4), 0u) << "256 MiB holds them all";
  // A wait in another thread ends at once when the stream stops.
  std::thread waiter([&] {
    const auto start = Clock::now();
    EXPECT_EQ(grotto_stream_area_ready(stream, far, 1.0, 0, 60'000), 0);
    EXPECT_LT(Clock::now() - start, 20s);
  });
  std::this_thread::sleep_for(100ms);
  grotto_stream_stop(stream);
  waiter.join();
  grotto_stream_get_stats(stream, &stats);
  EXPECT_EQ(stats.state, GROTTO_STATE_STOPPED);
  grotto_stream_destroy(stream);
}

// grotto_stream_area_ready fetches what it waits for: the ground 100 m away, in another sector,
// with the player standing at the spawn point. timeout 0 only answers.
TEST(CStream, area_ready_fetches_an_area_far_from_the_pose) {
  Server server;
  ASSERT_FALSE(server.url().empty());
  grotto_stream_config config{};
  config.url = server.url().c_str();
  char error[128] = "";
  grotto_stream* stream = grotto_stream_create(&config, error, sizeof error);
  ASSERT_NE(stream, nullptr) << error;
  grotto_pose pose{};
  ASSERT_TRUE(wait_for([&] { return grotto_stream_spawn_point(stream, pose.position, nullptr); }));
  grotto_stream_set_pose(stream, &pose);
  const auto [far, far_key] = far_point(pose.position);
  const double point[3] = {far.x, far.y, far.z};
  EXPECT_EQ(grotto_stream_area_ready(stream, point, 8.0, 0, 0), 0);
  ASSERT_EQ(grotto_stream_area_ready(stream, point, 8.0, 0, 30'000), 1)
      << grotto_stream_last_error(stream);
  bool far_room_polled = false;
  grotto_room rooms[16];
  for (size_t n; (n = grotto_stream_poll_rooms(stream, rooms, 16)) != 0;) {
    for (size_t i = 0; i < n; ++i)
      far_room_polled = far_room_polled || rooms[i].key == far_key;
  }
  EXPECT_TRUE(far_room_polled) << grotto::room_name(far_key) << " was not handed out";
  grotto_stream_destroy(stream);
}

// The C interface over the same queue: two streams on a server full with one player; the second
// reports GROTTO_STATE_QUEUED and its place, and becomes READY when the first is destroyed.
TEST(CStream, waits_in_the_admission_queue_and_plays_when_its_turn_comes) {
  Server server(1);
  ASSERT_FALSE(server.url().empty());
  grotto_stream_config config{};
  config.url = server.url().c_str();
  char error[128] = "";
  // Destroyed however the test ends, before the server.
  using Handle = std::unique_ptr<grotto_stream, decltype(&grotto_stream_destroy)>;
  Handle first(grotto_stream_create(&config, error, sizeof error), grotto_stream_destroy);
  ASSERT_NE(first, nullptr) << error;
  grotto_stream_stats stats;
  auto state_of = [&](grotto_stream* stream) {
    grotto_stream_get_stats(stream, &stats);
    return stats.state;
  };
  EXPECT_TRUE(wait_for([&] { return state_of(first.get()) == GROTTO_STATE_READY; }))
      << grotto_stream_state_name(stats.state) << ": " << grotto_stream_last_error(first.get());
  EXPECT_EQ(stats.queue_position, 0u);
  EXPECT_EQ(stats.queue_length, 0u);
  EXPECT_EQ(stats.times_queued, 0u);

  Handle second(grotto_stream_create(&config, error, sizeof error), grotto_stream_destroy);
  ASSERT_NE(second, nullptr) << error;
  EXPECT_TRUE(wait_for([&] { return state_of(second.get()) == GROTTO_STATE_QUEUED; }))
      << grotto_stream_state_name(stats.state) << ": " << grotto_stream_last_error(second.get());
  EXPECT_STREQ(grotto_stream_state_name(stats.state), "queued");
  EXPECT_EQ(stats.queue_position, 1u);
  EXPECT_EQ(stats.queue_length, 1u);
  EXPECT_LE(stats.queue_wait_ms, 86'400'000u);
  EXPECT_EQ(stats.times_queued, 1u);
  EXPECT_EQ(stats.connects, 0u);
  double spawn[3];
  EXPECT_EQ(grotto_stream_spawn_point(second.get(), spawn, nullptr), 0);
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(state_of(second.get()), GROTTO_STATE_QUEUED) << "it waits: no retries";
  EXPECT_EQ(stats.queue_position, 1u);
  EXPECT_GT(stats.queued_ms, 0.0) << "the current wait counts";

  first.reset();  // grotto_stream_destroy: the player ahead leaves
  EXPECT_TRUE(wait_for([&] { return state_of(second.get()) == GROTTO_STATE_READY; }))
      << grotto_stream_state_name(stats.state) << ": " << grotto_stream_last_error(second.get());
  EXPECT_EQ(stats.queue_position, 0u);
  EXPECT_EQ(stats.queue_length, 0u);
  EXPECT_EQ(stats.queue_wait_ms, 0u);
  EXPECT_EQ(stats.times_queued, 1u);
  EXPECT_GE(stats.queued_ms, 300.0);
  EXPECT_EQ(stats.connects, 1u);
  EXPECT_TRUE(
      wait_for([&] { return grotto_stream_spawn_point(second.get(), spawn, nullptr) == 1; }));
}

}  // namespace
