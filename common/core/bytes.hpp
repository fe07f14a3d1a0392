// Little-endian bytes whatever the host, with no unaligned loads: the one writer and reader
// behind every canonical byte format Grotto has (room frames on the wire, the cave's room bytes
// and digests, the world-parameters digest, the OpenCL binary cache's header). Doubles travel as
// their IEEE 754 bits. Changing a byte here changes the wire and the disk: room_frame_tests,
// world_digest_tests, cave_tests and binary_cache_tests pin them.
#pragma once

#include <bit>
#include <cassert>
#include <cstdint>
#include <vector>

#include "common/core/vec3.hpp"

namespace grotto::le {

// Writes v's low `count` bytes (1 to 8) to out[0, count), least significant first.
inline void store(uint8_t* out, uint64_t v, int count = 8) {
  assert(count >= 1 && count <= 8);
  for (int i = 0; i < count; ++i)
    out[i] = static_cast<uint8_t>(v >> (8 * i));
}

// The unsigned value of in[0, count) (1 to 8 bytes), least significant first.
inline uint64_t load(const uint8_t* in, int count = 8) {
  assert(count >= 1 && count <= 8);
  uint64_t v = 0;
  for (int i = count - 1; i >= 0; --i)
    v = (v << 8) | in[i];
  return v;
}
inline double load_f64(const uint8_t* in) {
  return std::bit_cast<double>(load(in, 8));
}
// Three doubles, x then y then z: 24 bytes.
inline Vec3 load_vec3(const uint8_t* in) {
  return {load_f64(in), load_f64(in + 8), load_f64(in + 16)};
}

// Appends v's low `count` bytes (1 to 8), least significant first.
inline void append(std::vector<uint8_t>& out, uint64_t v, int count = 8) {
  assert(count >= 1 && count <= 8);
  for (int i = 0; i < count; ++i)
    out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
inline void append_f64(std::vector<uint8_t>& out, double v) {
  append(out, std::bit_cast<uint64_t>(v), 8);
}
// Three doubles, x then y then z: 24 bytes.
inline void append_vec3(std::vector<uint8_t>& out, Vec3 v) {
  append_f64(out, v.x);
  append_f64(out, v.y);
  append_f64(out, v.z);
}

}  // namespace grotto::le
