// The generator's policy without threads (server/schedule.hpp): each row feeds a schedule some
// events (`given`), then more (`when`), and checks the actions and batches those returned, as
// lines of text, and what the metrics and the ledger say after. The clock is simulated (`later`),
// workers are steps (`work`: a free worker takes a batch, builds each room, reports it), and
// owners answer when a row says so. tests/server/generator_test.cpp checks the shell: real
// threads, builds, frames and owner fetches.
#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "server/metrics.hpp"
#include "server/schedule.hpp"

namespace grotto::server {
namespace {

using namespace std::chrono_literals;

constexpr uint64_t kSeed = 42;
constexpr uint32_t kFar = 60'000;  // far prefetch: due in a minute

cave::RoomId r(int i) {
  return cave::RoomId::interior({0, 0, 0}, i);
}

// "r3", with "@1" for another lod and "/43" for another world than kSeed's.
std::string name(const RoomKey& key) {
  std::string s = key.id.to_string().substr(6);  // "0.0.0.r3"
  if (key.lod != 0) s += "@" + std::to_string(key.lod);
  if (key.seed != kSeed) s += "/" + std::to_string(key.seed);
  return s;
}

std::string describe(const sched::Action& action) {
  struct Visitor {
    std::string operator()(const sched::Deliver& a) {
      const Delivery& d = a.delivery;
      std::string s = "c" + std::to_string(a.client) + " " + name(d.key);
      if (d.error) return s + " " + error_code_name(d.error->code);
      return s + (d.from_cache ? " cached" : "");
    }
    std::string operator()(const sched::Fetch& a) {
      return "fetch " + name(a.job.key) + " wait=" + std::to_string(a.wait.count());
    }
    std::string operator()(const sched::Wake&) { return "wake"; }
    std::string operator()(const sched::OpenWorld& a) { return "open " + std::to_string(a.seed); }
    std::string operator()(const sched::CloseWorld& a) { return "close " + std::to_string(a.seed); }
  };
  return std::visit(Visitor{}, action);
}

// The schedule, a simulated clock, what it said, and the jobs in flight outside it.
struct Sim {
  explicit Sim(ScheduleConfig config) : schedule(config, metrics) {}
  Metrics metrics;  // declared first: the schedule holds a reference
  Schedule schedule;
  ScheduleTime now{};
  std::vector<std::string> log;
  bool quiet = false;
  Batch batch;                   // the batch a worker holds (taken, not yet built)
  std::vector<JobRef> fetching;  // fetches not yet answered
  size_t frame_bytes = 100;      // each built room's frame

  void note(std::string line) {
    if (!quiet) log.push_back(std::move(line));
  }
  void drain() {
    for (const sched::Action& a : schedule.take()) {
      if (const auto* f = std::get_if<sched::Fetch>(&a)) fetching.push_back(f->job);
      note(describe(a));
    }
  }
  RoomPtr room(const RoomKey& key) const {
    auto built = std::make_shared<EncodedRoom>();
    built->key = key;
    built->frame.assign(frame_bytes, 0);
    return built;
  }
  void note_batch(const char* what) {
    std::string s = what;
    for (const JobRef& j : batch.jobs)
      s += " " + name(j.key);
    note(s + (batch.urgent ? " (urgent)" : ""));
  }
};

using Step = std::function<void(Sim&)>;

Step join(uint64_t seed = kSeed, Build build = Build::kAnywhere, uint32_t version = 2) {
  return [=](Sim& s) {
    Result<ClientId> c = s.schedule.join(seed, version, build);
    s.drain();
    s.note(c ? "joined c" + std::to_string(*c)
             : std::string("refused ") + error_code_name(c.error().code));
  };
}
Step leave(ClientId c) {
  return [=](Sim& s) {
    s.schedule.leave(c);
    s.drain();
  };
}
// Wants of client c: (room index, priority) pairs, at lod `lod`.
Step want(ClientId c, std::vector<std::pair<int, uint32_t>> rooms, uint32_t lod = 0) {
  return [=](Sim& s) {
    std::vector<Want> wants;
    for (auto [i, priority] : rooms)
      wants.push_back({r(i), lod, priority});
    s.schedule.request(c, wants, s.now);
    s.drain();
  };
}
// Rooms first..last, all of one priority.
Step want_range(ClientId c, int first, int last, uint32_t priority = 0) {
  std::vector<std::pair<int, uint32_t>> rooms;
  for (int i = first; i <= last; ++i)
    rooms.emplace_back(i, priority);
  return want(c, rooms);
}
Step cancel(ClientId c, std::vector<int> rooms) {
  return [=](Sim& s) {
    std::vector<cave::RoomId> ids;
    for (int i : rooms)
      ids.push_back(r(i));
    s.schedule.cancel(c, ids);
    s.drain();
  };
}
Step later(std::chrono::milliseconds ms) {
  return [=](Sim& s) { s.now += ms; };
}
Step expire() {
  return [](Sim& s) {
    s.schedule.expire(s.now);
    s.drain();
  };
}
// A worker with `idle` others waiting takes a batch (and holds it).
Step take(size_t idle = 0) {
  return [=](Sim& s) {
    s.batch = s.schedule.start_batch(s.now, idle);
    s.note_batch("batch");
  };
}
Step top_up() {
  return [](Sim& s) {
    s.schedule.top_up(s.batch, s.now);
    s.note_batch("topped up");
  };
}
// The held batch is about to build: jobs nobody waits for leave it.
Step seal() {
  return [](Sim& s) {
    s.schedule.seal(s.batch);
    s.note_batch("sealed");
  };
}
// The held (sealed) batch is built: each room reported, or failed with `error`, in order.
Step finish(std::optional<ErrorCode> error = std::nullopt) {
  return [=](Sim& s) {
    for (const JobRef& job : s.batch.jobs) {
      Result<RoomPtr> room = error ? Result<RoomPtr>(Error{*error, "failed"}) : s.room(job.key);
      s.schedule.built(job, std::move(room), s.now);
      s.drain();
    }
    s.batch = {};
  };
}
// The held batch is sealed and built.
Step build(std::optional<ErrorCode> error = std::nullopt) {
  return [=](Sim& s) {
    s.schedule.seal(s.batch);
    finish(error)(s);
  };
}
// A serial worker until nothing is queued.
Step serve() {
  return [](Sim& s) {
    while (s.schedule.queued_jobs() > 0) {
      take()(s);
      build()(s);
    }
  };
}
// The owner answers the fetch of room i: its room, or an error.
Step answer(int i, bool ok) {
  return [=](Sim& s) {
    auto it = std::find_if(s.fetching.begin(), s.fetching.end(),
                           [&](const JobRef& j) { return j.key.id == r(i); });
    ASSERT_NE(it, s.fetching.end()) << "no fetch of r" << i;
    const JobRef job = *it;
    s.fetching.erase(it);
    const bool wanted = s.schedule.fetch_wanted(job);
    Result<RoomPtr> room = ok && wanted ? Result<RoomPtr>(s.room(job.key))
                                        : Result<RoomPtr>(Error{ErrorCode::kUnavailable, "down"});
    s.schedule.fetched(job, std::move(room), wanted, s.now);
    s.drain();
  };
}
Step shutdown() {
  return [](Sim& s) {
    s.schedule.shutdown(s.now);
    s.drain();
  };
}
// Runs steps without noting what they say (setup inside `when`).
Step quietly(std::vector<Step> steps) {
  return [=](Sim& s) {
    s.quiet = true;
    for (const Step& step : steps)
      step(s);
    s.quiet = false;
  };
}

struct Row {
  std::string name;
  ScheduleConfig config;
  std::vector<Step> given;
  std::vector<Step> when;
  std::vector<std::string> then;
  std::function<void(const Sim&)> also = {};  // metrics and the ledger afterwards
};

ScheduleConfig config(std::function<void(ScheduleConfig&)> edit = {}) {
  ScheduleConfig c;
  c.own_seed = kSeed;
  if (edit) edit(c);
  return c;
}
ScheduleConfig serial(int urgent_ms) {
  return config([=](ScheduleConfig& c) {
    c.max_batch_rooms = 1;
    c.urgent_within = std::chrono::milliseconds(urgent_ms);
  });
}

void run(const std::vector<Row>& rows) {
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    Sim sim(row.config);
    for (const Step& step : row.given)
      step(sim);
    sim.log.clear();
    for (const Step& step : row.when)
      step(sim);
    EXPECT_EQ(sim.log, row.then) << row.name;
    if (row.also) row.also(sim);
  }
}

// Rooms first..last as expected lines: "c<client> r<i>" each (or one "batch" line).
std::vector<std::string> delivered(ClientId c, int first, int last) {
  std::vector<std::string> out;
  for (int i = first; i <= last; ++i)
    out.push_back("c" + std::to_string(c) + " r" + std::to_string(i));
  return out;
}
std::vector<std::string> operator+(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// ---- single flight, cancellation, clients leaving ----

TEST(ScheduleTest, single_flight_cancellation_and_leaving) {
  run({
      {"a room wanted by six clients is built once, for all of them",
       config(),
       {join(), join(), join(), join(), join(), join()},
       {want(1, {{1, 0}}), want(2, {{1, 1}}), want(3, {{1, 2}}), want(4, {{1, 3}}),
        want(5, {{1, 4}}), want(6, {{1, 5}}), serve()},
       {"wake", "batch r1 (urgent)", "c1 r1", "c2 r1", "c3 r1", "c4 r1", "c5 r1", "c6 r1"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_deduplicated.value(), 5u);
         EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0);
         EXPECT_EQ(s.schedule.jobs(), 0u);
       }},
      {"a want cancelled before its job starts is never built nor delivered; a job another "
       "client still wants stays",
       config(),
       {join(), join(), want(1, {{1, 0}, {2, 0}}), want(2, {{3, 0}, {4, 0}, {2, 0}})},
       {cancel(2, {3, 4, 2, 5 /* never wanted */}), serve()},
       {"batch r1 r2 (urgent)", "c1 r1", "c1 r2"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_cancelled.value(), 3u);
         EXPECT_EQ(s.metrics.queue_depth.value(), 0);
         EXPECT_EQ(s.schedule.jobs(), 0u);
       }},
      {"a client leaving drops its wants; jobs others want stay; its later wants are ignored",
       config(),
       {join(), join(), want(1, {{1, 0}, {2, 0}, {3, 0}, {4, 0}}), want(2, {{4, 0}, {5, 0}}),
        leave(1)},
       {want(1, {{1, 0}}), serve()},
       {"batch r4 r5 (urgent)", "c2 r4", "c2 r5"},
       [](const Sim& s) { EXPECT_EQ(s.metrics.rooms_cancelled.value(), 4u); }},
      {"a job everyone cancelled while its batch filled is not built (seal)",
       config([](ScheduleConfig& c) { c.urgent_within = 0ms; }),
       {join(), want(1, {{1, kFar}, {2, kFar}}), take()},
       {cancel(1, {1}), seal(), finish()},
       {"sealed r2", "c1 r2"},
       [](const Sim& s) {
         EXPECT_EQ(s.schedule.jobs(), 0u);
         EXPECT_EQ(s.schedule.cache().entries(), 1u);
       }},
      {"a job building when its last waiter leaves is built and cached, delivered to nobody; a "
       "client joining it meanwhile gets it",
       config(),
       {join(), join(), want(1, {{1, 0}, {2, 0}}), take(), seal()},
       {leave(1), want(2, {{2, 0}}), finish(), join(), want(3, {{1, 0}})},
       {"c2 r2", "joined c3", "c3 r1 cached"},
       [](const Sim& s) { EXPECT_EQ(s.metrics.rooms_deduplicated.value(), 1u); }},
      {"the same room of another lod, version or world is another job",
       config([](ScheduleConfig& c) { c.max_worlds = 2; }),
       {join(), join(kSeed, Build::kAnywhere, 1), join(43)},
       {want(1, {{1, 0}}), want(1, {{1, 0}}, 1), want(2, {{1, 0}}), want(3, {{1, 0}}), serve()},
       {"wake", "wake", "wake", "wake", "batch r1 r1 r1/43 (urgent)", "c1 r1", "c2 r1", "c3 r1/43",
        "batch r1@1 (urgent)", "c1 r1@1"},
       [](const Sim& s) { EXPECT_EQ(s.metrics.rooms_deduplicated.value(), 0u); }},
  });
}

// ---- order: priorities, deadline classes, round-robin ----

TEST(ScheduleTest, order_of_building) {
  run({
      {"within a client, smaller priority first, equals first come; a repeated want takes "
       "the new priority",
       serial(1000),
       {join(), want(1, {{1, 50}, {2, 30}, {3, 90}, {4, 10}, {5, 30}, {6, 70}}), want(1, {{3, 0}})},
       {quietly({later(2s)}), serve()},
       {"batch r3 (urgent)", "c1 r3", "batch r4 (urgent)", "c1 r4", "batch r2 (urgent)", "c1 r2",
        "batch r5 (urgent)", "c1 r5", "batch r1 (urgent)", "c1 r1", "batch r6 (urgent)", "c1 r6"}},
      {"rooms due soon go before another client's far prefetch",
       serial(1000),
       {join(), join(), want_range(1, 1, 6, kFar), want(2, {{7, 0}, {8, 200}})},
       {serve()},
       std::vector<std::string>{"batch r7 (urgent)", "c2 r7", "batch r8 (urgent)", "c2 r8"} +
           std::vector<std::string>{"batch r1", "c1 r1", "batch r2", "c1 r2", "batch r3", "c1 r3",
                                    "batch r4", "c1 r4", "batch r5", "c1 r5", "batch r6", "c1 r6"}},
      {"one class (urgent_within 0): plain round-robin, far prefetch between the near rooms",
       serial(0),
       {join(), join(), want_range(1, 1, 6, kFar), want(2, {{7, 0}, {8, 200}})},
       {serve()},
       {"batch r1", "c1 r1", "batch r7", "c2 r7", "batch r2", "c1 r2", "batch r8", "c2 r8",
        "batch r3", "c1 r3", "batch r4", "c1 r4", "batch r5", "c1 r5", "batch r6", "c1 r6"}},
      {"among urgent wants the one due soonest goes first, whichever client asked",
       serial(1000),
       {join(), join(), join(), want(1, {{1, 800}, {2, 600}}), want(2, {{3, 0}}),
        want(3, {{4, 300}})},
       {serve()},
       {"batch r3 (urgent)", "c2 r3", "batch r4 (urgent)", "c3 r4", "batch r2 (urgent)", "c1 r2",
        "batch r1 (urgent)", "c1 r1"}},
      {"one class: round-robin from the first client, its smallest priority each turn",
       serial(0),
       {join(), join(), join(), want(1, {{1, 800}, {2, 600}}), want(2, {{3, 0}}),
        want(3, {{4, 300}})},
       {serve()},
       {"batch r2", "c1 r2", "batch r3", "c2 r3", "batch r4", "c3 r4", "batch r1", "c1 r1"}},
      {"a batch holding an urgent room is not topped up with prefetch",
       config(),
       {join(), join(), want_range(1, 1, 10, kFar), want(2, {{11, 0}})},
       {serve()},
       std::vector<std::string>{"batch r11 (urgent)", "c2 r11",
                                "batch r1 r2 r3 r4 r5 r6 r7 r8 r9 r10"} +
           delivered(1, 1, 10)},
      {"one class: the batch takes every queued room, round-robin",
       config([](ScheduleConfig& c) { c.urgent_within = 0ms; }),
       {join(), join(), want_range(1, 1, 10, kFar), want(2, {{11, 0}})},
       {take()},
       {"batch r1 r11 r2 r3 r4 r5 r6 r7 r8 r9 r10"}},
      // C's room, due 5 ms after A's next, goes right after it: earliest deadline first, one
      // job a client a round.
      {"a client asking few rooms is not starved by one asking many",
       config([](ScheduleConfig& c) { c.max_batch_rooms = 8; }),
       {join(), join(), join(), want_range(1, 1, 500), want(2, {{501, 0}})},
       {take(), quietly({later(5ms), want(3, {{502, 0}}), build()}), take()},
       {"batch r1 r501 r2 r3 r4 r5 r6 r7 (urgent)",
        "batch r8 r502 r9 r10 r11 r12 r13 r14 (urgent)"}},
      {"a client arriving while the round-robin serves others gets the next turn",
       config([](ScheduleConfig& c) {
         c.max_batch_rooms = 4;
         c.urgent_within = 0ms;
       }),
       {join(), join(), join(), want_range(1, 1, 20, kFar), want_range(2, 21, 40, kFar), take()},
       {want(3, {{41, kFar}}), build(), take()},
       {"wake", "c1 r1", "c2 r21", "c1 r2", "c2 r22", "batch r41 r3 r23 r4"}},
      {"a batch is of one lod: the other lod's rooms wait for another batch",
       config([](ScheduleConfig& c) { c.urgent_within = 0ms; }),
       {join(), want(1, {{1, kFar}, {2, kFar}}, 1), want(1, {{3, 5}})},
       {take(), build(), take()},
       {"batch r3", "c1 r3", "batch r1@1 r2@1"}},
  });
}

// ---- batches: a worker's share, topping up ----

TEST(ScheduleTest, batches) {
  run({
      {"a few wants are shared among idle workers: 8 rooms, one other idle worker: 4 each",
       config(),
       {join(), want_range(1, 1, 8)},
       {take(1), quietly({build()}), take(0)},
       {"batch r1 r2 r3 r4 (urgent)", "batch r5 r6 r7 r8 (urgent)"}},
      {"one worker takes them all at once",
       config(),
       {join(), want_range(1, 1, 8)},
       {take(0)},
       {"batch r1 r2 r3 r4 r5 r6 r7 r8 (urgent)"}},
      {"a full queue: every worker takes max_batch_rooms",
       config([](ScheduleConfig& c) { c.max_batch_rooms = 3; }),
       {join(), want_range(1, 1, 20)},
       {take(3)},
       {"batch r1 r2 r3 (urgent)"}},
      {"a batch of prefetch waiting for more takes the wants of its lod that arrive",
       config([](ScheduleConfig& c) { c.max_batch_rooms = 4; }),
       {join(), join(), want(1, {{1, kFar}}), want(1, {{2, kFar}, {3, kFar}}, 1)},
       {take(), want(2, {{5, kFar}}, 1), want(2, {{4, kFar}}), top_up()},
       {"batch r1", "wake", "wake", "topped up r1 r4"}},
  });
}

// ---- the cache ----

TEST(ScheduleTest, cache) {
  run({
      {"a room built is served from the cache at once, to the next client that wants it",
       config(),
       {join(), join(), want(1, {{1, 0}}), serve()},
       {want(2, {{1, 0}}), want(2, {{1, 0}}, 1)},
       {"c2 r1 cached", "wake"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_from_cache.value(), 1u);
         EXPECT_EQ(s.metrics.cache_entries.value(), 1);
         EXPECT_EQ(s.metrics.cache_bytes.value(), 100);
       }},
      {"the cache keeps within its bytes, least recently used out first",
       config([](ScheduleConfig& c) { c.cache_bytes = 350; }),
       {join(), want(1, {{1, 0}}), serve(), want(1, {{2, 0}}), serve(), want(1, {{3, 0}}), serve(),
        want(1, {{1, 0}}), want(1, {{4, 0}}), serve()},
       {want(1, {{1, 0}}), want(1, {{4, 0}}), want(1, {{2, 0}})},
       {"c1 r1 cached", "c1 r4 cached", "wake"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.cache_bytes.value(), 300);
         EXPECT_EQ(s.schedule.cache().evictions(), 1u);
       }},
      {"a cache of 0 bytes keeps nothing: every want builds",
       config([](ScheduleConfig& c) { c.cache_bytes = 0; }),
       {join(), want(1, {{1, 0}}), serve()},
       {want(1, {{1, 0}})},
       {"wake"}},
      {"an owner's room is cached like a built one",
       config([](ScheduleConfig& c) { c.owners = true; }),
       {join(), join(), want(1, {{1, 2000}}), answer(1, true)},
       {want(2, {{1, 2000}})},
       {"c2 r1 cached"}},
  });
}

// ---- errors, deadlines, shutdown ----

TEST(ScheduleTest, errors_deadlines_and_shutdown) {
  run({
      {"a lod above kMaxServedLod is invalid_argument at once",
       config(),
       {join()},
       {want(1, {{1, 0}}, kMaxServedLod + 1)},
       {"c1 r1@" + std::to_string(kMaxServedLod + 1) + " invalid_argument"},
       [](const Sim& s) { EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0); }},
      {"a build's error goes to every waiter",
       config(),
       {join(), join(), want(1, {{1, 0}}), want(2, {{1, 0}}), take()},
       {build(ErrorCode::kNotFound)},
       {"c1 r1 not_found", "c2 r1 not_found"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_failed.value(), 1u);
         EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0);
         EXPECT_EQ(s.schedule.cache().entries(), 0u);
       }},
      {"jobs queued past the deadline fail overloaded, oldest first; younger ones wait",
       config([](ScheduleConfig& c) { c.job_deadline = 100ms; }),
       {join(), want(1, {{1, 0}, {2, 0}}), later(60ms), want(1, {{3, 0}})},
       {expire(), later(40ms), expire(), later(59ms), expire(), later(1ms), expire()},
       {"c1 r1 overloaded", "c1 r2 overloaded", "c1 r3 overloaded"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_failed.value(), 3u);
         EXPECT_EQ(s.metrics.queue_depth.value(), 0);
         EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0);
       }},
      {"a job taken by a worker has no deadline",
       config([](ScheduleConfig& c) { c.job_deadline = 100ms; }),
       {join(), want(1, {{1, 0}}), take()},
       {later(1s), expire(), build()},
       {"c1 r1"}},
      {"shutdown fails queued jobs with service_restart; building ones finish; later wants and "
       "other worlds are refused",
       config([](ScheduleConfig& c) { c.max_worlds = 2; }),
       {join(), want(1, {{1, 0}}), take(), want(1, {{2, 0}, {3, 0}})},
       {shutdown(), shutdown(), build(), want(1, {{4, 0}}), join(43), join()},
       {"c1 r2 service_restart", "c1 r3 service_restart", "wake", "c1 r1", "c1 r4 service_restart",
        "refused service_restart", "joined c2"},
       [](const Sim& s) {
         EXPECT_TRUE(s.schedule.stopping());
         EXPECT_EQ(s.metrics.rooms_failed.value(), 2u);
         EXPECT_EQ(s.metrics.rooms_in_flight.value(), 0);
         EXPECT_EQ(s.schedule.jobs(), 0u);
       }},
  });
}

// ---- worlds ----

TEST(ScheduleTest, worlds) {
  run({
      {"one world: another seed is world_mismatch",
       config(),
       {},
       {join(43), join(kSeed)},
       {"refused world_mismatch", "joined c1"},
       [](const Sim& s) { EXPECT_EQ(s.schedule.worlds_open(), 1u); }},
      {"max_worlds 3: with both others in use a fourth is refused; once idle, the least "
       "recently used other world closes for it; the own world never does",
       config([](ScheduleConfig& c) { c.max_worlds = 3; }),
       {},
       {join(43), join(44), join(45), leave(1), leave(2), join(45), join(44), join(43)},
       {"open 43", "joined c1", "open 44", "joined c2", "refused overloaded", "close 43", "open 45",
        "joined c3", "joined c4", "refused overloaded"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.worlds_opened.value(), 3u);
         EXPECT_EQ(s.metrics.worlds_refused.value(), 2u);
         EXPECT_EQ(s.metrics.worlds_open.value(), 3);
         EXPECT_TRUE(s.schedule.world_open(kSeed));
       }},
  });
  Metrics metrics;
  Schedule schedule(config([](ScheduleConfig& c) { c.max_worlds = 2; }), metrics);
  EXPECT_TRUE(schedule.joinable(43).ok());
  schedule.shutdown({});
  EXPECT_EQ(schedule.joinable(43).error().code, ErrorCode::kServiceRestart);
  EXPECT_TRUE(schedule.joinable(kSeed).ok());
}

// ---- rooms from their owner ----

TEST(ScheduleTest, owners) {
  const ScheduleConfig owners = config([](ScheduleConfig& c) { c.owners = true; });
  run({
      {"a room is asked of its owner once, whoever wants it, and not built here",
       owners,
       {join(), join()},
       {want(1, {{1, 2000}, {2, 2000}}), want(2, {{2, 2000}}), answer(1, true), answer(2, true)},
       {"fetch r1 wait=1000", "fetch r2 wait=1000", "c1 r1", "c1 r2", "c2 r2"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.rooms_fetched.value(), 2u);
         EXPECT_EQ(s.metrics.queue_depth.value(), 0);
         EXPECT_EQ(s.schedule.jobs(), 0u);
       }},
      {"an owner that fails: the room is built here, for every waiter",
       owners,
       {join(), join(), want(1, {{1, 2000}}), want(2, {{1, 3000}})},
       {answer(1, false), serve()},
       {"wake", "batch r1", "c1 r1", "c2 r1"},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.owner_failures.value(), 1u);
         EXPECT_EQ(s.metrics.rooms_fetched.value(), 0u);
       }},
      {"the owner's wait: due now, built here; due soon, a short wait; far, owner_timeout",
       owners,
       {join()},
       {want(1, {{1, 100}, {2, 1100}, {3, 5000}, {4, 0}})},
       {"fetch r1 wait=150", "fetch r2 wait=600", "fetch r3 wait=1000", "wake"}},
      {"a client that builds here (the tier's request) never asks the owner",
       owners,
       {join(kSeed, Build::kHere)},
       {want(1, {{1, 2000}})},
       {"wake"}},
      {"fetches cancelled while the owner is silent build nothing when it fails",
       owners,
       {join(), want(1, {{1, 2000}, {2, 2000}})},
       {cancel(1, {1, 2}), answer(1, false), answer(2, false)},
       {},
       [](const Sim& s) {
         EXPECT_EQ(s.metrics.owner_failures.value(), 2u);
         EXPECT_EQ(s.schedule.jobs(), 0u);
         EXPECT_EQ(s.schedule.queued_jobs(), 0u);
       }},
      {"the owner's own request for a room it is fetching builds it here at once; the fetch's "
       "late answer is not needed",
       owners,
       {join(), want(1, {{1, 2000}}), join(kSeed, Build::kHere)},
       {want(2, {{1, 2000}}), serve(), answer(1, false)},
       {"wake", "batch r1", "c1 r1", "c2 r1"},
       [](const Sim& s) { EXPECT_EQ(s.metrics.owner_failures.value(), 0u); }},
      {"an owner failing while the service stops: its waiters get service_restart",
       owners,
       {join(), want(1, {{1, 2000}}), shutdown()},
       {answer(1, false)},
       {"c1 r1 service_restart"}},
  });
}

// What admission reads (server/admission.hpp): how long players' urgent rooms have waited, the
// 90th percentile over the clients, so one client's own backlog does not speak for everyone.
TEST(ScheduleTest, oldest_urgent_is_the_90th_percentile_of_clients_oldest_urgent_wants) {
  Sim s(config());
  for (int i = 0; i < 10; ++i)
    join()(s);
  EXPECT_EQ(s.schedule.oldest_urgent(s.now).count(), 0);
  want_range(1, 0, 99, 0)(s);  // a greedy client: a hundred rooms due now
  want(2, {{200, kFar}})(s);   // prefetch does not count
  later(400ms)(s);
  EXPECT_EQ(s.schedule.oldest_urgent(s.now).count(), 0) << "one client of ten is its own backlog";
  want(3, {{300, 0}})(s);
  later(100ms)(s);
  EXPECT_EQ(s.schedule.oldest_urgent(s.now).count(), 100) << "two of ten: the second oldest";
  for (int c = 2; c <= 10; ++c)
    leave(static_cast<ClientId>(c))(s);
  EXPECT_EQ(s.schedule.oldest_urgent(s.now).count(), 500) << "alone, its wait is the server's";
}

// The burst budget's second signal: the same over every want, prefetch included.
TEST(ScheduleTest, oldest_want_counts_prefetch_too) {
  Sim s(config());
  for (int i = 0; i < 10; ++i)
    join()(s);
  want(2, {{200, kFar}})(s);
  want(3, {{300, kFar}})(s);
  later(400ms)(s);
  EXPECT_EQ(s.schedule.oldest_urgent(s.now).count(), 0) << "prefetch is not urgent";
  EXPECT_EQ(s.schedule.oldest_want(s.now).count(), 400) << "two of ten wait on prefetch";
}

}  // namespace
}  // namespace grotto::server
