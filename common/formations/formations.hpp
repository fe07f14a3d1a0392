// Speleothems as instanced geometry: where a room's stalactites, stalagmites, soda
// straws, columns and draperies are and what shape each has, as a pure function of (world, room):
// water drips along lines that follow the cracks in the ceiling (relief.glsl's crack field), in
// some cells of a 4 m lattice, more of them and longer where the region is wet and few where it
// is dry. Each line is a fringe of drips (soda straws to metres, longest in its middle), each
// hung plumb from the drawn ceiling with its stalagmite beneath it on the floor the drip falls
// on, over a flowstone mound beneath the line's middle; columns where the two would meet, and
// draperies along the slope of inclined ceilings. Slow lines (water that seeps too slowly to
// build on the floor) are fringes of stalactites alone. Between the lines the floor is bare. In
// halls the blocks fallen from the ceiling lie in heaps on the floor beneath where it broke
// (breakdown.cpp). The shape of one instance is shaders/formation.glsl's,
// compiled here as C++ over GLM (as relief.hpp does), so the renderer, collision, the glb export
// and engines see the same formations.
//
// The input is what every client already has: the room's patch mesh as decoded (positions in the
// room's frame, normals, roughness, rims) and its sphere's radius; nothing new on the wire, like
// the world's lights. Part of the world: proto::world_params_digest folds
// proto::kFormationsVersion. Deterministic: the lattice's hashes, the mesh's floats and float
// arithmetic in a fixed order.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "common/codec/room_codec.hpp"
#include "common/core/vec3.hpp"
#include "common/mesh/deform.hpp"

namespace grotto::formations {

using namespace glm;

#define RELIEF_FN inline
#include "shaders/formation.glsl"
#undef RELIEF_FN

// A room's patch mesh as placement reads it (codec::DecodedRoom's or mesh::RoomMesh's arrays).
struct Surface {
  Vec3 origin;                                    // the room's grid origin, world metres
  std::span<const mesh::core::float3> positions;  // metres from origin
  std::span<const mesh::core::float3> normals;    // unit, into the cave
  std::span<const float> roughness;
  std::span<const int8_t> rim_portal;  // >= 0 on a portal rim
  std::span<const uint32_t> indices;   // triangles
  double room_radius = 0;              // the room's sphere
};

// A received room's patch mesh (decoded: what every client has) as placement reads it.
inline Surface surface_of(const codec::DecodedRoom& mesh, Vec3 origin, double room_radius) {
  Surface s;
  s.origin = origin;
  s.positions = mesh.positions;
  s.normals = mesh.normals;
  s.roughness = mesh.roughness;
  s.rim_portal = mesh.rim_portal;
  s.indices = mesh.indices;
  s.room_radius = room_radius;
  return s;
}

// A formation's calcite colour (formation_colour of its tint) as sRGB, 0-1 a channel: what a glTF
// tool or a colour picker shows.
inline vec3 formation_srgb(float tint) {
  const vec3 c = clamp(formation_colour(tint), vec3(0.0f), vec3(1.0f));
  vec3 out;
  for (int i = 0; i < 3; ++i)
    out[i] = c[i] <= 0.0031308f ? 12.92f * c[i] : 1.055f * std::pow(c[i], 1.0f / 2.4f) - 0.055f;
  return out;
}

// The formations of the room, roots in its frame (metres from Surface::origin), in a fixed order
// (the speleothems by drip line and drip, then height; then a hall's boulders, heap by heap,
// biggest first). Empty for an empty mesh.
std::vector<FormationShape> place(const Surface& surface);

// How far the drawn rock can lie from the patch surface along its normal (relief_normal_bound at
// full strength): the root's embedding covers it.
float root_embed();

// The meshes formation.vert draws an instance with, finest first: sides round the axis and rings
// along it (rings + 1 rows of sides + 1 points; 2 x sides x rings triangles).
inline constexpr int kLods = 4;
inline constexpr int kLodSides[kLods] = {16, 10, 6, 4};
inline constexpr int kLodRings[kLods] = {32, 16, 8, 4};
inline constexpr int lod_triangles(int lod) {
  return 2 * kLodSides[lod] * kLodRings[lod];
}

// The level of detail of an instance whose nearest point is `distance` metres from the eye, with
// `pixel_scale` pixels per metre at 1 m: by its radius on screen (formation_bound_radius) and its
// length over the rings its profile needs. -1: under a pixel wide and long, not drawn.
inline int lod_for(const FormationShape& f, float distance, float pixel_scale) {
  const float d = std::max(distance, 0.05f);
  const float bound = formation_bound_radius(f);
  if (std::max(bound, 0.5f * f.length) * pixel_scale / d < 0.6f) return -1;
  const float detail = std::max(bound, f.length / 6.0f) * pixel_scale / d;
  return detail > 12.0f ? 0 : detail > 4.0f ? 1 : detail > 1.5f ? 2 : 3;
}

// The instance as triangles in the room's frame, as formation.vert draws it at level of detail
// `lod` (the same rings, points and normals): appended to positions and normals (one each a
// vertex) and indices (counter-clockwise seen from outside, offset by the vertices already
// there). For exports (grotto-layout --glb) and engines that do not instance.
void append_mesh(const FormationShape& f, int lod, std::vector<vec3>& positions,
                 std::vector<vec3>& normals, std::vector<uint32_t>& indices);

// A closed convex hull of the instance for collision: `sides` around, `rings` rings along the
// visible part, as triangles (three vec3 each), in the instance's frame (root included). A
// boulder's is its finest mesh's corners (kLodSides[0] round, its side, chamfer and top: the
// faces it is drawn with), whatever `sides` and `rings` say.
std::vector<vec3> collision_hull(const FormationShape& f, int sides = 6, int rings = 4);

}  // namespace grotto::formations
