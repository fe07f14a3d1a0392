// libFuzzer target for the room decoder (common/codec), in meshoptimizer's manner: any bytes
// must decode to a valid room or to an error, never crash, hang or allocate without bound; and a
// room that decodes must encode again and decode again (the decoder accepts nothing that the
// encoder would refuse). Seeds: tests/fuzz/seeds/room_decoder_fuzz (real patch rooms).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>

#include "codec/room_codec.hpp"
#include "core/grid.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace grotto::codec;
  auto room = decode_room(std::span<const uint8_t>(data, size));
  if (!room) {
    if (room.error().message.empty()) std::abort();  // every error says what was wrong
    return 0;
  }
  // Decoded rims are only promised on the wire's grid, which may be finer than the world grid.
  EncodeOptions options;
  options.grid_step_log2 = grotto::grid::kWireStepLog2;
  auto again = encode_room(view_of(room.value()), options);
  // The one refusal that is no contract of the room: the encoder's output over the format's
  // ceiling (kMaxPayloadBytes). Fuzzed values compress ~4x worse than real rooms at the encoder's
  // defaults, so a 64 KiB input can re-encode past 256 KiB.
  if (!again && again.error().message.find("over the format's") != std::string::npos) return 0;
  if (!again) {
    std::fprintf(stderr, "decoded room does not encode: %s\n", again.error().message.c_str());
    std::abort();
  }
  // Re-encoding may come out larger than the input (the input may use other Draco settings, and
  // noisy decoded values compress worse at the encoder's defaults), so the second decode gets the
  // format's ceilings, which encode_room itself enforces, not the patch level's limits.
  auto twice = decode_room(again.value(), kDetailLimits);
  if (!twice) {
    std::fprintf(stderr, "re-encoded room does not decode: %s\n", twice.error().message.c_str());
    std::abort();
  }
  return 0;
}
