// The generation service's shell round its policy (server/schedule.hpp): the workers and their
// OpenCL builders, encoding, the owners' fetches and the callbacks. Every decision (what to
// build, for whom, when, from where) is the schedule's; this file locks, feeds it events with
// the steady clock's time and carries out the actions it returns.
//
// One mutex guards the schedule. Layout, building, encoding and checking an owner's frame run
// outside it, on the worker that took the batch (or the fetcher's thread); deliver callbacks run
// outside it too, and remove_client waits for callbacks already started for that client, so that
// nothing reaches a removed client after remove_client returns.
#include "server/generator.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cassert>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

#include "common/codec/room_codec.hpp"
#include "common/core/thread_name.hpp"
#include "common/mesh/context.hpp"
#include "proto/lod.hpp"
#include "proto/room_frame.hpp"
#include "server/metrics.hpp"
#include "server/schedule.hpp"
#include "server/sector_cache.hpp"

namespace grotto::server {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// One open world: its layout, its mesh context and its sector cache. Clients, batches and fetches
// hold it, so a world closed while one of its rooms builds lives until the build ends.
struct WorldSlot {
  WorldSlot(const cave::World& w, mesh::MeshContext ctx, std::shared_ptr<SectorStore> store)
      : world(w), mesh_ctx(std::move(ctx)), sectors(w, std::move(store)) {}
  const cave::World world;
  const mesh::MeshContext mesh_ctx;
  SectorCache sectors;  // its layouts, in the store every world shares
};
using WorldPtr = std::shared_ptr<WorldSlot>;

// Where a client's deliveries go.
struct Sink {
  WorldPtr world;
  Generator::DeliverFn deliver;
  int delivering = 0;  // callbacks collected or running outside the lock
};
using SinkPtr = std::shared_ptr<Sink>;

struct Outgoing {
  SinkPtr sink;
  Delivery delivery;
};

// A job of a batch and the world it is built in.
struct Work {
  JobRef job;
  WorldPtr world;
};

ScheduleConfig schedule_config(uint64_t own_seed, const GeneratorConfig& c) {
  ScheduleConfig s;
  s.own_seed = own_seed;
  s.max_worlds = c.max_worlds;
  s.cache_bytes = c.cache_bytes;
  s.max_batch_rooms = c.max_batch_rooms;
  s.job_deadline = c.job_deadline;
  s.urgent_within = c.urgent_within;
  s.owners = c.owners != nullptr;
  s.owner_timeout = c.owner_timeout;
  return s;
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
      : home(std::move(own)),
        mesh_params(p),
        config(c),
        metrics(m),
        schedule(schedule_config(home->world.seed(), c), m) {
    worlds.emplace(home->world.seed(), home);
  }

  const WorldPtr home;  // the generator's own world; builders keep a pointer to its mesh context
  const mesh::MeshParams mesh_params;
  const GeneratorConfig config;
  Metrics& metrics;
  std::string compute_path;

  std::mutex mutex;
  std::condition_variable work_cv;      // queued work, or stopping
  std::condition_variable deliver_cv;   // a client's callbacks finished
  std::condition_variable exit_cv;      // a worker exited or its builder is ready
  Schedule schedule;                    // under the lock
  std::map<ClientId, SinkPtr> sinks;    // under the lock: the schedule's clients
  std::map<uint64_t, WorldPtr> worlds;  // under the lock: the schedule's open worlds
  WorldPtr opening;                     // under the lock: the world join() may open
  std::vector<std::thread> threads;
  std::vector<std::optional<kernels::RoomBuilder>> builders;
  kernels::RoomBuilder::Options builder_options;  // config.builder, with the shared device if any
  int builders_ready = 0;
  int workers_exited = 0;
  size_t idle_workers = 0;             // waiting on work_cv for queued work
  int fetches = 0;                     // asked of config.owners, not yet answered
  std::condition_variable fetched_cv;  // a fetch was answered

  // ---- under the lock ----

  // Carries out the schedule's actions; deliveries are collected in `out` for deliver().
  void carry_out(std::vector<Outgoing>& out) {
    for (sched::Action& action : schedule.take()) {
      if (auto* d = std::get_if<sched::Deliver>(&action)) {
        const SinkPtr& sink = sinks.at(d->client);
        ++sink->delivering;
        out.push_back({sink, std::move(d->delivery)});
      } else if (auto* f = std::get_if<sched::Fetch>(&action)) {
        fetch(*f);
      } else if (std::holds_alternative<sched::Wake>(action)) {
        work_cv.notify_all();
      } else if (auto* o = std::get_if<sched::OpenWorld>(&action)) {
        assert(opening && opening->world.seed() == o->seed);
        worlds.emplace(o->seed, std::move(opening));
      } else if (auto* c = std::get_if<sched::CloseWorld>(&action)) {
        worlds.erase(c->seed);
      }
    }
  }

  // Runs callbacks outside the lock, then lets remove_client know they are done.
  void deliver(std::unique_lock<std::mutex>& lock, std::vector<Outgoing>& out) {
    if (out.empty()) return;
    lock.unlock();
    for (Outgoing& o : out) {
      o.sink->deliver(std::move(o.delivery));
    }
    lock.lock();
    for (Outgoing& o : out)
      --o.sink->delivering;
    out.clear();
    deliver_cv.notify_all();
  }

  WorldPtr world_of(ClientId client) {
    std::lock_guard lock(mutex);
    auto it = sinks.find(client);
    return it != sinks.end() ? it->second->world : home;
  }

  // Asks the room's owner (fetch() only posts: it may be called under the lock).
  void fetch(const sched::Fetch& f) {
    ++fetches;
    config.owners->fetch(
        f.job.key, f.priority, f.wait,
        [this, job = f.job, world = worlds.at(f.job.key.seed)](Result<std::vector<uint8_t>> bytes) {
          fetched(job, *world, std::move(bytes));
        });
  }

  // The owner's answer, on the fetcher's thread, checked outside the lock.
  void fetched(const JobRef& job, WorldSlot& world, Result<std::vector<uint8_t>> bytes) {
    std::unique_lock lock(mutex);
    // Built here meanwhile (e.g. the owner was this replica): the owner's answer is not needed,
    // so it is not decoded and checked either.
    const bool wanted = schedule.fetch_wanted(job);
    lock.unlock();
    Result<RoomPtr> room = !wanted ? Result<RoomPtr>(Error{ErrorCode::kInternal, "not needed"})
                           : bytes ? checked(job.key, world, std::move(bytes).value())
                                   : Result<RoomPtr>(bytes.error());
    lock.lock();
    std::vector<Outgoing> out;
    schedule.fetched(job, std::move(room), wanted, Clock::now());
    carry_out(out);
    deliver(lock, out);
    // Last, under the lock: ~Generator waits for this count, and deliver() let go of the lock.
    --fetches;
    fetched_cv.notify_all();
  }

  // A frame from the owner, checked as untrusted input: it decodes, is of this key (version,
  // room, lod), and its room descriptor is byte for byte this replica's layout of the room (the
  // same world); the Draco payload is taken as it is.
  Result<RoomPtr> checked(const RoomKey& key, WorldSlot& world, std::vector<uint8_t> bytes) {
    proto::Limits limits;
    limits.max_lod = kMaxServedLod;
    Result<proto::RoomFrame> frame = proto::decode_room_frame(bytes, limits);
    if (!frame) return Error{ErrorCode::kBadFrame, "the owner's frame: " + frame.error().message};
    if (frame->version != key.version || frame->lod != key.lod || !(frame->room.id == key.id)) {
      return Error{ErrorCode::kBadFrame, "the owner answered room " + frame->room.id.to_string() +
                                             " lod " + std::to_string(frame->lod) + " version " +
                                             std::to_string(frame->version) + " for another key"};
    }
    Result<cave::Room> ours = world.sectors.room(key.id);
    if (!ours) return ours.error();
    if (proto::encode_room_frame(*ours, frame->lod, frame->origin, frame->payload,
                                 frame->version) != bytes) {
      return Error{ErrorCode::kBadFrame,
                   "the owner's room " + key.id.to_string() + " is not this world's"};
    }
    auto encoded = std::make_shared<EncodedRoom>();
    encoded->key = key;
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
  Built build(kernels::RoomBuilder& builder, const std::vector<Work>& batch) {
    Built out;
    out.meshes.assign(batch.size(), Result<mesh::RoomMesh>(mesh::RoomMesh{}));
    out.rooms.resize(batch.size());
    std::vector<cave::Room> rooms;
    std::vector<const mesh::MeshContext*> contexts;  // rooms[k]'s world's
    std::vector<size_t> slots;
    for (size_t i = 0; i < batch.size(); ++i) {
      WorldSlot& world = *batch[i].world;
      Result<cave::Room> room = world.sectors.room(batch[i].job.key.id);
      if (!room) {
        out.meshes[i] = room.error();
        continue;
      }
      rooms.push_back(std::move(room).value());
      contexts.push_back(&world.mesh_ctx);
      slots.push_back(i);
    }
    if (rooms.empty()) return out;
    uint8_t lod = batch.front().job.key.lod;
    auto t0 = Clock::now();
    std::vector<Result<mesh::RoomMesh>> meshes =
        builder.build(contexts, rooms, *proto::mesh_lod(lod));
    out.build_each = seconds_between(t0, Clock::now()) / static_cast<double>(rooms.size());
    metrics.batches.add();
    for (size_t k = 0; k < rooms.size(); ++k) {
      size_t i = slots[k];
      if (!meshes[k]) {
        spdlog::warn("event=room_build_failed seed={} room={} lod={} error=\"{}\"",
                     batch[i].job.key.seed, rooms[k].id.to_string(), lod,
                     meshes[k].error().message);
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
  Result<RoomPtr> encode(const RoomKey& key, const cave::Room& room, const mesh::RoomMesh& m,
                         double build_seconds) {
    auto t1 = Clock::now();
    const uint32_t version = key.version;
    codec::EncodeOptions options;
    options.normals = proto::payload_has_normals(version);
    Result<std::vector<uint8_t>> payload = codec::encode_room(m, options);
    if (!payload) {
      spdlog::warn("event=room_encode_failed seed={} room={} lod={} error=\"{}\"", key.seed,
                   room.id.to_string(), key.lod, payload.error().message);
      return Error{ErrorCode::kInternal, "room " + room.id.to_string() +
                                             " could not be encoded: " + payload.error().message};
    }
    auto encoded = std::make_shared<EncodedRoom>();
    encoded->key = key;
    encoded->frame = proto::encode_room_frame(room, key.lod, m.origin, *payload, version);
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
    while (true) {
      ++idle_workers;
      work_cv.wait(lock, [&] { return schedule.stopping() || schedule.queued_jobs() > 0; });
      --idle_workers;
      if (schedule.stopping()) break;
      schedule.expire(Clock::now());
      carry_out(out);
      if (!out.empty()) {
        // Tell those clients now rather than after the next build; then look again.
        deliver(lock, out);
        continue;
      }
      Batch batch = schedule.start_batch(Clock::now(), idle_workers);
      // Work this batch cannot take (another lod, or the idle workers' shares): theirs, now.
      if (schedule.queued_jobs() > 0) work_cv.notify_one();
      // A fuller batch amortizes the launch: wait a little for more wants of this lod, but not
      // with urgent rooms, which go now (waiting 2 ms for every few urgent rooms halved the
      // rooms built a second while a crowd arrived).
      if (!batch.urgent && batch.jobs.size() < batch.limit && !batch.jobs.empty() &&
          config.max_batch_wait.count() > 0) {
        auto until = Clock::now() + config.max_batch_wait;
        while (batch.jobs.size() < batch.limit && !schedule.stopping() &&
               work_cv.wait_until(lock, until) == std::cv_status::no_timeout) {
          schedule.top_up(batch, Clock::now());
        }
        schedule.top_up(batch, Clock::now());
      }
      if (schedule.queued_jobs() > 0) work_cv.notify_one();  // work left: wake another worker
      schedule.seal(batch);  // jobs cancelled by everyone while the batch filled are not built
      if (batch.jobs.empty()) continue;
      std::vector<Work> work;
      for (const JobRef& job : batch.jobs)
        work.push_back({job, worlds.at(job.key.seed)});  // a job with waiters: its world is open
      lock.unlock();
      Built built = build(builder, work);
      // Each room goes to its players as soon as it is encoded (the batch is in the schedule's
      // order: urgent first), not when the whole batch is.
      for (size_t i = 0; i < work.size(); ++i) {
        Result<RoomPtr> result = built.meshes[i] ? encode(work[i].job.key, built.rooms[i],
                                                          *built.meshes[i], built.build_each)
                                                 : Result<RoomPtr>(built.meshes[i].error());
        lock.lock();
        schedule.built(work[i].job, std::move(result), Clock::now());
        carry_out(out);
        if (i + 1 < work.size()) {
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
  if (Status joinable = s.schedule.joinable(seed); !joinable) return joinable.error();
  if (!s.schedule.world_open(seed)) {
    // The world is made before the schedule may close another for it (same layout and mesh
    // parameters as the generator's own; its sectors in the shared store).
    auto world = cave::World::create(seed, s.home->world.params());
    if (!world) return world.error();
    auto ctx = mesh::MeshContext::create(*world, s.mesh_params);
    if (!ctx) return ctx.error();
    s.opening =
        std::make_shared<WorldSlot>(*world, std::move(ctx).value(), s.home->sectors.store());
  }
  Result<ClientId> id = s.schedule.join(seed, version, build);
  std::vector<Outgoing> out;
  s.carry_out(out);  // open and close worlds: join delivers nothing
  assert(out.empty());
  s.opening.reset();
  if (!id) return id.error();
  auto sink = std::make_shared<Sink>();
  sink->world = s.worlds.at(seed);
  sink->deliver = std::move(deliver);
  s.sinks.emplace(*id, std::move(sink));
  return id;
}

void Generator::remove_client(ClientId id) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  auto it = s.sinks.find(id);
  if (it == s.sinks.end()) return;
  SinkPtr sink = it->second;
  s.schedule.leave(id);
  s.sinks.erase(it);
  // Callbacks already collected for this client finish before we return.
  s.deliver_cv.wait(lock, [&] { return sink->delivering == 0; });
}

void Generator::request(ClientId id, std::span<const server::Want> wants) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  std::vector<Outgoing> out;
  s.schedule.request(id, wants, Clock::now());
  s.carry_out(out);
  s.deliver(lock, out);
}

void Generator::cancel(ClientId id, std::span<const cave::RoomId> rooms) {
  State& s = *state_;
  std::lock_guard lock(s.mutex);
  s.schedule.cancel(id, rooms);
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
  if (!s.schedule.stopping()) {
    std::vector<Outgoing> out;
    s.schedule.shutdown(Clock::now());
    s.carry_out(out);
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
  return state_->schedule.worlds_open();
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
  return state_->schedule.queued_jobs();
}

std::chrono::milliseconds Generator::oldest_urgent() const {
  std::lock_guard lock(state_->mutex);
  return state_->schedule.oldest_urgent(Clock::now());
}

std::chrono::milliseconds Generator::oldest_want() const {
  std::lock_guard lock(state_->mutex);
  return state_->schedule.oldest_want(Clock::now());
}

}  // namespace grotto::server
