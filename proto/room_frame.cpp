#include "proto/room_frame.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>

#include "common/core/bytes.hpp"
#include "common/core/grid.hpp"

namespace grotto::proto {
namespace {

// Byte offsets of the fixed header (PROTOCOL.md, "Binary room frame").
constexpr std::size_t kOffVersion = 4;
constexpr std::size_t kOffType = 6;
constexpr std::size_t kOffFlags = 7;
constexpr std::size_t kOffId = 8;
constexpr std::size_t kOffLod = 16;
constexpr std::size_t kOffPortalCount = 17;
constexpr std::size_t kOffReserved = 18;
constexpr std::size_t kOffPayloadBytes = 20;
constexpr std::size_t kOffOrigin = 24;
constexpr std::size_t kOffCentre = 48;
constexpr std::size_t kOffRadius = 72;

Error bad_frame(std::string message) {
  return {ErrorCode::kBadFrame, "room frame: " + std::move(message)};
}

bool finite(Vec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
bool within(Vec3 v, double limit) {
  return std::fabs(v.x) <= limit && std::fabs(v.y) <= limit && std::fabs(v.z) <= limit;
}

Status check_position(Vec3 v, const std::string& field) {
  if (!finite(v)) return bad_frame(field + " is not finite");
  if (!within(v, kMaxCoordinate)) return bad_frame(field + " is outside [-16777216, 16777216] m");
  return {};
}

}  // namespace

Status validate_room_frame(const RoomFrame& frame, const Limits& limits) {
  const cave::Room& room = frame.room;
  std::size_t size = room_frame_size(room.portals.size(), frame.payload.size());
  if (size > limits.max_frame_bytes) {
    return Error{ErrorCode::kTooLarge, "room frame of " + std::to_string(size) +
                                           " bytes exceeds max_frame_bytes " +
                                           std::to_string(limits.max_frame_bytes)};
  }
  if (frame.lod > limits.max_lod) {
    return bad_frame("lod " + std::to_string(frame.lod) + " is over max_lod " +
                     std::to_string(limits.max_lod));
  }
  if (frame.payload.empty()) return bad_frame("payload is empty");
  if (Status s = check_position(frame.origin, "origin"); !s) return s;
  if (!grid::on_wire_grid(frame.origin.x) || !grid::on_wire_grid(frame.origin.y) ||
      !grid::on_wire_grid(frame.origin.z)) {
    return bad_frame("origin is not on the 1/256 m grid");
  }
  const Vec3 c = room.sphere.centre;
  const double r = room.sphere.radius;
  if (Status s = check_position(c, "centre"); !s) return s;
  if (!std::isfinite(r) || !(r > 0) || r > kMaxRoomRadius) {
    return bad_frame("radius must be in (0, 256] m");
  }
  Vec3 d = c - frame.origin;
  if (!within(d, kMaxOriginOffset - r)) {
    return bad_frame("the room's sphere reaches beyond 32768 m of the origin");
  }
  if (room.portals.size() > static_cast<std::size_t>(cave::kMaxPortalsPerRoom)) {
    return bad_frame(std::to_string(room.portals.size()) + " portals, more than " +
                     std::to_string(cave::kMaxPortalsPerRoom));
  }
  std::vector<uint64_t> neighbours;
  for (std::size_t i = 0; i < room.portals.size(); ++i) {
    const cave::Portal& p = room.portals[i];
    std::string at = "portals[" + std::to_string(i) + "]";
    if (p.neighbour == room.id) return bad_frame(at + ".to is the room itself");
    if (Status s = check_position(p.centre, at + ".centre"); !s) return s;
    // The disc lies inside its sphere (a little slack for the rounding of the layout's sqrt).
    if (length(p.centre - c) > r * (1 + 1e-9)) return bad_frame(at + ".centre is outside the room");
    if (!finite(p.normal)) return bad_frame(at + ".normal is not finite");
    if (std::fabs(length(p.normal) - 1) > kNormalTolerance) {
      return bad_frame(at + ".normal is not unit length");
    }
    if (!std::isfinite(p.radius) || !(p.radius > 0) || p.radius > r) {
      return bad_frame(at + ".radius must be in (0, room radius]");
    }
    neighbours.push_back(p.neighbour.packed());
  }
  std::sort(neighbours.begin(), neighbours.end());
  if (std::adjacent_find(neighbours.begin(), neighbours.end()) != neighbours.end()) {
    return bad_frame("two portals lead to the same room");
  }
  return {};
}

std::vector<uint8_t> encode_room_frame(const cave::Room& room, uint8_t lod, Vec3 origin,
                                       std::span<const uint8_t> payload, uint32_t version) {
  assert(room.portals.size() <= static_cast<std::size_t>(cave::kMaxPortalsPerRoom));
  assert(payload.size() <= 0xffffffffu);
  std::vector<uint8_t> out;
  out.reserve(room_frame_size(room.portals.size(), payload.size()));
  for (uint8_t c : kFrameMagic)
    out.push_back(c);
  le::append(out, version, 2);
  le::append(out, kFrameTypeRoom, 1);
  le::append(out, room.id.is_gate() ? kFlagGate : 0, 1);
  le::append(out, room.id.packed(), 8);
  le::append(out, lod, 1);
  le::append(out, room.portals.size(), 1);
  le::append(out, 0, 2);
  le::append(out, payload.size(), 4);
  le::append_vec3(out, origin);
  le::append_vec3(out, room.sphere.centre);
  le::append_f64(out, room.sphere.radius);
  for (const cave::Portal& p : room.portals) {
    le::append(out, p.neighbour.packed(), 8);
    le::append_vec3(out, p.centre);
    le::append_vec3(out, p.normal);
    le::append_f64(out, p.radius);
  }
  out.insert(out.end(), payload.begin(), payload.end());
  assert(out.size() == room_frame_size(room.portals.size(), payload.size()));
  return out;
}

std::vector<uint8_t> encode_room_frame(const RoomFrame& frame) {
  return encode_room_frame(frame.room, frame.lod, frame.origin, frame.payload, frame.version);
}

Result<RoomFrame> decode_room_frame(std::span<const uint8_t> bytes, const Limits& limits) {
  const std::size_t size = bytes.size();
  const uint8_t* b = bytes.data();
  if (size > limits.max_frame_bytes) {
    return Error{ErrorCode::kTooLarge, "room frame of " + std::to_string(size) +
                                           " bytes exceeds max_frame_bytes " +
                                           std::to_string(limits.max_frame_bytes)};
  }
  // Identify the frame from whatever prefix is there, then insist on the whole header.
  if (!std::equal(b, b + std::min<std::size_t>(size, 4), kFrameMagic)) {
    return bad_frame("wrong magic (a room frame starts with 'GRTO')");
  }
  if (size >= kOffType) {
    uint64_t version = le::load(b + kOffVersion, 2);
    if (!speaks_version(version)) {
      return Error{ErrorCode::kUnsupportedVersion,
                   "room frame: version " + std::to_string(version) + ", this decoder reads " +
                       std::to_string(kMinProtocolVersion) + ".." +
                       std::to_string(kProtocolVersion)};
    }
  }
  if (size > kOffType && b[kOffType] != kFrameTypeRoom) {
    return Error{ErrorCode::kUnknownType,
                 "binary frame of unknown type " + std::to_string(b[kOffType])};
  }
  if (size < kRoomHeaderBytes) {
    return bad_frame("truncated: " + std::to_string(size) + " bytes, the header needs " +
                     std::to_string(kRoomHeaderBytes));
  }
  const uint8_t flags = b[kOffFlags];
  const std::size_t portals = b[kOffPortalCount];
  const uint64_t payload_bytes = le::load(b + kOffPayloadBytes, 4);
  if (portals > static_cast<std::size_t>(cave::kMaxPortalsPerRoom)) {
    return bad_frame("portal count " + std::to_string(portals) + " is over " +
                     std::to_string(cave::kMaxPortalsPerRoom));
  }
  // Both terms are bounded (16 portals, a 32-bit length), so the sum cannot overflow.
  const uint64_t expected = room_frame_size(portals, payload_bytes);
  if (size != expected) {
    return bad_frame(std::string(size < expected ? "truncated: " : "trailing bytes: ") +
                     std::to_string(size) + " bytes, the header announces " +
                     std::to_string(expected) + " (" + std::to_string(portals) + " portals, " +
                     std::to_string(payload_bytes) + " payload bytes)");
  }
  if (le::load(b + kOffReserved, 2) != 0) return bad_frame("reserved header bytes are not zero");

  Result<cave::RoomId> id = cave::RoomId::unpack(le::load(b + kOffId, 8));
  if (!id) return Error{ErrorCode::kInvalidRoomId, "room frame: id: " + id.error().message};
  if ((flags & ~kFlagGate) != 0) return bad_frame("unknown flag bits are set");
  if (((flags & kFlagGate) != 0) != id->is_gate()) {
    return bad_frame("the gate flag disagrees with the room id " + id->to_string());
  }

  RoomFrame frame;
  frame.version = static_cast<uint32_t>(le::load(b + kOffVersion, 2));
  frame.room.id = *id;
  frame.lod = b[kOffLod];
  frame.origin = le::load_vec3(b + kOffOrigin);
  frame.room.sphere.centre = le::load_vec3(b + kOffCentre);
  frame.room.sphere.radius = le::load_f64(b + kOffRadius);
  frame.room.portals.reserve(portals);
  for (std::size_t i = 0; i < portals; ++i) {
    const uint8_t* p = b + kRoomHeaderBytes + kPortalRecordBytes * i;
    Result<cave::RoomId> to = cave::RoomId::unpack(le::load(p, 8));
    if (!to) {
      return Error{ErrorCode::kInvalidRoomId,
                   "room frame: portals[" + std::to_string(i) + "].to: " + to.error().message};
    }
    cave::Portal portal;
    portal.neighbour = *to;
    portal.centre = le::load_vec3(p + 8);
    portal.normal = le::load_vec3(p + 32);
    portal.radius = le::load_f64(p + 56);
    frame.room.portals.push_back(portal);
  }
  const uint8_t* payload = b + room_frame_size(portals, 0);
  frame.payload.assign(payload, payload + payload_bytes);
  if (Status s = validate_room_frame(frame, limits); !s) return s.error();
  return frame;
}

}  // namespace grotto::proto
