// The generation service's units, shared by the generator, its cache and the protocol
// conversation: which room a client waits for, and what comes back. Plain data: no sockets, no
// OpenCL, no scheduling.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "proto/lod.hpp"
#include "proto/messages.hpp"

namespace grotto::server {

using ClientId = uint64_t;

// The highest wire lod the generator builds (proto/lod.hpp maps wire lods to mesh lods). Checking
// a want's lod against the announced max_lod is the caller's job; the generator answers a lod
// above this with invalid_argument.
inline constexpr uint32_t kMaxServedLod = proto::kMaxWireLod;

// A room of a world at a level of detail, framed for a protocol version: the unit of building,
// caching and single flight. The version picks the payload's layout (proto::payload_has_normals),
// so clients of two versions wanting one room get two builds.
struct RoomKey {
  cave::RoomId id = cave::RoomId::interior({}, 0);
  uint8_t lod = 0;
  uint64_t seed = 0;  // the world
  uint32_t version = proto::kProtocolVersion;
  friend bool operator==(const RoomKey&, const RoomKey&) = default;
};

// A room a client waits for: which, at which wire lod (proto/lod.hpp), how soon (smaller first,
// e.g. milliseconds until the player can reach it).
struct Want {
  cave::RoomId id = cave::RoomId::interior({}, 0);
  uint32_t lod = 0;
  uint32_t priority = 0;
  friend bool operator==(const Want&, const Want&) = default;
};

// Where a client's rooms may come from: kAnywhere, the room's owner when the generator has
// owners, else built here; kHere, built here (the tier's requests to this replica as the owner).
enum class Build { kAnywhere, kHere };

// A built room, ready for the wire: the whole binary room frame (proto/room_frame.hpp: header,
// descriptor, Draco payload). Immutable and shared by the cache and every session sending it.
struct EncodedRoom {
  RoomKey key;
  std::vector<uint8_t> frame;
  double build_seconds = 0;   // this room's share of its batch's build
  double encode_seconds = 0;  // Draco encoding and framing
};
using RoomPtr = std::shared_ptr<const EncodedRoom>;

// The outcome of one wanted room for one client: a room, or an error whose code PROTOCOL.md lists
// (not_found: the id names no room; overloaded: the job waited past its deadline, retry later;
// internal: building or encoding failed; service_restart: the service is shutting down).
struct Delivery {
  RoomKey key;
  RoomPtr room;  // null exactly when error is set
  std::optional<Error> error;
  bool from_cache = false;  // served without touching the worker pool
};

}  // namespace grotto::server
