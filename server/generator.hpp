// The generation service behind the server's sockets: rooms wanted by
// clients are scheduled per client by priority and round-robin across clients, built once for
// all who want them (single flight), dropped before they run when nobody wants them any more
// (cancellation), built in batches that share one kernel launch, encoded into ready-to-send room
// frames, and kept in an LRU cache bounded in bytes. One generator serves up to max_worlds worlds
// (seeds) with the same parameters: its own, and others that clients name, opened on demand;
// workers, batches, cache and the round-robin are shared by all. No socket code here: sessions
// call in from their strands and receive results through a callback. The rules themselves live in
// a sans-I/O core, server/schedule.hpp; this class runs it with threads, OpenCL and the owners.
//
// Thread safety: every public member function may be called from any thread at any time.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/result.hpp"
#include "common/kernels/room_builder.hpp"
#include "common/mesh/params.hpp"
#include "proto/lod.hpp"
#include "server/room_tier.hpp"
#include "server/rooms.hpp"

namespace grotto::server {

class Metrics;

struct GeneratorConfig {
  int workers = 0;                         // build threads; 0: one per hardware thread
  size_t cache_bytes = size_t{256} << 20;  // encoded frames kept (LRU); 0 disables the cache
  size_t sector_cache_entries = 4096;      // sector layouts kept (LRU), all worlds together
  // Worlds served at once: the generator's own, which stays open, plus up to max_worlds - 1
  // others opened for the clients that name them. An idle one (no clients) is closed, least
  // recently used first, when another is wanted; with every one in use a new world is refused.
  // Eight by default, so that a link to another seed opens on a default server; 1 serves the
  // generator's own world alone (world_mismatch for any other).
  size_t max_worlds = 8;
  size_t max_batch_rooms = 32;                     // rooms per build call (one kernel launch)
  std::chrono::milliseconds max_batch_wait{2};     // a worker waits at most this for a fuller batch
  std::chrono::milliseconds job_deadline{30'000};  // queued longer than this: overloaded error
  // Deadline classes: a want due within this (received + priority, the priority being the
  // milliseconds until its player can reach the room) is urgent. Urgent wants are taken first,
  // round-robin across clients, then the rest, round-robin: a player about to walk into a room
  // goes before another's far prefetch, and a client calling everything urgent still gets only
  // its turn among the urgent. 0: one class (plain round-robin).
  std::chrono::milliseconds urgent_within{1'000};
  kernels::RoomBuilder::Options builder{};  // OpenCL device choice (each worker has a builder)
  // True: the workers' builders share one OpenCL context, queue and kernel (kernels::SharedDeform:
  // batches that wait for the device go up together in one launch). False: each worker opens
  // its own (a GPU time-sliced among as many contexts as workers).
  bool share_device = true;
  // In a cluster: where a room nobody here is building yet is asked for first (the
  // room tier: its owner replica through nginx), for clients that may have it from there
  // (Build::kAnywhere), unless it is due now (priority 0: the player waits; built here). A fetch
  // that fails, answers something other than that room's frame, or takes longer than its wait is
  // built here instead: the want's slack (its priority less 500 ms) between 150 ms and
  // owner_timeout, so a room a player is about to enter is not held up by a slow or silent owner.
  // Null: every room is built here.
  std::shared_ptr<RoomSource> owners;
  std::chrono::milliseconds owner_timeout{1'000};
};

// The build threads `config` runs: config.workers, or one per hardware thread when it is 0.
size_t resolved_workers(const GeneratorConfig& config);

class Generator {
 public:
  // Called once per (client, wanted room) outcome, on a worker thread or, for cache hits and
  // immediate errors, on the caller's thread inside request(). It must not block and must not
  // call back into the Generator synchronously (post to the session's strand instead).
  using DeliverFn = std::function<void(Delivery)>;

  // `world` is the generator's own, served to clients that name none. Errors: invalid
  // configuration (names the setting). Starts the workers.
  static Result<std::unique_ptr<Generator>> create(const cave::World& world,
                                                   const mesh::MeshParams& mesh_params,
                                                   const GeneratorConfig& config, Metrics& metrics);
  ~Generator();  // shutdown(), then joins the workers and waits for fetches in flight

  // A client of the generator's own world, speaking the newest protocol version.
  ClientId add_client(DeliverFn deliver);
  // A client of the world `seed`, opened now if it is not open (same layout and mesh parameters
  // as the generator's own), whose rooms are framed for protocol `version` (one proto::speaks).
  // Errors: world_mismatch when max_worlds is 1 and the seed is not the generator's; overloaded
  // when max_worlds worlds are open and each has clients.
  Result<ClientId> add_client(uint64_t seed, DeliverFn deliver,
                              uint32_t version = proto::kProtocolVersion,
                              Build build = Build::kAnywhere);
  // Forgets the client: its queued wants are dropped (jobs nobody else wants are never built) and
  // nothing more is delivered to it once this returns.
  void remove_client(ClientId client);

  // Queues rooms for a client; smaller priority is served sooner, equal priorities first come
  // first served. A (room, lod) the client already waits for only takes the new priority (the
  // same room at another lod is another want). Cache hits are delivered before this returns,
  // without the worker pool; so are immediate errors (a lod above kMaxServedLod:
  // invalid_argument; after shutdown: service_restart). Unknown or removed clients are ignored.
  // The caller enforces the per-client in-flight limit and the announced max_lod.
  void request(ClientId client, std::span<const Want> wants);
  // Stops waiting for these rooms (any lod). A job nobody waits for any more is never built; a
  // job already building finishes (and is cached) but is not delivered to this client. A
  // delivery already on its way when cancel() is called (its job finished a moment before) may
  // still arrive: sessions drop deliveries for rooms they no longer have in flight.
  void cancel(ClientId client, std::span<const cave::RoomId> rooms);

  // The layout side of the client's world, served from its sector cache (an unknown client gets
  // the generator's own world).
  std::optional<cave::RoomId> locate(ClientId client, Vec3 point);
  cave::Spawn spawn(ClientId client);

  // Stops taking work: queued jobs fail with `service_restart`, building ones finish, workers exit.
  // Idempotent; waits at most `timeout` for the workers.
  void shutdown(std::chrono::milliseconds timeout = std::chrono::milliseconds{5000});

  const cave::World& world() const;  // the generator's own
  size_t worlds_open() const;        // its own included
  // "opencl: <device>" or "cpu: <why>", as kernels::RoomBuilder::path() reports it.
  std::string compute_path() const;
  size_t queue_depth() const;  // jobs queued, not yet building
  // Schedule::oldest_urgent now: how late the most overdue urgent room is (admission's measure).
  std::chrono::milliseconds oldest_urgent() const;
  std::chrono::milliseconds oldest_want() const;  // Schedule::oldest_want now (any class)
  // The shared device's launches and the workers' batches they carried (share_device with a
  // usable device; zeros otherwise).
  struct DeviceLaunches {
    size_t launches = 0;
    size_t batches = 0;
  };
  DeviceLaunches device_launches() const;

 private:
  struct State;
  explicit Generator(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace grotto::server
