// What the player collides with: the surface grotto-client draws, i.e. each room's patch mesh as
// PN triangles with the rock's relief on top (common/relief/relief.hpp, the shader's own source:
// rock and flowstone) and its formations as simple hulls (common/formations/formations.hpp:
// stalactites, stalagmites, columns; six sides round what is drawn), added when client/stream
// delivers the room and removed when it is evicted, plus a wall over every portal whose neighbour
// is not loaded, so nobody falls out of the streamed cave. A patch triangle is refined into kRefine
// x kRefine triangles of that surface the first time a query comes near it (about 14 cm apart), and
// kept while its room is.
//
// Precision: a room keeps its decoded room-frame floats and its grid origin (as
// client/render/room_cache does); triangles leave the world in double (origin + float offset), so
// collision is as exact 10^4 m from the origin as at the spawn.
//
// Broad phase: each room has a bounding sphere around its vertices and a uniform grid of 1 m
// cells over its box, each cell listing the triangles whose box overlaps it. No GL, no network,
// not thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <vector>

#include "client/stream/room_store.hpp"
#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"
#include "common/formations/formations.hpp"

namespace grotto::play {

struct Triangle {
  Vec3 a, b, c;  // world metres
};

// A portal disc standing in for a neighbour room that is not loaded.
struct Disc {
  Vec3 centre;
  Vec3 normal;  // unit
  double radius = 0;
};

// Closest point of a triangle (Ericson, Real-Time Collision Detection §5.1.5) or a disc to p.
Vec3 closest_point(const Triangle& t, Vec3 p);
Vec3 closest_point(const Disc& d, Vec3 p);
// The unit normal of the triangle's winding (a, b, c counter-clockwise), zero when degenerate.
Vec3 unit_normal(const Triangle& t);
// Whether the segment [p, q] meets the triangle or the disc (touching counts).
bool segment_crosses(const Triangle& t, Vec3 p, Vec3 q);
bool segment_crosses(const Disc& d, Vec3 p, Vec3 q);

// The wall over a portal reaches this much beyond the farthest its rim can lie from the portal's
// centre (mesh::rim_reach: the irregular radius plus the surface noise that moves the rim), so
// that it closes over the rim's triangles.
inline constexpr double kPortalWallMargin = 0.15;

// Refinement of a patch triangle for collision: kRefine segments per edge.
inline constexpr int kRefine = 4;

// The collision geometry near a box: the loaded rooms' triangles and the walls over portals to
// rooms not loaded.
struct Neighbourhood {
  std::vector<Triangle> triangles;
  std::vector<Disc> walls;
};

class CollisionWorld {
  struct Formation {
    Vec3 lo, hi;
    std::vector<Triangle> triangles;
  };

 public:
  // relief_strength: RenderOptions::displacement of the surface to collide with (1: as drawn;
  // 0: the PN patch surface alone, e.g. for flat test shapes).
  // formations: the rooms' formations collide too (off: the rock alone, for tests of it).
  explicit CollisionWorld(float relief_strength = 1.0f, bool formations = true)
      : relief_strength_(relief_strength), formations_(formations) {}
  // Adds the room's patch mesh, replacing a room with the same id, with its formations placed
  // here (formations::place) or given (placed elsewhere, or to come through set_formations).
  void add(const stream::ReadyRoom& room);
  void add(const stream::ReadyRoom& room, std::span<const formations::FormationShape> formations);
  // The room's formations, when they were placed apart from add; nothing when it is gone.
  void set_formations(cave::RoomId id, std::span<const formations::FormationShape> formations);
  void evict(cave::RoomId id);
  void clear() { rooms_.clear(); }
  bool contains(cave::RoomId id) const { return rooms_.count(id) != 0; }
  size_t size() const { return rooms_.size(); }
  // Everything whose box overlaps [lo, hi] (world metres), appended to `out` (cleared first).
  // A triangle appears once.
  void gather(Vec3 lo, Vec3 hi, Neighbourhood& out) const;
  // The loaded room whose space holds p by the cave's rule (cave::room_at), or nullptr.
  const cave::Room* room_at(Vec3 p) const;

 private:
  struct Room {
    cave::Room room;
    Vec3 origin;
    std::vector<float> positions;  // x, y, z per vertex, metres from origin
    std::vector<float> normals;    // x, y, z per vertex
    std::vector<float> roughness;
    std::vector<float> rim;  // 1 on a portal rim, else 0
    std::vector<uint32_t> indices;
    // Metres the relief can move the surface along its normal.
    double relief_reach = 0;
    // The formations' hulls (formations::collision_hull), world metres, each with its box.
    std::vector<Formation> formations;
    // Patch triangle t's refined_count[t] triangles start at refined[refined_at[t] - 1] (0: not
    // refined yet).
    mutable std::vector<uint32_t> refined_at;
    mutable std::vector<uint8_t> refined_count;
    mutable std::vector<Triangle> refined;
    Vec3 bound_centre;  // world
    double bound_radius = 0;
    // The grid over [grid_lo, grid_lo + dims) cells of kCell metres in the room frame; cell c
    // holds triangles cell_triangles[cell_start[c], cell_start[c + 1]).
    int grid_lo[3] = {0, 0, 0};
    int dims[3] = {0, 0, 0};
    std::vector<uint32_t> cell_start;
    std::vector<uint32_t> cell_triangles;
  };
  // The triangles of the drawn surface over patch triangle t: kRefine^2, or the triangle itself
  // where it is flat and has no relief.
  std::span<const Triangle> refined(const Room& room, uint32_t t) const;

  float relief_strength_ = 1.0f;
  bool formations_ = true;
  std::map<cave::RoomId, Room> rooms_;
  mutable std::vector<uint32_t> seen_;  // gather's dedup scratch
};

}  // namespace grotto::play
