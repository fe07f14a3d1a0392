// client/stream's configuration and observable state: what a Stream is started with, the states it
// goes through and the counters it keeps. Plain structs, shared by the Beast-free protocol core
// (conversation.hpp) and the connection (stream.hpp).
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "client/stream/net_sim.hpp"
#include "client/stream/portal_graph.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "proto/messages.hpp"

namespace grotto::stream {

// The adaptive horizon's floor by default (StreamOptions::min_horizon_s): at 10 m/s, 15 m of
// path, the rooms around and in front of a player (docs/BENCHMARKS.md "Capacity").
inline constexpr double kDefaultMinHorizonS = 1.5;
// Requests with a priority (milliseconds to reach) up to this are the urgent class: the server
// takes them first (grotto-server --urgent-ms), and the adaptive horizon follows their latency.
inline constexpr uint32_t kUrgentPriorityMs = 1'000;

// Everything a Stream needs; brace-init plus a url works.
struct StreamOptions {
  std::string url;                     // ws://host:port/ws (path optional, default /ws)
  std::optional<uint64_t> seed;        // the world wanted; absent: the server's
  std::optional<uint64_t> params;      // its parameter digest; absent: the server's
  std::string name = "grotto-stream";  // hello.name, for the server's logs
  std::string token;                   // hello.token (proto/token.hpp); "": none
  // hello.queue: past its capacity the server may hold us in its queue (stats().queued says
  // where) rather than refuse us; false: admitted or refused, overloaded + retry_after_ms.
  bool queue = true;
  // Wire lod requested (0: the streamed patch mesh), capped at the server's max_lod. One lod a
  // session: rooms of lod 0 and lod 1 do not share rims, so neighbours must be of one lod.
  uint32_t lod = 0;
  PlanOptions plan{};  // horizon and view weighting
  // Adaptive prefetch (the default): the horizon follows how long the rooms a player needs soon
  // take to come, 1 s + 2 x the p90 of the last 32 request->room latencies of rooms requested
  // with a priority within kUrgentPriorityMs (reachable within a second; rooms still in flight
  // count with their wait so far), kept within [min(min_horizon_s, plan.horizon_s),
  // plan.horizon_s]; a stream starts at the floor. A healthy server then gets asked for fewer
  // rooms the player may never enter, a uniformly slow one for as many as a fixed horizon asks,
  // and a server busy with everyone's far prefetch is not asked for more of it (its near rooms
  // go first and stay quick, so the horizon stays low and the backlog drains).
  // 0: always plan.horizon_s (the fixed horizon).
  double min_horizon_s = kDefaultMinHorizonS;
  double cancel_factor = 1.5;              // cancel a room in flight once its cost exceeds
                                           // cancel_factor × horizon (or it is unreachable)
  uint32_t max_in_flight = 64;             // own cap; the server's max_rooms_in_flight also applies
  size_t store_bytes = size_t{256} << 20;  // RoomStore budget
  std::chrono::milliseconds backoff_initial{100};  // first reconnect delay (before jitter)
  std::chrono::milliseconds backoff_max{5'000};    // reconnect delays double up to this
  // After service_restart (a drain) the reconnect waits a delay drawn uniformly from
  // [backoff_initial / 2, restart_spread]: the players a drained replica sends away reach the
  // replica taking them over spread across this time instead of in the same 50 ms, which a
  // replica absorbs (docs/BENCHMARKS.md: 300 joins over 2 s, p99 12 ms; at once, 500 ms). The
  // rooms held are kept meanwhile. At least backoff_initial.
  std::chrono::milliseconds restart_spread{1'000};
  std::chrono::milliseconds connect_timeout{5'000};   // TCP connect + upgrade + welcome
  std::chrono::milliseconds request_timeout{30'000};  // a room in flight this long is re-requested
  std::chrono::milliseconds replan_interval{100};     // at most this often on pose changes
  int max_room_failures = 3;  // corrupt or failed deliveries of one room before giving up on it
  bool spawn = true;          // ask the server for a spawn point when no pose was set
  // The protocol version offered in hello: 0 offers every version this library speaks
  // (proto::kMinProtocolVersion..kProtocolVersion, the server picks the highest); 1 or 2 offers
  // that one alone (to measure or test one version against a server that speaks both).
  uint32_t protocol_version = 0;
  // A simulated network between this stream and the server (net_sim.hpp): latency, jitter, a
  // bandwidth cap on what it receives, stalls. Zero: the real network as it is.
  NetProfile net{};
};

// Whether Stream::start would take `options`: the url parses (url.hpp), the horizon is a positive
// number of seconds, min_horizon_s >= 0 (any floor: one above the horizon makes it fixed),
// cancel_factor >= 1, max_in_flight >= 1, 1 ms <= backoff_initial <=
// backoff_max, restart_spread >= backoff_initial, connect_timeout, request_timeout and
// replan_interval >= 1 ms, max_room_failures >= 1, lod <= 255, protocol_version 0 or one this
// library speaks, and the token, when there is one, is what proto/token.hpp accepts. Errors
// (kInvalidArgument) name the option.
Status validate_options(const StreamOptions& options);

enum class StreamState {
  kConnecting,  // TCP, upgrade, hello sent, waiting for welcome
  kReady,       // welcome received: requesting and receiving rooms
  kBackoff,     // dropped; waiting to reconnect
  kFailed,      // stopped for good: the server refused us (version, world, credentials)
  kStopped,     // stop() was called
};
const char* state_name(StreamState state);

// Counters since the Stream started (never reset by reconnects).
struct StreamStats {
  uint64_t connects = 0;        // welcomes received
  uint64_t reconnects = 0;      // connections after the first
  uint64_t drops = 0;           // connections lost or attempts failed (resolve, connect,
                                // upgrade, read/write error, close, fatal error)
  uint64_t requests_sent = 0;   // rooms named in request messages
  uint64_t cancels_sent = 0;    // rooms named in cancel messages
  uint64_t rooms_received = 0;  // room frames accepted (header valid)
  uint64_t rooms_ready = 0;     // rooms decoded and stored
  uint64_t rooms_rejected = 0;  // frames or payloads refused (corrupt, inconsistent, unasked)
  uint64_t rooms_evicted = 0;   // rooms the store evicted
  uint64_t rooms_given_up = 0;  // rooms abandoned after max_room_failures or not_found
  uint64_t bytes_received = 0;  // bytes of all frames, text and binary
  uint64_t in_flight = 0;       // rooms requested and not yet received (now)
  uint64_t store_bytes = 0;     // RoomStore bytes (now)
  uint64_t store_rooms = 0;     // rooms in the store (now)
  std::map<std::string, uint64_t> errors;  // error messages received, by wire code
  // `service_restart` messages: the server is draining and will close; we reconnect at once,
  // possibly to another replica, and ask again. A notice, not counted in `errors`.
  uint64_t restart_notices = 0;
  StreamState state = StreamState::kConnecting;
  std::string last_error;        // the last error, for people (empty when none)
  std::string server;            // welcome.server of the current or last connection
  std::optional<uint64_t> seed;  // welcome.seed: the world served (none before a welcome)
  proto::Limits limits;          // welcome.limits of the current or last connection
  double horizon_s = 0;          // the prefetch horizon in use (StreamOptions::min_horizon_s)
  // Waiting in the server's admission queue (state kConnecting, hello answered by `queued`
  // rather than welcome): the last place the server gave. None when not queued.
  struct QueuePlace {
    uint32_t position = 0;  // 1-based
    uint32_t wait_ms = 0;   // the server's estimate
    uint32_t queue = 0;     // sessions waiting
  };
  std::optional<QueuePlace> queued;
  uint64_t times_queued = 0;  // connections that waited in the queue before their welcome
  double queued_ms = 0;       // time spent queued, all connections (the current wait included)
};

// Per-room measurements, for grotto-load's percentiles; drained by take_samples().
struct RoomSample {
  cave::RoomId id = cave::RoomId::interior({}, 0);
  double latency_ms = 0;     // request sent → room frame received
  uint32_t priority_ms = 0;  // the request's priority: <= kUrgentPriorityMs is the urgent class
  double decode_ms = 0;      // decode on a worker
  size_t frame_bytes = 0;
};

}  // namespace grotto::stream
