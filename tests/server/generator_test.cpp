// The generation service's shell (server/generator.hpp) with real threads:
// rooms reach clients as frames that decode to the mesh built in-process, the
// same bytes whatever the batches and worlds; the workers build for every
// client and cache hits come back inside request(); clients requesting and
// cancelling from many threads leave nothing behind; shutdown; worlds opened
// and closed as the schedule says; owners' frames checked as untrusted input.
// Real OpenCL (PoCL, or whatever $GROTTO_OPENCL_DEVICE picks) and the CPU path
// (device "none"), real codec. Waits are condition variables with generous
// timeouts; nothing asserts a duration.
//
// The policy (priorities, deadline classes, round-robin, single flight,
// cancellation, batches, deadlines, the world registry, owner fetches) is
// tested without threads, by tables, in schedule_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "common/codec/room_codec.hpp"
#include "common/mesh/context.hpp"
#include "proto/lod.hpp"
#include "proto/room_frame.hpp"
#include "server/generator.hpp"
#include "server/metrics.hpp"
#include "server/room_cache.hpp"
#include "server/sector_cache.hpp"

namespace grotto::server {
namespace {

using namespace std::chrono_literals;
constexpr auto kWait = 60s;  // a bound for waits that normally end in milliseconds

const cave::World& test_world() {
  static const cave::World world = cave::World::create(42, cave::LayoutParams{}).value();
  return world;
}

// Interior rooms that exist, sector by sector along +x, in order.
std::vector<cave::RoomId> existing_rooms(size_t n, const cave::World& world = test_world()) {
  std::vector<cave::RoomId> out;
  for (int x = 0; out.size() < n; ++x) {
    cave::SectorLayout s = cave::generate_sector(world, {x, 0, 0});
    for (const cave::Room& r : s.rooms) {
      if (out.size() < n) out.push_back(r.id);
    }
  }
  return out;
}

std::vector<Want> wants_of(const std::vector<cave::RoomId>& ids, uint32_t lod = 0,
                           uint32_t priority = 0) {
  std::vector<Want> out;
  for (cave::RoomId id : ids)
    out.push_back({id, lod, priority});
  return out;
}

// Records the deliveries of one client, in order.
class Inbox {
 public:
  // on_deliver runs inside the callback, on the delivering thread, before the
  // delivery counts.
  Generator::DeliverFn fn(std::function<void()> on_deliver = {}) {
    return [this, on_deliver](Delivery d) {
      if (on_deliver) on_deliver();
      std::lock_guard lock(mutex_);
      got_.push_back(std::move(d));
      cv_.notify_all();
    };
  }
  // True when at least n deliveries arrived within the bound.
  bool wait_for(size_t n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, kWait, [&] { return got_.size() >= n; });
  }
  std::vector<Delivery> got() const {
    std::lock_guard lock(mutex_);
    return got_;
  }
  size_t size() const {
    std::lock_guard lock(mutex_);
    return got_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Delivery> got_;
};

GeneratorConfig cpu_config(int workers = 1) {
  GeneratorConfig c;
  c.workers = workers;
  c.builder.device.device = "none";
  return c;
}

std::unique_ptr<Generator> make_generator(const GeneratorConfig& config, Metrics& metrics) {
  auto g = Generator::create(test_world(), mesh::MeshParams{}, config, metrics);
  EXPECT_TRUE(g.ok()) << (g.ok() ? "" : g.error().message);
  return g.ok() ? std::move(g).value() : nullptr;
}

// ---- frames ----

class GeneratorPathTest : public ::testing::TestWithParam<std::string> {};

TEST_P(GeneratorPathTest, delivered_frame_decodes_to_the_mesh_built_in_process) {
  GeneratorConfig config;
  config.workers = 1;
  // "per-worker": the default device, with a context of the worker's own.
  const bool per_worker = GetParam() == "per-worker";
  config.builder.device.device = per_worker ? "" : GetParam();
  config.share_device = !per_worker;
  Metrics metrics;
  auto gen = make_generator(config, metrics);
  ASSERT_TRUE(gen);
  EXPECT_FALSE(gen->compute_path().empty());
  if (GetParam() == "none") {
    EXPECT_EQ(gen->compute_path().rfind("cpu:", 0), 0u);
  }

  cave::RoomId id = existing_rooms(3)[2];
  // A client of each protocol version: the newest (no normals in the payload)
  // and version 1.
  for (uint32_t version : {proto::kProtocolVersion, proto::kMinProtocolVersion}) {
    SCOPED_TRACE("protocol version " + std::to_string(version));
    Inbox inbox;
    auto c = gen->add_client(test_world().seed(), inbox.fn(), version);
    ASSERT_TRUE(c.ok());
    std::vector<Want> want = {{id, 0, 0}};
    gen->request(*c, want);
    ASSERT_TRUE(inbox.wait_for(1));
    Delivery d = inbox.got()[0];
    ASSERT_FALSE(d.error) << d.error->message;
    ASSERT_TRUE(d.room);
    EXPECT_EQ(d.key.id, id);
    EXPECT_EQ(d.key.version, version);
    EXPECT_FALSE(d.from_cache) << "the other version's frame is not this one's";

    auto frame = proto::decode_room_frame(d.room->frame, proto::Limits{.max_lod = 1});
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_EQ(frame->version, version);
    EXPECT_EQ(frame->lod, 0);
    cave::Room expected_room = cave::room(test_world(), id).value();
    std::vector<unsigned char> a, b;
    cave::append_bytes(frame->room, a);
    cave::append_bytes(expected_room, b);
    EXPECT_EQ(a, b);

    // The same room built here, with a builder of the same options, encoded the
    // same way.
    auto ctx = mesh::MeshContext::create(test_world(), mesh::MeshParams{}).value();
    auto builder = kernels::RoomBuilder::create(ctx, config.builder);
    auto meshes = builder.build(std::span(&expected_room, 1), mesh::Lod::kPatch);
    ASSERT_TRUE(meshes[0].ok());
    EXPECT_EQ(frame->origin, meshes[0]->origin);
    codec::EncodeOptions options;
    options.normals = proto::payload_has_normals(version);
    auto payload = codec::encode_room(*meshes[0], options);
    ASSERT_TRUE(payload.ok());
    codec::DecodeLimits limits;
    limits.normals = options.normals;
    auto got = codec::decode_room(frame->payload, limits);
    auto want_room = codec::decode_room(*payload, limits);
    ASSERT_TRUE(got.ok()) << got.error().message;
    ASSERT_TRUE(want_room.ok());
    EXPECT_GT(got->vertex_count(), 100u);
    EXPECT_EQ(got->normals.size(), version == 1 ? got->vertex_count() : 0u);
    EXPECT_EQ(got->positions.size(), want_room->positions.size());
    EXPECT_TRUE(std::equal(got->positions.begin(), got->positions.end(),
                           want_room->positions.begin(), want_room->positions.end(),
                           [](auto p, auto q) { return p.x == q.x && p.y == q.y && p.z == q.z; }));
    EXPECT_EQ(got->indices, want_room->indices);
    EXPECT_EQ(got->rim_portal, want_room->rim_portal);
    EXPECT_EQ(got->rim_index, want_room->rim_index);
    EXPECT_EQ(got->roughness, want_room->roughness);
    EXPECT_EQ(frame->payload, *payload);
    gen->remove_client(*c);
  }
  EXPECT_EQ(metrics.rooms_built.value(), 2u);
  EXPECT_EQ(metrics.batches.value(), 2u);
  // A shared device launches each batch (one worker: nothing to merge), and
  // says so.
  const bool shared = gen->compute_path().rfind("opencl:", 0) == 0 && !per_worker;
  EXPECT_EQ(gen->compute_path().find("shared=true") != std::string::npos, shared)
      << gen->compute_path();
  EXPECT_EQ(metrics.device_launches.value(), shared ? 2u : 0u);
  EXPECT_EQ(metrics.device_launch_seconds.count(), shared ? 2u : 0u);
  EXPECT_EQ(gen->device_launches().batches, shared ? 2u : 0u);
  EXPECT_EQ(metrics.build_seconds.count(), 2u);
  EXPECT_EQ(metrics.encode_seconds.count(), 2u);
  EXPECT_EQ(metrics.rooms_in_flight.value(), 0);
}

INSTANTIATE_TEST_SUITE_P(Paths, GeneratorPathTest, ::testing::Values("", "per-worker", "none"),
                         [](const ::testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param.empty() ? std::string("opencl_or_default")
                                  : param_info.param == "per-worker" ? std::string("per_worker")
                                                                     : std::string("cpu");
                         });

TEST(GeneratorTest, frames_are_identical_across_generators_and_batch_mixes) {
  std::vector<cave::RoomId> ids = existing_rooms(12);
  cave::RoomId target = ids[5];
  auto frame_of = [&](const GeneratorConfig& config, const std::vector<cave::RoomId>& batch) {
    Metrics metrics;
    auto gen = make_generator(config, metrics);
    Inbox inbox;
    ClientId c = gen->add_client(inbox.fn());
    gen->request(c, wants_of(batch));
    EXPECT_TRUE(inbox.wait_for(batch.size()));
    for (const Delivery& d : inbox.got()) {
      if (d.key.id == target && d.room) return d.room->frame;
    }
    ADD_FAILURE() << "target room not delivered";
    return std::vector<uint8_t>{};
  };
  GeneratorConfig alone;
  alone.workers = 1;
  alone.max_batch_rooms = 1;
  GeneratorConfig mixed;
  mixed.workers = 2;
  mixed.max_batch_rooms = 12;
  std::vector<uint8_t> a = frame_of(alone, {target});
  std::vector<uint8_t> b = frame_of(mixed, ids);
  std::vector<cave::RoomId> reversed(ids.rbegin(), ids.rend());
  std::vector<uint8_t> c = frame_of(mixed, reversed);
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a, b);
  EXPECT_EQ(a, c);
}

// ---- the workers ----

// Two clients' rooms from two workers: each room built once (the one both want
// too), errors of layout (not_found) and of the want (invalid_argument)
// delivered, and a room built before is delivered from the cache inside
// request(), on the caller's thread.
TEST(GeneratorTest, workers_build_for_every_client_and_cache_hits_come_inside_request) {
  Metrics metrics;
  auto gen = make_generator(cpu_config(2), metrics);
  ASSERT_TRUE(gen);
  const std::vector<cave::RoomId> ids = existing_rooms(2);
  const cave::RoomId missing = cave::RoomId::interior({0, 0, 0}, 4000);
  const cave::RoomId no_gate = cave::RoomId::gate({0, 0, 0}, 1, 15);
  Inbox inbox;  // both clients'
  ClientId a = gen->add_client(inbox.fn());
  ClientId b = gen->add_client(inbox.fn());
  std::vector<Want> a_wants = {
      {ids[0], 0, 0}, {ids[1], 0, 0}, {missing, 0, 0}, {ids[0], proto::kMaxWireLod + 1, 0}};
  std::vector<Want> b_wants = {{ids[1], 0, 0}, {no_gate, 0, 0}};
  gen->request(a, a_wants);
  gen->request(b, b_wants);
  ASSERT_TRUE(inbox.wait_for(6));
  std::map<std::pair<cave::RoomId, uint8_t>, std::vector<RoomPtr>> rooms;
  std::map<cave::RoomId, ErrorCode> errors;
  for (const Delivery& d : inbox.got()) {
    if (d.error) {
      EXPECT_FALSE(d.room);
      errors[d.key.id] = d.error->code;
    } else {
      rooms[{d.key.id, d.key.lod}].push_back(d.room);
    }
  }
  EXPECT_EQ(errors[missing], ErrorCode::kNotFound);
  EXPECT_EQ(errors[no_gate], ErrorCode::kNotFound);
  EXPECT_EQ(errors[ids[0]], ErrorCode::kInvalidArgument);
  const std::vector<RoomPtr>& both = rooms[{ids[1], 0}];
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both[0], both[1]) << "one encoded room for both";
  EXPECT_EQ(metrics.rooms_built.value(), 2u);
  EXPECT_EQ(metrics.rooms_failed.value(), 2u);
  EXPECT_EQ(metrics.rooms_in_flight.value(), 0);
  EXPECT_EQ(gen->queue_depth(), 0u);

  Inbox later;
  ClientId c = gen->add_client(later.fn());
  std::vector<Want> again = {{ids[0], 0, 0}};
  gen->request(c, again);
  ASSERT_EQ(later.size(), 1u);  // delivered before request() returned
  EXPECT_TRUE(later.got()[0].from_cache);
  const RoomPtr first_built = rooms[{ids[0], 0}].at(0);
  EXPECT_EQ(later.got()[0].room, first_built);
  EXPECT_EQ(metrics.rooms_from_cache.value(), 1u);
  EXPECT_EQ(metrics.cache_entries.value(), 2);
  // Removed clients get nothing more, and their requests are ignored.
  gen->remove_client(c);
  gen->request(c, again);
  EXPECT_EQ(later.size(), 1u);
}

// The workers carry a name the operating system shows (top -H, ps -L, perf).
TEST(GeneratorTest, workers_are_named_for_the_operating_system) {
  Metrics metrics;
  auto gen = make_generator(cpu_config(2), metrics);
  ASSERT_TRUE(gen);
  int named = 0;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string name;
    std::getline(comm, name);
    named += name == "grotto-build";
  }
  EXPECT_GE(named, 2);
}

TEST(GeneratorTest, concurrent_clients_requesting_and_cancelling_leave_nothing_behind) {
  GeneratorConfig config = cpu_config(2);
  config.max_batch_rooms = 4;
  config.cache_bytes = 40'000;  // some hits, some evictions
  Metrics metrics;
  auto gen = make_generator(config, metrics);
  std::vector<cave::RoomId> pool = existing_rooms(60);
  constexpr int kThreads = 4;
  std::atomic<int> errors{0}, stuck{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      // What this client still waits for. A delivery for a room it cancelled
      // (collected just before the cancel) may still come: it is counted apart,
      // never an error.
      std::mutex m;
      std::condition_variable cv;
      std::set<cave::RoomId> outstanding;
      ClientId c = gen->add_client([&](Delivery d) {
        std::lock_guard lock(m);
        if (d.error) ++errors;
        outstanding.erase(d.key.id);
        cv.notify_all();
      });
      std::mt19937 rng(1234 + t);
      auto pick = [&] { return pool[rng() % pool.size()]; };
      for (int round = 0; round < 25; ++round) {
        std::vector<Want> wants;
        {
          std::lock_guard lock(m);
          for (int i = 0; i < 5; ++i) {
            cave::RoomId id = pick();
            if (outstanding.insert(id).second) wants.push_back({id, 0, uint32_t(rng() % 4)});
          }
        }
        gen->request(c, wants);
        std::vector<cave::RoomId> cancel = {pick(), pick()};
        {
          std::lock_guard lock(m);
          for (cave::RoomId id : cancel)
            outstanding.erase(id);
        }
        gen->cancel(c, cancel);
      }
      {
        std::unique_lock lock(m);
        if (!cv.wait_for(lock, kWait, [&] { return outstanding.empty(); })) ++stuck;
      }
      gen->remove_client(c);
    });
  }
  for (std::thread& th : threads)
    th.join();
  EXPECT_EQ(errors.load(), 0);
  EXPECT_EQ(stuck.load(), 0);
  EXPECT_EQ(gen->queue_depth(), 0u);
  EXPECT_EQ(metrics.rooms_in_flight.value(), 0);
  EXPECT_EQ(metrics.queue_depth.value(), 0);
  // Single flight and the cache: far fewer builds than wants.
  EXPECT_GT(metrics.rooms_built.value(), 0u);
  EXPECT_LE(metrics.cache_bytes.value(), 40'000);
}

// ---- shutdown ----

// The workers stop and shutdown() returns; later wants fail with
// service_restart inside request(), and no other world opens. (What happens to
// queued work: schedule_test.cpp.)
TEST(GeneratorTest, shutdown_stops_the_workers_and_refuses_later_work) {
  Metrics metrics;
  GeneratorConfig config = cpu_config(2);
  config.max_worlds = 2;
  auto gen = make_generator(config, metrics);
  ASSERT_TRUE(gen);
  Inbox inbox;
  ClientId c = gen->add_client(inbox.fn());
  gen->shutdown();
  gen->shutdown(10ms);  // idempotent
  std::vector<Want> late = wants_of(existing_rooms(1));
  gen->request(c, late);
  ASSERT_EQ(inbox.size(), 1u);
  ASSERT_TRUE(inbox.got()[0].error);
  EXPECT_EQ(inbox.got()[0].error->code, ErrorCode::kServiceRestart);
  auto other = gen->add_client(43, [](Delivery) {});
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.error().code, ErrorCode::kServiceRestart);
  EXPECT_EQ(gen->worlds_open(), 1u);
  EXPECT_EQ(metrics.rooms_built.value(), 0u);
}

// ---- configuration ----

TEST(GeneratorTest, create_rejects_bad_config_naming_the_setting) {
  Metrics metrics;
  GeneratorConfig c = cpu_config();
  c.max_batch_rooms = 0;
  auto g = Generator::create(test_world(), mesh::MeshParams{}, c, metrics);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error().message.find("max_batch_rooms"), std::string::npos);
  c = cpu_config(-1);
  g = Generator::create(test_world(), mesh::MeshParams{}, c, metrics);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error().message.find("workers"), std::string::npos);
}

TEST(GeneratorTest, locate_and_spawn_agree) {
  Metrics metrics;
  auto gen = make_generator(cpu_config(), metrics);
  ClientId c = gen->add_client([](Delivery) {});
  cave::Spawn spawn = gen->spawn(c);
  EXPECT_EQ(gen->locate(c, spawn.position), spawn.room);
  EXPECT_FALSE(gen->locate(c, {1e30, 0, 0}));
}

// ---- worlds ----

// A generator with room for several worlds: its own (test_world, seed 42) and
// others opened for the clients that name them.
GeneratorConfig worlds_config(size_t max_worlds) {
  GeneratorConfig c = cpu_config(2);
  c.max_worlds = max_worlds;
  return c;
}

// Frames by room, from one client of world `seed` asking for `ids` (at `lod`)
// on `gen`; a Build::kHere client never asks an owner.
std::map<cave::RoomId, std::vector<uint8_t>> frames_from(Generator& gen, uint64_t seed,
                                                         const std::vector<cave::RoomId>& ids,
                                                         uint32_t lod = 0,
                                                         Build build = Build::kAnywhere) {
  Inbox inbox;
  auto c = gen.add_client(seed, inbox.fn(), proto::kProtocolVersion, build);
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
  if (!c.ok()) return {};
  gen.request(*c, wants_of(ids, lod));
  EXPECT_TRUE(inbox.wait_for(ids.size()));
  std::map<cave::RoomId, std::vector<uint8_t>> out;
  for (const Delivery& d : inbox.got()) {
    EXPECT_FALSE(d.error) << d.error->message;
    EXPECT_EQ(d.key.seed, seed);
    if (d.room) out[d.key.id] = d.room->frame;
  }
  gen.remove_client(*c);
  return out;
}

// The rooms of world 43 from a generator whose own world is 42, asked for at
// the same time as the same room ids of world 42 and in the other order, are
// those of a generator serving 43 alone: same bytes, never taken from the other
// world's cache or job.
TEST(GeneratorWorlds, another_worlds_rooms_equal_those_of_a_generator_of_that_world) {
  const cave::World world43 = cave::World::create(43, cave::LayoutParams{}).value();
  std::vector<cave::RoomId> ids = existing_rooms(6, world43);
  std::vector<cave::RoomId> reversed(ids.rbegin(), ids.rend());
  Metrics alone_metrics;
  auto alone = Generator::create(world43, mesh::MeshParams{}, cpu_config(1), alone_metrics);
  ASSERT_TRUE(alone.ok());
  auto expected43 = frames_from(**alone, 43, ids);
  ASSERT_EQ(expected43.size(), ids.size());

  Metrics metrics;
  auto gen = make_generator(worlds_config(2), metrics);
  ASSERT_TRUE(gen);
  std::map<cave::RoomId, std::vector<uint8_t>> got43, got42;
  std::thread other([&] { got43 = frames_from(*gen, 43, reversed); });
  got42 = frames_from(*gen, 42, ids);  // the same ids in world 42 (its sectors hold 20+ rooms)
  other.join();
  EXPECT_EQ(got43, expected43);
  EXPECT_EQ(metrics.worlds_opened.value(), 1u);
  EXPECT_EQ(metrics.worlds_open.value(), 2);
  size_t shared_ids = 0;
  for (const auto& [id, frame] : got42) {
    if (!expected43.contains(id)) continue;
    ++shared_ids;
    EXPECT_NE(frame, expected43.at(id)) << "room " << id.to_string() << " crossed worlds";
  }
  EXPECT_GT(shared_ids, 0u) << "the test wants ids that exist in both worlds";
  // The home world's rooms are still its own: the same as from a one-world
  // generator.
  Metrics home_metrics;
  auto home = make_generator(cpu_config(1), home_metrics);
  EXPECT_EQ(got42, frames_from(*home, 42, ids));
  // Layout questions are answered from the client's world.
  auto c43 = gen->add_client(43, [](Delivery) {});
  ASSERT_TRUE(c43.ok());
  ClientId c42 = gen->add_client([](Delivery) {});
  cave::Spawn s43 = gen->spawn(*c43);
  EXPECT_EQ(s43.room, cave::spawn_room(world43));
  EXPECT_EQ(gen->spawn(c42).room, cave::spawn_room(test_world()));
  EXPECT_EQ(gen->locate(*c43, s43.position), s43.room);
}

TEST(GeneratorWorlds, one_world_refuses_another_seed_with_world_mismatch) {
  Metrics metrics;
  GeneratorConfig one = cpu_config();
  one.max_worlds = 1;  // a generator of its own world alone (the default opens others)
  auto gen = make_generator(one, metrics);
  auto refused = gen->add_client(43, [](Delivery) {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kWorldMismatch);
  EXPECT_NE(refused.error().message.find("serves seed 42, not 43"), std::string::npos)
      << refused.error().message;
  EXPECT_TRUE(gen->add_client(42, [](Delivery) {}).ok());
  EXPECT_EQ(gen->worlds_open(), 1u);
}

// max_worlds 3: the own world (never closed) and two others. With both others
// in use a fourth seed is refused (overloaded); once idle, the least recently
// used other world is closed for it.
TEST(GeneratorWorlds, a_new_world_closes_the_least_recently_used_idle_one_or_is_refused) {
  Metrics metrics;
  auto gen = make_generator(worlds_config(3), metrics);
  auto add = [&](uint64_t seed) { return gen->add_client(seed, [](Delivery) {}); };
  auto a = add(43);
  auto b = add(44);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(gen->worlds_open(), 3u);
  auto refused = add(45);  // 42 is idle but is the server's own; 43 and 44 are in use
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kOverloaded);
  EXPECT_NE(refused.error().message.find("max_worlds"), std::string::npos)
      << refused.error().message;
  EXPECT_EQ(metrics.worlds_refused.value(), 1u);

  gen->remove_client(*a);  // 43 idle first...
  gen->remove_client(*b);  // ...then 44
  auto c = add(45);        // closes 43, the least recently used
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(gen->worlds_open(), 3u);
  auto d = add(44);  // still open: joins it, closes nothing
  ASSERT_TRUE(d.ok()) << d.error().message;
  auto e = add(43);  // 44 and 45 in use, 42 pinned: 43 was the one closed
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.error().code, ErrorCode::kOverloaded);
  EXPECT_EQ(metrics.worlds_opened.value(), 3u);  // 43, 44, 45
  EXPECT_EQ(metrics.worlds_open.value(), 3);
  // A stopping generator opens no world (nothing would be built in it).
  gen->remove_client(*c);
  gen->shutdown();
  auto late = add(46);
  ASSERT_FALSE(late.ok());
  EXPECT_EQ(late.error().code, ErrorCode::kServiceRestart);
  EXPECT_EQ(gen->worlds_open(), 3u);
}

TEST(GeneratorWorlds, max_worlds_out_of_range_is_refused_by_name) {
  Metrics metrics;
  GeneratorConfig c = cpu_config();
  c.max_worlds = 0;
  auto g = Generator::create(test_world(), mesh::MeshParams{}, c, metrics);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error().message.find("max_worlds"), std::string::npos) << g.error().message;
}

// ---- rooms from their owner ----

// A room tier without sockets: each fetch is answered on a thread of its own
// (never inside fetch(), as RoomSource promises) by `answer`.
class FakeOwners final : public RoomSource {
 public:
  explicit FakeOwners(std::function<Result<std::vector<uint8_t>>(const RoomKey&)> answer)
      : answer_(std::move(answer)) {}
  ~FakeOwners() override {
    for (std::thread& t : threads_)
      t.join();
  }
  void fetch(const RoomKey& key, uint32_t, std::chrono::milliseconds, Done done) override {
    std::lock_guard lock(mutex_);
    asked_.push_back(key.id);
    threads_.emplace_back([this, key, done = std::move(done)] { done(answer_(key)); });
  }
  std::vector<cave::RoomId> asked() {
    std::lock_guard lock(mutex_);
    return asked_;
  }

 private:
  std::function<Result<std::vector<uint8_t>>(const RoomKey&)> answer_;
  std::mutex mutex_;
  std::vector<cave::RoomId> asked_;
  std::vector<std::thread> threads_;
};

// Owners' frames are checked as untrusted input: the room's own frame is taken
// (and cached), and every other answer is built here: unreachable, garbage,
// another room's frame, the same room at another lod, the same id in another
// world. The rooms built here are the owner's bytes.
TEST(GeneratorOwners, an_owners_frame_is_taken_when_it_is_the_room_else_it_is_built_here) {
  const std::vector<cave::RoomId> ids = existing_rooms(6);
  Metrics reference_metrics;
  std::unique_ptr<Generator> reference = make_generator(cpu_config(), reference_metrics);
  ASSERT_TRUE(reference);
  auto frames = frames_from(*reference, 42, ids, 0, Build::kHere);
  auto detail = frames_from(*reference, 42, {ids[4]}, 1, Build::kHere);
  const cave::World other = cave::World::create(43, cave::LayoutParams{}).value();
  Metrics other_metrics;
  auto other_gen = Generator::create(other, mesh::MeshParams{}, cpu_config(), other_metrics);
  ASSERT_TRUE(other_gen.ok());
  // A room of the other world with the same id (sector 0,0,0 has enough rooms).
  auto elsewhere = frames_from(**other_gen, 43, {ids[5]}, 0, Build::kHere);
  ASSERT_EQ(frames.size(), ids.size());
  ASSERT_EQ(detail.size(), 1u);
  ASSERT_EQ(elsewhere.size(), 1u);
  std::map<cave::RoomId, Result<std::vector<uint8_t>>> answers = {
      {ids[0], frames.at(ids[0])},
      {ids[1], frames.at(ids[0])},  // another room's frame
      {ids[2], Error{ErrorCode::kUnavailable, "connection refused"}},
      {ids[3], std::vector<uint8_t>{'G', 'R', 'T', 'O', 1, 2, 3}},
      {ids[4], detail.at(ids[4])},
      {ids[5], elsewhere.at(ids[5])},
  };
  auto owners =
      std::make_shared<FakeOwners>([&](const RoomKey& key) { return answers.at(key.id); });
  GeneratorConfig config = cpu_config();
  config.owners = owners;
  Metrics metrics;
  std::unique_ptr<Generator> replica = make_generator(config, metrics);
  ASSERT_TRUE(replica);
  Inbox inbox;
  ClientId c = replica->add_client(inbox.fn());
  std::vector<Want> w = wants_of(ids, 0, 2000);  // due in 2 s: asked of the owner
  replica->request(c, w);
  ASSERT_TRUE(inbox.wait_for(ids.size()));
  EXPECT_EQ(owners->asked().size(), ids.size());
  EXPECT_EQ(metrics.rooms_fetched.value(), 1u);
  EXPECT_EQ(metrics.owner_failures.value(), ids.size() - 1);
  EXPECT_EQ(metrics.rooms_built.value(), ids.size() - 1);
  for (const Delivery& d : inbox.got()) {
    ASSERT_TRUE(d.room) << d.error->message;
    EXPECT_EQ(d.room->frame, frames.at(d.key.id)) << d.key.id.to_string();
  }
  // The owner's room is cached like a built one.
  Inbox again;
  ClientId c2 = replica->add_client(again.fn());
  std::vector<Want> first = wants_of({ids[0]});
  replica->request(c2, first);
  ASSERT_EQ(again.size(), 1u);
  EXPECT_TRUE(again.got()[0].from_cache);
  replica.reset();  // waits for the fetches' answers
}
}  // namespace
}  // namespace grotto::server
