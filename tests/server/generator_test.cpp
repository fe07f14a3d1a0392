// The generation service (server/generator.hpp): rooms reach clients as frames that decode to the
// mesh built in-process; single flight, cancellation, client removal, fairness, priorities, the
// encoded-room cache and its byte bound, not_found, deadlines, shutdown and determinism. Real
// OpenCL (PoCL, or whatever $GROTTO_OPENCL_DEVICE picks) and the CPU path (device "none"), real
// codec. Waits are condition variables with generous timeouts; nothing asserts a duration.
//
// Many tests stall the single worker inside a deliver callback (a Gate), so that what they
// queue next is known not to have started: scheduling is then deterministic.
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
  // on_deliver runs inside the callback, on the delivering thread, before the delivery counts.
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

// Holds the thread that enters it until opened; tells the test when a thread is inside.
class Gate {
 public:
  void pass() {
    std::unique_lock lock(mutex_);
    ++inside_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
  }
  bool wait_entered() {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, kWait, [&] { return inside_ > 0; });
  }
  void open() {
    std::lock_guard lock(mutex_);
    open_ = true;
    cv_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  int inside_ = 0;
  bool open_ = false;
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

// A generator whose only worker is held inside a deliver callback: work queued while it is
// held has not started. open() releases it.
struct Stalled {
  Gate gate;  // declared first: outlives the generator whose worker may be inside it
  Metrics metrics;
  std::unique_ptr<Generator> gen;
  ClientId staller = 0;

  explicit Stalled(GeneratorConfig config) {
    gen = make_generator(config, metrics);
    staller = gen->add_client([this](Delivery) { gate.pass(); });
    std::vector<Want> one = wants_of({existing_rooms(1)});
    gen->request(staller, one);
    EXPECT_TRUE(gate.wait_entered());
  }
  ~Stalled() { gate.open(); }
};

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
  // A client of each protocol version: the newest (no normals in the payload) and version 1.
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

    // The same room built here, with a builder of the same options, encoded the same way.
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
  // A shared device launches each batch (one worker: nothing to merge), and says so.
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

// ---- scheduling ----

TEST(GeneratorTest, single_flight_builds_a_room_once_for_every_client) {
  Stalled s(cpu_config());
  cave::RoomId id = existing_rooms(2)[1];
  constexpr int kClients = 6;
  std::vector<std::unique_ptr<Inbox>> inboxes;
  for (int i = 0; i < kClients; ++i) {
    inboxes.push_back(std::make_unique<Inbox>());
    ClientId c = s.gen->add_client(inboxes.back()->fn());
    std::vector<Want> want = {{id, 0, static_cast<uint32_t>(i)}};
    s.gen->request(c, want);
  }
  EXPECT_EQ(s.gen->queue_depth(), 1u);
  EXPECT_EQ(s.metrics.rooms_deduplicated.value(), kClients - 1u);
  uint64_t built = s.metrics.rooms_built.value();
  s.gate.open();
  for (auto& inbox : inboxes) {
    ASSERT_TRUE(inbox->wait_for(1));
    Delivery d = inbox->got()[0];
    ASSERT_TRUE(d.room);
    EXPECT_EQ(d.key.id, id);
  }
  EXPECT_EQ(s.metrics.rooms_built.value(), built + 1);
  // Every client got the very same encoded room.
  for (auto& inbox : inboxes)
    EXPECT_EQ(inbox->got()[0].room, inboxes[0]->got()[0].room);
}

TEST(GeneratorTest, cancelled_before_start_is_never_built_nor_delivered) {
  Stalled s(cpu_config());
  std::vector<cave::RoomId> ids = existing_rooms(6);
  Inbox keep, drop;
  ClientId a = s.gen->add_client(keep.fn());
  ClientId b = s.gen->add_client(drop.fn());
  std::vector<Want> keep_wants = wants_of({ids[1], ids[2]});
  std::vector<Want> drop_wants = wants_of({ids[3], ids[4], ids[2]});
  s.gen->request(a, keep_wants);
  s.gen->request(b, drop_wants);
  EXPECT_EQ(s.gen->queue_depth(), 4u);
  std::vector<cave::RoomId> cancel = {ids[3], ids[4], ids[2], ids[5] /* never wanted */};
  s.gen->cancel(b, cancel);
  EXPECT_EQ(s.gen->queue_depth(), 2u);  // ids[2] stays: a still wants it
  EXPECT_EQ(s.metrics.rooms_cancelled.value(), 3u);
  uint64_t built = s.metrics.rooms_built.value();
  s.gate.open();
  ASSERT_TRUE(keep.wait_for(2));
  // Once a's rooms are out the queue is empty; b's would have been built in the same batches.
  EXPECT_EQ(s.gen->queue_depth(), 0u);
  EXPECT_EQ(s.metrics.rooms_built.value(), built + 2);
  EXPECT_EQ(drop.size(), 0u);
  s.gen->shutdown();
  EXPECT_EQ(drop.size(), 0u);
  EXPECT_EQ(s.metrics.rooms_built.value(), built + 2);
}

TEST(GeneratorTest, remove_client_drops_its_work_and_delivers_nothing_more) {
  Stalled s(cpu_config());
  std::vector<cave::RoomId> ids = existing_rooms(8);
  Inbox gone, stays;
  ClientId a = s.gen->add_client(gone.fn());
  ClientId b = s.gen->add_client(stays.fn());
  std::vector<Want> a_wants = wants_of({ids[1], ids[2], ids[3], ids[4]});
  std::vector<Want> b_wants = wants_of({ids[4], ids[5]});
  s.gen->request(a, a_wants);
  s.gen->request(b, b_wants);
  EXPECT_EQ(s.gen->queue_depth(), 5u);
  s.gen->remove_client(a);
  EXPECT_EQ(s.gen->queue_depth(), 2u);
  EXPECT_EQ(s.metrics.rooms_in_flight.value(), 2);  // b's two (the staller's is answered)
  uint64_t built = s.metrics.rooms_built.value();
  // Requests for a removed client are ignored.
  s.gen->request(a, a_wants);
  EXPECT_EQ(s.gen->queue_depth(), 2u);
  s.gate.open();
  ASSERT_TRUE(stays.wait_for(2));
  EXPECT_EQ(s.metrics.rooms_built.value(), built + 2);
  EXPECT_EQ(gone.size(), 0u);
}

TEST(GeneratorTest, a_client_asking_few_rooms_is_not_starved_by_one_asking_many) {
  GeneratorConfig config = cpu_config();
  config.max_batch_rooms = 8;
  Stalled s(config);
  std::vector<cave::RoomId> ids = existing_rooms(502);
  // One worker delivers in order, so A's count read inside B's (or C's) callback is exactly
  // how many of A's rooms reached A first.
  Inbox many, few, later;
  std::atomic<size_t> a_at_b{0}, a_at_c{0};
  ClientId a = s.gen->add_client(many.fn());
  ClientId b = s.gen->add_client(few.fn([&] { a_at_b = many.size(); }));
  ClientId c = s.gen->add_client(later.fn([&] { a_at_c = many.size(); }));
  std::vector<cave::RoomId> a_ids(ids.begin(), ids.begin() + 500);
  s.gen->request(a, wants_of(a_ids));
  std::vector<Want> b_want = wants_of({ids[500]});
  s.gen->request(b, b_want);
  s.gate.open();
  // Round-robin: B's one room is in the first batch after A's 500 were queued.
  ASSERT_TRUE(few.wait_for(1));
  ASSERT_TRUE(few.got()[0].room);
  EXPECT_LT(a_at_b.load(), 8u);
  // A client arriving while A's batches are building waits for the batch building when it
  // asked and for the rest of its own batch: 8 + 7 of A's rooms with one worker (plus one
  // batch of slack: A's count is read just before C asks, and a batch may finish in between).
  size_t a_at_request = many.size();
  std::vector<Want> c_want = wants_of({ids[501]});
  s.gen->request(c, c_want);
  ASSERT_TRUE(later.wait_for(1));
  ASSERT_TRUE(later.got()[0].room);
  EXPECT_LE(a_at_c.load() - a_at_request, 15u + 8u);
  EXPECT_LT(a_at_c.load(), 50u);
  s.gen->remove_client(a);
  EXPECT_EQ(s.gen->queue_depth(), 0u);
}

// The order in which clients' rooms are delivered, one letter a client, and a serial generator
// (one worker, one room a batch, no batch wait) stalled at the gate, for the deadline tests.
struct DeliveryOrder {
  std::mutex m;
  std::string order;
  Generator::DeliverFn record(char who) {
    return [this, who](Delivery) {
      std::lock_guard lock(m);
      order += who;
    };
  }
  // The letters once n rooms came (or what came within the bound).
  std::string wait_for(size_t n) {
    for (int i = 0; i < 500; ++i) {
      {
        std::lock_guard lock(m);
        if (order.size() >= n) return order;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::lock_guard lock(m);
    return order;
  }
};

GeneratorConfig serial_config(int urgent_ms) {
  GeneratorConfig config = cpu_config();
  config.max_batch_rooms = 1;
  config.max_batch_wait = std::chrono::milliseconds(0);
  config.urgent_within = std::chrono::milliseconds(urgent_ms);
  return config;
}

// Deadline classes: B's two rooms are due now, A's six are far prefetch. Round-robin alone would
// build A, B, A, B...; with urgent_within, both of B's go first. Without it (0), one of A's far
// rooms comes between them.
TEST(GeneratorTest, rooms_due_soon_go_before_other_clients_far_prefetch) {
  for (int urgent_ms : {1000, 0}) {
    SCOPED_TRACE("urgent_within " + std::to_string(urgent_ms));
    Stalled s(serial_config(urgent_ms));
    std::vector<cave::RoomId> ids = existing_rooms(9);
    DeliveryOrder d;
    ClientId a = s.gen->add_client(d.record('A'));
    ClientId b = s.gen->add_client(d.record('B'));
    std::vector<Want> far;
    for (size_t i = 1; i <= 6; ++i)
      far.push_back({ids[i], 0, 60'000});
    s.gen->request(a, far);
    std::vector<Want> soon = {{ids[7], 0, 0}, {ids[8], 0, 200}};
    s.gen->request(b, soon);
    s.gate.open();
    const std::string order = d.wait_for(8);
    ASSERT_EQ(order.size(), 8u) << order;
    if (urgent_ms > 0) {
      EXPECT_EQ(order.substr(0, 2), "BB") << order;
    } else {
      EXPECT_NE(order.substr(0, 2), "BB") << order << " (round-robin alone)";
    }
  }
}

// Among urgent wants, the one due soonest goes first whichever client asked (one job a client a
// round): B's room is due now (a stream's first room), C's in 300 ms, A's in 600 and 800 ms.
// Round-robin from the first client would build A, B, C, A.
TEST(GeneratorTest, the_urgent_room_due_soonest_goes_first_across_clients) {
  for (int urgent_ms : {1000, 0}) {
    SCOPED_TRACE("urgent_within " + std::to_string(urgent_ms));
    Stalled s(serial_config(urgent_ms));
    std::vector<cave::RoomId> ids = existing_rooms(5);
    DeliveryOrder d;
    ClientId a = s.gen->add_client(d.record('A'));
    ClientId b = s.gen->add_client(d.record('B'));
    ClientId c = s.gen->add_client(d.record('C'));
    std::vector<Want> a_wants = {{ids[1], 0, 800}, {ids[2], 0, 600}};
    std::vector<Want> b_wants = {{ids[3], 0, 0}};
    std::vector<Want> c_wants = {{ids[4], 0, 300}};
    s.gen->request(a, a_wants);
    s.gen->request(b, b_wants);
    s.gen->request(c, c_wants);
    s.gate.open();
    const std::string order = d.wait_for(4);
    ASSERT_EQ(order.size(), 4u) << order;
    EXPECT_EQ(order == "BCAA", urgent_ms > 0) << order;
  }
}

// A batch holding an urgent room is not topped up with prefetch, and each room of a batch goes
// out as soon as it is encoded: when B's urgent room is delivered only it has been built since
// the gate, and A's ten far rooms follow in a batch of their own. With one class (0) the batch
// takes them all.
TEST(GeneratorTest, an_urgent_room_does_not_wait_for_a_batch_of_prefetch) {
  for (int urgent_ms : {1000, 0}) {
    SCOPED_TRACE("urgent_within " + std::to_string(urgent_ms));
    GeneratorConfig config = cpu_config();
    config.max_batch_rooms = 32;
    config.max_batch_wait = std::chrono::milliseconds(0);
    config.urgent_within = std::chrono::milliseconds(urgent_ms);
    Stalled s(config);
    const uint64_t built_before = s.metrics.rooms_built.value();
    const uint64_t batches_before = s.metrics.batches.value();
    std::vector<cave::RoomId> ids = existing_rooms(12);
    std::atomic<uint64_t> built_at_b{0};
    Inbox far_inbox;
    Inbox near_inbox;
    ClientId a = s.gen->add_client(far_inbox.fn());
    ClientId b = s.gen->add_client(
        near_inbox.fn([&] { built_at_b = s.metrics.rooms_built.value() - built_before; }));
    std::vector<Want> far;
    for (size_t i = 1; i <= 10; ++i)
      far.push_back({ids[i], 0, 60'000});
    s.gen->request(a, far);
    std::vector<Want> near = {{ids[11], 0, 0}};
    s.gen->request(b, near);
    s.gate.open();
    ASSERT_TRUE(near_inbox.wait_for(1));
    ASSERT_TRUE(far_inbox.wait_for(10));
    const uint64_t batches = s.metrics.batches.value() - batches_before;
    if (urgent_ms > 0) {
      EXPECT_EQ(built_at_b.load(), 1u);
      EXPECT_EQ(batches, 2u);
    } else {
      EXPECT_EQ(batches, 1u) << "one class: the batch takes every queued room";
    }
  }
}

// A few wants asked while every worker waits are shared among them, each worker a batch of its
// own (on its own core), instead of one batch on one worker while the others stay idle: 8 urgent
// rooms and two idle workers make at least two batches (the first worker takes 4; the second
// takes the rest unless the first comes back for some first). One worker takes them all at once.
TEST(GeneratorTest, a_few_wants_are_shared_among_idle_workers) {
  for (int workers : {2, 1}) {
    SCOPED_TRACE(std::to_string(workers) + " workers");
    GeneratorConfig config = cpu_config(workers);
    config.max_batch_rooms = 32;
    Metrics metrics;
    auto gen = make_generator(config, metrics);
    ASSERT_TRUE(gen);
    Inbox inbox;
    ClientId c = gen->add_client(inbox.fn());
    std::vector<Want> wants = wants_of(existing_rooms(8));
    gen->request(c, wants);
    ASSERT_TRUE(inbox.wait_for(8));
    if (workers == 2) {
      EXPECT_GE(metrics.batches.value(), 2u);
    } else {
      EXPECT_EQ(metrics.batches.value(), 1u);
    }
    gen->remove_client(c);
  }
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

TEST(GeneratorTest, priorities_are_honoured_within_a_client) {
  GeneratorConfig config = cpu_config();
  config.max_batch_rooms = 1;
  Stalled s(config);
  std::vector<cave::RoomId> ids = existing_rooms(7);
  Inbox inbox;
  ClientId c = s.gen->add_client(inbox.fn());
  std::vector<Want> wants = {{ids[1], 0, 50}, {ids[2], 0, 30}, {ids[3], 0, 90},
                             {ids[4], 0, 10}, {ids[5], 0, 30}, {ids[6], 0, 70}};
  s.gen->request(c, wants);
  // A repeated want changes the priority: ids[3] now comes first.
  std::vector<Want> again = {{ids[3], 0, 0}};
  s.gen->request(c, again);
  s.gate.open();
  ASSERT_TRUE(inbox.wait_for(6));
  std::vector<cave::RoomId> order;
  for (const Delivery& d : inbox.got())
    order.push_back(d.key.id);
  std::vector<cave::RoomId> expected = {ids[3], ids[4], ids[2], ids[5], ids[1], ids[6]};
  EXPECT_EQ(order, expected);
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
      // What this client still waits for. A delivery for a room it cancelled (collected just
      // before the cancel) may still come: it is counted apart, never an error.
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

// ---- cache ----

TEST(GeneratorTest, second_request_is_served_from_cache_inside_request) {
  Metrics metrics;
  auto gen = make_generator(cpu_config(), metrics);
  cave::RoomId id = existing_rooms(1)[0];
  Inbox first, second;
  ClientId a = gen->add_client(first.fn());
  ClientId b = gen->add_client(second.fn());
  std::vector<Want> want = {{id, 0, 0}};
  gen->request(a, want);
  ASSERT_TRUE(first.wait_for(1));
  ASSERT_TRUE(first.got()[0].room);
  EXPECT_FALSE(first.got()[0].from_cache);
  EXPECT_EQ(metrics.rooms_built.value(), 1u);
  gen->request(b, want);
  ASSERT_EQ(second.size(), 1u);  // delivered before request() returned
  EXPECT_TRUE(second.got()[0].from_cache);
  EXPECT_EQ(second.got()[0].room, first.got()[0].room);
  EXPECT_EQ(metrics.rooms_built.value(), 1u);
  EXPECT_EQ(metrics.rooms_from_cache.value(), 1u);
  EXPECT_EQ(metrics.cache_entries.value(), 1);
  EXPECT_EQ(metrics.cache_bytes.value(), static_cast<int64_t>(first.got()[0].room->frame.size()));
  // Another lod is another room.
  std::vector<Want> detail = {{id, 1, 0}};
  gen->request(b, detail);
  ASSERT_TRUE(second.wait_for(2));
  EXPECT_FALSE(second.got()[1].from_cache);
  EXPECT_EQ(second.got()[1].key.lod, 1);
  EXPECT_EQ(metrics.rooms_built.value(), 2u);
}

TEST(GeneratorTest, cache_keeps_within_its_byte_bound_evicting_least_recent) {
  GeneratorConfig config = cpu_config();
  config.cache_bytes = 12'000;  // a few patch frames
  Metrics metrics;
  auto gen = make_generator(config, metrics);
  std::vector<cave::RoomId> ids = existing_rooms(10);
  Inbox inbox;
  ClientId c = gen->add_client(inbox.fn());
  for (size_t i = 0; i < ids.size(); ++i) {
    std::vector<Want> one = wants_of({ids[i]});
    gen->request(c, one);
    ASSERT_TRUE(inbox.wait_for(i + 1));
    EXPECT_LE(metrics.cache_bytes.value(), 12'000);
  }
  EXPECT_GT(metrics.cache_entries.value(), 0);
  EXPECT_LT(metrics.cache_entries.value(), 10);
  uint64_t built = metrics.rooms_built.value();
  std::vector<Want> last = wants_of({ids.back()});
  gen->request(c, last);
  ASSERT_EQ(inbox.size(), ids.size() + 1);
  EXPECT_TRUE(inbox.got().back().from_cache);
  std::vector<Want> first = wants_of({ids.front()});
  gen->request(c, first);
  ASSERT_TRUE(inbox.wait_for(ids.size() + 2));
  EXPECT_FALSE(inbox.got().back().from_cache);
  EXPECT_EQ(metrics.rooms_built.value(), built + 1);
}

TEST(GeneratorTest, cache_disabled_builds_every_time) {
  GeneratorConfig config = cpu_config();
  config.cache_bytes = 0;
  Metrics metrics;
  auto gen = make_generator(config, metrics);
  Inbox inbox;
  ClientId c = gen->add_client(inbox.fn());
  std::vector<Want> one = wants_of(existing_rooms(1));
  gen->request(c, one);
  ASSERT_TRUE(inbox.wait_for(1));
  gen->request(c, one);
  ASSERT_TRUE(inbox.wait_for(2));
  EXPECT_EQ(metrics.rooms_built.value(), 2u);
  EXPECT_EQ(metrics.cache_entries.value(), 0);
}

TEST(RoomCacheTest, lru_bound_in_bytes) {
  auto room = [](int i, size_t bytes) {
    auto r = std::make_shared<EncodedRoom>();
    r->key = {cave::RoomId::interior({0, 0, 0}, i), 0};
    r->frame.assign(bytes, 0);
    return RoomPtr(r);
  };
  RoomCache cache(1000);
  cache.insert(room(0, 400));
  cache.insert(room(1, 400));
  EXPECT_TRUE(cache.find(room(0, 0)->key));  // 0 becomes the most recent
  cache.insert(room(2, 400));                // evicts 1
  EXPECT_EQ(cache.bytes(), 800u);
  EXPECT_FALSE(cache.find(room(1, 0)->key));
  EXPECT_TRUE(cache.find(room(0, 0)->key));
  cache.insert(room(3, 1001));  // larger than the bound: not kept, nothing evicted
  EXPECT_EQ(cache.entries(), 2u);
  cache.insert(room(2, 100));  // replaces
  EXPECT_EQ(cache.bytes(), 500u);
  RoomCache off(0);
  off.insert(room(0, 1));
  EXPECT_EQ(off.entries(), 0u);
}

// ---- errors ----

TEST(GeneratorTest, missing_room_is_not_found_and_bad_lod_invalid) {
  Metrics metrics;
  auto gen = make_generator(cpu_config(), metrics);
  Inbox inbox;
  ClientId c = gen->add_client(inbox.fn());
  std::vector<Want> wants = {{cave::RoomId::interior({0, 0, 0}, 4000), 0, 0},
                             {cave::RoomId::gate({0, 0, 0}, 1, 15), 0, 0},
                             {existing_rooms(1)[0], proto::kMaxWireLod + 1, 0}};
  gen->request(c, wants);
  ASSERT_TRUE(inbox.wait_for(3));
  std::map<cave::RoomId, ErrorCode> codes;
  for (const Delivery& d : inbox.got()) {
    ASSERT_TRUE(d.error);
    EXPECT_FALSE(d.room);
    codes[d.key.id] = d.error->code;
  }
  EXPECT_EQ(codes[wants[0].id], ErrorCode::kNotFound);
  EXPECT_EQ(codes[wants[1].id], ErrorCode::kNotFound);
  EXPECT_EQ(codes[wants[2].id], ErrorCode::kInvalidArgument);
  EXPECT_EQ(metrics.rooms_built.value(), 0u);
  EXPECT_EQ(metrics.rooms_failed.value(), 2u);
  EXPECT_EQ(metrics.rooms_in_flight.value(), 0);
}

TEST(GeneratorTest, jobs_queued_past_the_deadline_fail_overloaded) {
  GeneratorConfig config = cpu_config();
  config.job_deadline = 1ms;
  config.max_batch_rooms = 2;
  Stalled s(config);
  std::vector<cave::RoomId> ids = existing_rooms(11);
  Inbox inbox;
  ClientId c = s.gen->add_client(inbox.fn());
  std::vector<cave::RoomId> queued(ids.begin() + 1, ids.end());
  s.gen->request(c, wants_of(queued));
  // Let the deadline pass while the worker is held (a guaranteed wait, not a hope).
  std::this_thread::sleep_for(20ms);
  s.gate.open();
  ASSERT_TRUE(inbox.wait_for(queued.size()));
  size_t overloaded = 0;
  for (const Delivery& d : inbox.got()) {
    if (d.error) {
      EXPECT_EQ(d.error->code, ErrorCode::kOverloaded);
      ++overloaded;
    }
  }
  EXPECT_EQ(overloaded, queued.size());  // every one waited past 1 ms before any could start
  EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0);
}

TEST(GeneratorTest, shutdown_fails_queued_work_with_service_restart_and_returns) {
  auto s = std::make_unique<Stalled>(cpu_config());
  std::vector<cave::RoomId> ids = existing_rooms(21);
  Inbox inbox;
  ClientId c = s->gen->add_client(inbox.fn());
  std::vector<cave::RoomId> queued(ids.begin() + 1, ids.end());
  s->gen->request(c, wants_of(queued));
  auto start = std::chrono::steady_clock::now();
  s->gen->shutdown(200ms);  // the worker is held: shutdown stops waiting after 200 ms
  EXPECT_LT(std::chrono::steady_clock::now() - start, 30s);
  ASSERT_EQ(inbox.size(), queued.size());  // delivered inside shutdown()
  for (const Delivery& d : inbox.got()) {
    ASSERT_TRUE(d.error);
    EXPECT_EQ(d.error->code, ErrorCode::kServiceRestart);
  }
  s->gen->shutdown(10ms);  // idempotent
  std::vector<Want> late = wants_of({ids[0]});
  s->gen->request(c, late);
  ASSERT_EQ(inbox.size(), queued.size() + 1);
  EXPECT_EQ(inbox.got().back().error->code, ErrorCode::kServiceRestart);
  s->gate.open();
  s.reset();  // the destructor joins the released worker
}

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

// ---- layout side ----

TEST(SectorCacheTest, rooms_locate_and_spawn_match_the_layout_functions) {
  SectorCache cache(test_world(), 4);
  std::vector<cave::RoomId> ids = existing_rooms(40);
  cave::SectorLayout s0 = cave::generate_sector(test_world(), {0, 0, 0});
  for (const cave::Room& g : s0.gates)
    ids.push_back(g.id);
  ids.push_back(cave::RoomId::interior({0, 0, 0}, 4000));
  ids.push_back(cave::RoomId::gate({0, 0, 0}, 2, 15));
  for (cave::RoomId id : ids) {
    auto want = cave::room(test_world(), id);
    auto got = cache.room(id);
    ASSERT_EQ(want.ok(), got.ok()) << id.to_string();
    if (!want.ok()) {
      EXPECT_EQ(got.error().code, want.error().code);
      continue;
    }
    std::vector<unsigned char> a, b;
    cave::append_bytes(*want, a);
    cave::append_bytes(*got, b);
    EXPECT_EQ(a, b) << id.to_string();
  }
  EXPECT_LE(cache.size(), 4u);
  EXPECT_GT(cache.hits(), 0u);
  for (const cave::Room& r : s0.rooms) {
    EXPECT_EQ(cache.locate(r.sphere.centre), cave::locate(test_world(), r.sphere.centre));
  }
  cave::Spawn spawn = cache.spawn();
  EXPECT_EQ(spawn.room, cave::spawn_room(test_world()));
  EXPECT_EQ(cave::locate(test_world(), spawn.position), spawn.room);
}

// Two worlds in one store: the same sector coordinates of each world stay apart, each answer is
// its own world's, and one capacity bounds both together (least recently used goes first).
TEST(SectorCacheTest, worlds_sharing_a_store_keep_their_own_layouts_within_one_bound) {
  const cave::World other = cave::World::create(43, cave::LayoutParams{}).value();
  auto store = std::make_shared<SectorStore>(4);
  SectorCache a(test_world(), store);
  SectorCache b(other, store);
  for (int round = 0; round < 2; ++round) {
    for (int step = 0; step < 3; ++step) {
      int x = round == 0 ? step : 2 - step;  // back again: the last four are kept
      for (const auto& [cache, world] :
           {std::pair<SectorCache*, const cave::World*>{&a, &test_world()}, {&b, &other}}) {
        cave::SectorLayout want = cave::generate_sector(*world, {x, 0, 0});
        auto got = cache->sector({x, 0, 0});
        ASSERT_EQ(got->rooms.size(), want.rooms.size());
        std::vector<unsigned char> p, q;
        for (size_t i = 0; i < want.rooms.size(); ++i) {
          cave::append_bytes(want.rooms[i], p);
          cave::append_bytes(got->rooms[i], q);
        }
        EXPECT_EQ(p, q) << "world " << world->seed() << " sector " << x;
      }
    }
  }
  // Round 1: six misses, sectors 1 and 2 of both worlds kept. Round 2 (2, 1, 0): four hits, then
  // sector 0 of each world missed again.
  EXPECT_EQ(store->size(), 4u);
  EXPECT_EQ(store->hits(), 4u);
  EXPECT_EQ(store->misses(), 8u);
  EXPECT_NE(a.spawn().position, b.spawn().position);
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

// A generator with room for several worlds: its own (test_world, seed 42) and others opened for
// the clients that name them.
GeneratorConfig worlds_config(size_t max_worlds) {
  GeneratorConfig c = cpu_config(2);
  c.max_worlds = max_worlds;
  return c;
}

// Frames by room, from one client of world `seed` asking for `ids` on `gen`.
std::map<cave::RoomId, std::vector<uint8_t>> frames_from(Generator& gen, uint64_t seed,
                                                         const std::vector<cave::RoomId>& ids) {
  Inbox inbox;
  auto c = gen.add_client(seed, inbox.fn());
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
  if (!c.ok()) return {};
  gen.request(*c, wants_of(ids));
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

// The rooms of world 43 from a generator whose own world is 42, asked for at the same time as the
// same room ids of world 42 and in the other order, are those of a generator serving 43 alone:
// same bytes, never taken from the other world's cache or job.
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
  // The home world's rooms are still its own: the same as from a one-world generator.
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
  auto gen = make_generator(cpu_config(), metrics);
  auto refused = gen->add_client(43, [](Delivery) {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kWorldMismatch);
  EXPECT_NE(refused.error().message.find("serves seed 42, not 43"), std::string::npos)
      << refused.error().message;
  EXPECT_TRUE(gen->add_client(42, [](Delivery) {}).ok());
  EXPECT_EQ(gen->worlds_open(), 1u);
}

// max_worlds 3: the own world (never closed) and two others. With both others in use a fourth
// seed is refused (overloaded); once idle, the least recently used other world is closed for it.
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

// ---- rooms from their owner (issue 29) ----

// A want due in 2 s: asked of its owner (a want due now is built here at once).
constexpr uint32_t kPrefetch = 2000;

// A room tier without sockets: each fetch is answered on a thread of its own (never inside
// fetch(), as RoomSource promises) by `answer`.
class FakeOwners final : public RoomSource {
 public:
  explicit FakeOwners(std::function<Result<std::vector<uint8_t>>(const RoomKey&)> answer)
      : answer_(std::move(answer)) {}
  ~FakeOwners() override {
    for (std::thread& t : threads_)
      t.join();
  }
  void fetch(const RoomKey& key, uint32_t, std::chrono::milliseconds timeout, Done done) override {
    std::lock_guard lock(mutex_);
    asked_.push_back(key.id);
    timeouts_[key.id] = timeout;
    threads_.emplace_back([this, key, done = std::move(done)] {
      std::unique_lock hold(gate_mutex_);
      gate_cv_.wait(hold, [&] { return open_; });
      hold.unlock();
      done(answer_(key));
    });
  }
  std::vector<cave::RoomId> asked() {
    std::lock_guard lock(mutex_);
    return asked_;
  }
  std::map<cave::RoomId, std::chrono::milliseconds> timeouts() {
    std::lock_guard lock(mutex_);
    return timeouts_;
  }
  void hold() { open_ = false; }
  void open() {
    std::lock_guard lock(gate_mutex_);
    open_ = true;
    gate_cv_.notify_all();
  }

 private:
  std::function<Result<std::vector<uint8_t>>(const RoomKey&)> answer_;
  std::mutex mutex_;
  std::vector<cave::RoomId> asked_;
  std::map<cave::RoomId, std::chrono::milliseconds> timeouts_;
  std::vector<std::thread> threads_;
  std::mutex gate_mutex_;
  std::condition_variable gate_cv_;
  bool open_ = true;
};

// Owners that answer every fetch with an unavailable error saying `why`.
std::shared_ptr<FakeOwners> failing_owners(std::string why) {
  return std::make_shared<FakeOwners>([why](const RoomKey&) -> Result<std::vector<uint8_t>> {
    return Error{ErrorCode::kUnavailable, why};
  });
}

// A generator of the test world (CPU path, one worker) that asks `owners` first.
std::unique_ptr<Generator> replica_asking(std::shared_ptr<RoomSource> owners, Metrics& metrics,
                                          std::chrono::milliseconds owner_timeout = 1000ms) {
  GeneratorConfig config = cpu_config();
  config.owners = std::move(owners);
  config.owner_timeout = owner_timeout;
  return make_generator(config, metrics);
}

// The frame a generator of the test world builds for `id` (lod 0), through a Build::kHere client.
std::vector<uint8_t> frame_built_by(Generator& gen, cave::RoomId id) {
  Inbox inbox;
  auto client =
      gen.add_client(gen.world().seed(), inbox.fn(), proto::kProtocolVersion, Build::kHere);
  EXPECT_TRUE(client.ok());
  std::vector<Want> one = wants_of({id});
  gen.request(*client, one);
  EXPECT_TRUE(inbox.wait_for(1));
  gen.remove_client(*client);
  Delivery d = inbox.got().at(0);
  return d.room ? d.room->frame : std::vector<uint8_t>{};
}

TEST(GeneratorOwners, rooms_come_from_their_owner_once_and_are_not_built_here) {
  Metrics owner_metrics;
  std::unique_ptr<Generator> owner = make_generator(cpu_config(), owner_metrics);
  ASSERT_TRUE(owner);
  auto owners =
      std::make_shared<FakeOwners>([&](const RoomKey& key) -> Result<std::vector<uint8_t>> {
        return frame_built_by(*owner, key.id);
      });
  owners->hold();
  Metrics metrics;
  std::unique_ptr<Generator> replica = replica_asking(owners, metrics);
  ASSERT_TRUE(replica);
  const std::vector<cave::RoomId> ids = existing_rooms(4);
  Inbox a, b;
  ClientId ca = replica->add_client(a.fn()), cb = replica->add_client(b.fn());
  std::vector<Want> wa = wants_of(ids, 0, kPrefetch), wb = wants_of({ids[1], ids[2]}, 0, kPrefetch);
  replica->request(ca, wa);
  replica->request(cb, wb);  // joins the fetches in flight
  owners->open();
  ASSERT_TRUE(a.wait_for(ids.size()));
  ASSERT_TRUE(b.wait_for(2));
  EXPECT_EQ(owners->asked().size(), ids.size()) << "one fetch per room, whoever wants it";
  EXPECT_EQ(metrics.rooms_fetched.value(), ids.size());
  EXPECT_EQ(metrics.rooms_built.value(), 0u);
  EXPECT_EQ(metrics.owner_failures.value(), 0u);
  for (const Delivery& d : a.got()) {
    ASSERT_TRUE(d.room) << d.error->message;
    EXPECT_EQ(d.room->frame, frame_built_by(*owner, d.key.id));
  }
  // Fetched rooms are cached like built ones.
  Inbox c;
  ClientId cc = replica->add_client(c.fn());
  std::vector<Want> wc = wants_of({ids[0]});
  replica->request(cc, wc);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_TRUE(c.got()[0].from_cache);
}

TEST(GeneratorOwners, an_owner_that_fails_or_answers_wrong_bytes_is_built_here) {
  Metrics reference_metrics;
  std::unique_ptr<Generator> reference = make_generator(cpu_config(), reference_metrics);
  ASSERT_TRUE(reference);
  const std::vector<cave::RoomId> ids = existing_rooms(5);
  const cave::World other = cave::World::create(43, cave::LayoutParams{}).value();
  // Each room's owner goes wrong in its own way: unreachable, garbage, another room's frame,
  // the same room at another lod, and the same id in another world.
  std::map<cave::RoomId, std::function<Result<std::vector<uint8_t>>()>> answers = {
      {ids[0],
       [] {
         return Error{ErrorCode::kUnavailable, "connection refused"};
       }},
      {ids[1], [] { return std::vector<uint8_t>{'G', 'R', 'T', 'O', 1, 2, 3}; }},
      {ids[2], [&] { return frame_built_by(*reference, ids[3]); }},
      {ids[3],
       [&] {
         Inbox inbox;
         auto c = reference->add_client(test_world().seed(), inbox.fn(), proto::kProtocolVersion,
                                        Build::kHere);
         std::vector<Want> w = {{ids[3], 1, 0}};
         reference->request(*c, w);
         EXPECT_TRUE(inbox.wait_for(1));
         reference->remove_client(*c);
         return inbox.got()[0].room->frame;
       }},
      {ids[4],
       [&]() -> Result<std::vector<uint8_t>> {
         Metrics m;
         auto g = Generator::create(other, mesh::MeshParams{}, cpu_config(), m);
         if (!g) return g.error();
         // A room of the other world with the same id (sector 0,0,0 has enough rooms).
         return frame_built_by(**g, ids[4]);
       }},
  };
  auto owners =
      std::make_shared<FakeOwners>([&](const RoomKey& key) { return answers.at(key.id)(); });
  Metrics metrics;
  std::unique_ptr<Generator> replica = replica_asking(owners, metrics);
  ASSERT_TRUE(replica);
  Inbox inbox;
  ClientId c = replica->add_client(inbox.fn());
  std::vector<Want> w = wants_of(ids, 0, kPrefetch);
  replica->request(c, w);
  ASSERT_TRUE(inbox.wait_for(ids.size()));
  EXPECT_EQ(metrics.owner_failures.value(), ids.size());
  EXPECT_EQ(metrics.rooms_fetched.value(), 0u);
  EXPECT_EQ(metrics.rooms_built.value(), ids.size());
  for (const Delivery& d : inbox.got()) {
    ASSERT_TRUE(d.room) << d.error->message;
    EXPECT_EQ(d.room->frame, frame_built_by(*reference, d.key.id)) << d.key.id.to_string();
  }
}

TEST(GeneratorOwners, build_here_clients_never_ask_the_owner_and_cancelled_fetches_build_nothing) {
  auto owners = failing_owners("down");
  owners->hold();
  Metrics metrics;
  std::unique_ptr<Generator> replica = replica_asking(owners, metrics);
  ASSERT_TRUE(replica);
  const std::vector<cave::RoomId> ids = existing_rooms(3);
  Inbox here;
  auto h =
      replica->add_client(test_world().seed(), here.fn(), proto::kProtocolVersion, Build::kHere);
  ASSERT_TRUE(h.ok());
  std::vector<Want> one = wants_of({ids[0]});
  replica->request(*h, one);
  ASSERT_TRUE(here.wait_for(1));
  EXPECT_TRUE(here.got()[0].room);
  EXPECT_TRUE(owners->asked().empty());
  // A player's rooms are asked of the owner; cancelled while the owner is silent, then the owner
  // fails: nothing is built here and nothing delivered.
  Inbox player;
  ClientId p = replica->add_client(player.fn());
  std::vector<Want> two = wants_of({ids[1], ids[2]}, 0, kPrefetch);
  replica->request(p, two);
  EXPECT_EQ(owners->asked().size(), 2u);
  replica->cancel(p, std::vector<cave::RoomId>{ids[1], ids[2]});
  const uint64_t built = metrics.rooms_built.value();
  owners->open();
  replica.reset();  // waits for the fetches' answers
  EXPECT_EQ(metrics.owner_failures.value(), 2u);
  EXPECT_EQ(metrics.rooms_built.value(), built);
  EXPECT_EQ(player.size(), 0u);
}

TEST(GeneratorOwners, the_owners_own_request_for_a_room_it_is_fetching_builds_it_here_at_once) {
  // The tier hashes a room to its owner; when that is the replica asking, its fetch comes back
  // to it as a Build::kHere request. Waiting for the fetch would wait for itself.
  auto owners = failing_owners("the answer comes after the room was built");
  owners->hold();
  Metrics metrics;
  std::unique_ptr<Generator> replica = replica_asking(owners, metrics);
  ASSERT_TRUE(replica);
  const cave::RoomId id = existing_rooms(1)[0];
  Inbox player, tier;
  ClientId p = replica->add_client(player.fn());
  std::vector<Want> one = wants_of({id}, 0, kPrefetch);
  replica->request(p, one);
  auto t = replica->add_client(replica->world().seed(), tier.fn(), proto::kProtocolVersion,
                               Build::kHere);
  ASSERT_TRUE(t.ok());
  replica->request(*t, one);
  ASSERT_TRUE(player.wait_for(1));  // the owner's gate is still closed
  ASSERT_TRUE(tier.wait_for(1));
  EXPECT_TRUE(player.got()[0].room);
  EXPECT_EQ(player.got()[0].room, tier.got()[0].room);
  EXPECT_EQ(metrics.rooms_built.value(), 1u);
  owners->open();
  replica.reset();
  EXPECT_EQ(metrics.owner_failures.value(), 0u) << "a fetch answered after the room was built";
}

TEST(GeneratorOwners,
     a_room_due_now_is_built_here_one_due_soon_waits_briefly_far_prefetch_longest) {
  auto owners = failing_owners("down");
  Metrics metrics;
  std::unique_ptr<Generator> replica = replica_asking(owners, metrics);
  ASSERT_TRUE(replica);
  const std::vector<cave::RoomId> ids = existing_rooms(4);
  Inbox inbox;
  ClientId c = replica->add_client(inbox.fn());
  std::vector<Want> w = {{ids[0], 0, 100}, {ids[1], 0, 1100}, {ids[2], 0, 5000}, {ids[3], 0, 0}};
  replica->request(c, w);
  ASSERT_TRUE(inbox.wait_for(4));
  auto t = owners->timeouts();
  EXPECT_EQ(t.at(ids[0]), 150ms) << "due in 100 ms: built here after a short wait";
  EXPECT_FALSE(t.count(ids[3])) << "due now (the player waits): built here, not asked";
  EXPECT_EQ(t.at(ids[1]), 600ms) << "its slack: 1,100 ms less 500 to build it here";
  EXPECT_EQ(t.at(ids[2]), 1000ms) << "far prefetch: the whole owner_timeout";
}
}  // namespace
}  // namespace grotto::server
