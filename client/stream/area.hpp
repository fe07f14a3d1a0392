// "Does the ground exist yet?": whether every room within a distance of a point, measured along
// the portal graph, is decoded and held. A game holds spawning (or a teleport) on it. Pure: it
// reads a PortalGraph and a RoomStore, so the tests build both by hand; Stream::area_status and
// Stream::wait_area_ready run it over the rooms a Stream holds.
#pragma once
#include <cstddef>
#include <cstdint>
#include <optional>

#include "cave/room_id.hpp"
#include "client/stream/portal_graph.hpp"
#include "client/stream/room_store.hpp"
#include "core/vec3.hpp"

namespace grotto::client {

struct AreaStatus {
  bool ready = false;    // every room of the area is stored at a lod <= max_lod
  bool located = false;  // a known room holds the point (false: nothing is known there yet)
  size_t rooms = 0;      // rooms of the area found so far (their descriptors known or not)
  size_t missing = 0;    // of those, not stored, or stored above max_lod
  std::optional<cave::RoomId> first_missing;  // the nearest of them
};

// The area is the room that holds `point` (PortalGraph::room_at over the rooms known) and every
// room whose path from `point` through portal centres is at most radius_m metres long (the
// prefetch plan's distance, PortalGraph::plan, with no view weighting). A room known only as a
// neighbour's portal is in the area and missing: its own portals are not known, so the area is
// ready only once every room that could extend it has arrived. radius_m below 0 or NaN counts as
// 0 (the room holding the point alone). Not ready when no known room holds the point.
AreaStatus area_status(const PortalGraph& graph, const RoomStore& store, Vec3 point,
                       double radius_m, uint32_t max_lod);

}  // namespace grotto::client
