// Every control message survives serialize -> parse unchanged, in both directions, and the wire
// codes map one to one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "proto/messages.hpp"
#include "proto/token.hpp"

namespace grotto::proto {
namespace {

cave::RoomId id(std::string_view text) {
  Result<cave::RoomId> r = cave::RoomId::parse(text);
  EXPECT_TRUE(r.ok()) << text;
  return *r;
}

ClientMessage client_round_trip(const ClientMessage& m, const Limits& limits = {}) {
  std::string text = serialize(m);
  Result<ClientMessage> back = parse_client_message(text, limits);
  EXPECT_TRUE(back.ok()) << text << ": " << (back.ok() ? "" : back.error().message);
  return back.ok() ? *back : ClientMessage{};
}

ServerMessage server_round_trip(const ServerMessage& m) {
  std::string text = serialize(m);
  Result<ServerMessage> back = parse_server_message(text, Limits{});
  EXPECT_TRUE(back.ok()) << text << ": " << (back.ok() ? "" : back.error().message);
  return back.ok() ? *back : ServerMessage{};
}

TEST(ProtoRoundTrip, every_client_message_round_trips) {
  Limits limits;
  limits.max_lod = 3;
  const ClientMessage messages[] = {
      Hello{1,
            {1, 2, 65535},
            18446744073709551615ull,
            0x0123456789abcdefull,
            "grotto-load 0.1",
            std::nullopt,
            false},
      Hello{std::nullopt, {1}, std::nullopt, std::nullopt, "", std::nullopt, false},
      Hello{0, {1}, 0, 0, "ünïcode ok", std::nullopt, false},
      Hello{2, {1}, 7, std::nullopt, "fleet", "s3cret token ~!@#$%^&*()", false},
      Hello{3, {1}, std::nullopt, std::nullopt, "", std::string(kMaxTokenBytes, 't'), false},
      Hello{4, {1, 2}, std::nullopt, std::nullopt, "waits", std::nullopt, true},
      Locate{9007199254740991ull, {0.1, -0.0, -16777216.0}},
      Locate{std::nullopt, {1e-300, 123.456789012345678, 5e-324}},
      Spawn{3},
      Spawn{},
      Request{4,
              {{id("0.0.0.r0"), 0, 0},
               {id("-65535.65535.-3.x15"), 3, 4294967295u},
               {id("3.-1.0.r12"), 1, 17}}},
      Cancel{5, {id("0.0.0.r0"), id("0.0.0.r0"), id("2.0.0.z1")}},
      Ping{6, 1732339200123.25},
      Ping{std::nullopt, -1.5},
      StatsQuery{7},
  };
  for (const ClientMessage& m : messages) {
    EXPECT_EQ(client_round_trip(m, limits), m) << serialize(m);
    // Serializing is deterministic: the text of the parsed message is the same text.
    EXPECT_EQ(serialize(client_round_trip(m, limits)), serialize(m));
  }
}

TEST(ProtoRoundTrip, every_server_message_round_trips) {
  Limits limits{1 << 16, 1 << 22, 64, 512, 2, 30000, 5000};
  Limits capped{1 << 16, 1 << 22, 64, 512, 2, 30000, 5000, 100, 200, 512};  // max_kbps 512
  const ServerMessage messages[] = {
      Welcome{1, 1, "grotto-server 0.3.0", 42, 0xfedcba9876543210ull, limits},
      Welcome{1, 1, "grotto-server 0.3.0", 42, 0xfedcba9876543210ull, capped},
      Welcome{std::nullopt, 7, "", 0, 0, Limits{}},
      Located{2, {1.5, 2.5, -3.5}, id("0.0.0.r4")},
      Located{std::nullopt, {0, 0, 0}, std::nullopt},
      SpawnPoint{3, id("0.0.0.r0"), {48.1, 47.9, 48.0}},
      ErrorMessage{4,
                   ErrorCode::kNotFound,
                   "room 0.0.0.r999 does not exist",
                   id("0.0.0.r999"),
                   {},
                   false,
                   std::nullopt},
      ErrorMessage{std::nullopt,
                   ErrorCode::kUnsupportedVersion,
                   "no common version",
                   std::nullopt,
                   {1, 2},
                   true,
                   std::nullopt},
      ErrorMessage{7, ErrorCode::kOverloaded, "full", std::nullopt, {}, true, 2500},
      Queued{8, 14, 20000, 30},
      Pong{5, 12.75, 1732339200123ull},
      Stats{6, 10, 2000, 123456789, 3},
  };
  for (const ServerMessage& m : messages) {
    EXPECT_EQ(server_round_trip(m), m) << serialize(m);
  }
}

TEST(ProtoRoundTrip, text_matches_the_documented_shape) {
  // PROTOCOL.md's sample session shows these exact lines.
  Request r{12, {{id("0.0.0.r3"), 0, 250}}};
  EXPECT_EQ(serialize(ClientMessage(r)),
            R"({"type":"request","ref":12,"rooms":[{"id":"0.0.0.r3","lod":0,"priority":250}]})");
  Hello h{1, {1}, 7, std::nullopt, "grotto-client", std::nullopt, false};
  EXPECT_EQ(serialize(ClientMessage(h)),
            R"({"type":"hello","ref":1,"versions":[1],"seed":"7","name":"grotto-client"})");
  ErrorMessage e{12, ErrorCode::kInvalidRoomId, "bad", std::nullopt, {}, false, std::nullopt};
  EXPECT_EQ(serialize(ServerMessage(e)),
            R"({"type":"error","ref":12,"code":"invalid_room_id","message":"bad","fatal":false})");
}

TEST(ProtoRoundTrip, doubles_keep_every_bit) {
  const double values[] = {0.1, -0.0, 1e-300, 5e-324, 16777216.0, 1.0 / 3.0, -2.5e-7};
  for (double v : values) {
    auto back = client_round_trip(Locate{std::nullopt, {v, v, v}});
    const Locate& l = std::get<Locate>(back);
    EXPECT_EQ(std::signbit(l.point.x), std::signbit(v));
    EXPECT_EQ(l.point.x, v);
  }
}

TEST(ProtoRoundTrip, long_error_messages_are_cut_to_the_limit_and_still_parse) {
  ErrorMessage e{std::nullopt, ErrorCode::kInternal, std::string(5000, 'x'), std::nullopt, {},
                 false,        std::nullopt};
  std::string text = serialize(ServerMessage(e));
  Result<ServerMessage> back = parse_server_message(text, Limits{});
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_LE(std::get<ErrorMessage>(*back).message.size(), kMaxErrorBytes);
}

TEST(ProtoRoundTrip, invalid_utf8_in_a_string_is_replaced_not_thrown) {
  ErrorMessage e{std::nullopt, ErrorCode::kInternal, "bad \xff byte", std::nullopt, {},
                 false,        std::nullopt};
  std::string text = serialize(ServerMessage(e));
  EXPECT_TRUE(parse_server_message(text, Limits{}).ok()) << text;
}

TEST(ProtoWireCodes, every_wire_code_parses_back_to_itself) {
  for (int c = 0; c <= static_cast<int>(ErrorCode::kTimeout); ++c) {
    ErrorCode code = static_cast<ErrorCode>(c);
    std::optional<ErrorCode> back = parse_wire_code(wire_code_name(code));
    ASSERT_TRUE(back.has_value()) << wire_code_name(code);
    if (code == ErrorCode::kInvalidArgument) {
      EXPECT_EQ(*back, ErrorCode::kBadMessage);
    } else if (code == ErrorCode::kUnavailable) {
      EXPECT_EQ(*back, ErrorCode::kOverloaded);
    } else {
      EXPECT_EQ(*back, code) << wire_code_name(code);
    }
  }
  EXPECT_FALSE(parse_wire_code("invalid_argument").has_value());
  EXPECT_FALSE(parse_wire_code("").has_value());
}

TEST(ProtoWireCodes, unknown_codes_from_a_later_server_read_as_internal_and_keep_their_name) {
  Result<ServerMessage> m = parse_server_message(
      R"({"type":"error","code":"quota_spent","message":"try tomorrow","fatal":true})", Limits{});
  ASSERT_TRUE(m.ok()) << m.error().message;
  const ErrorMessage& e = std::get<ErrorMessage>(*m);
  EXPECT_EQ(e.code, ErrorCode::kInternal);
  EXPECT_EQ(e.message, "[quota_spent] try tomorrow");
  EXPECT_TRUE(e.fatal);
}

TEST(ProtoWireCodes, fatal_codes_are_the_documented_ones) {
  EXPECT_TRUE(is_fatal(ErrorCode::kUnsupportedVersion));
  EXPECT_TRUE(is_fatal(ErrorCode::kServiceRestart));
  EXPECT_TRUE(is_fatal(ErrorCode::kTimeout));
  EXPECT_FALSE(is_fatal(ErrorCode::kBadJson));
  EXPECT_FALSE(is_fatal(ErrorCode::kInvalidRoomId));
  EXPECT_FALSE(is_fatal(ErrorCode::kNotFound));
}

TEST(ProtoEcho, cuts_and_masks_untrusted_text) {
  EXPECT_EQ(echo("abc"), "abc");
  EXPECT_EQ(echo(std::string(100, 'a')), std::string(kMaxEchoBytes, 'a') + "...");
  EXPECT_EQ(echo("a\nb'\xff"), "a?b??");
}

}  // namespace
}  // namespace grotto::proto

namespace grotto::proto {
namespace {

TEST(ProtoErrorReply, carries_code_ref_room_and_the_default_fatality) {
  cave::RoomId room = *cave::RoomId::parse("0.0.0.r9");
  ErrorMessage e = error_reply(Error{ErrorCode::kNotFound, "no such room"}, 5, room);
  EXPECT_EQ(e.code, ErrorCode::kNotFound);
  EXPECT_EQ(e.ref, Ref(5));
  EXPECT_EQ(e.room, room);
  EXPECT_FALSE(e.fatal);
  EXPECT_TRUE(error_reply(Error{ErrorCode::kTimeout, "idle"}).fatal);
  ErrorMessage general = error_reply(invalid_argument(std::string(3000, 'x')));
  EXPECT_EQ(general.message.size(), kMaxErrorBytes);
  EXPECT_NE(serialize(ServerMessage(general)).find(R"("code":"bad_message")"), std::string::npos);
}

}  // namespace
}  // namespace grotto::proto

namespace grotto::proto {
namespace {

bool printable_ascii(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c < 0x7f; });
}

// PROTOCOL.md: error.message is printable ASCII within 1024 bytes. Serializing used to turn each
// invalid byte into U+FFFD (3 bytes), so 1024 such bytes went out as 3 KB that the client then
// refused as too_large.
TEST(ProtoErrorReply, messages_of_invalid_bytes_stay_printable_ascii_within_the_limit) {
  std::string bad;
  for (int i = 0; i < 3000; ++i)
    bad.push_back(static_cast<char>(0x80 + i % 0x80));  // no valid UTF-8 in it
  Limits tight;
  tight.max_message_bytes = 1100;  // room for the message and the JSON around it, not for 3 KB
  for (const std::string& message : {bad, bad.substr(0, kMaxErrorBytes), "a\x01\tb\x7f" + bad}) {
    ErrorMessage reply = error_reply(Error{ErrorCode::kInternal, message});
    EXPECT_LE(reply.message.size(), kMaxErrorBytes);
    EXPECT_TRUE(printable_ascii(reply.message)) << reply.message;
    // Also an ErrorMessage built by hand: serialize() masks and cuts the same way.
    for (const ErrorMessage& e :
         {reply,
          ErrorMessage{1, ErrorCode::kInternal, message, std::nullopt, {}, false, std::nullopt}}) {
      std::string text = serialize(ServerMessage(e));
      EXPECT_LE(text.size(), kMaxErrorBytes + 100);
      Result<ServerMessage> back = parse_server_message(text, tight);
      ASSERT_TRUE(back.ok()) << back.error().message;
      const std::string& got = std::get<ErrorMessage>(*back).message;
      EXPECT_LE(got.size(), kMaxErrorBytes);
      EXPECT_TRUE(printable_ascii(got)) << got;
    }
  }
  EXPECT_EQ(error_reply(Error{ErrorCode::kInternal, "caf\xc3\xa9\n"}).message, "caf??\?");
}

// A received error message is masked like a sent one, so parse -> serialize -> parse is stable.
TEST(ProtoErrorReply, a_received_message_with_control_characters_is_masked) {
  Result<ServerMessage> m = parse_server_message(
      R"({"type":"error","code":"internal","message":"a\u0007b\u00e9","fatal":false})", Limits{});
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(std::get<ErrorMessage>(*m).message, "a?b??");
  EXPECT_EQ(*parse_server_message(serialize(*m), Limits{}), *m);
}

TEST(ProtoRoundTrip, names_with_printable_unicode_survive) {
  Hello h{1,           {1}, std::nullopt, std::nullopt, "caf\xc3\xa9 \xe2\x98\x83 \xd7\xa9\xd7\x9c",
          std::nullopt};
  std::string text = serialize(ClientMessage(h));
  Result<ClientMessage> back = parse_client_message(text, Limits{});
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(std::get<Hello>(*back), h);
}

}  // namespace
}  // namespace grotto::proto
