// libFuzzer target for the room decoder (common/codec), in meshoptimizer's manner: any bytes
// must decode to a valid room or to an error, never crash, hang or allocate without bound; and a
// room that decodes must encode again and decode again (the decoder accepts nothing that the
// encoder would refuse). Seeds: tests/fuzz/seeds/room_decoder_fuzz (real patch rooms).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>

#include "common/codec/room_codec.hpp"
#include "common/core/grid.hpp"

namespace {

// One layout: decode, derive normals for version 2 (portal discs at the origin, one per slot the
// decoder allows), encode again, decode again.
void check(std::span<const uint8_t> bytes, bool normals) {
  using namespace grotto::codec;
  DecodeLimits limits;
  limits.normals = normals;
  limits.portal_count = 4;
  auto room = decode_room(bytes, limits);
  if (!room) {
    if (room.error().message.empty()) std::abort();  // every error says what was wrong
    return;
  }
  if (!normals) {
    const std::vector<PortalDisc> discs(4, PortalDisc{{0, 0, 0}, {0, 1, 0}});
    if (!derive_normals(room.value(), {}, discs).ok()) std::abort();
    for (const auto& n : room->normals) {
      const float len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
      if (!(std::fabs(len - 1.0f) <= kNormalTolerance)) std::abort();  // unit, never NaN
    }
  }
  // Decoded rims are only promised on the wire's grid, which may be finer than the world grid.
  EncodeOptions options;
  options.grid_step_log2 = grotto::grid::kWireStepLog2;
  options.normals = normals;
  auto again = encode_room(view_of(room.value()), options);
  // The one refusal that is no contract of the room: the encoder's output over the format's
  // ceiling (kMaxPayloadBytes). Fuzzed values compress ~4x worse than real rooms at the encoder's
  // defaults, so a 64 KiB input can re-encode past 256 KiB.
  if (!again && again.error().message.find("over the format's") != std::string::npos) return;
  if (!again) {
    std::fprintf(stderr, "decoded room does not encode: %s\n", again.error().message.c_str());
    std::abort();
  }
  // Re-encoding may come out larger than the input (the input may use other Draco settings, and
  // noisy decoded values compress worse at the encoder's defaults), so the second decode gets the
  // format's ceilings, which encode_room itself enforces, not the patch level's limits.
  DecodeLimits ceilings = kDetailLimits;
  ceilings.normals = normals;
  auto twice = decode_room(again.value(), ceilings);
  if (!twice) {
    std::fprintf(stderr, "re-encoded room does not decode: %s\n", twice.error().message.c_str());
    std::abort();
  }
}

}  // namespace

// Every input is tried as both protocol versions' payloads (with and without normals).
extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> bytes(data, size);
  check(bytes, true);
  check(bytes, false);
  return 0;
}
