// What a client knows of the cave: the room descriptors it has received (each room frame carries
// its room's sphere and portals), and the prefetch plan over that portal graph. Pure data and free
// functions, no network and no threads: client/stream's Stream calls them on its strand, and
// grotto-load and the tests call them directly.
//
// Prefetch: a room's cost is the time the player needs to reach it,
// the length of the shortest path from the player's position through portal centres divided by
// the player's speed, stretched for rooms behind the player (the first portal of the path against
// the view direction). A room whose descriptor is not known yet is a leaf of the search: its
// portals arrive with its frame, and the next plan goes one step further.
#pragma once
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"

namespace grotto::stream {

// Where the player is and where it looks. Brace-init is a player standing at the origin.
struct Pose {
  Vec3 position;
  Vec3 forward{0, 0, -1};  // view direction; need not be unit; zero: no preference
  double speed = 4.0;      // m/s used for time-to-reach; values below kMinSpeed count as kMinSpeed
  // The room the player is in, when the caller knows it (a walker on the portal graph does);
  // otherwise PortalGraph::room_at finds it among the known rooms.
  std::optional<cave::RoomId> room;
};

inline constexpr double kMinSpeed = 0.5;  // m/s: a standing player still prefetches nearby

struct PlanOptions {
  double horizon_s = 4.0;      // rooms reachable within this many seconds are wanted
  double behind_weight = 1.0;  // cost factor 1 + behind_weight * (1 - cos(angle)) / 2 for the
                               // first hop: 1 straight ahead, 1 + behind_weight straight behind
  size_t max_rooms = 4096;     // never more rooms in a plan than this (nearest first)
};

// One room of a plan: the time to reach it (seconds, view weighting included) and whether its
// descriptor is known (a room not yet received is known only as a neighbour's portal).
struct PlannedRoom {
  cave::RoomId id;
  double seconds = 0;
  bool known = false;
};

// The one check of a portal's two sides (PROTOCOL.md "Binary room frame"): `other` has a portal
// back to `room`, and it carries the same centre and radius as room.portals[slot], bit for bit,
// and the opposite normal (the layout computes the disc once and negates the normal for one side,
// common/cave/sector.cpp). Errors (kBadFrame) name the room, the slot, the neighbour and the first
// field that differs. Precondition: slot < room.portals.size(). PortalGraph::add and verify_seam
// call it.
Status check_portal_sides(const cave::Room& room, size_t slot, const cave::Room& other);

// The rooms a client has descriptors for, with their portals. Adding a room checks it against the
// neighbours already known: the two sides of a portal carry the same centre and radius, bit for
// bit, and opposite normals (PROTOCOL.md "Binary room frame").
class PortalGraph {
 public:
  // Adds or replaces `room`. Errors (kBadFrame, naming the portal and the neighbour) when a portal
  // disagrees with the known neighbour's side of it; the graph is then unchanged. A neighbour that
  // does not list this room back is an error too.
  Status add(const cave::Room& room);
  void remove(cave::RoomId id);
  void clear();
  const cave::Room* find(cave::RoomId id) const;  // nullptr when not known
  size_t size() const { return rooms_.size(); }

  // The known room that contains `point`: among rooms whose sphere holds it, the one with the
  // smallest distance/radius; nullopt when no known sphere holds it.
  std::optional<cave::RoomId> room_at(Vec3 point) const;

  // The rooms within options.horizon_s of the pose, cheapest first (ties by id), starting from
  // `start` (cost 0, whether known or not). Unknown rooms are leaves. Deterministic.
  std::vector<PlannedRoom> plan(cave::RoomId start, const Pose& pose,
                                const PlanOptions& options) const;

 private:
  void unlink(const cave::Room& room);  // drops room's entries from referrers_

  std::map<cave::RoomId, cave::Room> rooms_;
  // For each room id, the known rooms with a portal to it: add() checks the other direction
  // against these instead of scanning every room (a long walk knows thousands).
  std::map<cave::RoomId, std::set<cave::RoomId>> referrers_;
};

}  // namespace grotto::stream
