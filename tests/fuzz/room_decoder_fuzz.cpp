// libFuzzer target for the room decoder (common/codec), in meshoptimizer's manner: any bytes
// must decode to a valid room or to an error, never crash, hang or allocate without bound; and a
// room that decodes must encode again and decode again (the decoder accepts nothing that the
// encoder would refuse). Seeds: tests/fuzz/seeds/room_decoder_fuzz (real patch rooms).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "codec/room_codec.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace grotto::codec;
  auto room = decode_room(std::span<const uint8_t>(data, size));
  if (!room) {
    if (room.error().message.empty()) std::abort();  // every error says what was wrong
    return 0;
  }
  auto again = encode_room(view_of(room.value()));
  if (!again) {
    std::fprintf(stderr, "decoded room does not encode: %s\n", again.error().message.c_str());
    std::abort();
  }
  auto twice = decode_room(again.value());
  if (!twice) {
    std::fprintf(stderr, "re-encoded room does not decode: %s\n", twice.error().message.c_str());
    std::abort();
  }
  return 0;
}
