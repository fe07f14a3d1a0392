// The wire protocol's control messages (JSON text frames), as plain structs with strict parsers
// and serializers for both directions: the server parses ClientMessage and serializes
// ServerMessage; the client library does the reverse. proto/PROTOCOL.md is the contract; this
// header is its C++ face. Binary room frames live in proto/room_frame.hpp.
//
// Every parse function is safe for hostile input: the size limit is checked before any parsing,
// nesting deeper than kMaxJsonDepth is refused before nlohmann::json sees the text, no exception
// escapes, every field is type- and range-checked, and error messages quote at most
// kMaxEchoBytes of what they received. Parsing and serializing are pure functions; call them
// from any thread.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"

namespace grotto::proto {

// The protocol versions this library speaks, negotiated in hello/welcome (the highest in common
// wins) and carried in every room frame. Version 2's room payload leaves the normals out
// (PROTOCOL.md, "Versions"); everything else is version 1's.
inline constexpr uint32_t kProtocolVersion = 2;     // the newest
inline constexpr uint32_t kMinProtocolVersion = 1;  // the oldest still spoken
constexpr bool speaks_version(uint64_t version) {
  return version >= kMinProtocolVersion && version <= kProtocolVersion;
}
// Whether a room payload of this protocol version carries the normal attribute (common/codec).
constexpr bool payload_has_normals(uint32_t version) {
  return version < 2;
}
// The WebSocket endpoint's HTTP path.
inline constexpr std::string_view kWebSocketPath = "/ws";

// Fixed parse limits (not negotiated; the same for every server speaking version 1).
inline constexpr int kMaxJsonDepth = 16;             // arrays/objects nested; messages need 3
inline constexpr std::size_t kMaxNameBytes = 64;     // hello.name, welcome.server
inline constexpr std::size_t kMaxVersions = 16;      // hello.versions, error.versions
inline constexpr std::size_t kMaxTypeBytes = 32;     // error.code (longer: too_large)
inline constexpr std::size_t kMaxErrorBytes = 1024;  // error.message
inline constexpr std::size_t kMaxEchoBytes = 32;
inline constexpr uint32_t kMaxQueueLength = 1'000'000;  // queued.position and queued.queue
inline constexpr uint32_t kMaxWaitMs = 86'400'000;  // queued.wait_ms, error.retry_after_ms  // how
                                                    // much of bad input an error message quotes
// Integers travel as JSON numbers only up to 2^53 - 1 (exact in a JavaScript double); larger
// 64-bit values (seeds, digests) travel as strings.
inline constexpr uint64_t kMaxJsonInteger = (uint64_t{1} << 53) - 1;
// No coordinate a client may send or a server may report exceeds this (metres): the far face of
// the last sector, (65,535 + 1) sectors of at most 256 m.
inline constexpr double kMaxCoordinate = 16777216.0;  // 2^24

// The limits a server enforces, announced in welcome. Also what the parse functions check on
// the side that receives (a server passes its own limits; a client passes the welcome's, or
// defaults before it has one). Brace-init gives the defaults.
struct Limits {
  uint32_t max_message_bytes = 64 * 1024;      // a text frame, either direction
  uint32_t max_frame_bytes = 4 * 1024 * 1024;  // a binary room frame (server to client)
  uint32_t max_rooms_per_request = 256;        // entries in one request or cancel
  uint32_t max_rooms_in_flight = 1024;         // requested, not yet delivered/failed/cancelled
  uint32_t max_lod = 0;  // the highest wire lod served (≤ 255; proto/lod.hpp maps it to mesh::Lod)
  uint32_t idle_timeout_ms = 60'000;      // no message from the client for this long: closed
  uint32_t handshake_timeout_ms = 5'000;  // no hello this long after the upgrade: closed
  // Rooms named by request and cancel messages (each message at least one) per second, and the
  // most at once: a token bucket per client. 0 in a parsed welcome: not announced, no limit.
  uint32_t request_rate = 2000;
  uint32_t request_burst = 4000;
  // Room frames' bandwidth per connection, kilobits (1000 bits) a second, averaged over a second;
  // rooms ready beyond it wait, most urgent first. 0: not announced, no cap.
  uint32_t max_kbps = 0;
  friend bool operator==(const Limits&, const Limits&) = default;
};

// A client-chosen tag in [0, kMaxJsonInteger] that the server copies into its reply and into
// errors about the message. Optional on every client message.
using Ref = std::optional<uint64_t>;

// ---- client to server ----

struct Hello {
  Ref ref;
  std::vector<uint32_t> versions;  // 1..kMaxVersions entries, each in [1, 65535]
  std::optional<uint64_t> seed;    // the world wanted; absent: the server's world
  std::optional<uint64_t> params;  // its parameter digest; absent: whatever the server uses
  // ≤ kMaxNameBytes, no control characters (C0, DEL, C1) or bidirectional formatting
  // characters (U+061C, U+200E, U+200F, U+202A-U+202E, U+2066-U+2069)
  std::string name;
  // The deployment's shared secret (proto/token.hpp): ≤ kMaxTokenBytes of printable ASCII.
  // Absent: none presented. A server without a token ignores it.
  std::optional<std::string> token;
  // The client understands `queued`: past capacity it may wait in the server's queue. Without
  // it the server admits the client or refuses it (overloaded, retry_after_ms), never makes it
  // wait in silence.
  bool queue = false;
  friend bool operator==(const Hello&, const Hello&) = default;
};

struct Locate {
  Ref ref;
  Vec3 point;  // finite, each |coordinate| ≤ kMaxCoordinate
  friend bool operator==(const Locate&, const Locate&) = default;
};

struct Spawn {
  Ref ref;
  friend bool operator==(const Spawn&, const Spawn&) = default;
};

struct RoomWant {
  cave::RoomId id = cave::RoomId::interior({}, 0);
  uint32_t lod = 0;       // wire lod (proto/lod.hpp), ≤ Limits::max_lod
  uint32_t priority = 0;  // smaller is sooner
  friend bool operator==(const RoomWant&, const RoomWant&) = default;
};

struct Request {
  Ref ref;
  std::vector<RoomWant> rooms;  // 1..max_rooms_per_request, ids distinct
  friend bool operator==(const Request&, const Request&) = default;
};

struct Cancel {
  Ref ref;
  std::vector<cave::RoomId> rooms;  // 1..max_rooms_per_request; repeats are harmless
  friend bool operator==(const Cancel&, const Cancel&) = default;
};

struct Ping {
  Ref ref;
  double t = 0;  // the client's clock, any finite number; echoed in pong
  friend bool operator==(const Ping&, const Ping&) = default;
};

struct StatsQuery {
  Ref ref;
  friend bool operator==(const StatsQuery&, const StatsQuery&) = default;
};

using ClientMessage = std::variant<Hello, Locate, Spawn, Request, Cancel, Ping, StatsQuery>;

// ---- server to client ----

struct Welcome {
  Ref ref;
  uint32_t version = kProtocolVersion;  // the version chosen from hello.versions
  std::string server;                   // product and version, ≤ kMaxNameBytes
  uint64_t seed = 0;
  uint64_t params = 0;  // the world's parameter digest
  Limits limits;
  friend bool operator==(const Welcome&, const Welcome&) = default;
};

struct Located {
  Ref ref;
  Vec3 point;                        // as asked
  std::optional<cave::RoomId> room;  // none: the point is in rock or outside the sector range
  friend bool operator==(const Located&, const Located&) = default;
};

struct SpawnPoint {
  Ref ref;
  cave::RoomId room = cave::RoomId::interior({}, 0);
  Vec3 position;  // where a player starts, inside `room`
  friend bool operator==(const SpawnPoint&, const SpawnPoint&) = default;
};

struct ErrorMessage {
  Ref ref;  // the ref of the message that caused it, when it had a valid one
  ErrorCode code = ErrorCode::kInternal;
  std::string message;               // for people; printable ASCII, ≤ kMaxErrorBytes
  std::optional<cave::RoomId> room;  // the room it concerns (request failures)
  std::vector<uint32_t> versions;    // unsupported_version: the versions the server speaks
  bool fatal = false;                // the server closes the connection after sending it
  // overloaded at the door: come back after this many milliseconds (≤ kMaxWaitMs)
  std::optional<uint32_t> retry_after_ms;
  friend bool operator==(const ErrorMessage&, const ErrorMessage&) = default;
};

struct Pong {
  Ref ref;
  double t = 0;          // ping.t, unchanged
  uint64_t time_ms = 0;  // the server's clock (Unix milliseconds) when it answered
  friend bool operator==(const Pong&, const Pong&) = default;
};

struct Stats {
  Ref ref;
  uint64_t in_flight = 0;   // this client's rooms requested and not yet delivered or failed
  uint64_t rooms_sent = 0;  // room frames sent to this client
  uint64_t bytes_sent = 0;  // bytes of all frames sent to this client
  uint64_t errors = 0;      // error messages sent to this client
  friend bool operator==(const Stats&, const Stats&) = default;
};

// The server is past its capacity: the client waits in its queue, and `welcome` follows when it
// is admitted. Sent on queueing and again when the place or the estimate changes.
struct Queued {
  Ref ref;                // the hello's
  uint32_t position = 1;  // 1-based, ≤ kMaxQueueLength
  uint32_t wait_ms = 0;   // estimated, ≤ kMaxWaitMs
  uint32_t queue = 1;     // sessions waiting, ≥ position, ≤ kMaxQueueLength
  friend bool operator==(const Queued&, const Queued&) = default;
};

using ServerMessage = std::variant<Welcome, Located, SpawnPoint, ErrorMessage, Pong, Stats, Queued>;

// ---- parsing and serializing ----

// A server's side: one text frame from a client. Errors carry a wire code (bad_json,
// bad_message, unknown_type, too_large, invalid_room_id) and a message naming the field.
// Checks run in PROTOCOL.md's order (size, JSON, type, then fields; the order check between type
// and fields is the server's, since only it knows whether welcome was sent), and the first
// failure is returned.
// When `ref` is not null it receives the message's ref whenever the "ref" field itself was
// valid, also when parsing fails, so the error can name the message it concerns.
// When `type` is not null it is cleared, then receives the "type" string once it names a client
// message of this version ("hello", "locate", ...), also when a field fails later. Empty on
// return with an error: the error is from the size, JSON or type checks, which come before the
// order check. Non-empty: the server checks the order (hello first, and only once) before
// answering any field error, and knows whether the failed message was a hello.
Result<ClientMessage> parse_client_message(std::string_view text, const Limits& limits,
                                           Ref* ref = nullptr, std::string* type = nullptr);
// A client's side: one text frame from a server, checked as strictly.
Result<ServerMessage> parse_server_message(std::string_view text, const Limits& limits);

// Compact JSON, keys in a fixed order. Preconditions (asserted): the message satisfies the
// ranges above (finite numbers, refs and counters ≤ kMaxJsonInteger). Strings that are not
// valid UTF-8 have the bad bytes replaced, so serializing never fails.
std::string serialize(const ClientMessage& message);
std::string serialize(const ServerMessage& message);

// The code's name on the wire. The four general codes map onto wire codes: invalid_argument is
// sent as bad_message and unavailable as overloaded; every other code is sent under its name.
const char* wire_code_name(ErrorCode code);
// The code for a wire name; nullopt for a name this version does not know.
std::optional<ErrorCode> parse_wire_code(std::string_view name);

// Whether the connection survives an error of this code sent by a server (PROTOCOL.md's table).
bool is_fatal(ErrorCode code);

// The error a server sends for a refused message or room: the code, the message (masked to
// printable ASCII, each other byte a '?', and cut to kMaxErrorBytes) and is_fatal(code); set
// `fatal` afterwards where PROTOCOL.md says otherwise (every error before welcome, a whole
// message over max_message_bytes). serialize() applies the same mask and cut to any
// ErrorMessage, so an error's JSON text never exceeds its limit whatever the message held.
ErrorMessage error_reply(const Error& error, Ref ref = std::nullopt,
                         std::optional<cave::RoomId> room = std::nullopt);

// A parameter digest as the wire writes it: 16 lowercase hex digits.
std::string digest_text(uint64_t digest);

// A seed (hello.seed, welcome.seed, a room path's) in its one text form: an unsigned 64-bit
// integer in decimal, no sign or leading zeros. Errors (kBadMessage) name `field`.
Result<uint64_t> parse_seed_text(std::string_view text, std::string_view field);
// A parameter digest in its one text form (digest_text's). Errors (kBadMessage) name `field`.
Result<uint64_t> parse_digest_text(std::string_view text, std::string_view field);

// At most kMaxEchoBytes of untrusted text, control and non-ASCII bytes shown as '?', with "..."
// when cut: safe to put in an error message or a log line.
std::string echo(std::string_view untrusted);

}  // namespace grotto::proto
