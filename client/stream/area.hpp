// "Does the ground exist yet?": whether every room within a distance of a point, measured along
// the portal graph, is decoded and held. A game holds spawning (or a teleport) on it. Pure: it
// reads a PortalGraph and a RoomStore, so the tests build both by hand; Stream::area_status and
// Stream::wait_area_ready run it over the rooms a Stream holds, and the Conversation's pinned
// areas (conversation.hpp) request the rooms of the same walk.
#pragma once
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "client/stream/portal_graph.hpp"
#include "client/stream/room_store.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/vec3.hpp"

namespace grotto::stream {

struct AreaStatus {
  bool ready = false;    // every room of the area is stored at a lod <= max_lod
  bool located = false;  // a known room holds the point (false: nothing is known there yet)
  size_t rooms = 0;      // rooms of the area found so far (their descriptors known or not)
  size_t missing = 0;    // of those, not stored, or stored above max_lod
  std::optional<cave::RoomId> first_missing;  // the nearest of them
};

// The area's rooms as far as the graph knows them, starting from `start` (the room holding
// `point`, known or not): `start` and every room whose path from `point` through portal centres
// is at most radius_m metres long (the prefetch plan's walk, PortalGraph::plan, at 1 m/s with no
// view weighting; `seconds` is the path's length in metres), nearest first. A room known only as
// a neighbour's portal is a leaf: its own portals are not known yet. radius_m below 0 or NaN
// counts as 0 (`start` alone). The one walk behind area_status and the Conversation's pinned
// areas, so what a wait fetches is what it checks.
std::vector<PlannedRoom> area_rooms(const PortalGraph& graph, cave::RoomId start, Vec3 point,
                                    double radius_m);

// The area is the room that holds `point` (PortalGraph::room_at over the rooms known) and the
// rooms of area_rooms from it. A room known only as a neighbour's portal is in the area and
// missing: its own portals are not known, so the area is ready only once every room that could
// extend it has arrived. Not ready when no known room holds the point.
AreaStatus area_status(const PortalGraph& graph, const RoomStore& store, Vec3 point,
                       double radius_m, uint32_t max_lod);

}  // namespace grotto::stream
