// One client's side of the protocol (proto/PROTOCOL.md) as a plain state machine, in the manner
// of sans-I/O protocol cores (h11, quinn-proto): the session feeds it events (the upgrade's
// admission, a text message, a binary message, a message over the size limit, the timer firing,
// a room delivered by the generator, a write completed, shutdown) and carries out the actions it
// returns (send a text or a room, ask the generator for rooms or drop them, arm the timer, close
// with a code). The handshake, the token, the choice of world, the single in-flight ledger, the
// limits and every error and close code live here; the session only moves bytes and timers.
//
// No sockets, no Asio, no Beast, no OpenCL: tests drive it with tables of events and actions.
// Not thread-safe: one conversation is fed from one strand.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <variant>
#include <vector>

#include "proto/messages.hpp"
#include "server/rooms.hpp"

namespace grotto::server {

class Metrics;

// RFC 6455 close codes the server sends (PROTOCOL.md, "Closing").
enum class CloseCode : uint16_t {
  kNormal = 1000,
  kGoingAway = 1001,  // service_restart
  kPolicy = 1008,     // every other fatal error, and slow_client
  kTooBig = 1009,     // a message over max_message_bytes
};

// The close code that follows a fatal error of this code.
CloseCode close_code_for(ErrorCode code);

// What the server's admission (server/admission.hpp) says about a hello that passed its checks.
struct Entry {
  enum class Kind { kAdmitted, kQueued, kRefused };
  Kind kind = Kind::kAdmitted;
  uint32_t position = 0;        // kQueued: 1-based
  uint32_t wait_ms = 0;         // kQueued: estimated
  uint32_t queue = 0;           // kQueued: sessions waiting
  uint32_t retry_after_ms = 0;  // kRefused
  bool queue_full = false;      // kRefused: the queue was full (else the client cannot wait)
};

// What a conversation needs answered at once about worlds (the generator, behind the session).
class WorldPort {
 public:
  virtual ~WorldPort() = default;
  // A valid hello asks to enter; `can_queue` is hello.queue. Admitted: open() follows at once;
  // queued: Conversation::admitted() or queue_update() come later.
  virtual Entry enter(bool can_queue) {
    (void)can_queue;
    return {};
  }
  virtual uint64_t own_seed() const = 0;
  // A client of world `seed`, whose deliveries reach Conversation::delivery as frames of protocol
  // `version`. Errors: world_mismatch, overloaded (PROTOCOL.md's hello checks).
  virtual Result<ClientId> open(uint64_t seed, uint32_t version) = 0;
  virtual std::optional<cave::RoomId> locate(ClientId client, Vec3 point) = 0;
  virtual cave::Spawn spawn(ClientId client) = 0;
};

// The actions a conversation returns, carried out by the session in order.
namespace act {
struct SendText {  // a control message (JSON text frame)
  std::string text;
  friend bool operator==(const SendText&, const SendText&) = default;
};
struct SendRoom {  // a room frame (binary), shared with the cache
  RoomPtr room;
  // When the player can reach the room (steady ms: its request's arrival + priority): the send
  // queue puts frames due sooner first (send_queue.hpp).
  uint64_t due_ms = 0;
  friend bool operator==(const SendRoom&, const SendRoom&) = default;
};
struct Want {  // Generator::request, in this order (sorted by priority, stable)
  ClientId client = 0;
  std::vector<server::Want> rooms;
  friend bool operator==(const Want&, const Want&) = default;
};
struct Drop {  // Generator::cancel
  ClientId client = 0;
  std::vector<cave::RoomId> rooms;
  friend bool operator==(const Drop&, const Drop&) = default;
};
struct Release {  // Generator::remove_client: nothing more is wanted for this client
  ClientId client = 0;
  friend bool operator==(const Release&, const Release&) = default;
};
struct Timer {  // (re)arm the one timer: deadline() is called when it fires
  std::chrono::milliseconds after{0};
  friend bool operator==(const Timer&, const Timer&) = default;
};
struct Pace {  // (re)arm the bandwidth timer: pace() is called when it fires
  std::chrono::milliseconds after{0};
  friend bool operator==(const Pace&, const Pace&) = default;
};
struct Close {  // close with this code and reason once what is queued before it has been sent
  CloseCode code = CloseCode::kNormal;
  std::string reason;
  // Wait for the client's close frame (up to the HTTP timeout) before closing TCP. False after
  // `timeout`: a client silent that long, or stopped in the middle of a frame (inside which its
  // close frame would be read as payload), is not worth the wait; the session waits a short
  // grace instead (PROTOCOL.md, Closing).
  bool await_reply = true;
  friend bool operator==(const Close&, const Close&) = default;
};
}  // namespace act
using Action = std::variant<act::SendText, act::SendRoom, act::Want, act::Drop, act::Release,
                            act::Timer, act::Pace, act::Close>;

struct ConversationConfig {
  proto::Limits limits;
  std::string token;  // the deployment's shared secret; empty: none required
  uint64_t params_digest = 0;
  std::string server_name;              // welcome.server
  int max_connections = 0;              // named in the connection-limit error
  int max_handshakes = 0;               // named in the handshake-pool error
  std::function<uint64_t()> unix_ms;    // pong.time; null: the system clock
  std::function<uint64_t()> steady_ms;  // the request rate's and max_kbps's clock; null: steady
  uint64_t session = 0;                 // for log lines
  std::string peer;                     // for log lines
};

// Whether the server took the connection when its upgrade completed.
// kFull: max_connections players; kHandshakesFull: max_handshakes connections awaiting hello.
enum class Admission { kAdmitted, kFull, kHandshakesFull, kStopping };

class Conversation {
 public:
  enum class State {
    kNew,            // upgraded, not yet admitted
    kAwaitingHello,  // admitted; the handshake timer runs
    kQueued,         // a valid hello waits in the admission queue: only ping is answered
    kOpen,           // welcome sent; the idle timer runs
    kClosed,         // a close was returned, or the transport is gone: no more actions but none
  };

  // `metrics` may be null (tests).
  Conversation(ConversationConfig config, WorldPort& worlds, Metrics* metrics);

  // ---- events ----
  void admit(Admission admission);
  void text(std::string_view message);  // one whole text message
  void binary();                        // the client sent a binary message
  void oversized();                     // a message grew past max_message_bytes (not read whole)
  void deadline();                      // the timer fired
  void pace();                          // the bandwidth timer fired (act::Pace)
  void delivery(Delivery d);            // the generator's outcome for one wanted room
  void sent(uint64_t bytes);            // a message's write completed (stats.bytes_sent)
  void shutdown();                      // the server is stopping
  void slow_client(size_t queued_bytes = 0);  // the send queue went over its bound
  void transport_closed();                    // the socket is gone: release what is held
  void admitted();  // the admission queue let this queued session in: the world, then welcome
  void queue_update(uint32_t position, uint32_t wait_ms, uint32_t queue);  // a new place

  // The actions since the last call, in order.
  std::vector<Action> take();

  State state() const { return state_; }
  size_t in_flight() const { return in_flight_.size(); }
  size_t waiting_for_bandwidth() const { return waiting_; }
  uint64_t rooms_sent() const { return rooms_sent_; }
  uint64_t errors_sent() const { return errors_sent_; }

 private:
  struct InFlight {
    uint32_t lod = 0;
    uint32_t priority = 0;
    proto::Ref ref;       // of the request that named it, copied into an error about the room
    uint64_t due_ms = 0;  // steady_ms of the latest request naming it + its priority
    RoomPtr ready;        // built, waiting for bandwidth (Limits::max_kbps); it is still in flight
  };

  void on(const proto::Hello& m);
  void on(const proto::Locate& m);
  void on(const proto::Spawn& m);
  void on(const proto::Request& m);
  void on(const proto::Cancel& m);
  void on(const proto::Ping& m);
  void on(const proto::StatsQuery& m);

  void send(const proto::ServerMessage& m);
  void send_error(proto::ErrorMessage e);
  void log_unlogged();  // the summary line for errors past kErrorsLogged
  // A fatal error: the error, then the close (close_code_for its code); everything held is
  // released first.
  void fail(const Error& error, proto::Ref ref, std::vector<uint32_t> versions = {},
            std::optional<uint32_t> retry_after_ms = std::nullopt);
  void open_world();  // the hello admitted: its world, then welcome
  void close(CloseCode code, std::string reason, bool await_reply = true);
  void release();
  template <class A>
  void emit(A action) {
    actions_.emplace_back(std::in_place_type<A>, std::move(action));
  }

  ConversationConfig config_;
  WorldPort& worlds_;
  Metrics* metrics_;
  State state_ = State::kNew;
  ClientId client_ = 0;
  // The hello being admitted (kQueued until admitted()): what open_world() needs of it.
  proto::Ref hello_ref_;
  uint64_t hello_seed_ = 0;
  uint32_t hello_version_ = 0;
  std::string hello_name_;
  std::unordered_map<uint64_t, InFlight> in_flight_;  // the ledger, by packed room id
  uint64_t rooms_sent_ = 0;
  uint64_t bytes_sent_ = 0;
  uint64_t errors_sent_ = 0;
  // The request rate (Limits::request_rate, request_burst): a token bucket of rooms.
  static constexpr uint32_t kMaxRefusedInARow = 100;  // then the connection is closed
  bool take_tokens(size_t rooms);                     // false: refused
  double tokens_ = 0;
  uint64_t tokens_at_ = 0;  // steady_ms when tokens_ was last brought up to date
  uint32_t refused_in_a_row_ = 0;
  // The bandwidth cap (Limits::max_kbps): a token bucket of frame bytes holding one second's
  // worth. A ready room goes out while the bucket is not below zero, so a frame larger than the
  // bucket is never stuck; the most urgent waiting room (smallest priority) goes first.
  void send_ready();
  double bytes_tokens_ = 0;
  uint64_t bytes_tokens_at_ = 0;
  size_t waiting_ = 0;                           // entries of in_flight_ with `ready` set
  static constexpr uint64_t kErrorsLogged = 10;  // non-fatal errors logged per connection
  uint64_t errors_logged_ = 0;
  uint64_t errors_unlogged_ = 0;
  std::vector<Action> actions_;
};

}  // namespace grotto::server
