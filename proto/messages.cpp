#include "proto/messages.hpp"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "proto/json_reader.hpp"
#include "proto/token.hpp"

// Evaluates a Result-returning expression; on error returns it from the enclosing function,
// otherwise moves the value into `target`.
#define PROTO_TRY(target, expr)                               \
  do {                                                        \
    auto proto_try_result_ = (expr);                          \
    if (!proto_try_result_) return proto_try_result_.error(); \
    target = std::move(proto_try_result_).value();            \
  } while (0)

namespace grotto::proto {
namespace {

using detail::field_error;
using detail::Fields;
using detail::json;
using ojson = nlohmann::ordered_json;

constexpr uint64_t kMaxU32 = 0xffffffffu;

// ---- 64-bit values as strings (JavaScript numbers hold only 53 bits) ----

std::string seed_text(uint64_t seed) {
  return std::to_string(seed);
}

Result<cave::RoomId> room_id(const json& value, const std::string& field) {
  if (!value.is_string()) {
    return field_error(
        field, std::string("must be a room id string (got ") + detail::type_name(value) + ")");
  }
  Result<cave::RoomId> id = cave::RoomId::parse(value.get_ref<const std::string&>());
  if (!id) {
    // RoomId::parse quotes up to 64 bytes of the id: keep them printable ASCII for logs.
    std::string message = id.error().message;
    for (char& c : message) {
      unsigned char u = static_cast<unsigned char>(c);
      if (u < 0x20 || u >= 0x7f) c = '?';
    }
    return Error{ErrorCode::kInvalidRoomId, field + ": " + message};
  }
  return id;
}

Result<std::optional<cave::RoomId>> optional_room_id(const Fields& f, std::string_view key) {
  const json* v = f.find(key);
  if (!v || v->is_null()) return std::optional<cave::RoomId>();
  Result<cave::RoomId> id = room_id(*v, std::string(key));
  if (!id) return id.error();
  return std::optional<cave::RoomId>(*id);
}

Result<std::vector<uint32_t>> versions(const json& array, std::string_view key) {
  std::vector<uint32_t> out;
  for (std::size_t i = 0; i < array.size(); ++i) {
    std::string name = std::string(key) + "[" + std::to_string(i) + "]";
    uint64_t v = 0;
    PROTO_TRY(v, detail::to_uint(array[i], name, 65535, 1));
    out.push_back(static_cast<uint32_t>(v));
  }
  return out;
}

// Names and server strings end up in logs and on screens: no control characters (C0, DEL, C1)
// and no bidirectional formatting characters (UAX #9's explicit embeddings, overrides and
// isolates, and its implicit marks), which can make a log line read as something it is not
// ("Trojan Source", CVE-2021-42574). UTF-8 validity is already guaranteed by the JSON parser.
Status printable(const std::string& s, std::string_view field) {
  for (std::size_t i = 0; i < s.size();) {
    unsigned char c = static_cast<unsigned char>(s[i]);
    uint32_t cp = c;
    std::size_t n = c < 0x80 ? 1 : c < 0xe0 ? 2 : c < 0xf0 ? 3 : 4;
    if (n > 1 && i + n <= s.size()) {
      cp = c & (0x7f >> n);
      for (std::size_t k = 1; k < n; ++k)
        cp = (cp << 6) | (static_cast<unsigned char>(s[i + k]) & 0x3f);
    }
    if (cp < 0x20 || (cp >= 0x7f && cp <= 0x9f)) {
      return field_error(field, "must not contain control characters");
    }
    if (cp == 0x061c || cp == 0x200e || cp == 0x200f || (cp >= 0x202a && cp <= 0x202e) ||
        (cp >= 0x2066 && cp <= 0x2069)) {
      return field_error(field, "must not contain bidirectional formatting characters");
    }
    i += n;
  }
  return {};
}

// Error messages are printable ASCII (every other byte becomes '?') and at most kMaxErrorBytes
// ("..." at the end when cut): what is cut here is exactly what goes on the wire, since
// serializing printable ASCII escapes nothing but the quote and the backslash (and replaces
// nothing).
std::string cut_message(std::string message) {
  for (char& c : message) {
    unsigned char u = static_cast<unsigned char>(c);
    if (u < 0x20 || u >= 0x7f) c = '?';
  }
  if (message.size() <= kMaxErrorBytes) return message;
  message.resize(kMaxErrorBytes - 3);
  return message + "...";
}

// ---- client messages ----

Result<ClientMessage> parse_hello(const Fields& f, Ref ref) {
  Hello m;
  m.ref = ref;
  const json* list = nullptr;
  PROTO_TRY(list, f.array("versions", 1, kMaxVersions));
  PROTO_TRY(m.versions, versions(*list, "versions"));
  std::optional<std::string> text;
  PROTO_TRY(text, f.optional_string("seed", 64));
  if (text) PROTO_TRY(m.seed, parse_seed_text(*text, "seed"));
  PROTO_TRY(text, f.optional_string("params", 64));
  if (text) PROTO_TRY(m.params, parse_digest_text(*text, "params"));
  PROTO_TRY(text, f.optional_string("name", kMaxNameBytes));
  if (text) {
    if (Status s = printable(*text, "name"); !s) return s.error();
    m.name = std::move(*text);
  }
  PROTO_TRY(m.token, f.optional_string("token", kMaxTokenBytes));
  if (m.token) {
    // The token is not quoted back: the message names only what is wrong.
    if (Status s = check_token(*m.token); !s) return field_error("token", s.error().message);
  }
  if (f.find("queue")) PROTO_TRY(m.queue, f.boolean("queue"));
  return {std::move(m)};
}

Result<ClientMessage> parse_request(const Fields& f, Ref ref, const Limits& limits) {
  Request m;
  m.ref = ref;
  const json* list = nullptr;
  PROTO_TRY(list, f.array("rooms", 1, limits.max_rooms_per_request));
  m.rooms.reserve(list->size());
  for (std::size_t i = 0; i < list->size(); ++i) {
    std::string at = "rooms[" + std::to_string(i) + "]";
    const json& entry = (*list)[i];
    if (!entry.is_object()) {
      return field_error(at, std::string("must be an object {id, lod, priority} (got ") +
                                 detail::type_name(entry) + ")");
    }
    Fields e(entry);
    RoomWant want;
    const json* id = e.find("id");
    if (!id) return field_error(at + ".id", "is missing");
    PROTO_TRY(want.id, room_id(*id, at + ".id"));
    const json* lod = e.find("lod");
    if (!lod) return field_error(at + ".lod", "is missing");
    uint64_t v = 0;
    PROTO_TRY(v, detail::to_uint(*lod, at + ".lod", limits.max_lod));
    want.lod = static_cast<uint32_t>(v);
    const json* priority = e.find("priority");
    if (!priority) return field_error(at + ".priority", "is missing");
    PROTO_TRY(v, detail::to_uint(*priority, at + ".priority", kMaxU32));
    want.priority = static_cast<uint32_t>(v);
    m.rooms.push_back(want);
  }
  // A repeated id is ambiguous (which lod and priority?): the whole request is refused.
  std::vector<std::pair<uint64_t, std::size_t>> ids;
  ids.reserve(m.rooms.size());
  for (std::size_t i = 0; i < m.rooms.size(); ++i)
    ids.emplace_back(m.rooms[i].id.packed(), i);
  std::sort(ids.begin(), ids.end());
  for (std::size_t i = 1; i < ids.size(); ++i) {
    if (ids[i].first == ids[i - 1].first) {
      std::size_t later = std::max(ids[i].second, ids[i - 1].second);
      return field_error("rooms[" + std::to_string(later) + "].id",
                         "repeats room " + m.rooms[later].id.to_string() +
                             " (each room at most once per request)");
    }
  }
  return {std::move(m)};
}

Result<ClientMessage> parse_cancel(const Fields& f, Ref ref, const Limits& limits) {
  Cancel m;
  m.ref = ref;
  const json* list = nullptr;
  PROTO_TRY(list, f.array("rooms", 1, limits.max_rooms_per_request));
  m.rooms.reserve(list->size());
  for (std::size_t i = 0; i < list->size(); ++i) {
    cave::RoomId id = cave::RoomId::interior({}, 0);
    PROTO_TRY(id, room_id((*list)[i], "rooms[" + std::to_string(i) + "]"));
    m.rooms.push_back(id);
  }
  return {std::move(m)};
}

bool is_client_type(std::string_view type) {
  for (std::string_view t : {"hello", "locate", "spawn", "request", "cancel", "ping", "stats"}) {
    if (type == t) return true;
  }
  return false;
}

Result<ClientMessage> parse_client_body(const Fields& f, std::string_view type, Ref ref,
                                        const Limits& limits) {
  if (type == "hello") return parse_hello(f, ref);
  if (type == "locate") {
    Locate m;
    m.ref = ref;
    PROTO_TRY(m.point, f.point("point"));
    return {std::move(m)};
  }
  if (type == "spawn") return ClientMessage(Spawn{ref});
  if (type == "request") return parse_request(f, ref, limits);
  if (type == "cancel") return parse_cancel(f, ref, limits);
  if (type == "ping") {
    Ping m;
    m.ref = ref;
    PROTO_TRY(m.t, f.number("t"));
    return {std::move(m)};
  }
  if (type == "stats") return ClientMessage(StatsQuery{ref});
  return Error{ErrorCode::kUnknownType, "unknown message type '" + echo(type) + "'"};
}

// Reads "type", the field every message has.
Result<std::string> message_type(const Fields& f) {
  const json* type = f.find("type");
  if (!type) return field_error("type", "is missing");
  if (!type->is_string()) {
    return field_error("type",
                       std::string("must be a string (got ") + detail::type_name(*type) + ")");
  }
  return type->get<std::string>();
}

// ---- server messages ----

Result<Limits> parse_limits(const json& object) {
  Fields f(object);
  Limits l;
  auto read = [&](std::string_view key, uint64_t min, uint64_t max, uint32_t& out) -> Status {
    Result<uint64_t> r = f.uint(key, max);
    if (!r) {
      Error e = r.error();
      if (e.message.starts_with("field '")) e.message.insert(7, "limits.");
      return e;
    }
    if (*r < min) {
      return field_error("limits." + std::string(key), "must be at least " + std::to_string(min) +
                                                           " (got " + std::to_string(*r) + ")");
    }
    out = static_cast<uint32_t>(*r);
    return {};
  };
  if (Status s = read("max_message_bytes", 1024, kMaxU32, l.max_message_bytes); !s)
    return s.error();
  if (Status s = read("max_frame_bytes", 1024, kMaxU32, l.max_frame_bytes); !s) return s.error();
  if (Status s = read("max_rooms_per_request", 1, kMaxU32, l.max_rooms_per_request); !s) {
    return s.error();
  }
  if (Status s = read("max_rooms_in_flight", 1, kMaxU32, l.max_rooms_in_flight); !s) {
    return s.error();
  }
  if (Status s = read("max_lod", 0, 255, l.max_lod); !s) return s.error();
  if (Status s = read("idle_timeout_ms", 1, kMaxU32, l.idle_timeout_ms); !s) return s.error();
  if (Status s = read("handshake_timeout_ms", 1, kMaxU32, l.handshake_timeout_ms); !s) {
    return s.error();
  }
  // Added within version 1: a server that does not announce them has no request rate limit.
  l.request_rate = 0;
  l.request_burst = 0;
  if (f.find("request_rate")) {
    if (Status s = read("request_rate", 1, kMaxU32, l.request_rate); !s) return s.error();
  }
  if (f.find("request_burst")) {
    if (Status s = read("request_burst", 1, kMaxU32, l.request_burst); !s) return s.error();
  }
  l.max_kbps = 0;
  if (f.find("max_kbps")) {
    if (Status s = read("max_kbps", 1, kMaxU32, l.max_kbps); !s) return s.error();
  }
  return l;
}

Result<ServerMessage> parse_welcome(const Fields& f, Ref ref) {
  Welcome m;
  m.ref = ref;
  uint64_t v = 0;
  PROTO_TRY(v, f.uint("version", 65535, 1));
  m.version = static_cast<uint32_t>(v);
  PROTO_TRY(m.server, f.string("server", kMaxNameBytes));
  if (Status s = printable(m.server, "server"); !s) return s.error();
  std::string text;
  PROTO_TRY(text, f.string("seed", 64));
  PROTO_TRY(m.seed, parse_seed_text(text, "seed"));
  PROTO_TRY(text, f.string("params", 64));
  PROTO_TRY(m.params, parse_digest_text(text, "params"));
  const json* limits = nullptr;
  PROTO_TRY(limits, f.object("limits"));
  Result<Limits> l = parse_limits(*limits);
  if (!l) return l.error();
  m.limits = *l;
  return {std::move(m)};
}

Result<ServerMessage> parse_error_message(const Fields& f, Ref ref) {
  ErrorMessage m;
  m.ref = ref;
  std::string code;
  PROTO_TRY(code, f.string("code", kMaxTypeBytes));
  std::optional<ErrorCode> known = parse_wire_code(code);
  PROTO_TRY(m.message, f.string("message", kMaxErrorBytes));
  // A server's message is printable ASCII; whatever else arrives is masked the same way
  // serialize() would mask it, so a parsed error serializes to what it parsed from.
  m.message = cut_message(std::move(m.message));
  if (known) {
    m.code = *known;
  } else {
    // A code from a later revision: keep its name for people; the client treats it as internal.
    m.code = ErrorCode::kInternal;
    m.message = cut_message("[" + echo(code) + "] " + m.message);
  }
  PROTO_TRY(m.fatal, f.boolean("fatal"));
  PROTO_TRY(m.room, optional_room_id(f, "room"));
  if (f.find("versions")) {
    const json* list = nullptr;
    PROTO_TRY(list, f.array("versions", 0, kMaxVersions));
    PROTO_TRY(m.versions, versions(*list, "versions"));
  }
  std::optional<uint64_t> retry;
  PROTO_TRY(retry, f.optional_uint("retry_after_ms", kMaxWaitMs));
  if (retry) m.retry_after_ms = static_cast<uint32_t>(*retry);
  return {std::move(m)};
}

Result<ServerMessage> parse_queued(const Fields& f, Ref ref) {
  Queued m;
  m.ref = ref;
  uint64_t v = 0;
  PROTO_TRY(v, f.uint("position", kMaxQueueLength, 1));
  m.position = static_cast<uint32_t>(v);
  PROTO_TRY(v, f.uint("wait_ms", kMaxWaitMs));
  m.wait_ms = static_cast<uint32_t>(v);
  PROTO_TRY(v, f.uint("queue", kMaxQueueLength, 1));
  m.queue = static_cast<uint32_t>(v);
  if (m.queue < m.position) {
    return field_error("queue", "must be at least position (" + std::to_string(m.position) +
                                    ", got " + std::to_string(m.queue) + ")");
  }
  return {std::move(m)};
}

Result<ServerMessage> parse_server_body(const Fields& f, std::string_view type, Ref ref) {
  if (type == "welcome") return parse_welcome(f, ref);
  if (type == "located") {
    Located m;
    m.ref = ref;
    PROTO_TRY(m.point, f.point("point"));
    if (!f.find("room")) return field_error("room", "is missing (null when no room)");
    PROTO_TRY(m.room, optional_room_id(f, "room"));
    return {std::move(m)};
  }
  if (type == "spawn_point") {
    SpawnPoint m{ref, cave::RoomId::interior({}, 0), {}};
    const json* id = f.find("room");
    if (!id) return field_error("room", "is missing");
    PROTO_TRY(m.room, room_id(*id, "room"));
    PROTO_TRY(m.position, f.point("position"));
    return {std::move(m)};
  }
  if (type == "error") return parse_error_message(f, ref);
  if (type == "queued") return parse_queued(f, ref);
  if (type == "pong") {
    Pong m;
    m.ref = ref;
    PROTO_TRY(m.t, f.number("t"));
    PROTO_TRY(m.time_ms, f.uint("time", kMaxJsonInteger));
    return {std::move(m)};
  }
  if (type == "stats") {
    Stats m;
    m.ref = ref;
    PROTO_TRY(m.in_flight, f.uint("in_flight", kMaxJsonInteger));
    PROTO_TRY(m.rooms_sent, f.uint("rooms_sent", kMaxJsonInteger));
    PROTO_TRY(m.bytes_sent, f.uint("bytes_sent", kMaxJsonInteger));
    PROTO_TRY(m.errors, f.uint("errors", kMaxJsonInteger));
    return {std::move(m)};
  }
  return Error{ErrorCode::kUnknownType, "unknown message type '" + echo(type) + "'"};
}

// ---- serializing ----

ojson vec(Vec3 v) {
  assert(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
  return ojson::array({v.x, v.y, v.z});
}

ojson head(const char* type, const Ref& ref) {
  ojson out;
  out["type"] = type;
  if (ref) {
    assert(*ref <= kMaxJsonInteger);
    out["ref"] = *ref;
  }
  return out;
}

std::string dump(const ojson& value) {
  // Replace, never throw, on invalid UTF-8 in a string we were handed.
  return value.dump(-1, ' ', false, ojson::error_handler_t::replace);
}

ojson to_json(const Hello& m) {
  ojson out = head("hello", m.ref);
  out["versions"] = m.versions;
  if (m.seed) out["seed"] = seed_text(*m.seed);
  if (m.params) out["params"] = digest_text(*m.params);
  out["name"] = m.name;
  if (m.token) out["token"] = *m.token;
  if (m.queue) out["queue"] = true;
  return out;
}
ojson to_json(const Locate& m) {
  ojson out = head("locate", m.ref);
  out["point"] = vec(m.point);
  return out;
}
ojson to_json(const Spawn& m) {
  return head("spawn", m.ref);
}
ojson to_json(const Request& m) {
  ojson out = head("request", m.ref);
  ojson rooms = ojson::array();
  for (const RoomWant& w : m.rooms) {
    ojson entry;
    entry["id"] = w.id.to_string();
    entry["lod"] = w.lod;
    entry["priority"] = w.priority;
    rooms.push_back(std::move(entry));
  }
  out["rooms"] = std::move(rooms);
  return out;
}
ojson to_json(const Cancel& m) {
  ojson out = head("cancel", m.ref);
  ojson rooms = ojson::array();
  for (cave::RoomId id : m.rooms)
    rooms.push_back(id.to_string());
  out["rooms"] = std::move(rooms);
  return out;
}
ojson to_json(const Ping& m) {
  assert(std::isfinite(m.t));
  ojson out = head("ping", m.ref);
  out["t"] = m.t;
  return out;
}
ojson to_json(const StatsQuery& m) {
  return head("stats", m.ref);
}

ojson to_json(const Welcome& m) {
  ojson out = head("welcome", m.ref);
  out["version"] = m.version;
  out["server"] = m.server;
  out["seed"] = seed_text(m.seed);
  out["params"] = digest_text(m.params);
  ojson limits;
  limits["max_message_bytes"] = m.limits.max_message_bytes;
  limits["max_frame_bytes"] = m.limits.max_frame_bytes;
  limits["max_rooms_per_request"] = m.limits.max_rooms_per_request;
  limits["max_rooms_in_flight"] = m.limits.max_rooms_in_flight;
  limits["max_lod"] = m.limits.max_lod;
  limits["idle_timeout_ms"] = m.limits.idle_timeout_ms;
  limits["handshake_timeout_ms"] = m.limits.handshake_timeout_ms;
  if (m.limits.request_rate > 0) limits["request_rate"] = m.limits.request_rate;
  if (m.limits.request_burst > 0) limits["request_burst"] = m.limits.request_burst;
  if (m.limits.max_kbps > 0) limits["max_kbps"] = m.limits.max_kbps;
  out["limits"] = std::move(limits);
  return out;
}
ojson to_json(const Located& m) {
  ojson out = head("located", m.ref);
  out["point"] = vec(m.point);
  out["room"] = m.room ? ojson(m.room->to_string()) : ojson(nullptr);
  return out;
}
ojson to_json(const SpawnPoint& m) {
  ojson out = head("spawn_point", m.ref);
  out["room"] = m.room.to_string();
  out["position"] = vec(m.position);
  return out;
}
ojson to_json(const ErrorMessage& m) {
  ojson out = head("error", m.ref);
  out["code"] = wire_code_name(m.code);
  out["message"] = cut_message(m.message);
  out["fatal"] = m.fatal;
  if (m.room) out["room"] = m.room->to_string();
  if (!m.versions.empty()) out["versions"] = m.versions;
  if (m.retry_after_ms) {
    assert(*m.retry_after_ms <= kMaxWaitMs);
    out["retry_after_ms"] = *m.retry_after_ms;
  }
  return out;
}
ojson to_json(const Pong& m) {
  assert(std::isfinite(m.t) && m.time_ms <= kMaxJsonInteger);
  ojson out = head("pong", m.ref);
  out["t"] = m.t;
  out["time"] = m.time_ms;
  return out;
}
ojson to_json(const Queued& m) {
  assert(m.position >= 1 && m.position <= m.queue && m.queue <= kMaxQueueLength);
  assert(m.wait_ms <= kMaxWaitMs);
  ojson out = head("queued", m.ref);
  out["position"] = m.position;
  out["wait_ms"] = m.wait_ms;
  out["queue"] = m.queue;
  return out;
}
ojson to_json(const Stats& m) {
  ojson out = head("stats", m.ref);
  out["in_flight"] = m.in_flight;
  out["rooms_sent"] = m.rooms_sent;
  out["bytes_sent"] = m.bytes_sent;
  out["errors"] = m.errors;
  return out;
}

}  // namespace

Result<ClientMessage> parse_client_message(std::string_view text, const Limits& limits,
                                           Ref* ref_out, std::string* type_out) {
  // PROTOCOL.md, "Which error a message gets": size, JSON, type, (order: the server's), fields.
  if (type_out) type_out->clear();
  Result<json> value = detail::parse_object(text, limits.max_message_bytes);
  if (!value) return value.error();
  Fields f(*value);
  // The ref is a field (its errors come after the type's), but a valid one is reported
  // whatever fails, so that the error can name the message it concerns.
  Result<Ref> ref = f.optional_uint("ref", kMaxJsonInteger);
  if (ref && ref_out) *ref_out = *ref;
  std::string type;
  PROTO_TRY(type, message_type(f));
  if (!is_client_type(type)) {
    return Error{ErrorCode::kUnknownType, "unknown message type '" + echo(type) + "'"};
  }
  if (type_out) *type_out = type;
  if (!ref) return ref.error();
  return parse_client_body(f, type, *ref, limits);
}

Result<ServerMessage> parse_server_message(std::string_view text, const Limits& limits) {
  Result<json> value = detail::parse_object(text, limits.max_message_bytes);
  if (!value) return value.error();
  Fields f(*value);
  Ref ref;
  PROTO_TRY(ref, f.optional_uint("ref", kMaxJsonInteger));
  std::string type;
  PROTO_TRY(type, message_type(f));
  return parse_server_body(f, type, ref);
}

std::string serialize(const ClientMessage& message) {
  return std::visit([](const auto& m) { return dump(to_json(m)); }, message);
}

std::string serialize(const ServerMessage& message) {
  return std::visit([](const auto& m) { return dump(to_json(m)); }, message);
}

const char* wire_code_name(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
      return "bad_message";
    case ErrorCode::kUnavailable:
      return "overloaded";
    default:
      return error_code_name(code);
  }
}

std::optional<ErrorCode> parse_wire_code(std::string_view name) {
  static constexpr ErrorCode kWireCodes[] = {
      ErrorCode::kBadJson,        ErrorCode::kBadMessage,
      ErrorCode::kUnknownType,    ErrorCode::kUnsupportedVersion,
      ErrorCode::kTooLarge,       ErrorCode::kInvalidRoomId,
      ErrorCode::kNotFound,       ErrorCode::kLimitExceeded,
      ErrorCode::kWorldMismatch,  ErrorCode::kOutOfOrder,
      ErrorCode::kBadFrame,       ErrorCode::kUnauthorized,
      ErrorCode::kServiceRestart, ErrorCode::kOverloaded,
      ErrorCode::kTimeout,        ErrorCode::kInternal};
  for (ErrorCode c : kWireCodes) {
    if (name == error_code_name(c)) return c;
  }
  return std::nullopt;
}

bool is_fatal(ErrorCode code) {
  switch (code) {
    case ErrorCode::kUnsupportedVersion:
    case ErrorCode::kWorldMismatch:
    case ErrorCode::kOutOfOrder:
    case ErrorCode::kBadFrame:
    case ErrorCode::kUnauthorized:
    case ErrorCode::kServiceRestart:
    case ErrorCode::kTimeout:
      return true;
    default:
      return false;
  }
}

ErrorMessage error_reply(const Error& error, Ref ref, std::optional<cave::RoomId> room) {
  ErrorMessage m;
  m.ref = ref;
  m.code = error.code;
  m.message = cut_message(error.message);
  m.room = room;
  m.fatal = is_fatal(error.code);
  return m;
}

std::string echo(std::string_view untrusted) {
  std::string out;
  std::size_t n = std::min(untrusted.size(), kMaxEchoBytes);
  out.reserve(n + 3);
  for (std::size_t i = 0; i < n; ++i) {
    unsigned char c = static_cast<unsigned char>(untrusted[i]);
    out.push_back(c >= 0x20 && c < 0x7f && c != '\'' ? static_cast<char>(c) : '?');
  }
  if (untrusted.size() > n) out += "...";
  return out;
}

Result<uint64_t> parse_seed_text(std::string_view s, std::string_view field) {
  bool digits = !s.empty() && s.size() <= 20 &&
                std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
  uint64_t v = 0;
  if (digits && (s.size() == 1 || s[0] != '0')) {
    auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec == std::errc() && end == s.data() + s.size()) return v;
  }
  return field_error(field,
                     "must be an unsigned 64-bit integer in decimal, no sign or leading "
                     "zeros (got '" +
                         echo(s) + "')");
}

Result<uint64_t> parse_digest_text(std::string_view s, std::string_view field) {
  bool hex = s.size() == 16 && std::all_of(s.begin(), s.end(), [](char c) {
               return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
             });
  uint64_t v = 0;
  if (hex) {
    std::from_chars(s.data(), s.data() + s.size(), v, 16);
    return v;
  }
  return field_error(field, "must be 16 lowercase hexadecimal digits (got '" + echo(s) + "')");
}

std::string digest_text(uint64_t digest) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(digest));
  return buf;
}

}  // namespace grotto::proto
