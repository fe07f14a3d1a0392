// Grotto's streaming client for game engines (the installed library Grotto::stream).
//
// A grotto::Stream is one connection to a grotto-server: it follows the player's pose, asks for
// the cave rooms the player could reach within a few seconds (prefetch over the portal graph),
// cancels what falls behind, decodes rooms on worker threads and hands them over as plain arrays
// ready to upload to a GPU. It reconnects by itself after a drop. The C interface over the same
// library is grotto_stream.h; docs/INTEGRATION.md walks through embedding it.
//
// This header is the whole C++ interface, and it includes only the standard library: the
// network (Boost.Beast), the room codec (Draco) and logging stay inside the shared library, whose
// only exported symbols are the ones declared here and in grotto_stream.h. Standard types
// (std::string, std::vector, std::shared_ptr) cross the library's boundary, so the game must use
// the same C++ standard library ABI as the library (on Debian: g++ or clang++ with libstdc++);
// the C interface has no such condition.
//
// Threading: every function of a Stream may be called from any thread, concurrently; each takes
// a mutex for microseconds (wait_area_ready sleeps without holding it). The Stream runs one
// network thread and `decode_threads` decoding threads of its own; nothing runs on the caller's
// threads and no callback is ever made.
//
// Ownership: a Room is immutable and shared (RoomPtr): its arrays stay valid for as long as the
// caller holds the pointer, even after the Stream evicts the room or is destroyed.
//
// Errors: no function throws, except std::bad_alloc when memory runs out. start() returns
// nullptr with the reason; a running Stream never fails a call, it reports its state and its
// last error in stats().
//
// Coordinates: world space in metres, y up, as doubles (the cave is unbounded: far from the
// origin float32 loses millimetres). Vertex positions are floats relative to their room's origin.
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#if defined(__GNUC__) || defined(__clang__)
#define GROTTO_STREAM_API __attribute__((visibility("default")))
#else
#define GROTTO_STREAM_API
#endif

namespace grotto {

// A point or direction in world space, metres.
struct Vec3d {
  double x = 0, y = 0, z = 0;
};

// A room's id in its 64-bit form (proto/PROTOCOL.md "Room ids"): a key for the caller's maps.
// Room::id holds the text form ("0.0.0.r3"), room_name() makes it from a key.
using RoomKey = uint64_t;

// One portal of a room: a disc shared with the neighbouring room, bit for bit on both sides.
struct Portal {
  RoomKey neighbour = 0;
  Vec3d centre;  // world space
  Vec3d normal;  // unit, pointing out of this room into the neighbour
  double radius = 0;
};

// One decoded room. Vertex i lies at origin + (positions[3i], positions[3i+1], positions[3i+2]),
// computed in double. Every array holds vertex_count() entries of its width; every index is below
// vertex_count(). The mesh is closed except at its portals, where its rim matches the
// neighbour's rim exactly, so rooms meet without cracks. Triangles face into the cave.
struct Room {
  RoomKey key = 0;
  std::string id;               // text form of key, e.g. "0.0.0.r3"
  uint32_t lod = 0;             // the wire lod (0: the streamed patch mesh; see StreamConfig::lod)
  Vec3d origin;                 // on the world grid
  Vec3d centre;                 // the room's sphere, which holds every vertex (plus a little noise)
  double radius = 0;            // metres
  std::vector<Portal> portals;  // sorted by neighbour
  std::span<const float> positions;   // 3 per vertex: metres from origin
  std::span<const float> normals;     // 3 per vertex: unit, pointing into the cave
  std::span<const float> roughness;   // 1 per vertex, 0-1: the rock's detail channel
  std::span<const float> mineral;     // 1 per vertex, 0-1: mineral veins
  std::span<const uint32_t> indices;  // 3 per triangle

  size_t vertex_count() const { return positions.size() / 3; }
  size_t triangle_count() const { return indices.size() / 3; }
};
using RoomPtr = std::shared_ptr<const Room>;

// What a Stream is started with. Brace-init plus a url is a working configuration.
struct StreamConfig {
  std::string url;               // required: ws://host:port[/path] (path default /ws); no TLS
  std::optional<uint64_t> seed;  // the world wanted; absent: the one the server serves by default
  std::string token;             // the deployment's shared secret, if it has one
  std::string name = "grotto-engine";  // shown in the server's logs
  // Wire lod: 0 is the streamed patch mesh (a few hundred vertices a room, meant for GPU
  // tessellation); 1 the detail mesh, when the server offers it (else 0). One lod for the whole
  // session: rooms of different lods do not share rims.
  uint32_t lod = 0;
  double horizon_s = 4.0;  // rooms reachable within this many seconds of walking are fetched
  // The horizon adapts to how long the rooms due within a second take to come (1 s + 2 x their
  // recent p90), between min(min_horizon_s, horizon_s) and horizon_s, starting at the floor:
  // the default. 0: a fixed horizon of horizon_s.
  double min_horizon_s = 1.5;
  size_t memory_budget_bytes = size_t{256} << 20;  // decoded rooms held (a patch room: 20-100 KB)
  int decode_threads = 0;                          // 0: two; at most 64
};

// Where the player is. The Stream fetches what is reachable from here within the horizon.
struct Pose {
  Vec3d position;
  Vec3d forward{0, 0, -1};  // view direction, any length; zero: no preference. Rooms behind the
                            // player count up to twice as far.
  double speed = 4.0;       // m/s, for time-to-reach; below 0.5 counts as 0.5
};

// Where the server suggests the player starts (asked for when no pose was set first).
struct SpawnPoint {
  RoomKey room = 0;
  Vec3d position;
};

enum class StreamState {
  kConnecting,  // connecting, or waiting for the server's welcome
  kReady,       // connected: requesting and receiving rooms
  kBackoff,     // the connection dropped; reconnecting after a delay (rooms held stay usable)
  kFailed,      // the server refused this client for good (version, world, token): see last_error
  kStopped,     // stop() was called
  // Connected and waiting in the server's admission queue: the server is past its capacity and
  // lets newcomers in as players leave or it catches up (proto/PROTOCOL.md "Waiting to enter").
  // A Stream always offers to wait (hello.queue), so a full server tells it its place instead of
  // refusing it (a refusal, when even the queue is full: kBackoff, retrying after the server's
  // retry_after_ms). No spawn point and no rooms come meanwhile (a wait_area_ready may reach its
  // timeout); StreamStats::queued says where the stream stands. Then kReady, as after any
  // welcome. Last, so that the values before it keep theirs.
  kQueued,
};

// Counters since start() (reconnects do not reset them) and figures of now.
struct StreamStats {
  StreamState state = StreamState::kConnecting;
  uint64_t connects = 0;         // connections welcomed by a server
  uint64_t reconnects = 0;       // connections after the first
  uint64_t rooms_received = 0;   // room frames accepted
  uint64_t rooms_ready = 0;      // rooms decoded and held
  uint64_t rooms_rejected = 0;   // frames or payloads refused as corrupt (asked for again)
  uint64_t rooms_evicted = 0;    // rooms dropped to stay within memory_budget_bytes
  uint64_t bytes_received = 0;   // bytes of every message
  uint64_t in_flight = 0;        // rooms requested and not yet received (now)
  uint64_t rooms_held = 0;       // rooms held (now)
  uint64_t memory_bytes = 0;     // what they take (now)
  double horizon_s = 0;          // the prefetch horizon in use (now)
  std::optional<uint64_t> seed;  // the world served, once welcomed
  std::string last_error;        // the last error, for people; empty when none
  // Where the stream stands in the server's admission queue, as the server last said (it says
  // again when the place or the estimate changes, at most about once a second); set exactly while
  // state is kQueued. A player waits here instead of being refused, so the game should say so
  // rather than show a bare loading screen, e.g. "waiting to enter: 14th, about 20 s"
  // (position, and wait_ms in whole seconds).
  struct QueuePlace {
    uint32_t position = 0;  // 1-based: 1 enters next
    uint32_t length = 0;    // sessions waiting, this one included
    uint32_t wait_ms = 0;   // the server's estimate of the wait, from the rate it lets players in
  };
  std::optional<QueuePlace> queued;
  uint64_t times_queued = 0;  // connections that waited in the queue before their welcome
  double queued_ms = 0;       // time spent queued since start(), the current wait included
};

class GROTTO_STREAM_API Stream {
 public:
  // Checks `config` and starts connecting; never blocks on the network. Returns nullptr when the
  // configuration is invalid (the url does not parse, a number is out of range), with the reason
  // in *error when error is not null. A server that cannot be reached is no error here: the
  // Stream keeps trying (stats().state, stats().last_error).
  static std::unique_ptr<Stream> start(const StreamConfig& config, std::string* error = nullptr);
  // Stops (stop()) and joins the Stream's threads. Rooms the caller holds stay valid. No other
  // thread may be inside a call on this Stream: call stop() first, which makes a
  // wait_area_ready in another thread return at once, and let that call return.
  ~Stream();
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;

  // The player's pose; call it every frame or on every move. The fetch plan follows it at most
  // every 100 ms. Until a pose is set, the Stream asks the server for a spawn point and uses it.
  void set_pose(const Pose& pose);
  // The server's spawn point, once received (only asked for when no pose was set first).
  std::optional<SpawnPoint> spawn_point() const;

  // Rooms decoded since the last call, in the order they became ready: upload these. Drain it
  // every frame: at most the newest 65,536 wait here.
  std::vector<RoomPtr> poll_rooms();
  // Rooms evicted since the last call (to stay within memory_budget_bytes): free their GPU
  // buffers. A room is evicted only when it is outside the current fetch plan.
  std::vector<RoomKey> poll_evicted();
  // A room held now, or nullptr.
  RoomPtr room(RoomKey key) const;

  StreamStats stats() const;

  // Whether the ground exists around `point`: the room that holds it and every room within
  // radius_m metres of it along the portal graph (through portal centres) are held, at a lod
  // <= max_lod. False while no room holding `point` has arrived. Only answers: it fetches
  // nothing, so by itself it sees the rooms the pose's fetch plan brings (within horizon_s of
  // walking from the pose) and those of a wait_area_ready in progress. radius_m < 0 or NaN
  // counts as 0.
  bool area_ready(Vec3d point, double radius_m, uint32_t max_lod = 255) const;
  // The same, fetching the area and waiting up to `timeout` for it: returns true as soon as it
  // is complete, false at the timeout, and false at once when the Stream has failed or stopped
  // or when max_lod is below the session's lod (StreamConfig::lod, capped by the server: rooms
  // come at that lod only, so the area could never complete).
  //   What it fetches: while it waits, the area is pinned. The Stream asks the server which room
  // holds `point` (when no room it knows does), then requests that room and, ring by ring as
  // their portals arrive, every room within radius_m of `point`, whether or not the pose is
  // near: a teleport target, another player's spawn, an area larger than the horizon. These
  // requests go ahead of the pose's (they share the connection's cap on rooms in flight, so the
  // pose's prefetch slows while the area loads), and the rooms are handed out by poll_rooms like
  // any other. The call itself does not block the Stream, and any number of threads may wait at
  // once, for the same area or different ones.
  //   Memory: a pinned area's rooms are never evicted, so an area larger than
  // memory_budget_bytes holds the Stream over its budget until the wait returns. Once it
  // returns, whatever the result, the area is unpinned and its rooms are ordinary: evicted when
  // over budget and away from the pose, and those still in flight are cancelled unless the
  // pose's plan wants them. A game that wants to keep an area should set the pose there.
  //   Time: the area's rooms take a round trip per ring of rooms plus the server's generation
  // time (on a local server, about 100-300 ms for an 8 m area 100 m away); a point in rock or
  // outside the world is never ready, and the call runs to its timeout. timeout <= 0 only
  // answers, as area_ready does, and fetches nothing. Wakes on every room stored (no polling),
  // holds no lock while it sleeps; a game holds its spawn on it.
  bool wait_area_ready(Vec3d point, double radius_m, uint32_t max_lod,
                       std::chrono::milliseconds timeout) const;

  // Closes the connection and stops reconnecting; returns within about 3 s (a server that does
  // not answer the close). Idempotent. Rooms already held stay readable through room().
  void stop();

  struct Impl;

 private:
  explicit Stream(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The text form of a room key ("0.0.0.r3"); "" when `key` is no valid room id.
GROTTO_STREAM_API std::string room_name(RoomKey key);
// "connecting", "ready", "backoff", "failed", "stopped", "queued".
GROTTO_STREAM_API const char* state_name(StreamState state);

// The library logs one key=value line per event (a drop, a reconnect, a refusal) through spdlog's
// default logger: stdout, level info, unless the process configured spdlog otherwise. Sets that
// logger's level: "trace", "debug", "info", "warn", "error" or "off"; false (and no change) for
// anything else. Process-wide: it is the level of every Stream, and of the game's own spdlog
// logging if the game uses the same shared libspdlog. Thread-safe.
GROTTO_STREAM_API bool set_log_level(std::string_view level);

}  // namespace grotto
