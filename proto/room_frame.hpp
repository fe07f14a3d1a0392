// The binary room frame: one room's descriptor (sphere and portals, so the portal graph reaches
// the client with the rooms) and its mesh payload, which is opaque here (the Draco bytes of
// common/codec). proto/PROTOCOL.md, "Binary room frame", gives the byte layout.
//
// decode_room_frame is safe for untrusted input: every length is checked against the buffer
// before it is read, counts are capped before anything is allocated, numbers must be finite and
// in range, normals unit, ids valid. It never throws and allocates at most the payload's size.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"
#include "proto/messages.hpp"

namespace grotto::proto {

inline constexpr uint8_t kFrameMagic[4] = {'G', 'R', 'T', 'O'};
inline constexpr uint8_t kFrameTypeRoom = 1;
inline constexpr uint8_t kFlagGate = 1;                // header flags bit 0
inline constexpr std::size_t kRoomHeaderBytes = 80;    // fixed part before the portals
inline constexpr std::size_t kPortalRecordBytes = 64;  // one portal
inline constexpr double kMaxRoomRadius = 256.0;        // metres (cave::kMaxSectorSize)
inline constexpr double kNormalTolerance = 1e-6;       // | |normal| - 1 | allowed
// The room's sphere must lie within this distance of the origin on every axis, so payload
// offsets stay exact in float32 on the 1/256 m grid (core/grid.hpp: kFrameSize / 2).
inline constexpr double kMaxOriginOffset = 32768.0;

struct RoomFrame {
  uint32_t version =
      kProtocolVersion;          // the protocol version, kMinProtocolVersion..kProtocolVersion
  cave::Room room;               // id, sphere and portals, world coordinates
  uint8_t lod = 0;               // wire level of detail of the payload (proto/lod.hpp)
  Vec3 origin;                   // on the 1/256 m grid; payload positions are offsets from it
  std::vector<uint8_t> payload;  // the mesh (common/codec); at least one byte
};

// Bytes of a frame with this many portals and payload bytes.
constexpr std::size_t room_frame_size(std::size_t portals, std::size_t payload_bytes) {
  return kRoomHeaderBytes + kPortalRecordBytes * portals + payload_bytes;
}

// The checks decode applies after the header's, for senders that want to know before they send:
// kTooLarge when the frame would exceed limits.max_frame_bytes, otherwise kBadFrame naming the
// field on failure.
Status validate_room_frame(const RoomFrame& frame, const Limits& limits);

// Writes the frame's bytes. Preconditions (asserted): at most cave::kMaxPortalsPerRoom portals and
// fewer than 2^32 payload bytes (what the header's count and length fields hold). Nothing else is
// checked: encoding does not call validate_room_frame, so it also writes frames that
// decode_room_frame refuses (the tests build invalid frames this way). A sender validates first
// unless its frames are valid by construction (the layout's rooms, an origin on the grid, a
// non-empty payload, lod ≤ max_lod).
// The payload is passed separately so a server can send cached bytes without copying them first.
std::vector<uint8_t> encode_room_frame(const cave::Room& room, uint8_t lod, Vec3 origin,
                                       std::span<const uint8_t> payload,
                                       uint32_t version = kProtocolVersion);
std::vector<uint8_t> encode_room_frame(const RoomFrame& frame);

// Errors: kBadFrame (truncated, wrong magic, bad flags, counts or lengths, non-finite or
// out-of-range numbers, non-unit normals, repeated portals, a lod over limits.max_lod),
// kTooLarge (over limits.max_frame_bytes), kUnsupportedVersion (a version this library does not
// speak; which of its versions a session accepts is the session's to check),
// kUnknownType (a frame type other than room), kInvalidRoomId (an id field that is no valid id).
// Messages name the field ("portals[2].normal is not unit length").
Result<RoomFrame> decode_room_frame(std::span<const uint8_t> bytes, const Limits& limits);

}  // namespace grotto::proto
