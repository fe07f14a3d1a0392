// The server's protocol core without sockets: each row feeds a conversation some events (the
// state it starts from), then one more (the input), and checks the actions that input returned
// and the state it left. Every client message, every documented error and every close code has
// a row; tests/server/server_test.cpp checks the same over real WebSocket connections.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "proto/messages.hpp"
#include "server/conversation.hpp"

namespace grotto::server {
namespace {

using std::chrono::milliseconds;

constexpr uint64_t kSeed = 7;
constexpr uint64_t kDigest = 0x1234abcd5678ef90ull;

cave::RoomId room(const char* text) {
  return cave::RoomId::parse(text).value();
}

// The generator as a table: which seeds open, where points are, where players start.
class FakeWorlds : public WorldPort {
 public:
  uint64_t own_seed() const override { return kSeed; }
  Result<ClientId> open(uint64_t seed, uint32_t version) override {
    if (auto it = refuse.find(seed); it != refuse.end()) return it->second;
    opened_version = version;
    return ClientId{41};
  }
  std::optional<cave::RoomId> locate(ClientId, Vec3 point) override {
    if (point.x < 0) return std::nullopt;
    return room("0.0.0.r3");
  }
  cave::Spawn spawn(ClientId) override {
    cave::Spawn s;
    s.room = room("0.0.0.r0");
    s.position = {1, 2, 3};
    return s;
  }
  Entry enter(bool can_queue) override {
    asked_queue = can_queue;
    return entry;
  }
  Entry entry;  // what admission says to a valid hello (admitted unless a row says otherwise)
  bool asked_queue = false;
  uint32_t opened_version = 0;  // the version the last client opened was framed for
  std::map<uint64_t, Error> refuse = {
      {8, Error{ErrorCode::kWorldMismatch, "this server serves seed 7, not 8"}},
      {9, Error{ErrorCode::kOverloaded, "every world is open and in use"}}};
};

// One action as a line of text, so a row states what it expects in a few words.
std::string describe(const Action& action) {
  struct Visitor {
    std::string operator()(const act::SendText& a) {
      auto m = proto::parse_server_message(a.text, proto::Limits{});
      if (!m) return "unparsable " + a.text;
      return std::visit([](const auto& x) { return describe_message(x); }, m.value());
    }
    std::string operator()(const act::SendRoom& a) {
      return "room " + a.room->key.id.to_string() + "@" + std::to_string(a.room->key.lod);
    }
    std::string operator()(const act::Want& a) {
      std::string s = "want";
      for (const auto& w : a.rooms)
        s +=
            " " + w.id.to_string() + "@" + std::to_string(w.lod) + "/" + std::to_string(w.priority);
      return s;
    }
    std::string operator()(const act::Drop& a) {
      std::string s = "drop";
      for (const auto& id : a.rooms)
        s += " " + id.to_string();
      return s;
    }
    std::string operator()(const act::Release&) { return "release"; }
    std::string operator()(const act::Timer& a) {
      return "timer " + std::to_string(a.after.count());
    }
    std::string operator()(const act::Pace& a) { return "pace " + std::to_string(a.after.count()); }
    std::string operator()(const act::Close& a) {
      // "now": without waiting for the client's close frame (only the short grace).
      return "close " + std::to_string(static_cast<int>(a.code)) + " " + a.reason +
             (a.await_reply ? "" : " now");
    }

    static std::string ref_text(const proto::Ref& ref) {
      return ref ? " ref=" + std::to_string(*ref) : "";
    }
    static std::string describe_message(const proto::Welcome& m) {
      return "welcome v" + std::to_string(m.version) + " seed=" + std::to_string(m.seed) +
             ref_text(m.ref);
    }
    static std::string describe_message(const proto::Located& m) {
      return "located " + (m.room ? m.room->to_string() : std::string("null")) + ref_text(m.ref);
    }
    static std::string describe_message(const proto::SpawnPoint& m) {
      return "spawn_point " + m.room.to_string() + ref_text(m.ref);
    }
    static std::string describe_message(const proto::ErrorMessage& m) {
      std::string s = std::string("error ") + proto::wire_code_name(m.code) +
                      (m.fatal ? " fatal" : "") + ref_text(m.ref);
      if (m.room) s += " room=" + m.room->to_string();
      for (uint32_t v : m.versions)
        s += " v" + std::to_string(v);
      if (m.retry_after_ms) s += " retry=" + std::to_string(*m.retry_after_ms);
      return s;
    }
    static std::string describe_message(const proto::Queued& m) {
      return "queued pos=" + std::to_string(m.position) + " wait=" + std::to_string(m.wait_ms) +
             " of=" + std::to_string(m.queue) + ref_text(m.ref);
    }
    static std::string describe_message(const proto::Pong& m) {
      return "pong t=" + std::to_string(static_cast<int>(m.t)) +
             " time=" + std::to_string(m.time_ms) + ref_text(m.ref);
    }
    static std::string describe_message(const proto::Stats& m) {
      return "stats in_flight=" + std::to_string(m.in_flight) +
             " rooms_sent=" + std::to_string(m.rooms_sent) +
             " bytes_sent=" + std::to_string(m.bytes_sent) + " errors=" + std::to_string(m.errors) +
             ref_text(m.ref);
    }
  };
  return std::visit(Visitor{}, action);
}

// ---- events ----

using Event = std::function<void(Conversation&)>;

Event admit(Admission a = Admission::kAdmitted) {
  return [a](Conversation& c) { c.admit(a); };
}
Event text(std::string t) {
  return [t](Conversation& c) { c.text(t); };
}
Event binary() {
  return [](Conversation& c) { c.binary(); };
}
Event oversized() {
  return [](Conversation& c) { c.oversized(); };
}
Event deadline() {
  return [](Conversation& c) { c.deadline(); };
}
Event pace() {
  return [](Conversation& c) { c.pace(); };
}
Event shutdown() {
  return [](Conversation& c) { c.shutdown(); };
}
Event slow() {
  return [](Conversation& c) { c.slow_client(); };
}
Event sent(uint64_t bytes) {
  return [bytes](Conversation& c) { c.sent(bytes); };
}
Event gone() {
  return [](Conversation& c) { c.transport_closed(); };
}
Event deliver(const char* id, uint8_t lod = 0, size_t frame_bytes = 3) {
  return [id, lod, frame_bytes](Conversation& c) {
    auto r = std::make_shared<EncodedRoom>();
    r->key = {room(id), lod, kSeed};
    r->frame.assign(frame_bytes, 1);
    Delivery d;
    d.key = r->key;
    d.room = r;
    c.delivery(std::move(d));
  };
}
Event fail_room(const char* id, ErrorCode code, uint8_t lod = 0) {
  return [id, code, lod](Conversation& c) {
    Delivery d;
    d.key = {room(id), lod, kSeed};
    d.error = Error{code, "no such room"};
    c.delivery(std::move(d));
  };
}

uint64_t fake_steady_ms = 0;  // the request rate's clock in these tests
Event wait_ms(uint64_t ms) {
  return [ms](Conversation&) { fake_steady_ms += ms; };
}
std::string request_of(int rooms, int first = 0) {
  std::string s = R"({"type":"request","ref":30,"rooms":[)";
  for (int i = 0; i < rooms; ++i) {
    s += (i ? "," : "") + std::string(R"({"id":"2.0.0.r)") + std::to_string(first + i) +
         R"(","lod":0,"priority":0})";
  }
  return s + "]}";
}

const std::string kHello = R"({"type":"hello","ref":1,"versions":[1]})";
const std::vector<Event> kOpen = {admit(), text(kHello)};
std::vector<Event> open_then(std::vector<Event> more) {
  std::vector<Event> all = kOpen;
  all.insert(all.end(), more.begin(), more.end());
  return all;
}
const std::string kRequest3 =
    R"({"type":"request","ref":5,"rooms":[{"id":"0.0.0.r2","lod":0,"priority":9},)"
    R"({"id":"0.0.0.r1","lod":0,"priority":3},{"id":"0.0.0.r3","lod":1,"priority":3}]})";

using State = Conversation::State;

struct Row {
  const char* name;
  std::vector<Event> given;
  Event when;
  std::vector<std::string> then;
  State state;
};

ConversationConfig config(std::string token = {}) {
  ConversationConfig c;
  c.limits.max_lod = 1;
  c.limits.max_rooms_in_flight = 4;
  c.limits.max_rooms_per_request = 8;
  c.limits.max_message_bytes = 1024;
  c.limits.idle_timeout_ms = 60'000;
  c.limits.handshake_timeout_ms = 10'000;
  c.token = std::move(token);
  c.params_digest = kDigest;
  c.server_name = "grotto-server test";
  c.max_connections = 2;
  c.unix_ms = [] { return uint64_t{1000}; };
  c.steady_ms = [] { return fake_steady_ms; };
  return c;
}

void run(const std::vector<Row>& rows, const ConversationConfig& cfg = config(), Entry entry = {}) {
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    FakeWorlds worlds;
    worlds.entry = entry;
    Conversation c(cfg, worlds, nullptr);
    for (const Event& e : row.given)
      e(c);
    c.take();
    row.when(c);
    std::vector<std::string> got;
    for (const Action& a : c.take())
      got.push_back(describe(a));
    EXPECT_EQ(got, row.then);
    EXPECT_EQ(static_cast<int>(c.state()), static_cast<int>(row.state));
  }
}

TEST(Conversation, admission_and_the_handshake) {
  run({
      {"admitted: the handshake timer starts", {}, admit(), {"timer 10000"}, State::kAwaitingHello},
      {"over max_connections: overloaded before any hello, close 1008",
       {},
       admit(Admission::kFull),
       {"error overloaded fatal", "close 1008 overloaded"},
       State::kClosed},
      {"max_handshakes waiting for hello: overloaded before any hello, close 1008",
       {},
       admit(Admission::kHandshakesFull),
       {"error overloaded fatal", "close 1008 overloaded"},
       State::kClosed},
      {"while stopping: service_restart, close 1001",
       {},
       admit(Admission::kStopping),
       {"error service_restart fatal", "close 1001 service_restart"},
       State::kClosed},
      {"hello: welcome with the server's seed, then the idle timer",
       {admit()},
       text(kHello),
       {"welcome v1 seed=7 ref=1", "timer 60000"},
       State::kOpen},
      {"hello naming another world that opens",
       {admit()},
       text(R"({"type":"hello","versions":[1,2],"seed":"11"})"),
       {"welcome v2 seed=11", "timer 60000"},
       State::kOpen},
      {"hello for a seed a one-world server does not serve: world_mismatch, 1008",
       {admit()},
       text(R"({"type":"hello","ref":2,"versions":[1],"seed":"8"})"),
       {"error world_mismatch fatal ref=2", "close 1008 world_mismatch"},
       State::kClosed},
      {"hello for a world with no free slot: overloaded, 1008",
       {admit()},
       text(R"({"type":"hello","versions":[1],"seed":"9"})"),
       {"error overloaded fatal", "close 1008 overloaded"},
       State::kClosed},
      {"hello with another parameter digest: world_mismatch",
       {admit()},
       text(R"({"type":"hello","versions":[1],"params":"0000000000000001"})"),
       {"error world_mismatch fatal", "close 1008 world_mismatch"},
       State::kClosed},
      {"hello with its own digest is welcome",
       {admit()},
       text(R"({"type":"hello","versions":[1],"params":"1234abcd5678ef90"})"),
       {"welcome v1 seed=7", "timer 60000"},
       State::kOpen},
      {"no version in common: unsupported_version lists the server's",
       {admit()},
       text(R"({"type":"hello","ref":3,"versions":[3,4]})"),
       {"error unsupported_version fatal ref=3 v1 v2", "close 1008 unsupported_version"},
       State::kClosed},
      {"a message before hello: out_of_order",
       {admit()},
       text(R"({"type":"ping","ref":4,"t":1})"),
       {"error out_of_order fatal ref=4", "close 1008 out_of_order"},
       State::kClosed},
      {"a message before hello with a bad field: out_of_order still (order before fields)",
       {admit()},
       text(R"({"type":"ping","t":"x"})"),
       {"error out_of_order fatal", "close 1008 out_of_order"},
       State::kClosed},
      {"before welcome every error is fatal: bad_json",
       {admit()},
       text("{nope"),
       {"error bad_json fatal", "close 1008 bad_json"},
       State::kClosed},
      {"before welcome every error is fatal: bad_message",
       {admit()},
       text(R"({"type":"hello","ref":6,"versions":"1"})"),
       {"error bad_message fatal ref=6", "close 1008 bad_message"},
       State::kClosed},
      {"before welcome a field over its limit is too_large, fatal, close 1009",
       {admit()},
       text(R"({"type":"hello","versions":[1],"seed":")" + std::string(70, '1') + R"("})"),
       {"error too_large fatal", "close 1009 too_large"},
       State::kClosed},
      {"before welcome every error is fatal: unknown_type",
       {admit()},
       text(R"({"type":"teleport"})"),
       {"error unknown_type fatal", "close 1008 unknown_type"},
       State::kClosed},
      {"no hello within handshake_timeout_ms: timeout, 1008",
       {admit()},
       deadline(),
       {"error timeout fatal", "close 1008 timeout now"},
       State::kClosed},
      {"a second hello: out_of_order, whatever its fields",
       kOpen,
       text(R"({"type":"hello","ref":7,"versions":"x"})"),
       {"timer 60000", "release", "error out_of_order fatal ref=7", "close 1008 out_of_order"},
       State::kClosed},
  });
}

// PROTOCOL.md, "Which error a message gets": the token is the first thing checked of what hello
// asks (step 6), before the version and the world; the message's form (steps 1-5) comes first.
TEST(Conversation, the_token_comes_first_of_what_hello_asks) {
  run(
      {
          {"missing token, before the version and the world",
           {admit()},
           text(R"({"type":"hello","versions":[9],"seed":"8"})"),
           {"error unauthorized fatal", "close 1008 unauthorized"},
           State::kClosed},
          {"wrong token, before another parameter digest",
           {admit()},
           text(R"({"type":"hello","versions":[1],"params":"0000000000000001","token":"x"})"),
           {"error unauthorized fatal", "close 1008 unauthorized"},
           State::kClosed},
          {"a malformed field goes before the token (step 5 before step 6)",
           {admit()},
           text(R"({"type":"hello","ref":2,"versions":"1","token":"guess"})"),
           {"error bad_message fatal ref=2", "close 1008 bad_message"},
           State::kClosed},
          {"wrong token",
           {admit()},
           text(R"({"type":"hello","versions":[1],"token":"guess"})"),
           {"error unauthorized fatal", "close 1008 unauthorized"},
           State::kClosed},
          {"right token",
           {admit()},
           text(R"({"type":"hello","versions":[1],"token":"s3cret"})"),
           {"welcome v1 seed=7", "timer 60000"},
           State::kOpen},
      },
      config("s3cret"));
}

// A server without a token checks the field's form as it checks every field's (a client learns
// of a malformed token from any server, not first from the one that needs it), then ignores it.
TEST(Conversation, without_a_token_the_field_is_checked_then_ignored) {
  run({
      {"any well-formed token is ignored",
       {admit()},
       text(R"({"type":"hello","versions":[1],"token":"anything at all"})"),
       {"welcome v1 seed=7", "timer 60000"},
       State::kOpen},
      {"a token over 256 bytes is too_large",
       {admit()},
       text(R"({"type":"hello","versions":[1],"token":")" + std::string(257, 'k') + R"("})"),
       {"error too_large fatal", "close 1009 too_large"},
       State::kClosed},
      {"an empty token is bad_message",
       {admit()},
       text(R"({"type":"hello","versions":[1],"token":""})"),
       {"error bad_message fatal", "close 1008 bad_message"},
       State::kClosed},
      {"a token with a control character is bad_message",
       {admit()},
       text(R"({"type":"hello","versions":[1],"token":"a\u0001b"})"),
       {"error bad_message fatal", "close 1008 bad_message"},
       State::kClosed},
  });
}

// What PROTOCOL.md says of the token agrees with the two tests above: its form is checked by
// every server, and it is checked after the message's form, first of what hello asks.
TEST(Conversation, protocol_md_states_the_token_rules_the_code_follows) {
  std::ifstream in(GROTTO_PROTOCOL_MD);
  ASSERT_TRUE(in.good()) << GROTTO_PROTOCOL_MD;
  std::string token_field, unauthorized_row;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("| | `token` |")) token_field = line;
    if (line.starts_with("| `unauthorized` |")) unauthorized_row = line;
  }
  ASSERT_FALSE(token_field.empty());
  ASSERT_FALSE(unauthorized_row.empty());
  EXPECT_EQ(token_field.find("ignores the field"), std::string::npos) << token_field;
  EXPECT_NE(token_field.find("A server without one checks its form"), std::string::npos)
      << token_field;
  EXPECT_EQ(unauthorized_row.find("before anything else"), std::string::npos) << unauthorized_row;
  EXPECT_NE(unauthorized_row.find("first of what `hello` asks"), std::string::npos)
      << unauthorized_row;
}

TEST(Conversation, questions_after_welcome) {
  run({
      {"locate in a room",
       kOpen,
       text(R"({"type":"locate","ref":8,"point":[1,2,3]})"),
       {"timer 60000", "located 0.0.0.r3 ref=8"},
       State::kOpen},
      {"locate in rock",
       kOpen,
       text(R"({"type":"locate","point":[-1,2,3]})"),
       {"timer 60000", "located null"},
       State::kOpen},
      {"spawn",
       kOpen,
       text(R"({"type":"spawn","ref":9})"),
       {"timer 60000", "spawn_point 0.0.0.r0 ref=9"},
       State::kOpen},
      {"ping: pong with the server's clock",
       kOpen,
       text(R"({"type":"ping","ref":10,"t":42})"),
       {"timer 60000", "pong t=42 time=1000 ref=10"},
       State::kOpen},
      {"stats count what was sent, in payload bytes of completed writes",
       open_then(
           {text(kRequest3), deliver("0.0.0.r1"), sent(300), sent(3), text(R"({"type":"nope"})")}),
       text(R"({"type":"stats","ref":11})"),
       {"timer 60000", "stats in_flight=2 rooms_sent=1 bytes_sent=303 errors=1 ref=11"},
       State::kOpen},
      {"silence for idle_timeout_ms: timeout",
       kOpen,
       deadline(),
       {"release", "error timeout fatal", "close 1008 timeout now"},
       State::kClosed},
  });
}

TEST(Conversation, errors_after_welcome_refuse_one_message) {
  run({
      {"bad_json", kOpen, text("[1,"), {"timer 60000", "error bad_json"}, State::kOpen},
      {"bad_message names the message's ref",
       kOpen,
       text(R"({"type":"locate","ref":12,"point":[1,2]})"),
       {"timer 60000", "error bad_message ref=12"},
       State::kOpen},
      {"unknown_type",
       kOpen,
       text(R"({"type":"teleport","ref":13})"),
       {"timer 60000", "error unknown_type ref=13"},
       State::kOpen},
      {"invalid_room_id",
       kOpen,
       text(R"({"type":"request","ref":14,"rooms":[{"id":"0.0.0.r9999","lod":0,"priority":0}]})"),
       {"timer 60000", "error invalid_room_id ref=14"},
       State::kOpen},
      {"a lod above max_lod is bad_message",
       kOpen,
       text(R"({"type":"request","rooms":[{"id":"0.0.0.r1","lod":2,"priority":0}]})"),
       {"timer 60000", "error bad_message"},
       State::kOpen},
      {"a list over max_rooms_per_request is too_large, not fatal",
       kOpen,
       text(R"({"type":"cancel","ref":15,"rooms":["0.0.0.r1","0.0.0.r1","0.0.0.r1","0.0.0.r1",)"
            R"("0.0.0.r1","0.0.0.r1","0.0.0.r1","0.0.0.r1","0.0.0.r1"]})"),
       {"timer 60000", "error too_large ref=15"},
       State::kOpen},
      {"a whole message over max_message_bytes: too_large, close 1009",
       kOpen,
       text(std::string(2000, ' ')),
       {"release", "error too_large fatal", "close 1009 too_large"},
       State::kClosed},
      {"a message that grew past the limit while being read: the same",
       kOpen,
       oversized(),
       {"release", "error too_large fatal", "close 1009 too_large"},
       State::kClosed},
      {"a binary frame: bad_frame, close 1008",
       kOpen,
       binary(),
       {"release", "error bad_frame fatal", "close 1008 bad_frame"},
       State::kClosed},
  });
}

TEST(Conversation, the_in_flight_ledger) {
  run({
      {"a request asks the generator, by priority (ties in the order asked)",
       kOpen,
       text(kRequest3),
       {"timer 60000", "want 0.0.0.r1@0/3 0.0.0.r3@1/3 0.0.0.r2@0/9"},
       State::kOpen},
      {"a request over max_rooms_in_flight is refused whole: limit_exceeded",
       open_then({text(kRequest3)}),
       text(R"({"type":"request","ref":16,"rooms":[{"id":"1.0.0.r1","lod":0,"priority":0},)"
            R"({"id":"1.0.0.r2","lod":0,"priority":0}]})"),
       {"timer 60000", "error limit_exceeded ref=16"},
       State::kOpen},
      {"re-requesting rooms in flight does not count twice",
       open_then({text(kRequest3)}),
       text(R"({"type":"request","rooms":[{"id":"0.0.0.r1","lod":0,"priority":1},)"
            R"({"id":"0.0.0.r2","lod":0,"priority":1}]})"),
       {"timer 60000", "want 0.0.0.r1@0/1 0.0.0.r2@0/1"},
       State::kOpen},
      {"a new lod replaces the old one: the old want is dropped",
       open_then({text(kRequest3)}),
       text(R"({"type":"request","rooms":[{"id":"0.0.0.r1","lod":1,"priority":1}]})"),
       {"timer 60000", "drop 0.0.0.r1", "want 0.0.0.r1@1/1"},
       State::kOpen},
      {"a delivered room is sent",
       open_then({text(kRequest3)}),
       deliver("0.0.0.r2"),
       {"room 0.0.0.r2@0"},
       State::kOpen},
      {"a room at a lod the client replaced is not sent",
       open_then({text(kRequest3)}),
       deliver("0.0.0.r3", 0),
       {},
       State::kOpen},
      {"a room not in flight (cancelled meanwhile) is not sent",
       open_then({text(kRequest3), text(R"({"type":"cancel","rooms":["0.0.0.r2"]})")}),
       deliver("0.0.0.r2"),
       {},
       State::kOpen},
      {"a room delivered twice is sent once",
       open_then({text(kRequest3), deliver("0.0.0.r2")}),
       deliver("0.0.0.r2"),
       {},
       State::kOpen},
      {"not_found names the room and the request's ref",
       open_then({text(kRequest3)}),
       fail_room("0.0.0.r2", ErrorCode::kNotFound),
       {"error not_found ref=5 room=0.0.0.r2"},
       State::kOpen},
      {"a build failure is internal for that room only",
       open_then({text(kRequest3)}),
       fail_room("0.0.0.r1", ErrorCode::kInternal),
       {"error internal ref=5 room=0.0.0.r1"},
       State::kOpen},
      {"a job past its deadline is overloaded, not fatal",
       open_then({text(kRequest3)}),
       fail_room("0.0.0.r1", ErrorCode::kOverloaded),
       {"error overloaded ref=5 room=0.0.0.r1"},
       State::kOpen},
      {"the generator stopping is service_restart, close 1001",
       open_then({text(kRequest3)}),
       fail_room("0.0.0.r1", ErrorCode::kServiceRestart),
       {"release", "error service_restart fatal", "close 1001 service_restart"},
       State::kClosed},
      {"cancel drops only rooms in flight",
       open_then({text(kRequest3)}),
       text(R"({"type":"cancel","rooms":["0.0.0.r2","7.0.0.r1","0.0.0.r2"]})"),
       {"timer 60000", "drop 0.0.0.r2"},
       State::kOpen},
      {"cancel of nothing in flight: no action, no error",
       kOpen,
       text(R"({"type":"cancel","rooms":["0.0.0.r2"]})"),
       {"timer 60000"},
       State::kOpen},
  });
}

TEST(Conversation, closing) {
  run({
      {"shutdown: service_restart, close 1001",
       open_then({text(kRequest3)}),
       shutdown(),
       {"release", "error service_restart fatal", "close 1001 service_restart"},
       State::kClosed},
      {"a slow client is released and closed 1008 slow_client, without an error message",
       open_then({text(kRequest3)}),
       slow(),
       {"release", "close 1008 slow_client"},
       State::kClosed},
      {"the transport gone: the generator's client is released",
       open_then({text(kRequest3)}),
       gone(),
       {"release"},
       State::kClosed},
      {"nothing happens after the close",
       open_then({deadline()}),
       text(kRequest3),
       {},
       State::kClosed},
      {"a delivery after the close is dropped",
       open_then({text(kRequest3), shutdown()}),
       deliver("0.0.0.r1"),
       {},
       State::kClosed},
      {"nothing before admission", {}, text(kHello), {}, State::kNew},
  });
}

TEST(Conversation, the_request_rate) {
  ConversationConfig slow = config();
  slow.limits.request_rate = 10;  // rooms a second
  slow.limits.request_burst = 3;
  slow.limits.max_rooms_in_flight = 100;
  auto churn = [](int n) {
    std::vector<Event> events = kOpen;
    for (int i = 0; i < n; ++i) {
      events.push_back(text(request_of(1, i)));
      events.push_back(
          text(R"({"type":"cancel","rooms":["2.0.0.r)" + std::to_string(i) + R"("]})"));
    }
    return events;
  };
  run(
      {
          {"within the burst",
           open_then({text(request_of(2))}),
           text(request_of(1, 5)),
           {"timer 60000", "want 2.0.0.r5@0/0"},
           State::kOpen},
          {"over the burst: limit_exceeded, nothing queued",
           open_then({text(request_of(3))}),
           text(request_of(1, 5)),
           {"timer 60000", "error limit_exceeded ref=30"},
           State::kOpen},
          {"the bucket refills at the rate",
           open_then({text(request_of(3)), wait_ms(100)}),
           text(request_of(1, 5)),
           {"timer 60000", "want 2.0.0.r5@0/0"},
           State::kOpen},
          {"a cancel is never refused, but takes tokens",
           open_then({text(request_of(3)), wait_ms(200)}),
           text(R"({"type":"cancel","rooms":["2.0.0.r0","2.0.0.r1"]})"),
           {"timer 60000", "drop 2.0.0.r0 2.0.0.r1"},
           State::kOpen},
          {"...so a request after it waits",
           open_then({text(request_of(3)), wait_ms(200),
                      text(R"({"type":"cancel","rooms":["2.0.0.r0","2.0.0.r1"]})")}),
           text(request_of(1, 5)),
           {"timer 60000", "error limit_exceeded ref=30"},
           State::kOpen},
          {"a churner refused 100 times in a row is closed",
           churn(102),
           text(request_of(1, 500)),
           {"timer 60000", "release", "error limit_exceeded fatal ref=30",
            "close 1008 limit_exceeded"},
           State::kClosed},
      },
      slow);
}

// max_kbps: room frames go out at most at the cap, averaged over a second; ready rooms beyond it
// wait, the most urgent first, and still count as in flight.
TEST(Conversation, the_bandwidth_cap) {
  ConversationConfig capped = config();
  capped.limits.max_kbps = 80;  // 10,000 bytes a second, 10 a millisecond; the bucket holds 10,000
  const std::string request =
      R"({"type":"request","ref":30,"rooms":[{"id":"2.0.0.r0","lod":0,"priority":5},)"
      R"({"id":"2.0.0.r1","lod":0,"priority":5},{"id":"2.0.0.r2","lod":0,"priority":9},)"
      R"({"id":"2.0.0.r3","lod":0,"priority":1}]})";
  // r0 and r1 spend the bucket to -2,000 bytes; r2 then waits.
  const std::vector<Event> spent =
      open_then({text(request), deliver("2.0.0.r0", 0, 6000), deliver("2.0.0.r1", 0, 6000),
                 deliver("2.0.0.r2", 0, 6000)});
  std::vector<Event> both_wait = spent;
  both_wait.push_back(deliver("2.0.0.r3", 0, 6000));
  std::vector<Event> refilled = both_wait;
  refilled.push_back(wait_ms(200));
  run(
      {
          {"within the bucket a room goes at once",
           open_then({text(request)}),
           deliver("2.0.0.r0", 0, 6000),
           {"room 2.0.0.r0@0"},
           State::kOpen},
          {"a frame larger than what is left still goes while the bucket is not below zero",
           open_then({text(request), deliver("2.0.0.r0", 0, 6000)}),
           deliver("2.0.0.r1", 0, 6000),
           {"room 2.0.0.r1@0"},
           State::kOpen},
          {"below zero a ready room waits, the timer set for when the bucket is back at zero",
           open_then({text(request), deliver("2.0.0.r0", 0, 6000), deliver("2.0.0.r1", 0, 6000)}),
           deliver("2.0.0.r2", 0, 6000),
           {"pace 200"},
           State::kOpen},
          {"a waiting room is still in flight",
           spent,
           text(R"({"type":"stats","ref":4})"),
           {"timer 60000", "stats in_flight=2 rooms_sent=2 bytes_sent=0 errors=0 ref=4"},
           State::kOpen},
          {"too early, nothing goes", both_wait, pace(), {"pace 200"}, State::kOpen},
          {"the most urgent waiting room goes first",
           refilled,
           pace(),
           {"room 2.0.0.r3@0", "pace 600"},
           State::kOpen},
          {"a cancelled waiting room is never sent, and the generator has nothing to drop",
           spent,
           text(R"({"type":"cancel","rooms":["2.0.0.r2","2.0.0.r3"]})"),
           {"timer 60000", "drop 2.0.0.r3"},
           State::kOpen},
          {"...so the timer then sends nothing",
           [&] {
             auto e = refilled;
             e.push_back(text(R"({"type":"cancel","rooms":["2.0.0.r2","2.0.0.r3"]})"));
             return e;
           }(),
           pace(),
           {},
           State::kOpen},
          {"a waiting room asked again at another lod is dropped and wanted anew",
           spent,
           text(R"({"type":"request","ref":31,"rooms":[{"id":"2.0.0.r2","lod":1,"priority":0}]})"),
           {"timer 60000", "drop 2.0.0.r2", "want 2.0.0.r2@1/0"},
           State::kOpen},
      },
      capped);
}

// The highest version both speak is chosen, named in welcome, and the client's rooms are framed
// for it (the world port hears it); unknown versions in the list are ignored.
TEST(Conversation, the_highest_common_version_frames_the_rooms) {
  const std::vector<std::pair<std::string, uint32_t>> cases = {
      {R"({"type":"hello","versions":[1]})", 1},
      {R"({"type":"hello","versions":[2]})", 2},
      {R"({"type":"hello","versions":[9,1,2]})", 2},
      {R"({"type":"hello","versions":[1,3]})", 1}};
  for (const auto& [hello, version] : cases) {
    SCOPED_TRACE(hello);
    FakeWorlds worlds;
    Conversation c(config(), worlds, nullptr);
    admit()(c);
    c.take();
    c.text(hello);
    std::vector<std::string> got;
    for (const Action& a : c.take())
      got.push_back(describe(a));
    ASSERT_FALSE(got.empty());
    EXPECT_EQ(got.front(), "welcome v" + std::to_string(version) + " seed=7");
    EXPECT_EQ(worlds.opened_version, version);
  }
}

// A client sending garbage in a loop gets every error, but the log gets ten lines and a count.
TEST(Conversation, an_error_flood_is_logged_a_few_lines_and_a_count) {
  std::ostringstream log;
  auto previous = spdlog::default_logger();
  auto capture = std::make_shared<spdlog::logger>(
      "capture", std::make_shared<spdlog::sinks::ostream_sink_mt>(log));
  capture->set_level(spdlog::level::info);
  spdlog::set_default_logger(capture);
  FakeWorlds worlds;
  Conversation c(config(), worlds, nullptr);
  for (const Event& e : kOpen)
    e(c);
  size_t errors = 0;
  for (int i = 0; i < 1000; ++i) {
    c.text("[1,");
    for (const Action& a : c.take())
      errors += describe(a).starts_with("error bad_json");
  }
  c.deadline();  // closes: timeout
  spdlog::set_default_logger(previous);
  EXPECT_EQ(errors, 1000u) << "every message is still answered";
  EXPECT_EQ(c.errors_sent(), 1001u);
  std::string text = log.str();
  size_t lines = 0;
  for (size_t at = text.find("event=error_sent"); at != std::string::npos;
       at = text.find("event=error_sent", at + 1))
    ++lines;
  EXPECT_EQ(lines, 11u) << "ten bad_json and the fatal timeout";
  EXPECT_NE(text.find("event=errors_not_logged session=0 count=990"), std::string::npos) << text;
}

// PROTOCOL.md's error table names each code's close code: the conversation closes with it.
TEST(Conversation, close_codes_are_the_documented_ones) {
  std::ifstream in(GROTTO_PROTOCOL_MD);
  ASSERT_TRUE(in.good()) << GROTTO_PROTOCOL_MD;
  bool inside = false;
  int rows = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.starts_with("## ")) inside = line == "## Error codes";
    if (!inside || !line.starts_with("| `")) continue;
    // | `code` | fatal | close | sent when |
    std::string name = line.substr(3, line.find('`', 3) - 3);
    size_t fatal = line.find(" | ", 3);
    size_t close = line.find(" | ", fatal + 3);
    int documented = std::stoi(line.substr(close + 3, 4));
    auto code = proto::parse_wire_code(name);
    ASSERT_TRUE(code) << name;
    EXPECT_EQ(static_cast<int>(close_code_for(*code)), documented) << name;
    ++rows;
  }
  // One row per wire code: the protocol's own, and not_found and internal.
  EXPECT_EQ(rows,
            static_cast<int>(ErrorCode::kTimeout) - static_cast<int>(ErrorCode::kBadJson) + 3);
}

TEST(Conversation, close_codes_follow_the_error) {
  EXPECT_EQ(close_code_for(ErrorCode::kServiceRestart), CloseCode::kGoingAway);
  EXPECT_EQ(close_code_for(ErrorCode::kTooLarge), CloseCode::kTooBig);
  for (ErrorCode c : {ErrorCode::kTimeout, ErrorCode::kOverloaded, ErrorCode::kWorldMismatch,
                      ErrorCode::kUnauthorized, ErrorCode::kOutOfOrder, ErrorCode::kBadFrame,
                      ErrorCode::kUnsupportedVersion, ErrorCode::kBadJson}) {
    EXPECT_EQ(close_code_for(c), CloseCode::kPolicy) << error_code_name(c);
  }
}

// Past capacity (server/admission.hpp): the hello's answer is the admission's.
const std::string kQueueHello = R"({"type":"hello","ref":1,"versions":[1],"queue":true})";
Event admitted() {
  return [](Conversation& c) { c.admitted(); };
}
Event told(uint32_t position, uint32_t wait_ms, uint32_t queue) {
  return [=](Conversation& c) { c.queue_update(position, wait_ms, queue); };
}

TEST(Conversation, past_capacity_a_hello_waits_in_the_queue) {
  const Entry queued{Entry::Kind::kQueued, 3, 4000, 5, 0, false};
  const std::vector<Event> waiting = {admit(), text(kQueueHello)};
  auto then = [&](std::vector<Event> more) {
    std::vector<Event> all = waiting;
    all.insert(all.end(), more.begin(), more.end());
    return all;
  };
  run(
      {
          {"a hello that can wait is told its place, the hello's ref in it",
           {admit()},
           text(kQueueHello),
           {"queued pos=3 wait=4000 of=5 ref=1"},
           State::kQueued},
          {"a new place is told",
           waiting,
           told(2, 3000, 4),
           {"queued pos=2 wait=3000 of=4 ref=1"},
           State::kQueued},
          {"admitted: the world opens, welcome with the hello's ref, the idle timer",
           waiting,
           admitted(),
           {"welcome v1 seed=7 ref=1", "timer 60000"},
           State::kOpen},
          {"the handshake timer does not end a queued session",
           waiting,
           deadline(),
           {},
           State::kQueued},
          {"queued, a ping is answered",
           waiting,
           text(R"({"type":"ping","ref":4,"t":5})"),
           {"pong t=5 time=1000 ref=4"},
           State::kQueued},
          {"queued, anything but ping is out_of_order",
           waiting,
           text(R"({"type":"spawn","ref":4})"),
           {"error out_of_order fatal ref=4", "close 1008 out_of_order"},
           State::kClosed},
          {"queued, a second hello is out_of_order",
           waiting,
           text(kQueueHello),
           {"error out_of_order fatal ref=1", "close 1008 out_of_order"},
           State::kClosed},
          {"after welcome a late place is not sent",
           then({admitted()}),
           told(1, 0, 1),
           {},
           State::kOpen},
          {"shutdown while queued: service_restart",
           waiting,
           shutdown(),
           {"error service_restart fatal", "close 1001 service_restart"},
           State::kClosed},
      },
      config(), queued);
}

TEST(Conversation, past_capacity_a_hello_that_cannot_wait_is_refused_with_a_retry) {
  const Entry refused{Entry::Kind::kRefused, 0, 0, 0, 7000, false};
  run({{"overloaded, fatal, with retry_after_ms; never silence",
        {admit()},
        text(kHello),
        {"error overloaded fatal ref=1 retry=7000", "close 1008 overloaded"},
        State::kClosed}},
      config(), refused);
  const Entry full{Entry::Kind::kRefused, 0, 0, 0, 60000, true};
  run({{"the queue full: refused the same way",
        {admit()},
        text(kQueueHello),
        {"error overloaded fatal ref=1 retry=60000", "close 1008 overloaded"},
        State::kClosed}},
      config(), full);
}

TEST(Conversation, hello_queue_reaches_admission) {
  for (bool q : {false, true}) {
    FakeWorlds worlds;
    Conversation c(config(), worlds, nullptr);
    c.admit(Admission::kAdmitted);
    c.text(q ? kQueueHello : kHello);
    EXPECT_EQ(worlds.asked_queue, q);
  }
}

}  // namespace
}  // namespace grotto::server
