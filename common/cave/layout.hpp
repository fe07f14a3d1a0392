// The unbounded cave layout: rooms (spheres), portals (discs where two spheres overlap) and the
// portal graph, as pure functions of (seed, parameters, room id).
//
// Space is cut into cubic sectors. Each face between two sectors carries a few gate rooms placed
// by a hash of (seed, face), centred on the face and kept away from its edges. A sector links its
// gates with chains of overlapping spheres, then grows the rest with the thesis's growing tree
// (§3.1.2). Its own rooms stay inside its box, so a sector depends only on its seed and the gates
// of its six faces: any room is computed from at most two sectors, in any order, in any process.
// docs/ARCHITECTURE.md explains the scheme and why it is connected.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "common/cave/params.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"

namespace grotto::cave {

// No room has more portals than this (the mesh kernel keeps per-portal state in registers).
inline constexpr int kMaxPortalsPerRoom = 16;

struct Sphere {
  Vec3 centre;
  double radius = 0;
};

// The height (world y) of the floor of a room with this sphere, or nothing when it has none: rooms
// of at least params.floor_min_radius rest on a floor params.floor_depth x radius below their
// centre (the mesh lays it, mesh/deform_core.h), and no portal of theirs opens below it or
// within params.wall_clearance above it.
std::optional<double> floor_height(const LayoutParams& params, const Sphere& sphere);

// The ceiling of a room with a floor (params.ceiling_*): above `spring` (world y) the wall is
// lowered by squash x ramp(y - spring), where the ramp eases in over `bend` metres
// (t^2 / (2 bend) below it, t - bend / 2 beyond), so the sphere's upper cap becomes a low dome
// with a smooth shoulder. The mesh lowers its wall so (mesh/deform_core.h, away from portals);
// no portal of the room opens above `spring`.
struct Ceiling {
  double spring = 0;  // world y
  double bend = 0;    // metres
  double squash = 0;  // in (0, 1]
  // Where a point at world height y of the room's sphere ends up.
  double lower(double y) const;
};
std::optional<Ceiling> room_ceiling(const LayoutParams& params, const Sphere& sphere);

// The disc where two rooms' spheres overlap (thesis Figure 3-2), seen from one of them.
struct Portal {
  Vec3 centre;
  Vec3 normal;  // unit, pointing out of this room into the neighbour
  double radius = 0;
  RoomId neighbour = RoomId::interior({}, 0);
};

struct Room {
  RoomId id = RoomId::interior({}, 0);
  Sphere sphere;
  std::vector<Portal> portals;  // sorted by neighbour id
};

// A validated world: a seed and parameters that passed validate().
class World {
 public:
  static Result<World> create(uint64_t seed, const LayoutParams& params);
  uint64_t seed() const { return seed_; }
  const LayoutParams& params() const { return params_; }

 private:
  World(uint64_t seed, const LayoutParams& params) : seed_(seed), params_(params) {}
  uint64_t seed_;
  LayoutParams params_;
};

// Everything one sector decides: its interior rooms with all their portals, and the gates of its
// six faces with the portals they have on this sector's side.
struct SectorLayout {
  SectorCoord sector;
  SectorCharacter character;
  std::vector<Room> rooms;  // interior rooms, index i has id RoomId::interior(sector, i)
  int link_rooms = 0;       // rooms[0, link_rooms) are the hub and gate links; the rest grew
  std::vector<Room> gates;  // sorted by id; portals on this side only
  int attempts = 0;         // generation attempts used (1 unless linking the gates failed)
  bool connected = false;   // every room and gate in one component (true in all tested worlds)
};

// The gates on the face between `lower` and its +axis neighbour (no portals).
std::vector<Room> face_gates(const World& world, SectorCoord lower, int axis);

// Precondition: in_range(sector). Bounded work: the sector's own rooms and its faces' gates.
SectorLayout generate_sector(const World& world, SectorCoord sector);

// Where sector layouts come from: the World-only functions below generate them; a cache passes
// its own source to the overloads that take one. A source returns generate_sector(world, s) for
// the same world (from wherever it keeps it); it is called only for in_range sectors.
using SectorSource = std::function<std::shared_ptr<const SectorLayout>(SectorCoord)>;

// Any room with all its portals. Interior rooms need their sector; gates need both sectors of
// their face. Errors: kNotFound for a well-formed id that names no room (also a gate on the
// world's edge); kInternal for a sector that could not link its gates.
Result<Room> room(const World& world, RoomId id);
Result<Room> room(const World& world, RoomId id, const SectorSource& sectors);

// The room whose space (its sphere minus the caps beyond its portals) contains `point`; a point
// on a portal plane belongs to the room with the smaller id. None outside every room or outside
// the sector range.
std::optional<RoomId> locate(const World& world, Vec3 point);
std::optional<RoomId> locate(const World& world, Vec3 point, const SectorSource& sectors);

// Whether the point is in the room's space: inside its sphere and on its own side of every
// portal plane (a point on a plane belongs to the room with the smaller id). locate's rule.
bool in_space(const Room& room, Vec3 point);

// "Which room holds p", the one rule every stage uses (locate, the client's collision and
// camera): among `rooms`, the room whose space holds `point` (in_space), the smallest id when
// several do; nullptr when none does. Any set of rooms will do: a room whose neighbour through a
// portal is missing from the set still gives up the cap beyond that portal. `proj` maps an
// element of `rooms` to its `const Room&` (identity for a range of Room).
template <typename Rooms, typename Proj = std::identity>
const Room* room_at(const Rooms& rooms, Vec3 point, Proj proj = {}) {
  const Room* best = nullptr;
  for (const auto& element : rooms) {
    const Room& r = std::invoke(proj, element);
    if ((!best || r.id < best->id) && in_space(r, point)) best = &r;
  }
  return best;
}
// room_at over one sector's interior rooms and gates (the gates with this side's portals only):
// the answer locate gives for a point in that sector.
const Room* room_at(const SectorLayout& layout, Vec3 point);
// A point well inside the room's space: the sphere's centre, stepped back behind any portal plane
// whose cap holds it (overlapping spheres can put it there). Where a player starts in the room.
Vec3 interior_point(const Room& room);

// The deterministic place a new player starts: an interior room of sector (0,0,0) without a
// floor (not a hall), one with a portal into a hall when there is one (a hall's entrance),
// closest to the sector's centre; the first interior room when all have floors.
RoomId spawn_room(const World& world);
// spawn_room's room and where in it a player starts (interior_point).
struct Spawn {
  RoomId room = RoomId::interior({}, 0);
  Vec3 position;
};
Spawn spawn(const World& world, const SectorSource& sectors);

// The sector that contains a point (floor division by the sector size).
SectorCoord sector_of(const World& world, Vec3 point);

// A block of sectors [lo, hi] (inclusive): their interior rooms and the gates of their faces,
// each with all its portals (portals of boundary gates may lead out of the block), sorted by id.
struct Region {
  SectorCoord lo, hi;
  std::vector<Room> rooms;
  std::vector<SectorLayout> sectors;  // the block's sectors in x-major order
  const Room* find(RoomId id) const;  // nullptr when the room is not in the region
};
// Its sectors (and the sectors beyond its faces whose gates it needs) are laid out on `threads`
// threads, the caller's one of them: each sector is a pure function of the world and its
// coordinates, so the region is the same bytes whatever the count.
Region generate_region(const World& world, SectorCoord lo, SectorCoord hi, int threads = 1);

// generate_region in its two stages, for a caller that works on the block's interior rooms (they
// need only the block's own sectors) while the sectors beyond its faces are still laid out.
struct RegionPlan {
  SectorCoord lo, hi;
  std::vector<SectorCoord> block;    // the block's sectors, x-major
  std::vector<SectorCoord> outside;  // beyond its faces, with gates it needs; sorted
};
// Known from the faces' gates alone (face_gates: a few draws, no layout).
RegionPlan plan_region(const World& world, SectorCoord lo, SectorCoord hi);
// The region from generate_sector of plan.block's sectors, then of plan.outside's, in order.
Region assemble_region(const RegionPlan& plan, std::vector<SectorLayout> layouts);

// Canonical little-endian bytes of a room (ids packed, doubles as IEEE bits): the basis of
// determinism tests and digests.
void append_bytes(const Room& room, std::vector<unsigned char>& out);
uint64_t digest(const std::vector<Room>& rooms);

}  // namespace grotto::cave
