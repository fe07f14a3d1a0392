// Room paths (PROTOCOL.md, "Rooms over HTTP"): one text form per room, printed and parsed back,
// and every other text refused naming the part that is wrong.
#include "proto/room_path.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace grotto::proto {
namespace {

RoomPath sample() {
  RoomPath p;
  p.version = 2;
  p.seed = 7;
  p.params = 0x7a58bce46eb33930ull;
  p.lod = 0;
  p.id = cave::RoomId::parse("0.0.0.r0").value();
  return p;
}

TEST(RoomPath, prints_the_documented_form_and_parses_it_back) {
  EXPECT_EQ(room_path(sample()), "/rooms/v2/7/7a58bce46eb33930/0/0.0.0.r0");
  RoomPath far;
  far.version = 1;
  far.seed = 18446744073709551615ull;
  far.params = 0;
  far.lod = 255;
  far.id = cave::RoomId::parse("-65535.3.65535.z15").value();
  for (const RoomPath& p : {sample(), far}) {
    SCOPED_TRACE(room_path(p));
    auto back = parse_room_path(room_path(p));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(*back, p);
  }
}

TEST(RoomPath, every_other_text_is_refused_naming_the_part) {
  struct Case {
    const char* path;
    ErrorCode code;
    const char* mentions;
  };
  for (const Case& c : {
           Case{"/room/v2/7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "/rooms/"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0", ErrorCode::kBadMessage, "4 parts"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0/0.0.0.r0/", ErrorCode::kBadMessage, "more than 5"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0/0.0.0.r0/x", ErrorCode::kBadMessage, "more than 5"},
           Case{"/rooms/2/7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "version"},
           Case{"/rooms/v0/7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "version"},
           Case{"/rooms/v02/7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "version"},
           Case{"/rooms/v65536/7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "version"},
           Case{"/rooms/v2/07/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "'seed'"},
           Case{"/rooms/v2/-7/7a58bce46eb33930/0/0.0.0.r0", ErrorCode::kBadMessage, "'seed'"},
           Case{"/rooms/v2/18446744073709551616/7a58bce46eb33930/0/0.0.0.r0",
                ErrorCode::kBadMessage, "'seed'"},
           Case{"/rooms/v2/7/29A2B8C03927CB75/0/0.0.0.r0", ErrorCode::kBadMessage, "'params'"},
           Case{"/rooms/v2/7/29a2b8c03927cb7/0/0.0.0.r0", ErrorCode::kBadMessage, "'params'"},
           Case{"/rooms/v2/7/7a58bce46eb33930/00/0.0.0.r0", ErrorCode::kBadMessage, "lod"},
           Case{"/rooms/v2/7/7a58bce46eb33930/256/0.0.0.r0", ErrorCode::kBadMessage, "lod"},
           Case{"/rooms/v2/7/7a58bce46eb33930//0.0.0.r0", ErrorCode::kBadMessage, "lod"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0/0.0.0.r9999", ErrorCode::kInvalidRoomId,
                "interior index"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0/", ErrorCode::kInvalidRoomId, "room id"},
           Case{"/rooms/v2/7/7a58bce46eb33930/0/0.-0.0.r1", ErrorCode::kInvalidRoomId, "0.-0"},
       }) {
    SCOPED_TRACE(c.path);
    auto p = parse_room_path(c.path);
    ASSERT_FALSE(p.ok());
    EXPECT_EQ(p.error().code, c.code);
    EXPECT_NE(p.error().message.find(c.mentions), std::string::npos) << p.error().message;
    EXPECT_EQ(p.error().message.find('\n'), std::string::npos) << "one line";
  }
}

// PROTOCOL.md's example room URL is what room_path() prints.
TEST(RoomPath, protocol_md_example_parses) {
  std::ifstream in(GROTTO_PROTOCOL_MD);
  ASSERT_TRUE(in.good());
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string example = "/rooms/v2/7/7a58bce46eb33930/0/0.0.0.r0";
  EXPECT_NE(text.find("`/rooms/v<version>/<seed>/<params>/<lod>/<room id>`"), std::string::npos);
  EXPECT_NE(text.find(example), std::string::npos);
  EXPECT_EQ(room_path(*parse_room_path(example)), example);
}

}  // namespace
}  // namespace grotto::proto
