// libFuzzer target for everything that parses wire input in grotto::proto: client and server
// control messages (JSON text frames) and binary room frames. Each input goes to all three
// parsers; whatever parses must serialize and parse back to the same value (the frame to the
// same bytes), so the fuzzer checks the round trip as well as memory safety.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <string_view>

#include "proto/messages.hpp"
#include "proto/room_frame.hpp"

namespace {

using namespace grotto::proto;

[[noreturn]] void fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "proto_fuzz: %s: %s\n", what, detail.c_str());
  std::abort();
}

// Re-parsing our own output may exceed the input's limits (1 -> 1.0 grows the text).
Limits roomy(Limits limits) {
  limits.max_message_bytes = 1 << 24;
  return limits;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string_view text(reinterpret_cast<const char*>(data), size);
  Limits limits;
  limits.max_lod = 3;
  limits.max_rooms_per_request = 64;

  std::string type;
  auto client = parse_client_message(text, limits, nullptr, &type);
  // The type is reported exactly when parsing got past the type check (PROTOCOL.md's order):
  // after it, neither bad_json nor unknown_type can come.
  if (client.ok() && type.empty())
    fail("parsed client message reported no type", std::string(text));
  if (!client.ok() && !type.empty() &&
      (client.error().code == grotto::ErrorCode::kBadJson ||
       client.error().code == grotto::ErrorCode::kUnknownType)) {
    fail("a type was reported with an error from before the type check", client.error().message);
  }
  if (client.ok()) {
    std::string again = serialize(*client);
    auto back = parse_client_message(again, roomy(limits));
    if (!back.ok()) fail("client message does not re-parse", back.error().message + ": " + again);
    if (!(*back == *client)) fail("client message changed in a round trip", again);
  }
  if (auto server = parse_server_message(text, limits); server.ok()) {
    std::string again = serialize(*server);
    auto back = parse_server_message(again, roomy(limits));
    if (!back.ok()) fail("server message does not re-parse", back.error().message + ": " + again);
    if (!(*back == *server)) fail("server message changed in a round trip", again);
  }
  if (auto frame = decode_room_frame(std::span<const uint8_t>(data, size), limits); frame.ok()) {
    std::vector<uint8_t> again = encode_room_frame(*frame);
    if (again.size() != size || !std::equal(again.begin(), again.end(), data)) {
      fail("room frame does not encode to the bytes it came from", std::to_string(size));
    }
  }
  return 0;
}
