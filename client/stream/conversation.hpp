// client/stream's protocol core, sans-I/O (as h11, quinn-proto and rustls are): one connection's
// worth of proto/PROTOCOL.md from the client's side, and what survives reconnects (the rooms held,
// the failure counts, the backoff). It is fed events (the connection opened, a text or binary
// message arrived, the connection closed or was lost, a decode finished, a timer ticked, the pose
// moved) and answers each with actions for the I/O layer (send this message, decode this frame,
// drop the connection and reconnect after a delay, stop for good). It never touches a socket, a
// thread or a clock: every event carries `now`, and backoff jitter comes from a seeded generator.
// Beast-, Asio- and OpenCL-free; tests/client/conversation_test.cpp drives it by tables.
//
// What it owns: the handshake (hello; welcome's version, seed, params and limits), the one ledger
// of rooms in flight (requested and not yet delivered, refused or cancelled; within
// max_rooms_in_flight and max_rooms_per_request), the prefetch plan over the portal graph
// (portal_graph.hpp) that drives requests and cancels, frame acceptance (a frame for a room not in
// flight, or at another lod than requested, is not used), the failure and reconnect policy, and
// the decoded rooms (room_store.hpp), and the pinned areas: areas a caller waits for
// (Stream::wait_area_ready), whose rooms are requested ahead of the pose's and never evicted.
//
// One lod a session: rooms of lod 0 next to rooms of lod 1 do not share rims (PROTOCOL.md
// "Levels of detail"), so every room requested or held is at lod() = min(options.lod,
// welcome.limits.max_lod). When a welcome changes it, every room held is evicted and the
// neighbourhood is asked for again at the new lod.
//
// Not thread-safe: the I/O layer serializes calls (Stream holds a mutex on its strand).
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "client/stream/options.hpp"
#include "client/stream/portal_graph.hpp"
#include "client/stream/room_store.hpp"
#include "common/cave/room_id.hpp"
#include "common/codec/room_codec.hpp"
#include "common/core/result.hpp"
#include "proto/messages.hpp"
#include "proto/room_frame.hpp"

namespace grotto::stream {

using SteadyTime = std::chrono::steady_clock::time_point;

// ---- actions: what the I/O layer does next, in order ----

// Send one control message (serialize it with proto::serialize, one text frame).
struct SendMessage {
  proto::ClientMessage message;
};
// Decode a frame's payload off the I/O thread (decode_payload below) and hand the result back
// with Conversation::decoded().
struct DecodeRoom {
  proto::RoomFrame frame;
  codec::DecodeLimits limits;  // limits.normals: the frame's version carries them
  RoomSample sample;           // latency and size filled; decode_ms is the decoder's to measure
  uint64_t epoch = 0;  // the world the frame belongs to (a decode finishing later may be stale)
  // When the player can reach the room (the request's time + its priority): decodes waiting for
  // a worker go earliest due first (decode_queue.hpp).
  SteadyTime due;
};
// What carrying out DecodeRoom means: codec::decode_room with the job's limits, then, for a
// version 2 payload, codec::derive_normals from the frame's origin and portal discs. Pure and
// thread-safe; the errors are decode_room's.
Result<codec::DecodedRoom> decode_payload(const DecodeRoom& job);
// Read messages of up to this many bytes from now on (welcome's max_frame_bytes and
// max_message_bytes).
struct SetReadLimit {
  size_t bytes = 0;
};
// Drop the connection (no close handshake needed) and connect again after `delay`; then call
// connecting() and, once upgraded, opened().
struct Reconnect {
  std::chrono::milliseconds delay{0};
  std::string why;
};
// Drop the connection and never reconnect: the server refuses this client as configured.
struct Fail {
  std::string why;
};
using Action = std::variant<SendMessage, DecodeRoom, SetReadLimit, Reconnect, Fail>;
using Actions = std::vector<Action>;

// An area a caller waits for (Stream::wait_area_ready). While it is pinned, every plan requests
// its rooms: area_rooms (area.hpp) from the room holding `point`, found among the rooms known
// (PortalGraph::room_at) or else by asking the server (`locate`, once a connection; a point in
// rock or beyond the sector range stays unlocated). They go ahead of the pose's rooms, with
// priority 0, within the same cap on rooms in flight; they are not cancelled and the store never
// evicts them (so a pinned area larger than store_bytes holds the store over its budget). They
// are requested at the session's lod(): an area with max_lod below it cannot be ready in this
// session and fetches nothing. Once unpinned (or past its deadline) its rooms are ordinary again:
// the next plan cancels those in flight outside the pose's plan, and the store may evict them.
struct AreaPin {
  Vec3 point;
  double radius_m = 0;   // area_rooms's radius: below 0 or NaN, the room holding point alone
  uint32_t max_lod = 0;  // as area_status's
  SteadyTime deadline;   // the pin lapses at the first tick or plan at or after it
};

// One room of the ledger.
struct InFlightRoom {
  SteadyTime sent;
  uint32_t lod = 0;
  uint32_t priority = 0;
  uint64_t ref = 0;  // of the request that named it
};

// WebSocket close codes the protocol names (PROTOCOL.md "Transport").
inline constexpr uint16_t kCloseNormal = 1000;
inline constexpr uint16_t kCloseGoingAway = 1001;  // service_restart
inline constexpr uint16_t kClosePolicy = 1008;     // unauthorized, fatal protocol errors
inline constexpr uint16_t kCloseTooBig = 1009;     // a message over max_message_bytes
inline constexpr uint16_t kCloseInternal = 1011;

// Errors no reconnect can cure: the server refuses this client as it is configured.
bool is_final_error(ErrorCode code);

class Conversation {
 public:
  // `options` as validated by Stream::start (url unused here). `jitter_seed` seeds the backoff's
  // jitter, so a test can replay it.
  Conversation(const StreamOptions& options, uint64_t jitter_seed);

  // ---- connection events ----

  // The I/O layer starts a connection attempt (resolve, TCP, upgrade). State: kConnecting.
  void connecting();
  // The WebSocket upgrade succeeded: sends hello. The welcome must come within connect_timeout.
  Actions opened(SteadyTime now);
  // One text message (a control message, parsed here under welcome's limits).
  Actions text(std::string_view message, SteadyTime now);
  // One binary message (a room frame).
  Actions binary(std::span<const uint8_t> frame, SteadyTime now);
  // The server closed the connection with this close code and reason.
  Actions closed(uint16_t code, std::string_view reason, SteadyTime now);
  // The connection failed or broke without a close frame (resolve, connect, upgrade, read,
  // write errors): `why` says which, for people.
  Actions lost(std::string_view why, SteadyTime now);
  // A DecodeRoom action finished.
  Actions decoded(DecodeRoom job, Result<codec::DecodedRoom> mesh, SteadyTime now);
  // Periodic work (every replan_interval while a connection is open): the welcome deadline,
  // rooms in flight longer than request_timeout, the end of an overload hold, replanning after a
  // pose change, pings before idle_timeout_ms.
  Actions tick(SteadyTime now);
  // The player's pose; the plan follows at the next tick.
  void set_pose(const Pose& pose);
  // stop() was called: no further actions; state kStopped unless kFailed.
  void stop();
  // Pins an area (AreaPin) until unpin_area(handle) or its deadline; the plan follows at the
  // next tick, as for set_pose. Returns its handle, never 0. Pins survive reconnects (they are
  // located again on the new connection) and world changes.
  uint64_t pin_area(const AreaPin& pin);
  // Unpins it (an unknown handle: nothing). Its rooms stop being kept now; in-flight ones
  // outside the pose's plan are cancelled at the next tick.
  void unpin_area(uint64_t handle);

  // ---- what it knows ----

  StreamState state() const { return stats_.state; }
  bool welcomed() const { return welcomed_; }
  StreamStats stats()
      const;  // in_flight and store figures filled in (queued_ms as of the last event)
  const proto::Limits& limits() const { return limits_; }
  // The lod every room of this session is requested and held at.
  uint32_t lod() const { return lod_; }
  const std::map<cave::RoomId, InFlightRoom>& in_flight() const { return in_flight_; }
  const std::set<cave::RoomId>& given_up() const { return given_up_; }
  const std::set<cave::RoomId>& wanted() const { return wanted_; }
  // The rooms of the pinned areas as of the last plan (or unpin): requested ahead of wanted(),
  // never cancelled or evicted.
  const std::set<cave::RoomId>& pinned() const { return pinned_; }
  size_t pinned_areas() const { return pins_.size(); }
  std::optional<proto::SpawnPoint> spawn_point() const { return spawn_; }
  std::shared_ptr<const ReadyRoom> room(cave::RoomId id) const { return store_.find(id); }
  const RoomStore& store() const { return store_; }
  const PortalGraph& graph() const { return graph_; }
  std::vector<std::shared_ptr<const ReadyRoom>> take_new_rooms();
  std::vector<cave::RoomId> take_evicted();
  std::vector<RoomSample> take_samples();

  // The reconnect delay after `attempt` failed attempts: backoff_initial x 2^attempt, capped at
  // backoff_max, times a jitter in [0.5, 1) ("equal jitter").
  std::chrono::milliseconds backoff_delay(int attempt);
  // The reconnect delay after service_restart: uniform in [backoff_initial / 2, restart_spread].
  std::chrono::milliseconds restart_delay();

 private:
  void on_message(const proto::Welcome& w, SteadyTime now, Actions& out);
  void on_message(const proto::Located& l, SteadyTime now, Actions& out);
  void on_message(const proto::SpawnPoint& s, SteadyTime now, Actions& out);
  void on_message(const proto::ErrorMessage& e, SteadyTime now, Actions& out);
  void on_message(const proto::Pong&, SteadyTime, Actions&) {}
  void on_message(const proto::Stats&, SteadyTime, Actions&) {}
  void on_message(const proto::Queued& q, SteadyTime now, Actions& out);
  void leave_queue(SteadyTime now);  // the queued time so far into stats_.queued_ms

  void plan(SteadyTime now, Actions& out);
  // The pinned areas' rooms, nearest first (fills pinned_); with `out`, asks the server where a
  // pinned point lies when no known room holds it.
  std::vector<PlannedRoom> plan_areas(SteadyTime now, Actions* out);
  bool expire_pins(SteadyTime now);  // drops pins past their deadline; whether any went
  // StreamOptions::min_horizon_s: from recent_latency_ms_ and what is in flight at `now`.
  double horizon_s(SteadyTime now) const;
  void send(proto::ClientMessage message, SteadyTime now, Actions& out);
  uint32_t batch_size() const;
  void count_failure(cave::RoomId id);
  void give_up(cave::RoomId id);
  void note_error(const std::string& message);
  void drop_rooms_held(const char* why);  // every stored room to the evicted list
  // The connection ends: forget what was in flight on it and reconnect after a backoff (the
  // shortest one for a service_restart), unless the state is final.
  void reconnect(const std::string& why, bool restart, Actions& out);
  void fail(const std::string& why, Actions& out);
  void end_connection();

  const StreamOptions options_;
  std::mt19937_64 rng_;

  // This connection.
  bool open_ = false;
  bool welcomed_ = false;
  uint32_t version_ = proto::kProtocolVersion;  // what welcome chose
  SteadyTime opened_at_;
  SteadyTime last_send_;
  SteadyTime hold_until_;  // after overloaded or limit_exceeded: no requests before this
  std::optional<SteadyTime> queued_since_;  // this connection waits in the admission queue
  // error.retry_after_ms of the last fatal overloaded: the next reconnect waits at least this.
  std::chrono::milliseconds retry_after_{0};
  SteadyTime last_locate_;
  std::string fatal_;  // the fatal error the server sent before closing, if any
  std::map<cave::RoomId, InFlightRoom> in_flight_;
  std::map<uint64_t, std::vector<cave::RoomId>> pending_;  // request ref -> its rooms

  // Across connections.
  proto::Limits limits_;                                // the last welcome's, or defaults
  uint32_t lod_ = 0;                                    // min(options.lod, limits_.max_lod)
  std::optional<std::pair<uint64_t, uint64_t>> world_;  // (seed, params) of the last welcome
  uint64_t epoch_ = 0;                                  // bumped when the rooms held are dropped
  uint64_t next_ref_ = 1;
  int attempts_ = 0;  // failed connections since the last welcome
  Pose pose_;
  bool pose_set_ = false;
  bool pose_from_spawn_ = false;  // the pose is the server's spawn point, not the caller's
  bool pose_dirty_ = false;
  std::optional<proto::SpawnPoint> spawn_;
  std::optional<cave::RoomId> current_;
  PortalGraph graph_;
  RoomStore store_;
  std::set<cave::RoomId> decoding_;
  std::map<cave::RoomId, int> failures_;
  std::set<cave::RoomId> given_up_;
  std::set<cave::RoomId> wanted_;  // the last plan, within the horizon
  struct PinnedArea {
    AreaPin pin;
    std::optional<cave::RoomId> located;  // the server's answer to our locate
    bool asked = false;                   // a locate was sent on this connection
  };
  std::map<uint64_t, PinnedArea> pins_;  // by handle
  uint64_t next_pin_ = 1;
  std::map<uint64_t, uint64_t> pin_locates_;  // locate ref -> pin handle (this connection)
  std::set<cave::RoomId> pinned_;             // the pinned areas' rooms, as of the last plan
  std::vector<std::shared_ptr<const ReadyRoom>> fresh_;
  std::vector<RoomSample> samples_;
  // The last kLatencyWindow urgent request->room latencies (arrival, ms); those older than
  // kLatencyWindowTime are not used: a crowd's start says nothing about the minutes after it.
  std::deque<std::pair<SteadyTime, double>> recent_latency_ms_;
  static constexpr size_t kLatencyWindow = 32;
  static constexpr std::chrono::seconds kLatencyWindowTime{10};
  // Rooms come in the window before their quickest one is taken for the link's round trip.
  static constexpr size_t kRoundTripSamples = 4;
  // The last kLatencyWindow request->room latencies of every class: the quickest is the link's
  // round trip and a frame's time on it (horizon_s).
  std::deque<std::pair<SteadyTime, double>> recent_any_latency_ms_;
  double horizon_s_ = 0;  // the last plan's
  std::vector<cave::RoomId> evicted_;
  StreamStats stats_;
};

}  // namespace grotto::stream
