// The generation service: scheduling (per-client priority queues, round-robin across clients),
// single flight, cancellation, batching, deadlines, the encoded-room cache and the workers.
//
// One mutex guards the scheduler (clients, jobs, queues, the room cache). Layout, building and
// encoding run outside it, on the worker that took the batch; deliver callbacks run outside it
// too, and remove_client waits for callbacks already started for that client, so that nothing
// reaches a removed client after remove_client returns.
#include "server/generator.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cassert>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "common/codec/room_codec.hpp"
#include "common/core/thread_name.hpp"
#include "common/mesh/context.hpp"
#include "proto/lod.hpp"
#include "proto/room_frame.hpp"
#include "server/metrics.hpp"
#include "server/room_cache.hpp"
#include "server/sector_cache.hpp"

namespace grotto::server {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// One open world: its layout, its mesh context and its sector cache. Jobs and clients hold it,
// so a world closed while one of its rooms builds lives until the build ends.
struct WorldSlot {
  WorldSlot(const cave::World& w, mesh::MeshContext ctx, std::shared_ptr<SectorStore> store)
      : world(w), mesh_ctx(std::move(ctx)), sectors(w, std::move(store)) {}
  const cave::World world;
  const mesh::MeshContext mesh_ctx;
  SectorCache sectors;     // its layouts, in the store every world shares
  size_t clients = 0;      // under the generator's lock
  uint64_t last_used = 0;  // under the lock: when a client last came or went, for closing
};
using WorldPtr = std::shared_ptr<WorldSlot>;

// One room at one lod, wanted by one or more clients: built at most once while it exists.
struct Job {
  enum class Stage { kQueued, kFetching, kBuilding };
  RoomKey key;
  WorldPtr world;
  Stage stage = Stage::kQueued;
  std::vector<ClientId> waiters;
  Clock::time_point created;
};
using JobPtr = std::shared_ptr<Job>;

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
  Clock::time_point received;
  bool queued = false;    // in the client's queue (its job has not started)
  Clock::time_point due;  // when the player can reach the room: the last request's time + priority
};

struct Client {
  ClientId id = 0;
  WorldPtr world;
  uint32_t version = proto::kProtocolVersion;  // of the frames it gets
  Build build = Build::kAnywhere;
  Generator::DeliverFn deliver;
  std::map<RoomKey, Waiting, RoomKeyLess> wants;
  std::set<QueueEntry> queue;  // wants whose job is queued
  int delivering = 0;          // callbacks collected or running outside the lock
};
using ClientPtr = std::shared_ptr<Client>;

struct Outgoing {
  ClientPtr client;
  Delivery delivery;
};

Delivery error_delivery(RoomKey key, Error error) {
  Delivery d;
  d.key = key;
  d.error = std::move(error);
  return d;
}

// One OpenCL device opens at a time, process-wide: PoCL's device discovery run from several
// threads at once made some of them report "no OpenCL device" (seen in server_bench).
std::mutex& device_open_mutex() {
  static std::mutex m;
  return m;
}

}  // namespace

struct Generator::State {
  State(WorldPtr own, const mesh::MeshParams& p, const GeneratorConfig& c, Metrics& m)
      : home(std::move(own)), mesh_params(p), config(c), metrics(m), cache(c.cache_bytes) {
    worlds.emplace(home->world.seed(), home);
    metrics.worlds_open.set(1);
  }

  const WorldPtr home;  // the generator's own world; builders keep a pointer to its mesh context
  const mesh::MeshParams mesh_params;
  const GeneratorConfig config;
  Metrics& metrics;
  std::string compute_path;

  std::mutex mutex;
  std::condition_variable work_cv;     // queued work, or stopping
  std::condition_variable deliver_cv;  // a client's callbacks finished
  std::condition_variable exit_cv;     // a worker exited or its builder is ready
  bool stopping = false;
  ClientId next_client = 1;
  uint64_t next_seq = 1;
  ClientId rr_cursor = 0;  // the client served last; the next batch starts after it
  std::map<ClientId, ClientPtr> clients;
  // The clients with queued wants, by id: what a worker looks at for a batch (thousands of
  // clients, most with nothing queued at a given moment, under the one lock). touch() keeps it.
  std::set<ClientId> queued_clients;
  std::map<uint64_t, WorldPtr> worlds;  // open worlds by seed, home included
  uint64_t world_clock = 0;             // ticks at each client arrival and departure
  std::map<RoomKey, JobPtr, RoomKeyLess> jobs;
  size_t queued_jobs = 0;
  std::deque<std::weak_ptr<Job>> by_age;  // jobs in creation order, for the deadline sweep
  RoomCache cache;
  std::vector<std::thread> threads;
  std::vector<std::optional<kernels::RoomBuilder>> builders;
  kernels::RoomBuilder::Options builder_options;  // config.builder, with the shared device if any
  int builders_ready = 0;
  int workers_exited = 0;
  size_t idle_workers = 0;             // waiting on work_cv for queued work
  int fetches = 0;                     // asked of config.owners, not yet answered
  std::condition_variable fetched_cv;  // a fetch was answered

  // ---- under the lock ----

  // After a change to c's queue: whether c has queued wants.
  void touch(const Client& c) {
    if (c.queue.empty()) {
      queued_clients.erase(c.id);
    } else {
      queued_clients.insert(c.id);
    }
  }

  void publish_gauges() {
    metrics.queue_depth.set(static_cast<int64_t>(queued_jobs));
    metrics.cache_bytes.set(static_cast<int64_t>(cache.bytes()));
    metrics.cache_entries.set(static_cast<int64_t>(cache.entries()));
  }

  // The open world `seed`, or a newly opened one (closing the least recently used idle world
  // when max_worlds are open).
  Result<WorldPtr> open_world(uint64_t seed) {
    if (auto it = worlds.find(seed); it != worlds.end()) return it->second;
    if (config.max_worlds == 1) {
      return Error{ErrorCode::kWorldMismatch, "this server serves seed " +
                                                  std::to_string(home->world.seed()) + ", not " +
                                                  std::to_string(seed)};
    }
    auto world = cave::World::create(seed, home->world.params());
    if (!world) return world.error();
    auto ctx = mesh::MeshContext::create(*world, mesh_params);
    if (!ctx) return ctx.error();
    if (worlds.size() >= config.max_worlds) {
      auto idle = worlds.end();
      for (auto it = worlds.begin(); it != worlds.end(); ++it) {
        const WorldSlot& w = *it->second;
        if (it->second == home || w.clients > 0) continue;
        if (idle == worlds.end() || w.last_used < idle->second->last_used) idle = it;
      }
      if (idle == worlds.end()) {
        metrics.worlds_refused.add();
        return Error{ErrorCode::kOverloaded,
                     "this server has its " + std::to_string(config.max_worlds) +
                         " worlds (max_worlds) open and players in each; world " +
                         std::to_string(seed) + " cannot open now, retry later"};
      }
      spdlog::info("event=world_closed seed={} reason=idle", idle->first);
      worlds.erase(idle);
    }
    auto slot = std::make_shared<WorldSlot>(*world, std::move(ctx).value(), home->sectors.store());
    worlds.emplace(seed, slot);
    metrics.worlds_opened.add();
    metrics.worlds_open.set(static_cast<int64_t>(worlds.size()));
    spdlog::info("event=world_opened seed={} worlds_open={}", seed, worlds.size());
    return slot;
  }

  WorldPtr world_of(ClientId client) {
    std::lock_guard lock(mutex);
    auto it = clients.find(client);
    return it != clients.end() ? it->second->world : home;
  }

  // Answers one want of `client`: forgets it and queues the callback.
  void answer(const ClientPtr& client, const RoomKey& key, Delivery d, std::vector<Outgoing>& out) {
    auto it = client->wants.find(key);
    assert(it != client->wants.end());
    if (it->second.queued) {
      client->queue.erase({it->second.priority, it->second.seq, key});
      touch(*client);
    }
    metrics.room_latency_seconds.observe(seconds_between(it->second.received, Clock::now()));
    client->wants.erase(it);
    metrics.rooms_in_flight.add(-1);
    ++client->delivering;
    out.push_back({client, std::move(d)});
  }

  // Ends a job for every waiter with the same outcome and forgets it.
  void finish_job(const JobPtr& job, const RoomPtr& room, const std::optional<Error>& error,
                  std::vector<Outgoing>& out) {
    if (job->stage == Job::Stage::kQueued) --queued_jobs;
    for (ClientId id : job->waiters) {
      auto c = clients.find(id);
      assert(c != clients.end());
      Delivery d;
      d.key = job->key;
      d.room = room;
      d.error = error;
      answer(c->second, job->key, std::move(d), out);
    }
    job->waiters.clear();
    auto it = jobs.find(job->key);
    if (it != jobs.end() && it->second == job) jobs.erase(it);
  }

  // Removes one want of a client (cancel or removal); a queued job nobody waits for goes.
  void drop_want(Client& client, std::map<RoomKey, Waiting, RoomKeyLess>::iterator it) {
    RoomKey key = it->first;
    if (it->second.queued) {
      client.queue.erase({it->second.priority, it->second.seq, key});
      touch(client);
    }
    client.wants.erase(it);
    metrics.rooms_in_flight.add(-1);
    metrics.rooms_cancelled.add();
    auto j = jobs.find(key);
    if (j == jobs.end()) return;
    JobPtr job = j->second;
    std::erase(job->waiters, client.id);
    if (job->waiters.empty() && job->stage == Job::Stage::kQueued) {
      --queued_jobs;
      jobs.erase(j);
    }
  }

  // Fails queued jobs older than the deadline with `overloaded`.
  void expire(Clock::time_point now, std::vector<Outgoing>& out) {
    while (!by_age.empty()) {
      JobPtr job = by_age.front().lock();
      if (job && job->stage == Job::Stage::kQueued) {
        if (now - job->created < config.job_deadline) break;
        metrics.rooms_failed.add();
        finish_job(job, nullptr,
                   Error{ErrorCode::kOverloaded, "room " + job->key.id.to_string() +
                                                     " waited longer than " +
                                                     std::to_string(config.job_deadline.count()) +
                                                     " ms for a builder; retry later"},
                   out);
      }
      by_age.pop_front();
    }
  }

  // Moves up to `limit` queued jobs into `batch` by deadline class (GeneratorConfig::
  // urgent_within): first the wants already due (the player is in the room or at its portal: a
  // stream's first room, priority 0), then the urgent ones (take_due), then any, round-robin
  // from the client served last (take_any). A client's turn takes its smallest priority. All jobs
  // of a batch share the lod of its first job; worlds may mix (one launch serves them all). A batch
  // holding urgent jobs is not topped up with prefetch (`urgent` says it holds some): its rooms
  // are built, encoded and delivered before far ones, each as soon as it is encoded, while the
  // other workers take the prefetch.
  void take(std::vector<JobPtr>& batch, size_t limit, bool& urgent) {
    const auto now = Clock::now();
    if (config.urgent_within.count() > 0) {
      const size_t before = batch.size();
      take_due(batch, limit, now, now + config.urgent_within);
      if (batch.size() > before) urgent = true;
    }
    if (!urgent) take_any(batch, limit);
  }

  // How many queued jobs a worker about to take a batch takes: all it may (max_batch) while the
  // queue keeps every worker busy, else an even share with the workers waiting for work, so
  // that a few wants (one player's first rooms) are built and encoded on every core instead of
  // one worker's while the others wait. A batch's rooms are built on its worker's thread alone
  // (RoomBuilder::Options::threads is 1 in the server), so one batch is one core.
  size_t batch_share(size_t max_batch) const {
    const size_t share = (queued_jobs + idle_workers) / (idle_workers + 1);
    return std::clamp<size_t>(share, 1, max_batch);
  }

  // A client's most urgent queued want that fits the batch (of its lod, once it has a job).
  std::set<QueueEntry>::iterator head(Client& c, const std::vector<JobPtr>& batch) {
    auto e = c.queue.begin();
    if (!batch.empty()) {
      const uint8_t lod = batch.front()->key.lod;
      while (e != c.queue.end() && e->key.lod != lod)
        ++e;
    }
    return e;
  }

  // Moves the job of `e` (in c's queue) into the batch.
  void take_job(Client& c, std::set<QueueEntry>::iterator e, std::vector<JobPtr>& batch) {
    JobPtr job = jobs.at(e->key);
    assert(job->stage == Job::Stage::kQueued);
    job->stage = Job::Stage::kBuilding;
    --queued_jobs;
    // The job leaves every waiter's queue; the wants stay until it is answered.
    for (ClientId id : job->waiters) {
      Client& w = *clients.at(id);
      Waiting& want = w.wants.at(job->key);
      w.queue.erase({want.priority, want.seq, job->key});
      want.queued = false;
      touch(w);
    }
    batch.push_back(std::move(job));
    rr_cursor = c.id;
  }

  // Prefetch: round-robin across the clients with queued wants, one job each in turn, from the
  // client after the one served last.
  void take_any(std::vector<JobPtr>& batch, size_t limit) {
    std::vector<ClientId> order;
    while (batch.size() < limit && queued_jobs > 0) {
      order.assign(queued_clients.upper_bound(rr_cursor), queued_clients.end());
      order.insert(order.end(), queued_clients.begin(), queued_clients.upper_bound(rr_cursor));
      bool progress = false;
      for (ClientId id : order) {
        if (batch.size() >= limit) break;
        Client& c = *clients.at(id);
        auto e = head(c, batch);  // taking a job takes it from every waiter's queue
        if (e == c.queue.end()) continue;
        take_job(c, e, batch);
        progress = true;
      }
      if (!progress) break;
    }
  }

  // The deadline classes: first the wants due by `now`, then those due by `window`, each
  // earliest deadline first with one job per client a round. Each round orders the clients whose
  // most urgent want is due by then by that want's due time and takes one job from each in that
  // order: the player who reaches a missing room soonest goes first (a stream's first room before
  // another player's next one), and a client calling everything urgent still gets one job a
  // round. The clients with queued wants are scanned once a call (thousands of them, under the
  // one lock); the rounds look again only at those found due by `window`.
  void take_due(std::vector<JobPtr>& batch, size_t limit, Clock::time_point now,
                Clock::time_point window) {
    if (queued_jobs == 0 || batch.size() >= limit) return;
    std::vector<std::pair<Clock::time_point, Client*>> due;
    for (ClientId id : queued_clients) {
      Client& c = *clients.at(id);
      auto e = head(c, batch);
      if (e == c.queue.end()) continue;
      const auto at = c.wants.at(e->key).due;
      if (at <= window) due.emplace_back(at, &c);
    }
    auto earlier = [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first < b.first : a.second->id < b.second->id;
    };
    for (const Clock::time_point until : {now, window}) {
      while (batch.size() < limit && !due.empty()) {
        std::sort(due.begin(), due.end(), earlier);
        bool progress = false;
        size_t kept = 0;
        for (auto& [at, client] : due) {
          // The batch's lod is set by its first job, and taking a job takes it from every
          // waiter: each client's head is looked at again.
          auto e = head(*client, batch);
          if (e == client->queue.end() || client->wants.at(e->key).due > window) continue;
          if (client->wants.at(e->key).due <= until && batch.size() < limit) {
            take_job(*client, e, batch);
            progress = true;
            e = head(*client, batch);
            if (e == client->queue.end() || client->wants.at(e->key).due > window) continue;
          }
          due[kept++] = {client->wants.at(e->key).due, client};
        }
        due.resize(kept);
        if (!progress) break;
      }
    }
  }

  // Runs callbacks outside the lock, then lets remove_client know they are done.
  void deliver(std::unique_lock<std::mutex>& lock, std::vector<Outgoing>& out) {
    if (out.empty()) return;
    publish_gauges();
    lock.unlock();
    for (Outgoing& o : out) {
      o.client->deliver(std::move(o.delivery));
    }
    lock.lock();
    for (Outgoing& o : out)
      --o.client->delivering;
    out.clear();
    deliver_cv.notify_all();
  }

  // Asks the room's owner for a new job's room (under the lock: fetch() only posts).
  // The wait is the want's slack (its priority, the time until the player can reach the room,
  // less what building it here may take behind other work), between kMinOwnerWait and
  // owner_timeout: a room the player is about to enter is built here if its owner has not
  // answered within kMinOwnerWait (a silent owner costs that, not owner_timeout), far prefetch
  // waits the whole timeout.
  void fetch(const JobPtr& job, uint32_t priority_ms) {
    constexpr std::chrono::milliseconds kBuildHere{500}, kMinOwnerWait{150};
    const auto slack = std::chrono::milliseconds{priority_ms} - kBuildHere;
    const auto wait =
        std::clamp(slack, std::min(kMinOwnerWait, config.owner_timeout), config.owner_timeout);
    job->stage = Job::Stage::kFetching;
    ++fetches;
    config.owners->fetch(
        job->key, priority_ms, wait,
        [this, job](Result<std::vector<uint8_t>> bytes) { fetched(job, std::move(bytes)); });
  }

  // The owner's answer, on the fetcher's thread: the room for every waiter, or the job goes to
  // this replica's builders.
  void fetched(const JobPtr& job, Result<std::vector<uint8_t>> bytes) {
    std::unique_lock lock(mutex);
    // Built here meanwhile (build_here, e.g. the owner was this replica): the owner's answer is
    // not needed, so it is not decoded and checked either.
    const bool wanted = job->stage == Job::Stage::kFetching;
    lock.unlock();
    Result<RoomPtr> room = !wanted ? Result<RoomPtr>(Error{ErrorCode::kInternal, "not needed"})
                           : bytes ? checked(*job, std::move(bytes).value())
                                   : Result<RoomPtr>(bytes.error());
    lock.lock();
    std::vector<Outgoing> out;
    if (job->stage != Job::Stage::kFetching) {
      if (wanted && room) cache.insert(*room);  // built here while it was checked
    } else if (room) {
      metrics.rooms_fetched.add();
      cache.insert(*room);
      finish_job(job, *room, std::nullopt, out);
    } else {
      metrics.owner_failures.add();
      spdlog::warn("event=owner_fetch_failed seed={} room={} lod={} error=\"{}\"", job->key.seed,
                   job->key.id.to_string(), job->key.lod, room.error().message);
      if (job->waiters.empty()) {
        if (auto it = jobs.find(job->key); it != jobs.end() && it->second == job) jobs.erase(it);
      } else if (stopping) {
        finish_job(job, nullptr,
                   Error{ErrorCode::kServiceRestart, "the generation service is stopping"}, out);
      } else {
        build_here(job);
        work_cv.notify_all();
      }
    }
    deliver(lock, out);
    // Last, under the lock: ~Generator waits for this count, and deliver() let go of the lock.
    --fetches;
    fetched_cv.notify_all();
  }

  // A fetching job goes to this replica's builders: into every waiter's queue, where it was
  // (priority, then arrival). Its fetch's answer, when it comes, is not waited for.
  void build_here(const JobPtr& job) {
    job->stage = Job::Stage::kQueued;
    job->created = Clock::now();
    ++queued_jobs;
    by_age.push_back(job);
    for (ClientId id : job->waiters) {
      Client& w = *clients.at(id);
      Waiting& want = w.wants.at(job->key);
      want.queued = true;
      w.queue.insert({want.priority, want.seq, job->key});
      touch(w);
    }
  }

  // A frame from the owner, checked as untrusted input: it decodes, is of this key (version,
  // room, lod), and its room descriptor is byte for byte this replica's layout of the room (the
  // same world); the Draco payload is taken as it is.
  Result<RoomPtr> checked(const Job& job, std::vector<uint8_t> bytes) {
    proto::Limits limits;
    limits.max_lod = kMaxServedLod;
    Result<proto::RoomFrame> frame = proto::decode_room_frame(bytes, limits);
    if (!frame) return Error{ErrorCode::kBadFrame, "the owner's frame: " + frame.error().message};
    if (frame->version != job.key.version || frame->lod != job.key.lod ||
        !(frame->room.id == job.key.id)) {
      return Error{ErrorCode::kBadFrame, "the owner answered room " + frame->room.id.to_string() +
                                             " lod " + std::to_string(frame->lod) + " version " +
                                             std::to_string(frame->version) + " for another key"};
    }
    Result<cave::Room> ours = job.world->sectors.room(job.key.id);
    if (!ours) return ours.error();
    if (proto::encode_room_frame(*ours, frame->lod, frame->origin, frame->payload,
                                 frame->version) != bytes) {
      return Error{ErrorCode::kBadFrame,
                   "the owner's room " + job.key.id.to_string() + " is not this world's"};
    }
    auto encoded = std::make_shared<EncodedRoom>();
    encoded->key = job.key;
    encoded->frame = std::move(bytes);
    return RoomPtr(std::move(encoded));
  }

  // ---- outside the lock ----

  // Layout and build: a mesh (or the error) per job of the batch, in order, and each job's room.
  struct Built {
    std::vector<Result<mesh::RoomMesh>> meshes;
    std::vector<cave::Room> rooms;  // rooms[i] is batch[i]'s when meshes[i] holds a mesh
    double build_each = 0;          // seconds per room of the one build call
  };
  Built build(kernels::RoomBuilder& builder, const std::vector<JobPtr>& batch) {
    Built out;
    out.meshes.assign(batch.size(), Result<mesh::RoomMesh>(mesh::RoomMesh{}));
    out.rooms.resize(batch.size());
    std::vector<cave::Room> rooms;
    std::vector<const mesh::MeshContext*> contexts;  // rooms[k]'s world's
    std::vector<size_t> slots;
    for (size_t i = 0; i < batch.size(); ++i) {
      WorldSlot& world = *batch[i]->world;
      Result<cave::Room> room = world.sectors.room(batch[i]->key.id);
      if (!room) {
        out.meshes[i] = room.error();
        continue;
      }
      rooms.push_back(std::move(room).value());
      contexts.push_back(&world.mesh_ctx);
      slots.push_back(i);
    }
    if (rooms.empty()) return out;
    uint8_t lod = batch.front()->key.lod;
    auto t0 = Clock::now();
    std::vector<Result<mesh::RoomMesh>> meshes =
        builder.build(contexts, rooms, *proto::mesh_lod(lod));
    out.build_each = seconds_between(t0, Clock::now()) / static_cast<double>(rooms.size());
    metrics.batches.add();
    for (size_t k = 0; k < rooms.size(); ++k) {
      size_t i = slots[k];
      if (!meshes[k]) {
        spdlog::warn("event=room_build_failed seed={} room={} lod={} error=\"{}\"",
                     batch[i]->key.seed, rooms[k].id.to_string(), lod, meshes[k].error().message);
        out.meshes[i] =
            Error{ErrorCode::kInternal, "room " + rooms[k].id.to_string() +
                                            " could not be built: " + meshes[k].error().message};
        continue;
      }
      out.meshes[i] = std::move(meshes[k]);
      out.rooms[i] = std::move(rooms[k]);
    }
    return out;
  }

  // Encodes one built room into its frame.
  Result<RoomPtr> encode(const Job& job, const cave::Room& room, const mesh::RoomMesh& m,
                         double build_seconds) {
    auto t1 = Clock::now();
    const uint32_t version = job.key.version;
    codec::EncodeOptions options;
    options.normals = proto::payload_has_normals(version);
    Result<std::vector<uint8_t>> payload = codec::encode_room(m, options);
    if (!payload) {
      spdlog::warn("event=room_encode_failed seed={} room={} lod={} error=\"{}\"", job.key.seed,
                   room.id.to_string(), job.key.lod, payload.error().message);
      return Error{ErrorCode::kInternal, "room " + room.id.to_string() +
                                             " could not be encoded: " + payload.error().message};
    }
    auto encoded = std::make_shared<EncodedRoom>();
    encoded->key = job.key;
    encoded->frame = proto::encode_room_frame(room, job.key.lod, m.origin, *payload, version);
    encoded->build_seconds = build_seconds;
    encoded->encode_seconds = seconds_between(t1, Clock::now());
    metrics.build_seconds.observe(encoded->build_seconds);
    metrics.encode_seconds.observe(encoded->encode_seconds);
    metrics.rooms_built.add();
    return RoomPtr(std::move(encoded));
  }

  void worker_main(size_t index) {
    {
      std::lock_guard open_lock(device_open_mutex());
      builders[index].emplace(kernels::RoomBuilder::create(home->mesh_ctx, builder_options));
    }
    kernels::RoomBuilder& builder = *builders[index];
    std::unique_lock lock(mutex);
    ++builders_ready;
    exit_cv.notify_all();
    std::vector<Outgoing> out;
    size_t max_batch = config.max_batch_rooms;
    while (true) {
      ++idle_workers;
      work_cv.wait(lock, [&] { return stopping || queued_jobs > 0; });
      --idle_workers;
      if (stopping) break;
      expire(Clock::now(), out);
      if (!out.empty()) {
        // Tell those clients now rather than after the next build; then look again.
        deliver(lock, out);
        continue;
      }
      std::vector<JobPtr> batch;
      bool urgent = false;
      const size_t limit = batch_share(max_batch);
      take(batch, limit, urgent);
      // Work this batch cannot take (another lod, or the idle workers' shares): theirs, now.
      if (queued_jobs > 0) work_cv.notify_one();
      // A fuller batch amortizes the launch: wait a little for more wants of this lod, but not
      // with urgent rooms, which go now (waiting 2 ms for every few urgent rooms halved the
      // rooms built a second while a crowd arrived).
      if (!urgent && batch.size() < limit && !batch.empty() && config.max_batch_wait.count() > 0) {
        auto until = Clock::now() + config.max_batch_wait;
        while (batch.size() < limit && !stopping &&
               work_cv.wait_until(lock, until) == std::cv_status::no_timeout) {
          take(batch, limit, urgent);
        }
        take(batch, limit, urgent);
      }
      if (queued_jobs > 0) work_cv.notify_one();  // work left: wake another worker
      // Jobs cancelled by everyone while the batch filled are not built.
      std::erase_if(batch, [&](const JobPtr& job) {
        if (!job->waiters.empty()) return false;
        jobs.erase(job->key);
        return true;
      });
      publish_gauges();
      if (batch.empty()) {
        deliver(lock, out);
        continue;
      }
      lock.unlock();
      Built built = build(builder, batch);
      // Each room goes to its players as soon as it is encoded (the batch is in take's order:
      // urgent first), not when the whole batch is.
      for (size_t i = 0; i < batch.size(); ++i) {
        Result<RoomPtr> result =
            built.meshes[i] ? encode(*batch[i], built.rooms[i], *built.meshes[i], built.build_each)
                            : Result<RoomPtr>(built.meshes[i].error());
        lock.lock();
        if (result) {
          cache.insert(*result);
          finish_job(batch[i], *result, std::nullopt, out);
        } else {
          metrics.rooms_failed.add();
          finish_job(batch[i], nullptr, result.error(), out);
        }
        if (i + 1 < batch.size()) {
          deliver(lock, out);
          lock.unlock();
        }
      }
      deliver(lock, out);
    }
    ++workers_exited;
    exit_cv.notify_all();
  }
};

size_t resolved_workers(const GeneratorConfig& config) {
  return config.workers > 0 ? static_cast<size_t>(config.workers)
                            : std::max(1u, std::thread::hardware_concurrency());
}

Result<std::unique_ptr<Generator>> Generator::create(const cave::World& world,
                                                     const mesh::MeshParams& mesh_params,
                                                     const GeneratorConfig& config,
                                                     Metrics& metrics) {
  if (config.workers < 0 || config.workers > 1024) {
    return invalid_argument("workers must be in [0, 1024] (0: one per hardware thread), got " +
                            std::to_string(config.workers));
  }
  if (config.max_batch_rooms < 1 || config.max_batch_rooms > 4096) {
    return invalid_argument("max_batch_rooms must be in [1, 4096], got " +
                            std::to_string(config.max_batch_rooms));
  }
  if (config.max_batch_wait.count() < 0 || config.max_batch_wait.count() > 10'000) {
    return invalid_argument("max_batch_wait must be in [0, 10000] ms, got " +
                            std::to_string(config.max_batch_wait.count()));
  }
  if (config.max_worlds < 1 || config.max_worlds > 4096) {
    return invalid_argument("max_worlds must be in [1, 4096], got " +
                            std::to_string(config.max_worlds));
  }
  if (config.job_deadline.count() < 1) {
    return invalid_argument("job_deadline must be at least 1 ms, got " +
                            std::to_string(config.job_deadline.count()));
  }
  Result<mesh::MeshContext> ctx = mesh::MeshContext::create(world, mesh_params);
  if (!ctx) return Error{ctx.error().code, "mesh parameters: " + ctx.error().message};

  auto home = std::make_shared<WorldSlot>(
      world, std::move(ctx).value(), std::make_shared<SectorStore>(config.sector_cache_entries));
  auto state = std::make_unique<State>(std::move(home), mesh_params, config, metrics);
  const size_t workers = resolved_workers(config);
  State* s = state.get();
  s->builder_options = config.builder;
  if (config.share_device && !config.builder.shared_device) {
    std::lock_guard open_lock(device_open_mutex());
    // Without a device, each builder says why when it opens (the CPU path, logged once each).
    auto shared = kernels::SharedDeform::open(config.builder.device, s->home->mesh_ctx,
                                              [&metrics](size_t, double seconds) {
                                                metrics.device_launches.add();
                                                metrics.device_launch_seconds.observe(seconds);
                                              });
    if (shared) s->builder_options.shared_device = std::move(shared).value();
  }
  s->builders.resize(workers);
  // Each worker opens its own builder on its thread (builders are not thread-safe), on the shared
  // device or, per-worker, on an OpenCL context of its own. They open one after another (see
  // worker_main).
  for (size_t i = 0; i < workers; ++i) {
    s->threads.emplace_back([s, i] {
      name_this_thread("grotto-build");
      s->worker_main(i);
    });
  }
  {
    std::unique_lock lock(s->mutex);
    s->exit_cv.wait(lock, [&] { return s->builders_ready == static_cast<int>(workers); });
  }
  s->compute_path = s->builders[0]->path();
  for (size_t i = 1; i < workers; ++i) {
    if (s->builders[i]->path() != s->compute_path) {
      spdlog::warn("event=builder_path_differs worker={} path=\"{}\" first=\"{}\"", i,
                   s->builders[i]->path(), s->compute_path);
    }
  }
  metrics.set_compute_path(s->compute_path);
  spdlog::info(
      "event=generator_started workers={} path=\"{}\" cache_bytes={} max_batch_rooms={} "
      "max_worlds={}",
      workers, s->compute_path, config.cache_bytes, config.max_batch_rooms, config.max_worlds);
  return std::unique_ptr<Generator>(new Generator(std::move(state)));
}

Generator::Generator(std::unique_ptr<State> state) : state_(std::move(state)) {}

Generator::~Generator() {
  shutdown();
  for (std::thread& t : state_->threads) {
    if (t.joinable()) t.join();
  }
  // A fetch's answer comes within owner_timeout (or at once when the source stops).
  std::unique_lock lock(state_->mutex);
  state_->fetched_cv.wait(lock, [&] { return state_->fetches == 0; });
}

ClientId Generator::add_client(DeliverFn deliver) {
  return *add_client(state_->home->world.seed(), std::move(deliver));  // its own world is open
}

Result<ClientId> Generator::add_client(uint64_t seed, DeliverFn deliver, uint32_t version,
                                       Build build) {
  State& s = *state_;
  std::lock_guard lock(s.mutex);
  if (s.stopping && seed != s.home->world.seed()) {
    // Opening a world (and closing another) for a client that gets nothing built is no use.
    return Error{ErrorCode::kServiceRestart, "the generation service is stopping"};
  }
  Result<WorldPtr> world = s.open_world(seed);
  if (!world) return world.error();
  auto client = std::make_shared<Client>();
  client->id = s.next_client++;
  client->world = std::move(world).value();
  client->version = version;
  client->build = build;
  ++client->world->clients;
  client->world->last_used = ++s.world_clock;
  client->deliver = std::move(deliver);
  s.clients.emplace(client->id, client);
  return client->id;
}

void Generator::remove_client(ClientId id) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  auto it = s.clients.find(id);
  if (it == s.clients.end()) return;
  ClientPtr client = it->second;
  while (!client->wants.empty())
    s.drop_want(*client, client->wants.begin());
  --client->world->clients;
  client->world->last_used = ++s.world_clock;
  s.clients.erase(it);
  s.queued_clients.erase(id);
  s.publish_gauges();
  // Callbacks already collected for this client finish before we return.
  s.deliver_cv.wait(lock, [&] { return client->delivering == 0; });
}

void Generator::request(ClientId id, std::span<const server::Want> wants) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  auto c = s.clients.find(id);
  if (c == s.clients.end()) return;
  ClientPtr client = c->second;
  std::vector<Outgoing> out;
  auto now = Clock::now();
  bool queued = false;
  for (const server::Want& w : wants) {
    if (!proto::mesh_lod(w.lod)) {
      ++client->delivering;
      out.push_back({client, error_delivery({w.id, static_cast<uint8_t>(std::min(w.lod, 255u)),
                                             client->world->world.seed(), client->version},
                                            invalid_argument("lod " + std::to_string(w.lod) +
                                                             " is not served"))});
      continue;
    }
    RoomKey key{w.id, static_cast<uint8_t>(w.lod), client->world->world.seed(), client->version};
    if (s.stopping) {
      ++client->delivering;
      out.push_back({client, error_delivery(key, Error{ErrorCode::kServiceRestart,
                                                       "the generation service is stopping"})});
      continue;
    }
    if (auto known = client->wants.find(key); known != client->wants.end()) {
      // Already waiting: only the priority changes (its place among equals stays).
      Waiting& want = known->second;
      if (want.queued) {
        client->queue.erase({want.priority, want.seq, key});
        client->queue.insert({w.priority, want.seq, key});
      }
      want.priority = w.priority;
      want.due = now + std::chrono::milliseconds(w.priority);
      continue;
    }
    if (RoomPtr hit = s.cache.find(key)) {
      s.metrics.rooms_from_cache.add();
      s.metrics.room_latency_seconds.observe(0);
      Delivery d;
      d.key = key;
      d.room = std::move(hit);
      d.from_cache = true;
      ++client->delivering;
      out.push_back({client, std::move(d)});
      continue;
    }
    Waiting want{w.priority, s.next_seq++, now, false, now + std::chrono::milliseconds(w.priority)};
    auto j = s.jobs.find(key);
    if (j != s.jobs.end()) {
      s.metrics.rooms_deduplicated.add();
      if (j->second->stage == Job::Stage::kFetching && client->build == Build::kHere) {
        // This replica is the room's owner: the tier sent our own fetch back here. Waiting for
        // the fetch would wait for ourselves; the job is built here now.
        s.build_here(j->second);
        queued = true;
      }
      j->second->waiters.push_back(id);
      want.queued = j->second->stage == Job::Stage::kQueued;
    } else {
      auto job = std::make_shared<Job>();
      job->key = key;
      job->world = client->world;
      job->created = now;
      job->waiters.push_back(id);
      s.jobs.emplace(key, job);
      // A room due now (a stream's first room, a player at its portal) is built here: the player
      // already waits, and waiting for an owner busy with everyone's first rooms too made the
      // start of a crowd stall (bench/cluster.sh: 0-35 stalls, 134-585 owner failures; built
      // here, 0 stalls and 23-32).
      if (s.config.owners && client->build == Build::kAnywhere && w.priority > 0) {
        s.fetch(job, w.priority);
      } else {
        s.by_age.push_back(job);
        ++s.queued_jobs;
        want.queued = true;
        queued = true;
      }
    }
    if (want.queued) {
      client->queue.insert({want.priority, want.seq, key});
      s.touch(*client);
    }
    client->wants.emplace(key, want);
    s.metrics.rooms_in_flight.add(1);
  }
  s.publish_gauges();
  if (queued) s.work_cv.notify_all();
  s.deliver(lock, out);
}

void Generator::cancel(ClientId id, std::span<const cave::RoomId> rooms) {
  State& s = *state_;
  std::lock_guard lock(s.mutex);
  auto c = s.clients.find(id);
  if (c == s.clients.end()) return;
  Client& client = *c->second;
  for (cave::RoomId room : rooms) {
    // Every lod of the room: keys order by id first (and a client's wants are of one world).
    auto it = client.wants.lower_bound(RoomKey{room, 0, 0, 0});
    while (it != client.wants.end() && it->first.id == room) {
      auto next = std::next(it);
      s.drop_want(client, it);
      it = next;
    }
  }
  s.publish_gauges();
}

std::optional<cave::RoomId> Generator::locate(ClientId client, Vec3 point) {
  return state_->world_of(client)->sectors.locate(point);
}

cave::Spawn Generator::spawn(ClientId client) {
  return state_->world_of(client)->sectors.spawn();
}

void Generator::shutdown(std::chrono::milliseconds timeout) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  if (!s.stopping) {
    s.stopping = true;
    std::vector<Outgoing> out;
    std::vector<JobPtr> queued;
    for (auto& [key, job] : s.jobs) {
      if (job->stage == Job::Stage::kQueued) queued.push_back(job);
    }
    for (const JobPtr& job : queued) {
      s.metrics.rooms_failed.add();
      s.finish_job(job, nullptr,
                   Error{ErrorCode::kServiceRestart, "the generation service is stopping"}, out);
    }
    s.by_age.clear();
    s.work_cv.notify_all();
    spdlog::info("event=generator_stopping failed_queued={}", queued.size());
    s.deliver(lock, out);
  }
  s.exit_cv.wait_for(lock, timeout,
                     [&] { return s.workers_exited == static_cast<int>(s.threads.size()); });
}

const cave::World& Generator::world() const {
  return state_->home->world;
}

size_t Generator::worlds_open() const {
  std::lock_guard lock(state_->mutex);
  return state_->worlds.size();
}

std::string Generator::compute_path() const {
  return state_->compute_path;
}

Generator::DeviceLaunches Generator::device_launches() const {
  const auto& shared = state_->builder_options.shared_device;
  if (!shared) return {};
  return {shared->stats().launches, shared->batches()};
}

size_t Generator::queue_depth() const {
  std::lock_guard lock(state_->mutex);
  return state_->queued_jobs;
}

}  // namespace grotto::server
