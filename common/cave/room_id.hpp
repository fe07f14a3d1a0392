// Room ids: which sector a room belongs to and which slot it fills there. Compact (64 bits on the
// wire), stable (a pure function of the layout, never of generation order) and printable.
//
// Interior rooms belong to one sector. Gate rooms sit on the face between a sector and its
// neighbour in +x, +y or +z and belong to that face; the face is named by its lower sector.
//
// Text form:  "<sx>.<sy>.<sz>.r<n>"  interior room n of sector (sx, sy, sz)
//             "<sx>.<sy>.<sz>.x<n>"  gate n on the face between (sx, sy, sz) and (sx+1, sy, sz)
//             ("y", "z" likewise). Example: "3.-1.0.r12". Safe in JSON strings and URL paths.
// Binary form: bits 0-12 slot, 13-29 sx, 30-46 sy, 47-63 sz, each coordinate offset by
//             kSectorCoordLimit (see proto/PROTOCOL.md).
#pragma once

#include <compare>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/core/result.hpp"

namespace grotto::cave {

// Sector coordinates are bounded so that an id packs into 64 bits: 131,071 sectors per axis.
inline constexpr int32_t kSectorCoordLimit = 65535;
inline constexpr int kMaxInteriorRooms = 4096;
inline constexpr int kMaxGatesPerFace = 16;
inline constexpr int kGateSlotBase = kMaxInteriorRooms;
inline constexpr int kSlotCount = kGateSlotBase + 3 * kMaxGatesPerFace;

struct SectorCoord {
  int32_t x = 0, y = 0, z = 0;

  int32_t operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
  int32_t& operator[](int axis) { return axis == 0 ? x : (axis == 1 ? y : z); }
  friend auto operator<=>(const SectorCoord&, const SectorCoord&) = default;
};

// True when every coordinate is within ±kSectorCoordLimit.
bool in_range(SectorCoord s);
SectorCoord neighbour(SectorCoord s, int axis, int step);
std::string to_string(SectorCoord s);

class RoomId {
 public:
  // Preconditions (asserted): sector in range, index within the slot kind's limit, axis in 0..2.
  static RoomId interior(SectorCoord sector, int index);
  static RoomId gate(SectorCoord lower_sector, int axis, int index);

  // Validating constructors for ids that come from outside.
  static Result<RoomId> parse(std::string_view text);
  static Result<RoomId> unpack(uint64_t packed);

  SectorCoord sector() const { return sector_; }
  bool is_gate() const { return slot_ >= kGateSlotBase; }
  // Interior rooms: the index within the sector. Gates: the index within the face.
  int index() const { return is_gate() ? (slot_ - kGateSlotBase) % kMaxGatesPerFace : slot_; }
  // Gates only: 0, 1 or 2 for the face normal to x, y or z.
  int gate_axis() const { return (slot_ - kGateSlotBase) / kMaxGatesPerFace; }

  uint64_t packed() const;
  std::string to_string() const;

  friend auto operator<=>(const RoomId&, const RoomId&) = default;

 private:
  RoomId(SectorCoord sector, uint16_t slot) : sector_(sector), slot_(slot) {}
  SectorCoord sector_;
  uint16_t slot_ = 0;
};

}  // namespace grotto::cave
