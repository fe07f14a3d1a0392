// client/stream's protocol core without sockets: tables of (state, input) -> (actions, next state)
// for every server message, close code, frame fault, timer and limit (proto/PROTOCOL.md), plus
// the reconnect backoff and the one-lod-a-session rule. The rooms are hand-made (a hub with four
// neighbours and one room beyond) so that the plan's order is worked out by hand.
#include "client/stream/conversation.hpp"

#if defined(BOOST_VERSION) || defined(BOOST_ASIO_VERSION) || defined(BOOST_BEAST_VERSION)
#error "client/stream/conversation.hpp must not pull in Boost"
#endif
#if defined(CL_VERSION_1_0) || defined(__OPENCL_CL_H) || defined(__CL_PLATFORM_H)
#error "client/stream/conversation.hpp must not pull in OpenCL"
#endif

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "proto/room_frame.hpp"

namespace grotto::stream {
namespace {

using cave::Room;
using cave::RoomId;
using std::chrono::milliseconds;
using std::chrono::seconds;

RoomId rid(int index) {
  return RoomId::interior({}, index);
}

// r0 at the origin (radius 6) with r1 (+x), r2 (-x), r3 (+z), r4 (-z) 10 m away and r5 beyond r1
// (x = 20); portal discs halfway between centres. The spawn pose looks along -z (Pose's default):
// from r0 the first hop costs 5 m / 4 m/s = 1.25 s times the view factor (1 ahead, 1.5 sideways,
// 2 behind): r4 1.25 s, r1 and r2 1.875 s, r3 2.5 s; r5 1.875 + 2.5 = 4.375 s, past the 4 s
// horizon but within 1.5 x 4 s, so it is kept in flight but never requested.
// Far away, and not connected to those (another sector's rooms, as far as the client knows), a
// chain r10 (x = 100), r11 (x = 110), r12 (x = 120): no plan from the pose reaches them, only a
// pinned area (AreaPin).
std::map<RoomId, Room> make_rooms() {
  std::map<RoomId, Room> rooms;
  auto room = [&](int i, Vec3 c) {
    rooms[rid(i)].id = rid(i);
    rooms[rid(i)].sphere = {c, 6.0};
  };
  room(0, {0, 0, 0});
  room(1, {10, 0, 0});
  room(2, {-10, 0, 0});
  room(3, {0, 0, 10});
  room(4, {0, 0, -10});
  room(5, {20, 0, 0});
  room(10, {100, 0, 0});
  room(11, {110, 0, 0});
  room(12, {120, 0, 0});
  auto link = [&](int a, int b) {
    Room& ra = rooms.at(rid(a));
    Room& rb = rooms.at(rid(b));
    const Vec3 centre = (ra.sphere.centre + rb.sphere.centre) * 0.5;
    const Vec3 n = normalize(rb.sphere.centre - ra.sphere.centre);
    ra.portals.push_back({centre, n, 1.0, rb.id});
    rb.portals.push_back({centre, -n, 1.0, ra.id});
  };
  link(0, 1);
  link(0, 2);
  link(0, 3);
  link(0, 4);
  link(1, 5);
  link(10, 11);
  link(11, 12);
  return rooms;
}

const std::map<RoomId, Room>& rooms() {
  static const auto all = make_rooms();
  return all;
}

std::vector<uint8_t> frame_of(int i, uint8_t lod = 0) {
  const std::vector<uint8_t> payload{1, 2, 3};
  return proto::encode_room_frame(rooms().at(rid(i)), lod, Vec3{}, payload);
}

std::string text(const proto::ServerMessage& m) {
  return proto::serialize(m);
}

proto::Welcome welcome(proto::Limits limits = {}) {
  proto::Welcome w;
  w.ref = 1;
  w.server = "test-server";
  w.seed = 7;
  w.params = 0x5d1c0a2e9b7f3c44;
  w.limits = limits;
  return w;
}

proto::ErrorMessage error(ErrorCode code, bool fatal, std::optional<RoomId> room = std::nullopt,
                          proto::Ref ref = std::nullopt) {
  proto::ErrorMessage e;
  e.code = code;
  e.message = "test";
  e.fatal = fatal;
  e.room = room;
  e.ref = ref;
  return e;
}

// One action, as the tables spell it.
std::string describe(const Action& action) {
  struct Visitor {
    std::string operator()(const SendMessage& m) const {
      return std::visit(
          [](const auto& msg) -> std::string {
            using T = std::decay_t<decltype(msg)>;
            if constexpr (std::is_same_v<T, proto::Hello>) return "hello";
            if constexpr (std::is_same_v<T, proto::Locate>) return "locate";
            if constexpr (std::is_same_v<T, proto::Spawn>) return "spawn";
            if constexpr (std::is_same_v<T, proto::Ping>) return "ping";
            if constexpr (std::is_same_v<T, proto::StatsQuery>) return "stats";
            if constexpr (std::is_same_v<T, proto::Request>) {
              std::string s = "request";
              for (const auto& w : msg.rooms)
                s += " " + w.id.to_string() + "@" + std::to_string(w.lod);
              return s;
            }
            if constexpr (std::is_same_v<T, proto::Cancel>) {
              std::string s = "cancel";
              for (const auto& id : msg.rooms)
                s += " " + id.to_string();
              return s;
            }
            return "?";
          },
          m.message);
    }
    std::string operator()(const DecodeRoom& d) const {
      return "decode " + d.frame.room.id.to_string() + "@" + std::to_string(d.frame.lod) +
             (d.limits.normals ? " with normals" : "");
    }
    std::string operator()(const SetReadLimit& r) const {
      return "read_limit " + std::to_string(r.bytes);
    }
    std::string operator()(const Reconnect&) const { return "reconnect"; }
    std::string operator()(const Fail&) const { return "fail"; }
  };
  return std::visit(Visitor{}, action);
}

std::vector<std::string> describe(const Actions& actions) {
  std::vector<std::string> out;
  for (const auto& a : actions)
    out.push_back(describe(a));
  return out;
}

// A conversation, its clock and the last decode it was asked for.
// The tables were worked out for the fixed 4 s horizon (above); the adaptive one, the default,
// has rows of its own.
StreamOptions fixed_horizon() {
  StreamOptions o;
  o.min_horizon_s = 0;
  return o;
}

struct Harness {
  explicit Harness(StreamOptions o = fixed_horizon()) : options(std::move(o)), c(options, 42) {}
  StreamOptions options;
  Conversation c;
  SteadyTime now = SteadyTime{} + seconds(1000);
  std::vector<DecodeRoom> decodes;

  Actions keep(Actions actions) {
    for (const auto& a : actions)
      if (const auto* d = std::get_if<DecodeRoom>(&a)) decodes.push_back(*d);
    return actions;
  }
  Actions open() {
    c.connecting();
    return keep(c.opened(now));
  }
  Actions msg(const proto::ServerMessage& m) { return keep(c.text(text(m), now)); }
  Actions raw(std::string_view t) { return keep(c.text(t, now)); }
  Actions frame(const std::vector<uint8_t>& bytes) { return keep(c.binary(bytes, now)); }
  Actions decode_ok(RoomId id) {
    for (auto it = decodes.begin(); it != decodes.end(); ++it) {
      if (it->frame.room.id != id) continue;
      DecodeRoom job = std::move(*it);
      decodes.erase(it);
      return keep(c.decoded(std::move(job), codec::DecodedRoom{}, now));
    }
    ADD_FAILURE() << "no decode of " << id.to_string();
    return {};
  }
  Actions decode_fail(RoomId id) {
    for (auto it = decodes.begin(); it != decodes.end(); ++it) {
      if (it->frame.room.id != id) continue;
      DecodeRoom job = std::move(*it);
      decodes.erase(it);
      return keep(c.decoded(std::move(job), Error{ErrorCode::kBadFrame, "corrupt payload"}, now));
    }
    ADD_FAILURE() << "no decode of " << id.to_string();
    return {};
  }
  Actions tick(milliseconds later) {
    now += later;
    return keep(c.tick(now));
  }
  // The ref of the request that put `id` in flight.
  uint64_t ref_of(RoomId id) const { return c.in_flight().at(id).ref; }
};

// ---- the states the tables start from ----

enum class Start {
  kConnecting,  // connecting() called, no upgrade yet
  kHelloSent,   // upgraded, hello sent, no welcome
  kReady,       // welcomed (limits as the row says), spawned in r0, r0 in flight
  kDecoding,    // kReady and r0's frame accepted: its decode pending, r4 r1 r2 r3 in flight
  kKnown,       // kDecoding and r0 decoded and stored
};

void reach(Harness& h, Start start, const proto::Limits& limits) {
  if (start == Start::kConnecting) return h.c.connecting();
  h.open();
  if (start == Start::kHelloSent) return;
  h.msg(welcome(limits));
  proto::SpawnPoint s;
  s.ref = 2;
  s.room = rid(0);
  s.position = {0, 0, 0};
  h.msg(s);
  if (start == Start::kReady) return;
  h.frame(frame_of(0));
  if (start == Start::kDecoding) return;
  h.decode_ok(rid(0));
}

struct Row {
  const char* name;
  Start start;
  std::function<Actions(Harness&)> input;
  std::vector<std::string> actions;
  StreamState next;
  std::function<void(const Harness&)> check = nullptr;  // more about the next state
  proto::Limits limits{};
  StreamOptions options = fixed_horizon();
};

void run_table(const std::vector<Row>& rows) {
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    Harness h(row.options);
    reach(h, row.start, row.limits);
    const Actions out = row.input(h);
    EXPECT_EQ(describe(out), row.actions);
    EXPECT_EQ(state_name(h.c.state()), std::string(state_name(row.next)))
        << "last_error: " << h.c.stats().last_error;
    if (row.check) row.check(h);
  }
}

StreamOptions with_seed(uint64_t seed) {
  StreamOptions o = fixed_horizon();
  o.seed = seed;
  return o;
}
StreamOptions with_params(uint64_t params) {
  StreamOptions o = fixed_horizon();
  o.params = params;
  return o;
}
StreamOptions with_lod(uint32_t lod) {
  StreamOptions o = fixed_horizon();
  o.lod = lod;
  return o;
}
proto::Limits max_lod(uint32_t lod) {
  proto::Limits l;
  l.max_lod = lod;
  return l;
}

const std::string kRead = "read_limit " + std::to_string(proto::Limits{}.max_frame_bytes);
const std::string kAll4 = "request 0.0.0.r4@0 0.0.0.r1@0 0.0.0.r2@0 0.0.0.r3@0";

auto in_flight_is(std::vector<int> ids) {
  return [ids](const Harness& h) {
    std::vector<RoomId> want;
    for (int i : ids)
      want.push_back(rid(i));
    std::sort(want.begin(), want.end());
    std::vector<RoomId> got;
    for (const auto& [id, _] : h.c.in_flight())
      got.push_back(id);
    EXPECT_EQ(got, want);
  };
}
auto last_error_has(std::string part) {
  return [part](const Harness& h) {
    EXPECT_NE(h.c.stats().last_error.find(part), std::string::npos) << h.c.stats().last_error;
  };
}

// ---- the handshake ----

TEST(Conversation, handshake_table) {
  run_table({
      {"upgrade sends hello",
       Start::kConnecting,
       [](Harness& h) { return h.c.opened(h.now); },
       {"hello"},
       StreamState::kConnecting},
      {"welcome: read limit, spawn",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(welcome()); },
       {kRead, "spawn"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().connects, 1u);
         EXPECT_EQ(h.c.stats().server, "test-server");
       }},
      {"welcome of another version",
       Start::kHelloSent,
       [](Harness& h) {
         auto w = welcome();
         w.version = 3;
         return h.msg(w);
       },
       {"fail"},
       StreamState::kFailed,
       last_error_has("version 3")},
      {"welcome of version 1 (an older server): ready",
       Start::kHelloSent,
       [](Harness& h) {
         auto w = welcome();
         w.version = 1;
         return h.msg(w);
       },
       {kRead, "spawn"},
       StreamState::kReady},
      {"welcome of another seed",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(welcome()); },
       {"fail"},
       StreamState::kFailed,
       last_error_has("seed 7, not the requested 8"),
       {},
       with_seed(8)},
      {"welcome of the seed asked for",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(welcome()); },
       {kRead, "spawn"},
       StreamState::kReady,
       nullptr,
       {},
       with_seed(7)},
      {"welcome of other params",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(welcome()); },
       {"fail"},
       StreamState::kFailed,
       last_error_has("5d1c0a2e9b7f3c44"),
       {},
       with_params(1)},
      {"welcome limits bound reads",
       Start::kHelloSent,
       [](Harness& h) {
         proto::Limits l;
         l.max_frame_bytes = 2048;
         l.max_message_bytes = 4096;
         return h.msg(welcome(l));
       },
       {"read_limit 4096", "spawn"},
       StreamState::kReady},
      {"unsupported_version",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(error(ErrorCode::kUnsupportedVersion, true)); },
       {"fail"},
       StreamState::kFailed,
       last_error_has("unsupported_version")},
      {"world_mismatch",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(error(ErrorCode::kWorldMismatch, true)); },
       {"fail"},
       StreamState::kFailed},
      {"unauthorized",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(error(ErrorCode::kUnauthorized, true)); },
       {"fail"},
       StreamState::kFailed},
      {"unauthorized marked non-fatal is fatal before welcome",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(error(ErrorCode::kUnauthorized, false)); },
       {"fail"},
       StreamState::kFailed},
      {"overloaded before welcome: wait for the close",
       Start::kHelloSent,
       [](Harness& h) { return h.msg(error(ErrorCode::kOverloaded, true)); },
       {},
       StreamState::kConnecting},
      {"overloaded then close: reconnect, the error says why",
       Start::kHelloSent,
       [](Harness& h) {
         h.msg(error(ErrorCode::kOverloaded, true));
         return h.c.closed(kClosePolicy, "overloaded", h.now);
       },
       {"reconnect"},
       StreamState::kBackoff,
       last_error_has("overloaded: test")},
      {"timeout then close",
       Start::kHelloSent,
       [](Harness& h) {
         h.msg(error(ErrorCode::kTimeout, true));
         return h.c.closed(kClosePolicy, "timeout", h.now);
       },
       {"reconnect"},
       StreamState::kBackoff},
      {"invalid text before welcome",
       Start::kHelloSent,
       [](Harness& h) { return h.raw("{not json"); },
       {"reconnect"},
       StreamState::kBackoff,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().errors.at("bad_message"), 1u); }},
      {"room frame before welcome",
       Start::kHelloSent,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"reconnect"},
       StreamState::kBackoff},
      {"spawn_point before welcome is ignored",
       Start::kHelloSent,
       [](Harness& h) {
         proto::SpawnPoint s;
         s.room = rid(0);
         return h.msg(s);
       },
       {},
       StreamState::kConnecting},
      {"no welcome within connect_timeout",
       Start::kHelloSent,
       [](Harness& h) { return h.tick(StreamOptions{}.connect_timeout); },
       {"reconnect"},
       StreamState::kBackoff,
       last_error_has("no welcome")},
      {"tick before the deadline",
       Start::kHelloSent,
       [](Harness& h) { return h.tick(seconds(1)); },
       {},
       StreamState::kConnecting},
      {"connection refused",
       Start::kConnecting,
       [](Harness& h) { return h.c.lost("connecting: refused", h.now); },
       {"reconnect"},
       StreamState::kBackoff},
  });
}

// ---- every server message after welcome ----

TEST(Conversation, server_messages_table) {
  const auto r0 = rid(0);
  run_table({
      {"spawn_point: the start room is requested",
       Start::kHelloSent,
       [](Harness& h) {
         h.msg(welcome());
         proto::SpawnPoint s;
         s.room = rid(0);
         return h.msg(s);
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       in_flight_is({0})},
      {"located: nothing new",
       Start::kReady,
       [](Harness& h) {
         proto::Located l;
         l.room = rid(0);
         return h.msg(l);
       },
       {},
       StreamState::kReady,
       in_flight_is({0})},
      {"located in rock",
       Start::kReady,
       [](Harness& h) { return h.msg(proto::Located{}); },
       {},
       StreamState::kReady},
      {"pong",
       Start::kReady,
       [](Harness& h) { return h.msg(proto::Pong{}); },
       {},
       StreamState::kReady},
      {"stats",
       Start::kReady,
       [](Harness& h) { return h.msg(proto::Stats{}); },
       {},
       StreamState::kReady},
      {"second welcome is noted, nothing else",
       Start::kReady,
       [](Harness& h) { return h.msg(welcome()); },
       {},
       StreamState::kReady,
       last_error_has("second welcome")},
      {"invalid text after welcome: counted, goes on",
       Start::kReady,
       [](Harness& h) { return h.raw("[]"); },
       {},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().errors.at("bad_message"), 1u); }},
      {"not_found: given up",
       Start::kReady,
       [r0](Harness& h) { return h.msg(error(ErrorCode::kNotFound, false, r0)); },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.given_up().count(rid(0)), 1u);
         EXPECT_TRUE(h.c.in_flight().empty());
       }},
      {"internal for a room: asked again",
       Start::kReady,
       [r0](Harness& h) { return h.msg(error(ErrorCode::kInternal, false, r0)); },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       in_flight_is({0})},
      {"internal for a room, third time: given up",
       Start::kReady,
       [r0](Harness& h) {
         h.msg(error(ErrorCode::kInternal, false, r0));
         h.msg(error(ErrorCode::kInternal, false, r0));
         return h.msg(error(ErrorCode::kInternal, false, r0));
       },
       {},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().rooms_given_up, 1u); }},
      {"unknown code: internal, fatal as sent",
       Start::kReady,
       [](Harness& h) {
         return h.raw(R"({"type":"error","code":"teleported","message":"x","room":"0.0.0.r0",)"
                      R"("fatal":false})");
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().errors.at("internal"), 1u); }},
      {"limit_exceeded: the request put nothing in flight, hold",
       Start::kReady,
       [](Harness& h) {
         return h.msg(error(ErrorCode::kLimitExceeded, false, {}, h.ref_of(rid(0))));
       },
       {},
       StreamState::kReady,
       in_flight_is({})},
      {"limit_exceeded: asked again after the hold",
       Start::kReady,
       [](Harness& h) {
         h.msg(error(ErrorCode::kLimitExceeded, false, {}, h.ref_of(rid(0))));
         return h.tick(seconds(1));
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       in_flight_is({0})},
      {"overloaded: hold, nothing requested before it ends",
       Start::kReady,
       [](Harness& h) {
         h.msg(error(ErrorCode::kOverloaded, false, {}, h.ref_of(rid(0))));
         return h.tick(milliseconds(50));
       },
       {},
       StreamState::kReady,
       in_flight_is({})},
      {"bad_json refusal: counted, nothing else",
       Start::kReady,
       [](Harness& h) { return h.msg(error(ErrorCode::kBadJson, false)); },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().errors.at("bad_json"), 1u);
         EXPECT_EQ(h.c.in_flight().size(), 1u);
       }},
      {"bad_message, unknown_type, invalid_room_id, too_large refusals",
       Start::kReady,
       [](Harness& h) {
         h.msg(error(ErrorCode::kBadMessage, false, {}, 99));
         h.msg(error(ErrorCode::kUnknownType, false, {}, 99));
         h.msg(error(ErrorCode::kInvalidRoomId, false, {}, 99));
         return h.msg(error(ErrorCode::kTooLarge, false, {}, 99));
       },
       {},
       StreamState::kReady,
       in_flight_is({0})},
      {"service_restart: a notice, not an error",
       Start::kReady,
       [](Harness& h) { return h.msg(error(ErrorCode::kServiceRestart, true)); },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().restart_notices, 1u);
         EXPECT_TRUE(h.c.stats().errors.empty());
       }},
      {"out_of_order (fatal): wait for the close",
       Start::kReady,
       [](Harness& h) { return h.msg(error(ErrorCode::kOutOfOrder, true)); },
       {},
       StreamState::kReady},
      {"bad_frame (fatal) then close",
       Start::kReady,
       [](Harness& h) {
         h.msg(error(ErrorCode::kBadFrame, true));
         return h.c.closed(kClosePolicy, "bad_frame", h.now);
       },
       {"reconnect"},
       StreamState::kBackoff,
       last_error_has("bad_frame: test")},
      {"unauthorized after welcome",
       Start::kReady,
       [](Harness& h) { return h.msg(error(ErrorCode::kUnauthorized, true)); },
       {"fail"},
       StreamState::kFailed},
  });
}

// ---- close codes and lost connections ----

TEST(Conversation, close_codes_table) {
  auto closed = [](uint16_t code, const char* reason) {
    return [=](Harness& h) { return h.c.closed(code, reason, h.now); };
  };
  auto empties_ledger = [](const Harness& h) {
    EXPECT_TRUE(h.c.in_flight().empty());
    EXPECT_EQ(h.c.stats().drops, 1u);
  };
  run_table({
      {"1000 normal",
       Start::kReady,
       closed(kCloseNormal, ""),
       {"reconnect"},
       StreamState::kBackoff,
       empties_ledger},
      {"1001 service_restart",
       Start::kReady,
       closed(kCloseGoingAway, "service_restart"),
       {"reconnect"},
       StreamState::kBackoff,
       empties_ledger},
      {"1008 unauthorized",
       Start::kReady,
       closed(kClosePolicy, "unauthorized"),
       {"fail"},
       StreamState::kFailed,
       last_error_has("1008 unauthorized")},
      {"1008 world_mismatch",
       Start::kHelloSent,
       closed(kClosePolicy, "world_mismatch"),
       {"fail"},
       StreamState::kFailed},
      {"1008 unsupported_version",
       Start::kHelloSent,
       closed(kClosePolicy, "unsupported_version"),
       {"fail"},
       StreamState::kFailed},
      {"1008 out_of_order",
       Start::kReady,
       closed(kClosePolicy, "out_of_order"),
       {"reconnect"},
       StreamState::kBackoff},
      {"1008 bad_frame",
       Start::kReady,
       closed(kClosePolicy, "bad_frame"),
       {"reconnect"},
       StreamState::kBackoff},
      {"1008 timeout",
       Start::kReady,
       closed(kClosePolicy, "timeout"),
       {"reconnect"},
       StreamState::kBackoff},
      {"1009 too_large",
       Start::kReady,
       closed(kCloseTooBig, "too_large"),
       {"reconnect"},
       StreamState::kBackoff,
       last_error_has("1009")},
      {"1011 internal",
       Start::kReady,
       closed(kCloseInternal, "internal"),
       {"reconnect"},
       StreamState::kBackoff},
      {"read error",
       Start::kReady,
       [](Harness& h) { return h.c.lost("reading: eof", h.now); },
       {"reconnect"},
       StreamState::kBackoff,
       empties_ledger},
      {"close after a final failure: nothing",
       Start::kReady,
       [](Harness& h) {
         h.msg(error(ErrorCode::kUnauthorized, true));
         return h.c.closed(kClosePolicy, "unauthorized", h.now);
       },
       {},
       StreamState::kFailed},
      {"reopened after a drop: hello again",
       Start::kReady,
       [](Harness& h) {
         h.c.lost("reading: eof", h.now);
         h.c.connecting();
         return h.c.opened(h.now);
       },
       {"hello"},
       StreamState::kConnecting},
      {"reconnected: the ledger starts empty and asks again",
       Start::kKnown,
       [](Harness& h) {
         h.c.lost("reading: eof", h.now);
         h.open();
         return h.msg(welcome());
       },
       {kRead, kAll4},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().reconnects, 1u);
         EXPECT_EQ(h.c.store().size(), 1u) << "what was decoded is kept";
       }},
  });
}

// ---- room frames and decodes ----

TEST(Conversation, room_frames_table) {
  run_table({
      {"valid frame in flight: decode, plan its neighbours",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"decode 0.0.0.r0@0", kAll4},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_received, 1u);
         in_flight_is({1, 2, 3, 4})(h);
       }},
      {"frame of another version than welcome's: refused, asked again",
       Start::kReady,
       [](Harness& h) {
         return h.frame(proto::encode_room_frame(rooms().at(rid(0)), 0, Vec3{},
                                                 std::vector<uint8_t>{1, 2, 3}, 1));
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_rejected, 1u);
         EXPECT_NE(h.c.stats().last_error.find("version 1, the session's is 2"), std::string::npos);
       }},
      {"frame of a room not in flight: dropped",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(5)); },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_received, 0u);
         EXPECT_EQ(h.c.graph().find(rid(5)), nullptr);
         in_flight_is({0})(h);
       }},
      {"frame at another lod than requested: refused, asked again",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0, 1)); },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_rejected, 1u);
         EXPECT_EQ(h.c.graph().find(rid(0)), nullptr);
       },
       max_lod(1)},
      {"frame over max_lod: refused",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0, 1)); },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().rooms_rejected, 1u); }},
      {"corrupt frame naming a room in flight: refused, asked again",
       Start::kReady,
       [](Harness& h) {
         auto bytes = frame_of(0);
         bytes[0] = 'X';  // magic
         return h.frame(bytes);
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.stats().rooms_rejected, 1u); }},
      {"truncated frame: refused, the room stays in flight",
       Start::kReady,
       [](Harness& h) {
         auto bytes = frame_of(0);
         bytes.resize(12);
         return h.frame(bytes);
       },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_rejected, 1u);
         in_flight_is({0})(h);
       }},
      {"frame whose portal disagrees with a known neighbour",
       Start::kKnown,
       [](Harness& h) {
         Room r1 = rooms().at(rid(1));
         r1.portals[0].radius = 0.5;  // r1's side of its portal to r0
         return h.frame(proto::encode_room_frame(r1, 0, Vec3{}, std::vector<uint8_t>{1}));
       },
       {"request 0.0.0.r1@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.stats().rooms_rejected, 1u);
         EXPECT_EQ(h.c.graph().find(rid(1)), nullptr);
       }},
      {"decoded: stored, nothing to send",
       Start::kDecoding,
       [](Harness& h) { return h.decode_ok(rid(0)); },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_NE(h.c.room(rid(0)), nullptr);
         EXPECT_EQ(h.c.stats().rooms_ready, 1u);
       }},
      {"corrupt payload: refused, asked again",
       Start::kDecoding,
       [](Harness& h) { return h.decode_fail(rid(0)); },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.room(rid(0)), nullptr);
         EXPECT_EQ(h.c.stats().rooms_rejected, 1u);
       }},
      {"decode finishing after a drop is still stored",
       Start::kDecoding,
       [](Harness& h) {
         h.c.lost("reading: eof", h.now);
         return h.decode_ok(rid(0));
       },
       {},
       StreamState::kBackoff,
       [](const Harness& h) { EXPECT_NE(h.c.room(rid(0)), nullptr); }},
  });
}

// The link's round trip raises the adaptive horizon's floor: when every room takes
// `latency` to come (here the first five rooms, round after round), the p90 rule alone gives
// 1 + 2 x latency, but no room can come sooner than the quickest did, so the floor keeps six of
// those ahead: 1 + 6 x 0.3 s = 2.8 s over a 300 ms link. On loopback (3 ms) the floor stays 1.5 s.
double horizon_after_rooms_that_took(milliseconds latency) {
  Harness h{StreamOptions{}};  // the adaptive horizon, the default
  reach(h, Start::kReady, {});
  Pose fast;  // running: the neighbours are within even the shortest horizon
  fast.room = rid(0);
  fast.speed = 40.0;
  h.c.set_pose(fast);
  // Every room asked for comes `latency` later, round after round, until five have come.
  auto asked_in = [](const Actions& out, std::vector<int>& into) {
    for (const std::string& a : describe(out))
      for (size_t at = a.find(".r"); a.starts_with("request") && at != std::string::npos;
           at = a.find(".r", at + 1))
        into.push_back(std::stoi(a.substr(at + 2)));
  };
  std::vector<int> due = {0};
  int came = 0;
  for (int round = 0; round < 8 && came < 5 && !due.empty(); ++round) {
    h.now += latency;
    std::vector<int> next;
    for (int i : due) {
      asked_in(h.frame(frame_of(i)), next);
      asked_in(h.decode_ok(rid(i)), next);
      ++came;
    }
    due = std::move(next);
  }
  EXPECT_GE(came, 5);
  return h.c.stats().horizon_s;
}

TEST(Conversation, a_far_links_round_trip_raises_the_horizon_floor) {
  EXPECT_NEAR(horizon_after_rooms_that_took(milliseconds(300)), 2.8, 1e-9);
  EXPECT_NEAR(horizon_after_rooms_that_took(milliseconds(3)), 1.5, 1e-9);
  EXPECT_NEAR(horizon_after_rooms_that_took(milliseconds(600)), 4.0, 1e-9);  // at most the max
}

// ---- timers, the in-flight limit, cancels ----

TEST(Conversation, timers_limits_and_cancels_table) {
  proto::Limits two;
  two.max_rooms_in_flight = 2;
  two.max_rooms_per_request = 1;
  StreamOptions own_cap = fixed_horizon();
  own_cap.max_in_flight = 3;
  const StreamOptions adaptive;  // the default
  ASSERT_EQ(adaptive.min_horizon_s, 1.5);
  run_table({
      {"quiet tick: nothing",
       Start::kReady,
       [](Harness& h) { return h.tick(seconds(1)); },
       {},
       StreamState::kReady},
      {"ping before idle_timeout",
       Start::kReady,
       [](Harness& h) { return h.tick(seconds(11)); },
       {"ping"},
       StreamState::kReady},
      {"ping at a third of a short idle_timeout",
       Start::kReady,
       [](Harness& h) { return h.tick(milliseconds(400)); },
       {"ping"},
       StreamState::kReady,
       nullptr,
       [] {
         proto::Limits l;
         l.idle_timeout_ms = 900;
         return l;
       }()},
      {"request_timeout: asked again",
       Start::kReady,
       [](Harness& h) { return h.tick(StreamOptions{}.request_timeout + milliseconds(1)); },
       {"request 0.0.0.r0@0"},
       StreamState::kReady,
       in_flight_is({0})},  // it was a send: no ping
      {"max_rooms_in_flight and max_rooms_per_request",
       Start::kDecoding,
       [](Harness& h) { return h.tick(milliseconds(1)); },
       {},
       StreamState::kReady,
       in_flight_is({1, 4}),
       two},
      {"the server's limit: one room a request",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"decode 0.0.0.r0@0", "request 0.0.0.r4@0", "request 0.0.0.r1@0"},
       StreamState::kReady,
       in_flight_is({1, 4}),
       two},
      {"the client's own cap",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"decode 0.0.0.r0@0", "request 0.0.0.r4@0 0.0.0.r1@0 0.0.0.r2@0"},
       StreamState::kReady,
       in_flight_is({1, 2, 4}),
       {},
       own_cap},
      {"a slot frees: the next room",
       Start::kReady,
       [](Harness& h) {
         h.frame(frame_of(0));
         return h.frame(frame_of(4));
       },
       {"decode 0.0.0.r4@0", "request 0.0.0.r2@0"},
       StreamState::kReady,
       in_flight_is({1, 2}),
       two},
      {"adaptive horizon: rooms come at once, so only what is 1.5 s away is asked for",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"decode 0.0.0.r0@0", "request 0.0.0.r4@0"},
       StreamState::kReady,
       [](const Harness& h) {
         in_flight_is({4})(h);
         EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 1.5);
       },
       {},
       adaptive},
      {"adaptive horizon: a room that took 1.2 s widens it to 1 + 2 x 1.2 = 3.4 s",
       Start::kReady,
       [](Harness& h) {
         h.now += milliseconds(1200);  // no tick: nothing else happens meanwhile
         return h.frame(frame_of(0));
       },
       {"decode 0.0.0.r0@0", "request 0.0.0.r4@0 0.0.0.r1@0 0.0.0.r2@0 0.0.0.r3@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_NEAR(h.c.stats().horizon_s, 3.4, 1e-9); },
       {},
       adaptive},
      {"adaptive horizon: a stream starts at the floor, and an urgent room still waiting "
       "counts, so a slowing server widens it",
       Start::kReady,
       [](Harness& h) {
         EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 1.5);  // r0 asked for at 1.5 s
         h.now += seconds(2);  // r0 (priority 0, urgent) has waited 2 s: 1 + 2 x 2 s, at most 4 s
         Pose p;
         p.room = rid(0);
         p.speed = 4.0;
         h.c.set_pose(p);
         return h.tick(milliseconds(0));
       },
       {},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 4.0); },
       {},
       adaptive},
      {"adaptive horizon: a far room waiting is the server's backlog and does not widen it",
       Start::kReady,
       [](Harness& h) {
         h.frame(frame_of(0));  // at once: 1.5 s, r4 (1.25 s away: not urgent) asked for
         h.now += seconds(2);   // r4 has waited 2 s
         Pose p;
         p.room = rid(0);
         p.speed = 4.0;
         h.c.set_pose(p);
         return h.tick(milliseconds(0));
       },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         in_flight_is({4})(h);
         EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 1.5);
       },
       {},
       adaptive},
      {"adaptive horizon: a far room that came late is not sampled either",
       Start::kReady,
       [](Harness& h) {
         h.frame(frame_of(0));
         h.now += seconds(2);
         return h.frame(frame_of(4));  // 2 s late, but it was not due within a second
       },
       {"decode 0.0.0.r4@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 1.5); },
       {},
       adaptive},
      {"fixed horizon (min_horizon_s 0): 4 s whatever the latency",
       Start::kReady,
       [](Harness& h) { return h.frame(frame_of(0)); },
       {"decode 0.0.0.r0@0", kAll4},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 4.0); }},
      {"adaptive horizon: never past plan.horizon_s (r5 at 4.375 s stays unasked)",
       Start::kReady,
       [](Harness& h) {
         h.now += seconds(9);
         return h.frame(frame_of(0));
       },
       {"decode 0.0.0.r0@0", "request 0.0.0.r4@0 0.0.0.r1@0 0.0.0.r2@0 0.0.0.r3@0"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_DOUBLE_EQ(h.c.stats().horizon_s, 4.0); },
       {},
       adaptive},
      {"turning away: what leaves the horizon is cancelled",
       Start::kDecoding,
       [](Harness& h) {
         Pose p;
         p.room = rid(0);
         p.position = {0, 0, 0};
         p.forward = {-1, 0, 0};
         p.speed = 1.0;  // 5 m to r1's portal, straight behind: 10 s, past 1.5 x 4 s
         h.c.set_pose(p);
         return h.tick(milliseconds(100));
       },
       {"cancel 0.0.0.r1 0.0.0.r3 0.0.0.r4"},
       StreamState::kReady,
       [](const Harness& h) {
         in_flight_is({2})(h);
         EXPECT_EQ(h.c.stats().cancels_sent, 3u);
       }},
      {"a cancelled room's frame is dropped",
       Start::kDecoding,
       [](Harness& h) {
         Pose p;
         p.room = rid(0);
         p.forward = {-1, 0, 0};
         p.speed = 1.0;
         h.c.set_pose(p);
         h.tick(milliseconds(100));
         return h.frame(frame_of(1));
       },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.graph().find(rid(1)), nullptr);
         EXPECT_EQ(h.c.stats().rooms_received, 1u);  // r0's only
       }},
      {"no start room: locate, at most once a second",
       Start::kHelloSent,
       [](Harness& h) {
         Pose p;
         p.position = {100, 0, 0};
         h.c.set_pose(p);
         EXPECT_EQ(describe(h.msg(welcome())), (std::vector<std::string>{kRead, "locate"}));
         h.c.set_pose(p);
         EXPECT_EQ(describe(h.tick(milliseconds(100))), std::vector<std::string>{});
         h.c.set_pose(p);
         return h.tick(seconds(2));
       },
       {"locate"},
       StreamState::kReady},
      {"located answers the start room",
       Start::kHelloSent,
       [](Harness& h) {
         Pose p;
         p.position = {1, 0, 0};
         h.c.set_pose(p);
         h.msg(welcome());
         proto::Located l;
         l.room = rid(0);
         return h.msg(l);
       },
       {"request 0.0.0.r0@0"},
       StreamState::kReady},
  });
}

// ---- reconnect backoff ----

TEST(Conversation, reconnect_backoff_doubles_with_jitter_up_to_the_cap_and_resets_on_welcome) {
  StreamOptions o = fixed_horizon();
  o.backoff_initial = milliseconds(100);
  o.backoff_max = milliseconds(1000);
  Harness h(o);
  auto delay_of = [](const Actions& a) {
    EXPECT_EQ(a.size(), 1u);
    const auto* r = a.empty() ? nullptr : std::get_if<Reconnect>(&a[0]);
    EXPECT_NE(r, nullptr);
    return r ? r->delay.count() : -1;
  };
  const int64_t bases[] = {100, 200, 400, 800, 1000, 1000};
  for (int64_t base : bases) {
    h.c.connecting();
    const int64_t d = delay_of(h.c.lost("connecting: refused", h.now));
    EXPECT_GE(d, base / 2) << base;
    EXPECT_LE(d, base) << base;
  }
  // A welcome resets the count.
  h.open();
  h.msg(welcome());
  int64_t d = delay_of(h.c.lost("reading: eof", h.now));
  EXPECT_GE(d, 50);
  EXPECT_LE(d, 100);
  // service_restart reconnects within restart_spread, however many attempts failed before.
  for (int i = 0; i < 4; ++i) {
    h.c.connecting();
    h.c.lost("connecting: refused", h.now);
  }
  h.open();
  d = delay_of(h.c.closed(kCloseGoingAway, "service_restart", h.now));
  EXPECT_GE(d, 50);
  EXPECT_LE(d, 1000);
  // Same seed, same delays: the jitter is the generator's, not the clock's.
  Conversation a(o, 7), b(o, 7);
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(a.backoff_delay(i), b.backoff_delay(i));
}

// The players a drained replica sends away come back spread over restart_spread, not all within
// the first 100 ms (what a replica taking 300 of them over cannot absorb at once).
TEST(Conversation, restart_reconnects_spread_over_restart_spread) {
  StreamOptions o = fixed_horizon();
  o.restart_spread = milliseconds(2000);
  std::vector<int64_t> delays;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    Conversation c(o, seed);
    c.connecting();
    c.opened(SteadyTime{});
    Actions a = c.closed(kCloseGoingAway, "service_restart", SteadyTime{});
    ASSERT_EQ(a.size(), 1u);
    ASSERT_TRUE(std::holds_alternative<Reconnect>(a[0]));
    delays.push_back(std::get<Reconnect>(a[0]).delay.count());
  }
  std::sort(delays.begin(), delays.end());
  EXPECT_GE(delays.front(), 50);
  EXPECT_LE(delays.back(), 2000);
  // Uniform: a quarter of them in each quarter of [50, 2000] ms, give or take.
  const auto in = [&](int64_t lo, int64_t hi) {
    return std::count_if(delays.begin(), delays.end(),
                         [&](int64_t d) { return d >= lo && d < hi; });
  };
  EXPECT_GT(in(50, 537), 30);
  EXPECT_GT(in(1512, 2001), 30);
  o.restart_spread = milliseconds(99);  // below backoff_initial (100 ms)
  EXPECT_FALSE(validate_options(o));
}

// ---- one lod a session ----

// Every room held and every room in flight is at the session's lod (rooms of lod 0 next to rooms
// of lod 1 do not share rims).
void expect_one_lod(const Conversation& c) {
  for (auto id : c.store().ids())
    EXPECT_EQ(c.room(id)->lod, c.lod()) << id.to_string();
  for (const auto& [id, f] : c.in_flight())
    EXPECT_EQ(f.lod, c.lod()) << id.to_string();
}

TEST(Conversation, neighbouring_rooms_are_never_held_or_requested_at_two_lods) {
  Harness h(with_lod(1));
  h.open();
  EXPECT_EQ(describe(h.msg(welcome(max_lod(1)))), (std::vector<std::string>{kRead, "spawn"}));
  proto::SpawnPoint s;
  s.room = rid(0);
  EXPECT_EQ(describe(h.msg(s)), std::vector<std::string>{"request 0.0.0.r0@1"});
  h.frame(frame_of(0, 1));
  h.decode_ok(rid(0));
  h.frame(frame_of(4, 1));  // r4's decode is still running when the connection drops
  ASSERT_EQ(h.c.lod(), 1u);
  expect_one_lod(h.c);
  EXPECT_NE(h.c.room(rid(0)), nullptr);

  // Back on a replica that serves lod 0 only: what was held at lod 1 goes, the neighbourhood is
  // asked for again at lod 0, and r4's late lod-1 decode is not stored.
  h.c.closed(kCloseGoingAway, "service_restart", h.now);
  h.open();
  EXPECT_EQ(describe(h.msg(welcome(max_lod(0)))),
            (std::vector<std::string>{
                kRead, "request 0.0.0.r0@0 0.0.0.r4@0 0.0.0.r1@0 0.0.0.r2@0 0.0.0.r3@0"}));
  EXPECT_EQ(h.c.lod(), 0u);
  EXPECT_EQ(h.c.store().size(), 0u);
  auto evicted = h.c.take_evicted();
  EXPECT_EQ(evicted, std::vector<RoomId>{rid(0)});
  h.decode_ok(rid(4));
  EXPECT_EQ(h.c.room(rid(4)), nullptr);
  expect_one_lod(h.c);

  // A lod-1 frame on this connection is refused; the lod-0 one is used.
  EXPECT_EQ(describe(h.frame(frame_of(0, 1))),  // over max_lod: refused, asked again
            std::vector<std::string>{"request 0.0.0.r0@0"});
  h.frame(frame_of(0, 0));
  h.decode_ok(rid(0));
  ASSERT_NE(h.c.room(rid(0)), nullptr);
  EXPECT_EQ(h.c.room(rid(0))->lod, 0u);
  expect_one_lod(h.c);

  // And back to a lod-1 server: the lod-0 rooms go in turn.
  h.c.closed(kCloseGoingAway, "service_restart", h.now);
  h.open();
  h.msg(welcome(max_lod(1)));
  EXPECT_EQ(h.c.lod(), 1u);
  EXPECT_EQ(h.c.store().size(), 0u);
  expect_one_lod(h.c);
}

TEST(Conversation, a_world_change_drops_every_room_and_asks_for_a_spawn_again) {
  Harness h;
  reach(h, Start::kKnown, {});
  h.c.lost("reading: eof", h.now);
  h.open();
  auto w = welcome();
  w.seed = 8;
  EXPECT_EQ(describe(h.msg(w)), (std::vector<std::string>{kRead, "spawn"}));
  EXPECT_EQ(h.c.store().size(), 0u);
  EXPECT_EQ(h.c.graph().size(), 0u);
  EXPECT_EQ(h.c.take_evicted(), std::vector<RoomId>{rid(0)});
}

TEST(Conversation, stop_ends_every_action) {
  Harness h;
  reach(h, Start::kDecoding, {});
  h.c.stop();
  EXPECT_EQ(h.c.state(), StreamState::kStopped);
  EXPECT_TRUE(h.frame(frame_of(4)).empty());
  EXPECT_TRUE(h.tick(seconds(60)).empty());
  EXPECT_TRUE(h.c.lost("x", h.now).empty());
  EXPECT_TRUE(h.decode_ok(rid(0)).empty());
  EXPECT_EQ(h.c.state(), StreamState::kStopped);
}

// ---- pinned areas (Stream::wait_area_ready) ----

// The ref of the (first) locate among `actions`, for the located reply.
uint64_t locate_ref(const Actions& actions) {
  for (const auto& a : actions) {
    const auto* m = std::get_if<SendMessage>(&a);
    if (!m) continue;
    if (const auto* l = std::get_if<proto::Locate>(&m->message)) return l->ref.value_or(0);
  }
  ADD_FAILURE() << "no locate";
  return 0;
}

proto::Located located(uint64_t ref, std::optional<RoomId> room) {
  proto::Located l;
  l.ref = ref;
  l.room = room;
  return l;
}

// An area around r10's centre, 6 m along the portal graph: r10, and r11 (its portal is 5 m away);
// r12 is 5 + 10 = 15 m away. The player stands at the origin, from where no plan reaches r10.
AreaPin far_area(const Harness& h, double radius_m = 6.0, uint32_t max_lod = 0,
                 std::chrono::milliseconds for_how_long = seconds(10)) {
  return AreaPin{{100, 0, 0}, radius_m, max_lod, h.now + for_how_long};
}

// The pin, its locate and the server's answer (r10): r10 requested.
Actions pin_and_locate(Harness& h, AreaPin pin) {
  h.c.pin_area(pin);
  const uint64_t ref = locate_ref(h.tick(milliseconds(100)));
  return h.msg(located(ref, rid(10)));
}

TEST(Conversation, pinned_areas_table) {
  StreamOptions two;
  two.max_in_flight = 2;
  run_table({
      {"an area no known room holds: the server is asked where its point lies",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area(far_area(h));
         return h.tick(milliseconds(100));
       },
       {"locate"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.pinned_areas(), 1u); }},
      {"located: the room holding the point is requested, priority 0, though the pose is 100 m "
       "away",
       Start::kKnown,
       [](Harness& h) { return pin_and_locate(h, far_area(h)); },
       {"request 0.0.0.r10@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.in_flight().at(rid(10)).priority, 0u);
         EXPECT_EQ(h.c.pinned(), std::set<RoomId>{rid(10)});
         EXPECT_FALSE(h.c.wanted().count(rid(10)));
       }},
      {"its frame extends the area: the neighbours within the radius are requested",
       Start::kKnown,
       [](Harness& h) {
         pin_and_locate(h, far_area(h));
         return h.frame(frame_of(10));
       },
       {"decode 0.0.0.r10@0", "request 0.0.0.r11@0"},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.pinned(), (std::set<RoomId>{rid(10), rid(11)}));
       }},
      {"the area ends at its radius: r12, 15 m away, is not asked for",
       Start::kKnown,
       [](Harness& h) {
         pin_and_locate(h, far_area(h));
         h.frame(frame_of(10));
         return h.frame(frame_of(11));
       },
       {"decode 0.0.0.r11@0"},
       StreamState::kReady},
      {"a larger radius takes r12 too",
       Start::kKnown,
       [](Harness& h) {
         pin_and_locate(h, far_area(h, 15.0));
         h.frame(frame_of(10));
         return h.frame(frame_of(11));
       },
       {"decode 0.0.0.r11@0", "request 0.0.0.r12@0"},
       StreamState::kReady},
      {"within the cap on rooms in flight, the area's rooms go before the pose's",
       Start::kReady,
       [](Harness& h) {
         // r0 (the spawn) and r10 fill the two slots; r0's frame frees one for the pose's r4.
         EXPECT_EQ(describe(pin_and_locate(h, far_area(h))),
                   std::vector<std::string>{"request 0.0.0.r10@0"});
         EXPECT_EQ(describe(h.frame(frame_of(0))),
                   (std::vector<std::string>{"decode 0.0.0.r0@0", "request 0.0.0.r4@0"}));
         // r10's frame frees the other: the area's r11 comes before the pose's r1, r2, r3.
         return h.frame(frame_of(10));
       },
       {"decode 0.0.0.r10@0", "request 0.0.0.r11@0"},
       StreamState::kReady,
       in_flight_is({4, 11}),
       {},
       two},
      {"turning away cancels the pose's rooms, not the area's",
       Start::kKnown,
       [](Harness& h) {
         pin_and_locate(h, far_area(h));
         Pose p;
         p.room = rid(0);
         p.forward = {-1, 0, 0};
         p.speed = 1.0;
         h.c.set_pose(p);
         return h.tick(milliseconds(100));
       },
       {"cancel 0.0.0.r1 0.0.0.r3 0.0.0.r4"},
       StreamState::kReady,
       in_flight_is({2, 10})},
      {"unpinned: the area's rooms in flight are ordinary, and cancelled at the next tick",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area(far_area(h));
         const uint64_t pin = h.c.pin_area(far_area(h));  // two waits on one area
         h.msg(located(locate_ref(h.tick(milliseconds(100))), rid(10)));
         h.c.unpin_area(pin);
         EXPECT_TRUE(describe(h.tick(milliseconds(100))).empty()) << "the other wait goes on";
         h.c.unpin_area(1);
         EXPECT_TRUE(h.c.pinned().empty());
         return h.tick(milliseconds(100));
       },
       {"cancel 0.0.0.r10"},
       StreamState::kReady,
       in_flight_is({1, 2, 3, 4})},
      {"past its deadline a pin lapses by itself",
       Start::kKnown,
       [](Harness& h) {
         pin_and_locate(h, far_area(h, 6.0, 0, seconds(1)));
         return h.tick(seconds(1));
       },
       {"cancel 0.0.0.r10"},
       StreamState::kReady,
       [](const Harness& h) { EXPECT_EQ(h.c.pinned_areas(), 0u); }},
      {"a point a known room holds needs no locate: its area's rooms are known or in flight",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area({{0, 0, 0}, 16.0, 0, h.now + seconds(10)});
         return h.tick(milliseconds(100));
       },
       {},
       StreamState::kReady,
       [](const Harness& h) {
         EXPECT_EQ(h.c.pinned(), (std::set<RoomId>{rid(0), rid(1), rid(2), rid(3), rid(4)}));
       }},
      {"in rock: not asked again on this connection",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area(far_area(h));
         h.msg(located(locate_ref(h.tick(milliseconds(100))), std::nullopt));
         return h.tick(seconds(2));
       },
       {},
       StreamState::kReady},
      {"located again after a reconnect",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area(far_area(h));
         h.msg(located(locate_ref(h.tick(milliseconds(100))), std::nullopt));
         h.c.lost("reading: eof", h.now);
         h.open();
         return h.msg(welcome());
       },
       {kRead, "locate", kAll4},
       StreamState::kReady},
      {"a point beyond the protocol's coordinates is never sent",
       Start::kKnown,
       [](Harness& h) {
         h.c.pin_area({{1e300, 0, 0}, 1.0, 0, h.now + seconds(10)});
         h.c.pin_area({{std::nan(""), 0, 0}, 1.0, 0, h.now + seconds(10)});
         return h.tick(milliseconds(100));
       },
       {},
       StreamState::kReady},
      {"an area asked for below the session's lod fetches nothing (one lod a session)",
       Start::kReady,
       [](Harness& h) {
         h.c.pin_area(far_area(h, 6.0, /*max_lod=*/0));
         return h.tick(milliseconds(100));
       },
       {},
       StreamState::kReady,
       nullptr,
       max_lod(1),
       with_lod(1)},
      {"at or above it, the area comes at the session's lod",
       Start::kReady,
       [](Harness& h) { return pin_and_locate(h, far_area(h, 6.0, /*max_lod=*/5)); },
       {"request 0.0.0.r10@1"},
       StreamState::kReady,
       nullptr,
       max_lod(1),
       with_lod(1)},
  });
}

// The store keeps a pinned area's rooms however far they are from the player and however small
// its budget, and evicts them like any other room once the area is unpinned.
TEST(Conversation, a_pinned_areas_rooms_are_not_evicted_until_it_is_unpinned) {
  StreamOptions o = fixed_horizon();
  o.store_bytes = 1;  // every room is over budget: only what a plan keeps stays
  Harness h(o);
  reach(h, Start::kKnown, {});
  ASSERT_TRUE(h.c.room(rid(0))) << "the pose's room is wanted";
  const uint64_t pin = h.c.pin_area(far_area(h));
  pin_and_locate(h, far_area(h));  // a second pin on the same area, lapsing with the first
  h.frame(frame_of(10));
  h.decode_ok(rid(10));
  h.frame(frame_of(11));
  h.decode_ok(rid(11));
  EXPECT_TRUE(h.c.room(rid(10)));
  EXPECT_TRUE(h.c.room(rid(11)));
  EXPECT_TRUE(h.c.take_evicted().empty());
  // The player's neighbours still arrive and stay (wanted); the area's rooms, 94 and 104 m from
  // the player, are the farthest, and still stay.
  h.frame(frame_of(4));
  h.decode_ok(rid(4));
  EXPECT_TRUE(h.c.take_evicted().empty());
  EXPECT_EQ(h.c.store().size(), 4u);

  h.c.unpin_area(pin);
  h.c.unpin_area(pin + 1);
  ASSERT_EQ(h.c.pinned_areas(), 0u);
  h.frame(frame_of(1));
  h.decode_ok(rid(1));
  EXPECT_EQ(h.c.take_evicted(), (std::vector<RoomId>{rid(11), rid(10)})) << "farthest first";
  EXPECT_FALSE(h.c.room(rid(10)));
  EXPECT_EQ(h.c.graph().find(rid(10)), nullptr) << "the descriptors go with them";
  EXPECT_TRUE(h.c.room(rid(0)));
  EXPECT_TRUE(h.c.room(rid(4)));
}

// Past a server's capacity (PROTOCOL.md, "Waiting to enter").
TEST(Conversation, the_admission_queue) {
  auto hello_of = [](const Actions& a) -> std::optional<proto::Hello> {
    for (const auto& x : a) {
      if (const auto* m = std::get_if<SendMessage>(&x)) {
        if (const auto* h = std::get_if<proto::Hello>(&m->message)) return *h;
      }
    }
    return std::nullopt;
  };
  {
    Harness h;
    auto hello = hello_of(h.open());
    ASSERT_TRUE(hello);
    EXPECT_TRUE(hello->queue) << "a stream says it can wait";
    StreamOptions o = fixed_horizon();
    o.queue = false;
    Harness plain(o);
    hello = hello_of(plain.open());
    ASSERT_TRUE(hello);
    EXPECT_FALSE(hello->queue);
  }
  {
    Harness h;
    h.open();
    EXPECT_TRUE(h.msg(proto::Queued{1, 3, 4000, 5}).empty());
    auto s = h.c.stats();
    EXPECT_EQ(s.state, StreamState::kConnecting);
    ASSERT_TRUE(s.queued);
    EXPECT_EQ(s.queued->position, 3u);
    EXPECT_EQ(s.queued->wait_ms, 4000u);
    EXPECT_EQ(s.queued->queue, 5u);
    EXPECT_EQ(s.times_queued, 1u);
    // Queued past connect_timeout: the server is talking, no reconnect; a ping now and then.
    Actions a = h.tick(milliseconds(6'000));
    for (const auto& x : a)
      EXPECT_FALSE(std::holds_alternative<Reconnect>(x)) << describe(x);
    a = h.tick(milliseconds(6'000));
    ASSERT_EQ(a.size(), 1u);
    EXPECT_EQ(describe(a[0]), "ping");
    ASSERT_TRUE(h.c.stats().queued) << "ticks keep the place";
    EXPECT_EQ(h.c.stats().queued->position, 3u);
    h.msg(proto::Queued{1, 1, 1000, 2});
    EXPECT_EQ(h.c.stats().queued->position, 1u);
    h.tick(milliseconds(3'000));
    // Admitted: ready, no longer queued, the time it waited counted.
    EXPECT_FALSE(h.msg(welcome()).empty());
    s = h.c.stats();
    EXPECT_EQ(s.state, StreamState::kReady);
    EXPECT_FALSE(s.queued);
    EXPECT_EQ(s.times_queued, 1u);
    EXPECT_DOUBLE_EQ(s.queued_ms, 15'000);
  }
  {
    // Refused with a time to come back: the reconnect waits at least that long.
    Harness h;
    h.open();
    proto::ErrorMessage e;
    e.ref = 1;
    e.code = ErrorCode::kOverloaded;
    e.message = "the server is full";
    e.fatal = true;
    e.retry_after_ms = 7'000;
    h.msg(e);
    Actions a = h.c.closed(kClosePolicy, "overloaded", h.now);
    ASSERT_EQ(a.size(), 1u);
    const auto* r = std::get_if<Reconnect>(&a[0]);
    ASSERT_NE(r, nullptr);
    EXPECT_GE(r->delay.count(), 7'000);
    // Only once: the next failure backs off as usual.
    h.c.connecting();
    a = h.c.lost("connecting: refused", h.now);
    ASSERT_EQ(a.size(), 1u);
    EXPECT_LT(std::get<Reconnect>(a[0]).delay.count(), 7'000);
  }
}

}  // namespace
}  // namespace grotto::stream
