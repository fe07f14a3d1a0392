// The malformed-input corpus for control messages: each case yields the error code documented in
// proto/PROTOCOL.md and a message that names the problem.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "proto/messages.hpp"

namespace grotto::proto {
namespace {

struct Case {
  const char* what;
  std::string text;
  ErrorCode code;
  std::string names;  // a piece of the message that says what was wrong
};

std::string hello_with(const std::string& fields) {
  return R"({"type":"hello","versions":[1])" + fields + "}";
}
std::string request_with(const std::string& entry) {
  return R"({"type":"request","rooms":[)" + entry + "]}";
}

std::vector<Case> client_corpus() {
  std::string many_versions = "[1";
  for (int i = 0; i < 16; ++i)
    many_versions += ",1";
  many_versions += "]";
  std::string many_rooms;
  for (int i = 0; i < 257; ++i) {
    many_rooms += (i ? "," : "") + std::string(R"({"id":"0.0.0.r)") + std::to_string(i) +
                  R"(","lod":0,"priority":0})";
  }
  return {
      // Not JSON at all.
      {"empty text", "", ErrorCode::kBadJson, "unexpected end of input"},
      {"unterminated object", "{", ErrorCode::kBadJson, "not valid JSON"},
      {"trailing garbage", R"({"type":"spawn"} x)", ErrorCode::kBadJson, "not valid JSON"},
      {"NaN literal", R"({"type":"locate","point":[NaN,0,0]})", ErrorCode::kBadJson,
       "not valid JSON"},
      {"Infinity literal", R"({"type":"locate","point":[Infinity,0,0]})", ErrorCode::kBadJson,
       "not valid JSON"},
      {"single quotes", "{'type':'spawn'}", ErrorCode::kBadJson, "not valid JSON"},
      {"invalid UTF-8", hello_with(R"(,"name":")" + std::string("\xff\xfe") + "\"}"),
       ErrorCode::kBadJson, "UTF-8"},
      {"overlong UTF-8 slash", hello_with(R"(,"name":")" + std::string("\xc0\xaf") + "\"}"),
       ErrorCode::kBadJson, "UTF-8"},
      {"60k open brackets", std::string(60000, '['), ErrorCode::kBadJson, "nested deeper than 16"},
      {"10k nested objects",
       [] {
         std::string s;
         for (int i = 0; i < 10000; ++i)
           s += R"({"a":)";
         return s;
       }(),
       ErrorCode::kBadJson, "nested deeper than 16"},
      {"17 levels inside an ignored field",
       R"({"type":"spawn","x":)" + std::string(16, '[') + std::string(16, ']') + "}",
       ErrorCode::kBadJson, "nested deeper than 16"},
      // JSON, but not a message.
      {"array", "[1,2]", ErrorCode::kBadMessage, "must be a JSON object (got array)"},
      {"number", "42", ErrorCode::kBadMessage, "must be a JSON object (got integer)"},
      {"string", R"("hello")", ErrorCode::kBadMessage, "must be a JSON object (got string)"},
      {"no type", "{}", ErrorCode::kBadMessage, "field 'type' is missing"},
      {"type not a string", R"({"type":7})", ErrorCode::kBadMessage,
       "field 'type' must be a string (got integer)"},
      {"unknown type", R"({"type":"explode"})", ErrorCode::kUnknownType,
       "unknown message type 'explode'"},
      {"huge unknown type", R"({"type":")" + std::string(60000, 'z') + "\"}",
       ErrorCode::kUnknownType, "'zzzzzzzzzzzzzzzzzzzzzzzzzzzzzzzz...'"},
      {"ref negative", R"({"type":"spawn","ref":-1})", ErrorCode::kBadMessage,
       "field 'ref' must be in [0, 9007199254740991] (got -1)"},
      {"ref beyond 2^53", R"({"type":"spawn","ref":9007199254740992})", ErrorCode::kBadMessage,
       "field 'ref'"},
      {"ref a string", R"({"type":"spawn","ref":"7"})", ErrorCode::kBadMessage,
       "field 'ref' must be an integer (got string)"},
      // hello
      {"hello without versions", R"({"type":"hello"})", ErrorCode::kBadMessage,
       "field 'versions' is missing"},
      {"versions a string", R"({"type":"hello","versions":"1"})", ErrorCode::kBadMessage,
       "field 'versions' must be an array (got string)"},
      {"versions empty", R"({"type":"hello","versions":[]})", ErrorCode::kBadMessage,
       "field 'versions' must not be empty"},
      {"version 0", R"({"type":"hello","versions":[0]})", ErrorCode::kBadMessage,
       "field 'versions[0]' must be in [1, 65535] (got 0)"},
      {"version a float", R"({"type":"hello","versions":[1.5]})", ErrorCode::kBadMessage,
       "field 'versions[0]' must be an integer (got float)"},
      {"version too big", R"({"type":"hello","versions":[1,65536]})", ErrorCode::kBadMessage,
       "field 'versions[1]' must be in [1, 65535] (got 65536)"},
      {"version negative", R"({"type":"hello","versions":[-1]})", ErrorCode::kBadMessage,
       "field 'versions[0]' must be in [1, 65535] (got -1)"},
      {"17 versions", R"({"type":"hello","versions":)" + many_versions + "}", ErrorCode::kTooLarge,
       "field 'versions' has 17 entries, over the limit of 16"},
      {"seed a number", hello_with(R"(,"seed":42)"), ErrorCode::kBadMessage,
       "field 'seed' must be a string (got integer)"},
      {"seed with leading zero", hello_with(R"(,"seed":"042")"), ErrorCode::kBadMessage,
       "field 'seed' must be an unsigned 64-bit integer in decimal"},
      {"seed over 2^64", hello_with(R"(,"seed":"18446744073709551616")"), ErrorCode::kBadMessage,
       "field 'seed'"},
      {"seed negative", hello_with(R"(,"seed":"-1")"), ErrorCode::kBadMessage, "field 'seed'"},
      {"seed empty", hello_with(R"(,"seed":"")"), ErrorCode::kBadMessage, "field 'seed'"},
      {"params upper case", hello_with(R"(,"params":"0123456789ABCDEF")"), ErrorCode::kBadMessage,
       "field 'params' must be 16 lowercase hexadecimal digits"},
      {"params short", hello_with(R"(,"params":"abc")"), ErrorCode::kBadMessage, "field 'params'"},
      {"name too long", hello_with(R"(,"name":")" + std::string(65, 'n') + "\""),
       ErrorCode::kTooLarge, "field 'name' is 65 bytes, over the limit of 64"},
      {"name with a control character", hello_with(R"(,"name":"a\u0001b")"), ErrorCode::kBadMessage,
       "field 'name' must not contain control characters"},
      {"name with a NUL", hello_with(R"(,"name":"a\u0000b")"), ErrorCode::kBadMessage,
       "field 'name'"},
      {"name with a C1 control", hello_with(R"(,"name":"a\u0085b")"), ErrorCode::kBadMessage,
       "field 'name' must not contain control characters"},
      {"name with DEL", hello_with(R"(,"name":"a\u007fb")"), ErrorCode::kBadMessage,
       "field 'name' must not contain control characters"},
      {"name with a right-to-left override", hello_with(R"(,"name":"evil\u202etxt.exe")"),
       ErrorCode::kBadMessage, "field 'name' must not contain bidirectional formatting"},
      {"name with a bidi isolate", hello_with(R"(,"name":"a\u2066b")"), ErrorCode::kBadMessage,
       "field 'name' must not contain bidirectional formatting"},
      {"queue a number", hello_with(R"(,"queue":1)"), ErrorCode::kBadMessage,
       "field 'queue' must be true or false"},
      {"queue a string", hello_with(R"(,"queue":"yes")"), ErrorCode::kBadMessage,
       "field 'queue' must be true or false"},
      {"token a number", hello_with(R"(,"token":12345)"), ErrorCode::kBadMessage,
       "field 'token' must be a string (got integer)"},
      {"token an array", hello_with(R"(,"token":["a"])"), ErrorCode::kBadMessage,
       "field 'token' must be a string (got array)"},
      {"token too long", hello_with(R"(,"token":")" + std::string(257, 't') + "\""),
       ErrorCode::kTooLarge, "field 'token' is 257 bytes, over the limit of 256"},
      {"token empty", hello_with(R"(,"token":"")"), ErrorCode::kBadMessage,
       "field 'token' must not be empty"},
      {"token with a control character", hello_with(R"(,"token":"a\u0001b")"),
       ErrorCode::kBadMessage, "field 'token' must be printable ASCII"},
      {"token not ASCII", hello_with(R"(,"token":"caf\u00e9")"), ErrorCode::kBadMessage,
       "field 'token' must be printable ASCII"},
      {"room id over 64 characters",
       request_with(R"({"id":")" + std::string(65, '1') + R"(","lod":0,"priority":0})"),
       ErrorCode::kInvalidRoomId, "rooms[0].id"},
      // locate
      {"locate without point", R"({"type":"locate"})", ErrorCode::kBadMessage,
       "field 'point' is missing"},
      {"point of two", R"({"type":"locate","point":[1,2]})", ErrorCode::kBadMessage,
       "field 'point' must be an array of 3 numbers"},
      {"point an object", R"({"type":"locate","point":{"x":1}})", ErrorCode::kBadMessage,
       "field 'point' must be an array of 3 numbers"},
      {"number overflowing a double", R"({"type":"locate","point":[0,1e400,0]})",
       ErrorCode::kBadJson, "number overflow parsing '1e400'"},
      {"long number overflowing a double",
       R"({"type":"locate","point":[0,1)" + std::string(400, '0') + ",0]}", ErrorCode::kBadJson,
       "number overflow parsing '10000000000000000000000000000000...'"},
      {"point far away", R"({"type":"locate","point":[0,0,-1e9]})", ErrorCode::kBadMessage,
       "field 'point[2]' must be within"},
      {"point a string", R"({"type":"locate","point":["1",0,0]})", ErrorCode::kBadMessage,
       "field 'point[0]' must be a number (got string)"},
      // request
      {"request without rooms", R"({"type":"request"})", ErrorCode::kBadMessage,
       "field 'rooms' is missing"},
      {"empty request", R"({"type":"request","rooms":[]})", ErrorCode::kBadMessage,
       "field 'rooms' must not be empty"},
      {"too many rooms", request_with(many_rooms), ErrorCode::kTooLarge,
       "field 'rooms' has 257 entries, over the limit of 256"},
      {"entry a string", request_with(R"("0.0.0.r0")"), ErrorCode::kBadMessage,
       "field 'rooms[0]' must be an object"},
      {"id missing", request_with(R"({"lod":0,"priority":0})"), ErrorCode::kBadMessage,
       "field 'rooms[0].id' is missing"},
      {"id a number", request_with(R"({"id":5,"lod":0,"priority":0})"), ErrorCode::kBadMessage,
       "field 'rooms[0].id' must be a room id string (got integer)"},
      {"id index out of range", request_with(R"({"id":"0.0.0.r9999","lod":0,"priority":0})"),
       ErrorCode::kInvalidRoomId, "rooms[0].id: malformed room id '0.0.0.r9999'"},
      {"id with leading zero", request_with(R"({"id":"01.0.0.r0","lod":0,"priority":0})"),
       ErrorCode::kInvalidRoomId, "rooms[0].id: malformed room id"},
      {"id sector out of range", request_with(R"({"id":"65536.0.0.r0","lod":0,"priority":0})"),
       ErrorCode::kInvalidRoomId, "sector coordinate outside"},
      {"huge id",
       request_with(R"({"id":")" + std::string(50000, '9') + R"(","lod":0,"priority":0})"),
       ErrorCode::kInvalidRoomId, "longer than 64 characters"},
      {"lod over max_lod", request_with(R"({"id":"0.0.0.r0","lod":1,"priority":0})"),
       ErrorCode::kBadMessage, "field 'rooms[0].lod' must be in [0, 0] (got 1)"},
      {"lod missing", request_with(R"({"id":"0.0.0.r0","priority":0})"), ErrorCode::kBadMessage,
       "field 'rooms[0].lod' is missing"},
      {"priority negative", request_with(R"({"id":"0.0.0.r0","lod":0,"priority":-1})"),
       ErrorCode::kBadMessage, "field 'rooms[0].priority'"},
      {"priority over 32 bits", request_with(R"({"id":"0.0.0.r0","lod":0,"priority":4294967296})"),
       ErrorCode::kBadMessage, "field 'rooms[0].priority' must be in [0, 4294967295]"},
      {"priority a float", request_with(R"({"id":"0.0.0.r0","lod":0,"priority":0.5})"),
       ErrorCode::kBadMessage, "field 'rooms[0].priority' must be an integer (got float)"},
      {"repeated id",
       request_with(
           R"({"id":"0.0.0.r1","lod":0,"priority":0},{"id":"0.0.0.r2","lod":0,"priority":0},)"
           R"({"id":"0.0.0.r1","lod":0,"priority":5})"),
       ErrorCode::kBadMessage, "field 'rooms[2].id' repeats room 0.0.0.r1"},
      // cancel, ping
      {"empty cancel", R"({"type":"cancel","rooms":[]})", ErrorCode::kBadMessage,
       "field 'rooms' must not be empty"},
      {"cancel a bad id", R"({"type":"cancel","rooms":["0.0.0.r0","nope"]})",
       ErrorCode::kInvalidRoomId, "rooms[1]: malformed room id 'nope'"},
      {"id with control bytes", R"({"type":"cancel","rooms":["0.0.0.r\u0007\u001b[2J"]})",
       ErrorCode::kInvalidRoomId, "malformed room id '0.0.0.r??[2J'"},
      {"cancel an object", R"({"type":"cancel","rooms":[{"id":"0.0.0.r0"}]})",
       ErrorCode::kBadMessage, "field 'rooms[0]' must be a room id string (got object)"},
      {"ping without t", R"({"type":"ping"})", ErrorCode::kBadMessage, "field 't' is missing"},
      {"ping t a string", R"({"type":"ping","t":"now"})", ErrorCode::kBadMessage,
       "field 't' must be a number (got string)"},
  };
}

TEST(ProtoMalformed, every_corpus_case_yields_its_documented_code_and_names_the_problem) {
  for (const Case& c : client_corpus()) {
    Result<ClientMessage> r = parse_client_message(c.text, Limits{});
    ASSERT_FALSE(r.ok()) << c.what;
    EXPECT_EQ(error_code_name(r.error().code), std::string(error_code_name(c.code))) << c.what;
    EXPECT_NE(r.error().message.find(c.names), std::string::npos)
        << c.what << ": message was \"" << r.error().message << "\", expected it to contain \""
        << c.names << "\"";
    // Error messages stay short and printable whatever came in (they are sent back and logged).
    EXPECT_LE(r.error().message.size(), 200u) << c.what;
    for (char ch : r.error().message) {
      EXPECT_TRUE(ch >= 0x20 && ch < 0x7f) << c.what << ": byte " << int(ch) << " in message";
    }
  }
}

TEST(ProtoMalformed, size_limit_is_checked_before_parsing) {
  Limits limits;
  limits.max_message_bytes = 100;
  std::string text = R"({"type":"ping","t":1})";
  text.resize(101, ' ');  // valid JSON, one byte over
  Result<ClientMessage> r = parse_client_message(text, limits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kTooLarge);
  EXPECT_EQ(r.error().message, "message of 101 bytes exceeds max_message_bytes 100");
  text.resize(100);
  EXPECT_TRUE(parse_client_message(text, limits).ok());
  // A multi-megabyte frame is refused without being parsed (or echoed).
  std::string huge(8 << 20, '[');
  r = parse_client_message(huge, Limits{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kTooLarge);
}

TEST(ProtoMalformed, deep_nesting_is_refused_before_the_parser_recurses) {
  // Under a limit large enough to let 100k brackets through the size check, the depth scan
  // still refuses them (nlohmann would otherwise build and destroy a 100k-deep value).
  Limits limits;
  limits.max_message_bytes = 1 << 20;
  for (std::string text : {std::string(100000, '['), std::string(100000, '{'),
                           R"({"type":"spawn","x":)" + std::string(100000, '[')}) {
    Result<ClientMessage> r = parse_client_message(text, limits);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code, ErrorCode::kBadJson);
    EXPECT_NE(r.error().message.find("nested deeper than 16 levels"), std::string::npos)
        << r.error().message;
  }
}

TEST(ProtoMalformed, rooms_per_request_follows_the_limits_given) {
  Limits limits;
  limits.max_rooms_per_request = 2;
  std::string three = request_with(
      R"({"id":"0.0.0.r1","lod":0,"priority":0},{"id":"0.0.0.r2","lod":0,"priority":0},)"
      R"({"id":"0.0.0.r3","lod":0,"priority":0})");
  Result<ClientMessage> r = parse_client_message(three, limits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kTooLarge);
  limits.max_rooms_per_request = 3;
  EXPECT_TRUE(parse_client_message(three, limits).ok());
}

TEST(ProtoMalformed, the_ref_is_recovered_from_a_message_that_fails_later) {
  Ref ref;
  Result<ClientMessage> r =
      parse_client_message(R"({"type":"request","ref":77,"rooms":[]})", Limits{}, &ref);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(ref, Ref(77));
  ref.reset();
  r = parse_client_message(R"({"type":"nope","ref":78})", Limits{}, &ref);
  EXPECT_EQ(r.error().code, ErrorCode::kUnknownType);
  EXPECT_EQ(ref, Ref(78));
}

TEST(ProtoMalformed, unknown_fields_are_ignored_and_brackets_in_strings_do_not_count) {
  Result<ClientMessage> r = parse_client_message(
      R"({"type":"spawn","future_field":{"a":[1,2,{"b":null}]},"x":"[[[[[[[[[[[[[[[[[[[[[["})",
      Limits{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(std::holds_alternative<Spawn>(*r));
  // Exactly the depth limit is fine.
  std::string deep = R"({"type":"spawn","x":)" + std::string(15, '[') + std::string(15, ']') + "}";
  EXPECT_TRUE(parse_client_message(deep, Limits{}).ok());
  // An escaped quote does not end a string for the depth scan.
  EXPECT_TRUE(
      parse_client_message(R"({"type":"spawn","x":"\"[[[[[[[[[[[[[[[[[[[["})", Limits{}).ok());
}

TEST(ProtoMalformed, server_messages_are_checked_as_strictly) {
  struct ServerCase {
    const char* what;
    std::string text;
    ErrorCode code;
    std::string names;
  };
  const std::string limits =
      R"("limits":{"max_message_bytes":65536,"max_frame_bytes":4194304,"max_rooms_per_request":256,)"
      R"("max_rooms_in_flight":1024,"max_lod":0,"idle_timeout_ms":60000,"handshake_timeout_ms":10000})";
  const ServerCase cases[] = {
      {"welcome without limits",
       R"({"type":"welcome","version":1,"server":"s","seed":"1","params":"0000000000000000"})",
       ErrorCode::kBadMessage, "field 'limits' is missing"},
      {"welcome seed as number",
       R"({"type":"welcome","version":1,"server":"s","seed":1,"params":"0000000000000000",)" +
           limits + "}",
       ErrorCode::kBadMessage, "field 'seed' must be a string"},
      {"max_lod over 255",
       R"({"type":"welcome","version":1,"server":"s","seed":"1","params":"0000000000000000",)" +
           std::string(R"("limits":{"max_message_bytes":65536,"max_frame_bytes":4194304,)"
                       R"("max_rooms_per_request":256,"max_rooms_in_flight":1024,"max_lod":256,)"
                       R"("idle_timeout_ms":60000,"handshake_timeout_ms":10000}})"),
       ErrorCode::kBadMessage, "field 'limits.max_lod' must be in [0, 255]"},
      {"max_kbps zero (absent means no cap)",
       R"({"type":"welcome","version":1,"server":"s","seed":"1","params":"0000000000000000",)" +
           std::string(R"("limits":{"max_message_bytes":65536,"max_frame_bytes":4194304,)"
                       R"("max_rooms_per_request":256,"max_rooms_in_flight":1024,"max_lod":0,)"
                       R"("idle_timeout_ms":60000,"handshake_timeout_ms":10000,"max_kbps":0}})"),
       ErrorCode::kBadMessage, "field 'limits.max_kbps' must be"},
      {"tiny message limit",
       R"({"type":"welcome","version":1,"server":"s","seed":"1","params":"0000000000000000",)" +
           std::string(R"("limits":{"max_message_bytes":10,"max_frame_bytes":4194304,)"
                       R"("max_rooms_per_request":256,"max_rooms_in_flight":1024,"max_lod":0,)"
                       R"("idle_timeout_ms":60000,"handshake_timeout_ms":10000}})"),
       ErrorCode::kBadMessage, "field 'limits.max_message_bytes' must be at least 1024"},
      {"located without room", R"({"type":"located","point":[0,0,0]})", ErrorCode::kBadMessage,
       "field 'room' is missing"},
      {"located with a bad room", R"({"type":"located","point":[0,0,0],"room":"0.0.0.q1"})",
       ErrorCode::kInvalidRoomId, "room: malformed room id"},
      {"error without fatal", R"({"type":"error","code":"internal","message":"x"})",
       ErrorCode::kBadMessage, "field 'fatal' is missing"},
      {"error code a number", R"({"type":"error","code":3,"message":"x","fatal":false})",
       ErrorCode::kBadMessage, "field 'code' must be a string"},
      {"pong time negative", R"({"type":"pong","t":1,"time":-5})", ErrorCode::kBadMessage,
       "field 'time'"},
      {"queued position 0", R"({"type":"queued","position":0,"wait_ms":0,"queue":1})",
       ErrorCode::kBadMessage, "field 'position' must be in [1, 1000000] (got 0)"},
      {"queued past its queue", R"({"type":"queued","position":3,"wait_ms":0,"queue":2})",
       ErrorCode::kBadMessage, "field 'queue' must be at least position (3, got 2)"},
      {"queued wait over a day", R"({"type":"queued","position":1,"wait_ms":86400001,"queue":1})",
       ErrorCode::kBadMessage, "field 'wait_ms' must be in [0, 86400000]"},
      {"queued without wait_ms", R"({"type":"queued","position":1,"queue":1})",
       ErrorCode::kBadMessage, "field 'wait_ms' is missing"},
      {"error retry_after_ms a string",
       R"({"type":"error","code":"overloaded","message":"x","fatal":true,"retry_after_ms":"5"})",
       ErrorCode::kBadMessage, "field 'retry_after_ms' must be"},
      {"a client message type", R"({"type":"hello","versions":[1]})", ErrorCode::kUnknownType,
       "unknown message type 'hello'"},
      {"welcome version 0",
       R"({"type":"welcome","version":0,"server":"s","seed":"1","params":"0000000000000000",)" +
           limits + "}",
       ErrorCode::kBadMessage, "field 'version' must be in [1, 65535] (got 0)"},
      {"welcome version 65536",
       R"({"type":"welcome","version":65536,"server":"s","seed":"1","params":"0000000000000000",)" +
           limits + "}",
       ErrorCode::kBadMessage, "field 'version' must be in [1, 65535] (got 65536)"},
      {"server name with a bidi override",
       R"({"type":"welcome","version":1,"server":"s\u202e","seed":"1","params":"0000000000000000",)" +
           limits + "}",
       ErrorCode::kBadMessage, "field 'server' must not contain bidirectional formatting"},
      {"error code over 32 bytes",
       R"({"type":"error","code":")" + std::string(33, 'c') + R"(","message":"x","fatal":false})",
       ErrorCode::kTooLarge, "field 'code' is 33 bytes, over the limit of 32"},
  };
  for (const ServerCase& c : cases) {
    Result<ServerMessage> r = parse_server_message(c.text, Limits{});
    ASSERT_FALSE(r.ok()) << c.what;
    EXPECT_EQ(error_code_name(r.error().code), std::string(error_code_name(c.code))) << c.what;
    EXPECT_NE(r.error().message.find(c.names), std::string::npos)
        << c.what << ": message was \"" << r.error().message << "\"";
  }
}

}  // namespace
}  // namespace grotto::proto

namespace grotto::proto {
namespace {

TEST(ProtoMalformed, a_repeated_key_counts_once_with_its_last_value) {
  Result<ClientMessage> r = parse_client_message(R"({"type":"nope","type":"spawn"})", Limits{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(std::holds_alternative<Spawn>(*r));
}

TEST(ProtoMalformed, minus_zero_is_zero_but_other_negatives_are_refused) {
  Result<ClientMessage> r = parse_client_message(R"({"type":"spawn","ref":-0})", Limits{});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(std::get<Spawn>(*r).ref, Ref(0));
  EXPECT_FALSE(parse_client_message(R"({"type":"spawn","ref":-1})", Limits{}).ok());
}

}  // namespace
}  // namespace grotto::proto

namespace grotto::proto {
namespace {

// PROTOCOL.md, "Which error a message gets": the type is checked before any field, the ref
// included, and reported to the server, which needs it to choose between out_of_order and the field
// error.
TEST(ProtoMalformed, the_type_is_read_before_the_ref_and_reported) {
  Ref ref;
  std::string type = "stale";
  Result<ClientMessage> r =
      parse_client_message(R"({"type":"hello","ref":-1,"versions":[1]})", Limits{}, &ref, &type);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kBadMessage);
  EXPECT_NE(r.error().message.find("field 'ref'"), std::string::npos) << r.error().message;
  EXPECT_EQ(type, "hello");  // a malformed hello is known to be a hello
  EXPECT_EQ(ref, std::nullopt);

  // A field error after the type: the type is reported, and so is a valid ref.
  type = "stale";
  r = parse_client_message(R"({"type":"hello","ref":4,"versions":"1"})", Limits{}, &ref, &type);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(type, "hello");
  EXPECT_EQ(ref, Ref(4));

  // Errors before the type is known leave it empty: a bad ref does not hide a missing type.
  for (const char* text : {R"({"ref":"x"})", R"({"type":7,"ref":"x"})", "[1]", "{", ""}) {
    type = "stale";
    r = parse_client_message(text, Limits{}, nullptr, &type);
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_EQ(type, "") << text;
  }
  r = parse_client_message(R"({"ref":"x"})", Limits{}, nullptr, &type);
  EXPECT_EQ(r.error().message, "field 'type' is missing");

  // An unknown type wins over a bad ref, and is not reported as a type.
  type = "stale";
  r = parse_client_message(R"({"type":"teleport","ref":"x"})", Limits{}, nullptr, &type);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kUnknownType);
  EXPECT_EQ(type, "");

  // A valid ref is still reported when the type is missing.
  ref.reset();
  r = parse_client_message(R"({"ref":9})", Limits{}, &ref, &type);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(ref, Ref(9));

  // Success reports the type too; the old three-argument call still works.
  r = parse_client_message(R"({"type":"spawn","ref":1})", Limits{}, &ref, &type);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(type, "spawn");
  EXPECT_TRUE(parse_client_message(R"({"type":"stats"})", Limits{}, &ref).ok());
}

TEST(ProtoMalformed, an_overflowing_number_is_quoted_at_most_kMaxEchoBytes) {
  for (std::string number : {"1" + std::string(500, '0'), "1" + std::string(500, '0') + "e400",
                             "-" + std::string(300, '9') + ".5e999"}) {
    std::string text = R"({"type":"locate","point":[)" + number + ",0,0]}";
    Result<ClientMessage> r = parse_client_message(text, Limits{});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().code, ErrorCode::kBadJson);
    const std::string& m = r.error().message;
    std::size_t open = m.find('\'');
    ASSERT_NE(open, std::string::npos) << m;
    std::size_t close = m.find('\'', open + 1);
    ASSERT_NE(close, std::string::npos) << m;
    EXPECT_LE(close - open - 1, kMaxEchoBytes + 3) << m;  // "..." marks the cut
    EXPECT_EQ(m.substr(open + 1, 8), number.substr(0, 8)) << m;
  }
}

}  // namespace
}  // namespace grotto::proto
