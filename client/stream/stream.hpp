// client/stream: a game client's connection to a Grotto server, without graphics. It speaks
// proto/PROTOCOL.md over one WebSocket, reconnects with exponential backoff and jitter after a
// drop, prefetches rooms over the portal graph by time-to-reach (portal_graph.hpp), cancels what
// falls out of the horizon, decodes rooms on worker threads and keeps them in a RoomStore bounded
// in memory. The protocol itself is a sans-I/O core (conversation.hpp, tested without sockets);
// a Stream is its transport: connect, read, write, timers, decode workers. grotto-client renders
// what it delivers and grotto-load measures it, so what the load tool reports is what players get.
//
// Thread safety: every public member function may be called from any thread. The network runs on
// a Runtime's I/O threads (one strand per Stream), decoding on its worker threads; many Streams
// may share one Runtime (grotto-load runs hundreds).
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/stream/area.hpp"
#include "client/stream/options.hpp"
#include "client/stream/portal_graph.hpp"
#include "client/stream/room_store.hpp"
#include "client/stream/url.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "proto/messages.hpp"

namespace grotto::stream {

// I/O threads and decode workers, shared by the Streams created with it. Destroy it after them.
class Runtime {
 public:
  // io_threads 0: one; workers 0: one per hardware thread.
  explicit Runtime(int io_threads = 1, int workers = 0);
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;
  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

class Stream {
 public:
  // Validates the options (the url names what is wrong) and starts connecting; never blocks on
  // the network. The Stream uses `runtime`, which must outlive it.
  static Result<std::unique_ptr<Stream>> start(const StreamOptions& options, Runtime& runtime);
  ~Stream();  // stop()
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;

  // The player's pose; the plan follows it (at most every replan_interval).
  void set_pose(const Pose& pose);
  // The server's spawn point, once received (only asked for when no pose was set first).
  std::optional<proto::SpawnPoint> spawn_point() const;

  // A stored room, or nullptr.
  std::shared_ptr<const ReadyRoom> room(cave::RoomId id) const;
  bool ready(cave::RoomId id) const { return room(id) != nullptr; }
  // The descriptor of a room whose frame was received (before or after its decode), or nullopt;
  // a room the store evicted is forgotten here too.
  std::optional<cave::Room> descriptor(cave::RoomId id) const;
  // Rooms stored since the last call, in the order they became ready (rooms evicted before the
  // call are left out). The take_* functions are meant to be drained every frame; undrained
  // samples and evicted ids are capped at the newest 65,536.
  std::vector<std::shared_ptr<const ReadyRoom>> take_new_rooms();
  // Rooms the store evicted since the last call (a renderer frees their GPU buffers).
  std::vector<cave::RoomId> take_evicted();
  // Measurements since the last call.
  std::vector<RoomSample> take_samples();

  StreamStats stats() const;
  StreamState state() const;

  // area_status (area.hpp) over the rooms held now: is everything within radius_m metres of
  // `point`, along the portal graph, decoded at a lod <= max_lod? Only answers: it fetches
  // nothing beyond what the pose's plan (or a wait_area_ready in progress) asks for.
  AreaStatus area_status(Vec3 point, double radius_m, uint32_t max_lod) const;
  // Blocks until area_status(point, radius_m, max_lod).ready, the timeout passes, or the Stream
  // fails or stops; returns whether the area is ready. While it waits the area is pinned
  // (Conversation::pin_area): its rooms are requested ahead of the pose's, wherever the point
  // lies (located with the server when no known room holds it), and are not evicted; when it
  // returns they are ordinary rooms again. A timeout <= 0 only answers. It returns false at once
  // when the session's lod is above max_lod (those rooms never come). It wakes when a room is
  // stored, not by polling, and holds no lock while it waits.
  bool wait_area_ready(Vec3 point, double radius_m, uint32_t max_lod,
                       std::chrono::milliseconds timeout) const;
  // Closes the connection (normal close) and stops reconnecting. Idempotent; returns when the
  // Stream's handlers have finished.
  void stop();

  struct Impl;

 private:
  explicit Stream(std::shared_ptr<Impl> impl);
  std::shared_ptr<Impl> impl_;
};

}  // namespace grotto::stream
