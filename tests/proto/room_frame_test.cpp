// Binary room frames: real rooms round-trip bit for bit, and every way a frame can be malformed
// is refused with the documented code and a message naming the field, never a crash.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "common/cave/layout.hpp"
#include "common/core/grid.hpp"
#include "proto/room_frame.hpp"

namespace grotto::proto {
namespace {

const cave::World& world() {
  static const cave::World w = *cave::World::create(7, cave::LayoutParams{});
  return w;
}

RoomFrame sample_frame(std::string_view id_text = "0.0.0.x0") {
  cave::RoomId id = *cave::RoomId::parse(id_text);
  Result<cave::Room> room = cave::room(world(), id);
  EXPECT_TRUE(room.ok());
  RoomFrame f;
  f.room = *room;
  f.lod = 0;
  f.origin = grid::snap(room->sphere.centre);
  f.payload = {0xd7, 0xac, 0x00, 0x01, 0x00};
  return f;
}

std::vector<uint8_t> sample_bytes() {
  return encode_room_frame(sample_frame());
}

void put_u64(std::vector<uint8_t>& b, std::size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i)
    b[at + i] = static_cast<uint8_t>(v >> (8 * i));
}
void put_f64(std::vector<uint8_t>& b, std::size_t at, double v) {
  put_u64(b, at, std::bit_cast<uint64_t>(v));
}
double get_f64(const std::vector<uint8_t>& b, std::size_t at) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i)
    v = (v << 8) | b[at + i];
  return std::bit_cast<double>(v);
}

Error decode_error(const std::vector<uint8_t>& bytes, const Limits& limits = {}) {
  Result<RoomFrame> r = decode_room_frame(bytes, limits);
  EXPECT_FALSE(r.ok());
  return r.ok() ? Error{} : r.error();
}

void expect_error(const std::vector<uint8_t>& bytes, ErrorCode code, std::string_view names,
                  const Limits& limits = {}) {
  Error e = decode_error(bytes, limits);
  EXPECT_EQ(error_code_name(e.code), std::string(error_code_name(code))) << e.message;
  EXPECT_NE(e.message.find(names), std::string::npos)
      << "message \"" << e.message << "\" should name \"" << names << "\"";
}

void expect_same_room(const cave::Room& a, const cave::Room& b) {
  std::vector<unsigned char> ba, bb;
  cave::append_bytes(a, ba);
  cave::append_bytes(b, bb);
  EXPECT_EQ(ba, bb);  // ids, doubles and portals bit for bit
}

// Portal record i starts here; fields at +0 to, +8 centre, +32 normal, +56 radius.
constexpr std::size_t portal_at(std::size_t i) {
  return kRoomHeaderBytes + kPortalRecordBytes * i;
}

TEST(RoomFrame, real_rooms_round_trip_bit_for_bit) {
  for (std::string_view text : {"0.0.0.x0", "0.0.0.r0", "0.0.0.r5", "-1.0.2.r3"}) {
    RoomFrame f = sample_frame(text);
    ASSERT_FALSE(f.room.portals.empty()) << text;
    std::vector<uint8_t> bytes = encode_room_frame(f);
    EXPECT_EQ(bytes.size(), room_frame_size(f.room.portals.size(), f.payload.size()));
    Result<RoomFrame> back = decode_room_frame(bytes, Limits{});
    ASSERT_TRUE(back.ok()) << text << ": " << back.error().message;
    expect_same_room(back->room, f.room);
    EXPECT_EQ(back->lod, f.lod);
    EXPECT_EQ(back->origin, f.origin);
    EXPECT_EQ(back->payload, f.payload);
    EXPECT_EQ(encode_room_frame(*back), bytes);
  }
}

TEST(RoomFrame, header_bytes_are_the_documented_layout) {
  RoomFrame f = sample_frame("0.0.0.x0");
  std::vector<uint8_t> b = encode_room_frame(f);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "GRTO");
  EXPECT_EQ(b[4] | b[5] << 8, 2);  // version: the newest by default
  f.version = 1;
  std::vector<uint8_t> v1 = encode_room_frame(f);
  EXPECT_EQ(v1[4] | v1[5] << 8, 1);
  EXPECT_EQ(decode_room_frame(v1, Limits{})->version, 1u) << "version 1 frames still decode";
  EXPECT_EQ(b[6], 1);  // type: room
  EXPECT_EQ(b[7], kFlagGate);
  uint64_t id = 0;
  for (int i = 7; i >= 0; --i)
    id = (id << 8) | b[8 + i];
  EXPECT_EQ(id, f.room.id.packed());
  EXPECT_EQ(b[16], 0);  // lod
  EXPECT_EQ(b[17], f.room.portals.size());
  EXPECT_EQ(b[18] | b[19] << 8, 0);
  EXPECT_EQ(b[20] | b[21] << 8 | b[22] << 16 | b[23] << 24, 5);  // payload bytes
  EXPECT_EQ(get_f64(b, 24), f.origin.x);
  EXPECT_EQ(get_f64(b, 48), f.room.sphere.centre.x);
  EXPECT_EQ(get_f64(b, 72), f.room.sphere.radius);
  EXPECT_EQ(get_f64(b, portal_at(0) + 56), f.room.portals[0].radius);
  EXPECT_EQ(b.back(), 0x0);
}

TEST(RoomFrame, truncated_at_every_length_is_a_bad_frame) {
  std::vector<uint8_t> bytes = sample_bytes();
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + n);
    Error e = decode_error(cut);
    ASSERT_EQ(e.code, ErrorCode::kBadFrame) << n << ": " << e.message;
    EXPECT_NE(e.message.find("truncated"), std::string::npos) << n << ": " << e.message;
  }
}

TEST(RoomFrame, trailing_bytes_are_a_bad_frame) {
  std::vector<uint8_t> bytes = sample_bytes();
  bytes.push_back(0);
  expect_error(bytes, ErrorCode::kBadFrame, "trailing bytes");
}

TEST(RoomFrame, wrong_magic_version_and_type_are_named) {
  std::vector<uint8_t> b = sample_bytes();
  b[0] = 'X';
  expect_error(b, ErrorCode::kBadFrame, "wrong magic");
  b = sample_bytes();
  b[4] = 3;
  expect_error(b, ErrorCode::kUnsupportedVersion, "version 3, this decoder reads 1..2");
  b[4] = 0;
  expect_error(b, ErrorCode::kUnsupportedVersion, "version 0");
  b = sample_bytes();
  b[6] = 9;
  expect_error(b, ErrorCode::kUnknownType, "unknown type 9");
  expect_error({'{', '"', 't', 'y'}, ErrorCode::kBadFrame, "wrong magic");  // JSON sent as binary
}

TEST(RoomFrame, counts_and_lengths_are_checked_before_reading) {
  std::vector<uint8_t> b = sample_bytes();
  b[17] = 17;
  expect_error(b, ErrorCode::kBadFrame, "portal count 17 is over 16");
  b = sample_bytes();
  b[17] = 255;
  expect_error(b, ErrorCode::kBadFrame, "portal count 255");
  b = sample_bytes();
  b[20] = b[21] = b[22] = b[23] = 0xff;  // a 4 GiB payload announced in a small frame
  expect_error(b, ErrorCode::kBadFrame, "4294967295 payload bytes");
  b = sample_bytes();
  b[17] -= 1;  // one portal fewer than present: the sizes disagree
  expect_error(b, ErrorCode::kBadFrame, "trailing bytes");
  b = sample_bytes();
  b[18] = 1;
  expect_error(b, ErrorCode::kBadFrame, "reserved");
}

TEST(RoomFrame, frames_over_the_limit_are_too_large) {
  std::vector<uint8_t> b = sample_bytes();
  Limits limits;
  limits.max_frame_bytes = static_cast<uint32_t>(b.size() - 1);
  expect_error(b, ErrorCode::kTooLarge, "exceeds max_frame_bytes", limits);
  limits.max_frame_bytes = static_cast<uint32_t>(b.size());
  EXPECT_TRUE(decode_room_frame(b, limits).ok());
}

TEST(RoomFrame, ids_must_be_valid) {
  std::vector<uint8_t> b = sample_bytes();
  put_u64(b, 8, 5000);  // slot 5000 is no slot
  expect_error(b, ErrorCode::kInvalidRoomId, "id: room id 5000 has slot");
  b = sample_bytes();
  put_u64(b, portal_at(1), ~uint64_t{0});
  expect_error(b, ErrorCode::kInvalidRoomId, "portals[1].to");
  b = sample_bytes();
  put_u64(b, portal_at(0), sample_frame().room.id.packed());
  expect_error(b, ErrorCode::kBadFrame, "portals[0].to is the room itself");
  b = sample_bytes();
  put_u64(b, portal_at(1), sample_frame().room.portals[0].neighbour.packed());
  expect_error(b, ErrorCode::kBadFrame, "two portals lead to the same room");
}

TEST(RoomFrame, flags_must_agree_with_the_id) {
  std::vector<uint8_t> b = sample_bytes();
  b[7] = 0;  // a gate id without the gate flag
  expect_error(b, ErrorCode::kBadFrame, "gate flag disagrees");
  b = sample_bytes();
  b[7] |= 0x80;
  expect_error(b, ErrorCode::kBadFrame, "unknown flag bits");
}

TEST(RoomFrame, numbers_must_be_finite_and_in_range) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Patch {
    std::size_t at;
    double value;
    const char* names;
  };
  const Patch patches[] = {
      {24, nan, "origin is not finite"},
      {32, inf, "origin is not finite"},
      {40, 0.001, "origin is not on the 1/256 m grid"},
      {24, 1e12, "origin is outside"},
      {48, nan, "centre is not finite"},
      {56, -inf, "centre is not finite"},
      {72, nan, "radius must be in (0, 256]"},
      {72, 0.0, "radius must be in (0, 256]"},
      {72, -3.0, "radius must be in (0, 256]"},
      {72, 1e6, "radius must be in (0, 256]"},
      {portal_at(0) + 8, nan, "portals[0].centre is not finite"},
      {portal_at(0) + 16, 1e5, "portals[0].centre is outside the room"},
      {portal_at(1) + 32, nan, "portals[1].normal is not finite"},
      {portal_at(1) + 40, inf, "portals[1].normal is not finite"},
      {portal_at(0) + 56, nan, "portals[0].radius"},
      {portal_at(0) + 56, 0.0, "portals[0].radius"},
      {portal_at(0) + 56, 1000.0, "portals[0].radius"},
  };
  for (const Patch& p : patches) {
    std::vector<uint8_t> b = sample_bytes();
    put_f64(b, p.at, p.value);
    SCOPED_TRACE(p.names);
    expect_error(b, ErrorCode::kBadFrame, p.names);
  }
}

TEST(RoomFrame, normals_must_be_unit_within_tolerance) {
  std::vector<uint8_t> b = sample_bytes();
  double nx = get_f64(b, portal_at(0) + 32);
  put_f64(b, portal_at(0) + 32, nx * 1.1 + (nx == 0 ? 0.5 : 0));
  expect_error(b, ErrorCode::kBadFrame, "portals[0].normal is not unit length");
  // A last-bit change is within the tolerance.
  b = sample_bytes();
  put_f64(b, portal_at(0) + 32, std::nextafter(nx, 2.0));
  EXPECT_TRUE(decode_room_frame(b, Limits{}).ok());
}

TEST(RoomFrame, the_room_must_lie_near_its_origin) {
  RoomFrame f = sample_frame();
  f.origin.x += 40000;  // still on the grid, but offsets would lose float32 bits
  expect_error(encode_room_frame(f), ErrorCode::kBadFrame, "beyond 32768 m of the origin");
}

TEST(RoomFrame, lod_and_payload_are_checked) {
  RoomFrame f = sample_frame();
  f.lod = 2;
  std::vector<uint8_t> b = encode_room_frame(f);
  expect_error(b, ErrorCode::kBadFrame, "lod 2 is over max_lod 0");
  Limits limits;
  limits.max_lod = 2;
  EXPECT_TRUE(decode_room_frame(b, limits).ok());
  f = sample_frame();
  f.payload.clear();
  expect_error(encode_room_frame(f), ErrorCode::kBadFrame, "payload is empty");
}

TEST(RoomFrame, validate_agrees_with_decode) {
  RoomFrame f = sample_frame();
  EXPECT_TRUE(validate_room_frame(f, Limits{}).ok());
  f.room.portals[0].normal.y += 0.5;
  Status s = validate_room_frame(f, Limits{});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kBadFrame);
}

// room_frame.hpp: validate reports kTooLarge (not kBadFrame) over max_frame_bytes, as decode does.
TEST(RoomFrame, validate_reports_an_oversized_frame_as_too_large) {
  RoomFrame f = sample_frame();
  Limits limits;
  limits.max_frame_bytes = static_cast<uint32_t>(encode_room_frame(f).size());
  EXPECT_TRUE(validate_room_frame(f, limits).ok());
  f.payload.push_back(0);
  Status s = validate_room_frame(f, limits);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kTooLarge);
  Result<RoomFrame> d = decode_room_frame(encode_room_frame(f), limits);
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.error().code, ErrorCode::kTooLarge);
}

// room_frame.hpp: encoding does not validate, so invalid frames can be built (and are refused
// when decoded); only the header's own capacity is asserted.
TEST(RoomFrame, encode_writes_frames_that_validate_refuses) {
  RoomFrame f = sample_frame();
  f.origin.x += 1.0 / 512;  // off the grid
  ASSERT_FALSE(validate_room_frame(f, Limits{}).ok());
  std::vector<uint8_t> b = encode_room_frame(f);
  EXPECT_EQ(b.size(), room_frame_size(f.room.portals.size(), f.payload.size()));
  expect_error(b, ErrorCode::kBadFrame, "origin is not on the 1/256 m grid");
}

TEST(RoomFrame, every_single_byte_flip_is_decoded_or_refused_without_crashing) {
  // Cheap, deterministic cousin of the fuzzer: flip each bit of a valid frame. Whatever still
  // decodes must encode back to the same bytes.
  std::vector<uint8_t> bytes = sample_bytes();
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> b = bytes;
      b[i] ^= static_cast<uint8_t>(1u << bit);
      Result<RoomFrame> r = decode_room_frame(b, Limits{});
      if (r.ok()) {
        EXPECT_EQ(encode_room_frame(*r), b) << "byte " << i << " bit " << bit;
      }
    }
  }
}

}  // namespace
}  // namespace grotto::proto
