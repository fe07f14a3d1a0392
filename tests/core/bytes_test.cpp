// core/bytes.hpp: the one little-endian writer and reader. The formats built on it (room frames,
// digests, the binary cache) pin their own bytes; these pin the primitives.
#include "common/core/bytes.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace grotto {
namespace {

TEST(LittleEndian, appends_least_significant_byte_first) {
  std::vector<uint8_t> out;
  le::append(out, 0x0102030405060708u);
  le::append(out, 0xA1B2u, 2);
  le::append(out, 0x1FFu, 1);  // only the low byte
  EXPECT_EQ(out, (std::vector<uint8_t>{8, 7, 6, 5, 4, 3, 2, 1, 0xB2, 0xA1, 0xFF}));
}

TEST(LittleEndian, doubles_travel_as_their_ieee_bits) {
  std::vector<uint8_t> out;
  le::append_f64(out, 1.0);  // 0x3FF0000000000000
  EXPECT_EQ(out, (std::vector<uint8_t>{0, 0, 0, 0, 0, 0, 0xF0, 0x3F}));
  le::append_vec3(out, {-2.5, 0.0, 1e300});
  ASSERT_EQ(out.size(), 32u);
  EXPECT_EQ(le::load_f64(out.data()), 1.0);
  EXPECT_EQ(le::load_vec3(out.data() + 8), (Vec3{-2.5, 0.0, 1e300}));
}

TEST(LittleEndian, store_and_load_round_trip_at_any_width) {
  uint8_t buffer[9] = {};
  le::store(buffer + 1, 0x8877665544332211u);  // unaligned on purpose
  EXPECT_EQ(buffer[1], 0x11);
  EXPECT_EQ(buffer[8], 0x88);
  EXPECT_EQ(le::load(buffer + 1), 0x8877665544332211u);
  EXPECT_EQ(le::load(buffer + 1, 4), 0x44332211u);
  EXPECT_EQ(le::load(buffer + 1, 1), 0x11u);
}

}  // namespace
}  // namespace grotto
