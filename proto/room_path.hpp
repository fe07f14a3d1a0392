// A room as an HTTP resource (PROTOCOL.md, "Rooms over HTTP"): its URL path names everything that
// shapes the room frame's bytes, so the bytes behind a path never change and any HTTP cache may
// keep them for good:
//
//   /rooms/v<version>/<seed>/<params>/<lod>/<room id>      e.g.
//   /rooms/v2/7/7a58bce46eb33930/0/0.0.0.r0
//
// Every part has exactly one text form (the one hello, welcome and room ids use), so one room has
// one URL and a cache keeps it once. Parsing is safe for untrusted input; it checks form only
// (whether a server speaks the version, serves the world or the lod is its business).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "proto/messages.hpp"

namespace grotto::proto {

// Every room path starts with this.
inline constexpr std::string_view kRoomPathPrefix = "/rooms/";

struct RoomPath {
  uint32_t version = kProtocolVersion;  // the room frame's protocol version, 1-65535
  uint64_t seed = 0;                    // the world
  uint64_t params = 0;                  // the world's parameter digest (welcome.params)
  uint32_t lod = 0;                     // wire lod, 0-255
  cave::RoomId id = cave::RoomId::interior({}, 0);
  friend bool operator==(const RoomPath&, const RoomPath&) = default;
};

// The path's one text form.
std::string room_path(const RoomPath& room);

// A path (without query string) as room_path() writes it. Errors (kBadMessage) name the part
// that is wrong and quote at most kMaxEchoBytes of it; a malformed room id is kInvalidRoomId.
Result<RoomPath> parse_room_path(std::string_view path);

}  // namespace grotto::proto
