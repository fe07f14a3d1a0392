// The generation service's policy as a plain state machine, in the manner of the protocol cores
// (server/conversation.hpp; h11, quinn-proto): the generator feeds it events (a client joined or
// left, rooms wanted or cancelled, a worker free for a batch, a batch's rooms built, an owner's
// answer, shutdown), each with the time as a `now` passed in, and carries out the actions it
// returns (deliver this outcome to this client, ask the owner for this room, wake the workers,
// open or close a world). Priorities, deadline classes, round-robin across clients, single
// flight, cancellation, deadlines, batching, the world registry, owner fetches and the
// encoded-room cache live here; threads, OpenCL, encoding and the owners' sockets do not.
//
// The schedule keeps the one ledger of what is in flight: each client's wants, and one job per
// (room, lod, world, version), queued, fetching from its owner or building.
//
// No threads, no clocks, no sockets, no OpenCL: tests drive it with tables of events and actions.
// Not thread-safe: the generator calls it under its lock.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <variant>
#include <vector>

#include "common/core/result.hpp"
#include "server/room_cache.hpp"
#include "server/rooms.hpp"

namespace grotto::server {

class Metrics;

// The schedule's clock: the generator passes steady_clock::now(), tests a simulated time.
using ScheduleTime = std::chrono::steady_clock::time_point;

// The generator's settings that are policy (GeneratorConfig documents each).
struct ScheduleConfig {
  uint64_t own_seed = 0;  // the generator's own world: open from the start, never closed
  size_t max_worlds = 1;
  size_t cache_bytes = size_t{256} << 20;
  size_t max_batch_rooms = 32;
  std::chrono::milliseconds job_deadline{30'000};
  std::chrono::milliseconds urgent_within{1'000};
  bool owners = false;  // rooms may be asked of their owner (GeneratorConfig::owners is set)
  std::chrono::milliseconds owner_timeout{1'000};
};

// One job as the generator sees it: its room, and which job of that room it is (a key's job may
// end and another begin while an answer about the first is on its way).
struct JobRef {
  uint64_t job = 0;
  RoomKey key;
  friend bool operator==(const JobRef&, const JobRef&) = default;
};

// Jobs a worker takes for one build call (one kernel launch), all of one lod, in the order their
// rooms go out. `limit` is the worker's share; `urgent`: it holds rooms due soon, so it is not
// topped up with prefetch.
struct Batch {
  std::vector<JobRef> jobs;
  size_t limit = 0;
  bool urgent = false;
};

// The actions the schedule returns, carried out by the generator in order.
namespace sched {
struct Deliver {  // the outcome of one wanted room for one client (DeliverFn)
  ClientId client = 0;
  Delivery delivery;
};
struct Fetch {  // ask the room's owner (RoomSource::fetch), then report through fetched()
  JobRef job;
  uint32_t priority = 0;
  std::chrono::milliseconds wait{0};  // how long the owner may take
};
struct Wake {};     // work was queued: wake the workers
struct OpenWorld {  // the world `seed` is open from now on (the client that named it joined)
  uint64_t seed = 0;
};
struct CloseWorld {  // the world `seed` is closed (idle, and another was wanted)
  uint64_t seed = 0;
};
using Action = std::variant<Deliver, Fetch, Wake, OpenWorld, CloseWorld>;
}  // namespace sched

class Schedule {
 public:
  Schedule(ScheduleConfig config, Metrics& metrics);

  // ---- clients and worlds ----

  // Whether a client of world `seed` may join, asked before the generator spends time opening
  // the world: service_restart while stopping (for a world other than its own), world_mismatch
  // when max_worlds is 1 and the seed is not its own.
  Status joinable(uint64_t seed) const;
  // A client of world `seed`, whose rooms are framed for protocol `version`. A world not open is
  // opened (OpenWorld), closing the least recently used idle world when max_worlds are open
  // (CloseWorld first); with every one in use it is refused: overloaded. Rechecks joinable().
  Result<ClientId> join(uint64_t seed, uint32_t version, Build build);
  // Forgets the client and its wants: a queued job nobody else wants goes. Nothing more is
  // delivered to it. Unknown clients are ignored.
  void leave(ClientId client);

  // ---- wants ----

  // GeneratorConfig and Generator::request say the rules: already waiting takes the new
  // priority; a cache hit is delivered at once; a job in flight is joined (single flight); a new
  // job is queued, or asked of its owner. Errors are delivered at once.
  void request(ClientId client, std::span<const Want> wants, ScheduleTime now);
  // Stops waiting for these rooms (any lod); a queued job nobody waits for goes.
  void cancel(ClientId client, std::span<const cave::RoomId> rooms);

  // ---- workers ----

  // Fails queued jobs older than job_deadline with overloaded.
  void expire(ScheduleTime now);
  // A worker is free (`idle_workers` others wait for work): the jobs it builds, taken out of
  // the queues by deadline class and round-robin, up to its share of the queue.
  Batch start_batch(ScheduleTime now, size_t idle_workers);
  // More wants arrived while the worker waited for a fuller batch: takes them, up to the limit.
  void top_up(Batch& batch, ScheduleTime now);
  // The batch is about to build: jobs everyone cancelled meanwhile leave it (and the ledger).
  void seal(Batch& batch);
  // A job of a batch ended: its room (cached), or the error, for every waiter.
  void built(const JobRef& job, Result<RoomPtr> room, ScheduleTime now);

  // ---- owners ----

  // Whether the owner's answer for `job` is still needed (the job is still fetching): if not,
  // the generator need not check it.
  bool fetch_wanted(const JobRef& job) const;
  // The owner's answer, checked by the generator (an error when it failed, was not what was
  // asked, or `wanted` was false): the room for every waiter, or the job is queued to build here.
  void fetched(const JobRef& job, Result<RoomPtr> room, bool wanted, ScheduleTime now);

  // Stops taking work: queued jobs fail with service_restart, later wants too. Idempotent.
  void shutdown(ScheduleTime now);

  // The actions since the last call, in order.
  std::vector<sched::Action> take();

  // How long the clients' urgent wants (asked due within urgent_within) still queued have
  // waited: each client's oldest, the 90th percentile over all clients (those with none waiting
  // count as 0). What admission (server/admission.hpp) reads to tell whether the players are
  // served in time. Looks only at the queues' urgent heads.
  std::chrono::milliseconds oldest_urgent(ScheduleTime now) const;
  // The same over every want still queued, prefetch included: where a crowd's cost shows first
  // (its prefetch waits behind everyone's urgent rooms), which admission's burst budget reads.
  std::chrono::milliseconds oldest_want(ScheduleTime now) const;
  bool stopping() const { return stopping_; }
  size_t queued_jobs() const { return queued_jobs_; }  // jobs queued, not fetching or building
  size_t jobs() const { return jobs_.size(); }         // the ledger: queued, fetching, building
  size_t worlds_open() const { return worlds_.size(); }
  bool world_open(uint64_t seed) const { return worlds_.contains(seed); }
  const RoomCache& cache() const { return cache_; }

 private:
  std::chrono::milliseconds oldest_queued(ScheduleTime now, bool urgent_only) const;
  struct Job {
    enum class Stage { kQueued, kFetching, kBuilding };
    uint64_t id = 0;
    Stage stage = Stage::kQueued;
    std::vector<ClientId> waiters;
    ScheduleTime created;
  };
  // A client's place for one job in its queue: smaller priority first, then first come.
  struct QueueEntry {
    uint32_t priority = 0;
    uint64_t seq = 0;  // unique per want, increasing
    RoomKey key;
    friend bool operator<(const QueueEntry& a, const QueueEntry& b) {
      return a.priority != b.priority ? a.priority < b.priority : a.seq < b.seq;
    }
  };
  struct Waiting {
    uint32_t priority = 0;
    uint64_t seq = 0;
    ScheduleTime received;
    bool queued = false;  // in the client's queue (its job has not started)
    ScheduleTime due;     // when the player can reach the room: the last request's time + priority
  };
  struct Client {
    ClientId id = 0;
    uint64_t seed = 0;
    uint32_t version = 0;
    Build build = Build::kAnywhere;
    std::map<RoomKey, Waiting, RoomKeyLess> wants;
    std::set<QueueEntry> queue;  // wants whose job is queued
  };
  struct World {
    size_t clients = 0;
    uint64_t last_used = 0;  // when a client last came or went, for closing
  };
  using Jobs = std::map<RoomKey, Job, RoomKeyLess>;

  void touch(const Client& c);
  void publish_gauges();
  Job* find(const JobRef& ref);
  void answer(Client& client, const RoomKey& key, Delivery d, ScheduleTime now);
  void finish_job(Jobs::iterator job, const RoomPtr& room, const std::optional<Error>& error,
                  ScheduleTime now);
  void drop_want(Client& client, std::map<RoomKey, Waiting, RoomKeyLess>::iterator it);
  void fetch(const RoomKey& key, Job& job, uint32_t priority_ms);
  void build_here(const RoomKey& key, Job& job, ScheduleTime now);
  void take_jobs(Batch& batch, ScheduleTime now);
  std::set<QueueEntry>::iterator head(Client& c, const Batch& batch);
  void take_job(Client& c, std::set<QueueEntry>::iterator e, Batch& batch);
  void take_any(Batch& batch);
  void take_due(Batch& batch, ScheduleTime now, ScheduleTime window);
  template <class A>
  void emit(A action) {
    actions_.emplace_back(std::in_place_type<A>, std::move(action));
  }

  const ScheduleConfig config_;
  Metrics& metrics_;
  bool stopping_ = false;
  ClientId next_client_ = 1;
  uint64_t next_seq_ = 1;
  uint64_t next_job_ = 1;
  ClientId rr_cursor_ = 0;  // the client served last; the next batch starts after it
  std::map<ClientId, Client> clients_;
  // The clients with queued wants, by id: what a batch looks at (thousands of clients, most
  // with nothing queued at a given moment). touch() keeps it.
  std::set<ClientId> queued_clients_;
  std::map<uint64_t, World> worlds_;  // open worlds by seed, the own included
  uint64_t world_clock_ = 0;          // ticks at each client arrival and departure
  Jobs jobs_;                         // the ledger: one job per key
  size_t queued_jobs_ = 0;
  std::deque<JobRef> by_age_;  // queued jobs in the order they were queued, for the deadline
  RoomCache cache_;
  std::vector<sched::Action> actions_;
};

}  // namespace grotto::server
