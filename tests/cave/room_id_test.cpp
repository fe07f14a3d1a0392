#include "common/cave/room_id.hpp"

#include <gtest/gtest.h>

namespace grotto::cave {
namespace {

TEST(RoomId, text_and_binary_forms_round_trip) {
  const RoomId ids[] = {
      RoomId::interior({0, 0, 0}, 0),
      RoomId::interior({3, -1, 0}, 12),
      RoomId::interior({-kSectorCoordLimit, kSectorCoordLimit, -7}, kMaxInteriorRooms - 1),
      RoomId::gate({5, 6, -7}, 0, 0),
      RoomId::gate({-1, 0, 1}, 1, 3),
      RoomId::gate({kSectorCoordLimit, -kSectorCoordLimit, 0}, 2, kMaxGatesPerFace - 1),
  };
  for (RoomId id : ids) {
    auto parsed = RoomId::parse(id.to_string());
    ASSERT_TRUE(parsed.ok()) << id.to_string() << ": " << parsed.error().message;
    EXPECT_EQ(*parsed, id);
    auto unpacked = RoomId::unpack(id.packed());
    ASSERT_TRUE(unpacked.ok()) << unpacked.error().message;
    EXPECT_EQ(*unpacked, id);
  }
}

TEST(RoomId, text_form_is_readable) {
  EXPECT_EQ(RoomId::interior({3, -1, 0}, 12).to_string(), "3.-1.0.r12");
  EXPECT_EQ(RoomId::gate({0, 2, 0}, 1, 1).to_string(), "0.2.0.y1");
  RoomId gate = RoomId::gate({0, 2, 0}, 2, 4);
  EXPECT_TRUE(gate.is_gate());
  EXPECT_EQ(gate.gate_axis(), 2);
  EXPECT_EQ(gate.index(), 4);
  EXPECT_FALSE(RoomId::interior({0, 0, 0}, 4).is_gate());
}

TEST(RoomId, packed_ids_are_distinct) {
  EXPECT_NE(RoomId::interior({1, 0, 0}, 0).packed(), RoomId::interior({0, 1, 0}, 0).packed());
  EXPECT_NE(RoomId::interior({0, 0, 0}, 1).packed(), RoomId::gate({0, 0, 0}, 0, 1).packed());
  EXPECT_NE(RoomId::interior({-1, 0, 0}, 0).packed(), RoomId::interior({1, 0, 0}, 0).packed());
}

TEST(RoomId, malformed_text_is_rejected_with_a_clear_error) {
  const char* bad[] = {
      "",          "r1",           "1.2.3",         "1.2.3.",
      "1.2.3.r",   "1.2.3.q1",     "1.2.3.r-1",     "1.2.3.r01",
      "01.2.3.r1", "+1.2.3.r1",    "-0.2.3.r1",     "1.2.3.r1.",
      "1..3.r1",   " 1.2.3.r1",    "1.2.3.r1 ",     "1.2.3.r4096",
      "1.2.3.x16", "65536.0.0.r0", "0.-65536.0.r0", "1.2.3.rx",
      "a.b.c.r1",  "1.2.3.R1",     "1e3.0.0.r1",    "99999999999999999999.0.0.r0",
  };
  for (const char* text : bad) {
    auto parsed = RoomId::parse(text);
    ASSERT_FALSE(parsed.ok()) << "accepted '" << text << "'";
    EXPECT_EQ(parsed.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(parsed.error().message.find("malformed room id"), std::string::npos)
        << parsed.error().message;
  }
  std::string huge(100000, '7');
  auto parsed = RoomId::parse(huge);
  ASSERT_FALSE(parsed.ok());
  EXPECT_LT(parsed.error().message.size(), 300u) << "errors must not echo huge input";
}

TEST(RoomId, malformed_binary_is_rejected) {
  // Slot beyond the gates of the z axis.
  uint64_t bad_slot = RoomId::interior({0, 0, 0}, 0).packed() | 0x1fff;
  EXPECT_FALSE(RoomId::unpack(bad_slot).ok());
  // Coordinate field 131071 decodes to 65536, outside the range.
  uint64_t bad_coord = (uint64_t{131071} << 13);
  auto r = RoomId::unpack(bad_coord);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("outside"), std::string::npos);
  EXPECT_FALSE(RoomId::unpack(~uint64_t{0}).ok());
}

}  // namespace
}  // namespace grotto::cave
