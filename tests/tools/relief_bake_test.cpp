// grotto-layout --bake-relief (common/relief/relief_bake.hpp): the client's relief moved into a
// mesh, for engines that do not tessellate. Seed 7's hall in sector 0,0,0 at the detail level.
#include "common/relief/relief_bake.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace grotto::relief {
namespace {

struct Hall {
  cave::World world = cave::World::create(7, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  cave::Room room = cave::room(world, cave::RoomId::parse("0.0.0.r0").value()).value();
  mesh::RoomMesh plain = mesh::build_room_mesh(ctx, room, mesh::Lod::kDetail).value();
};

const Hall& hall() {
  static const Hall h;
  return h;
}

TEST(ReliefBake, moves_the_rock_and_keeps_the_rims_bit_for_bit) {
  const Hall& h = hall();
  ASSERT_GE(h.room.sphere.radius, 12.0) << "the hall of seed 7's first sector";
  mesh::RoomMesh baked = h.plain;
  const BakeStats stats = bake_relief(baked);
  ASSERT_EQ(baked.vertex_count(), h.plain.vertex_count());
  const double bound = relief_bound(1.0f) + 1e-4;
  size_t rims = 0, moved = 0;
  for (size_t v = 0; v < baked.vertex_count(); ++v) {
    const Vec3 before = h.plain.world_position(v), after = baked.world_position(v);
    if (baked.rim_portal[v] >= 0) {
      ++rims;
      EXPECT_EQ(baked.positions[v].x, h.plain.positions[v].x);
      EXPECT_EQ(baked.positions[v].y, h.plain.positions[v].y);
      EXPECT_EQ(baked.positions[v].z, h.plain.positions[v].z);
      continue;
    }
    const Vec3 d = after - before;
    EXPECT_LE(length(d), bound) << v;
    moved += length(d) > 1e-4;
    const auto& n = baked.normals[v];
    EXPECT_NEAR(std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z), 1.0, 1e-3) << v;
  }
  EXPECT_GT(rims, 0u);
  EXPECT_EQ(stats.moved, baked.vertex_count() - rims);
  EXPECT_GT(moved, stats.moved * 9 / 10) << "the relief moves nearly every vertex off a rim";
  // Speleothems are in the bake where a vertex lands on one (the mesh's ~0.3 m spacing samples
  // them; the thinnest need the GPU's tessellation or relief.hpp itself).
}

TEST(ReliefBake, the_same_mesh_bakes_to_the_same_bits) {
  const Hall& h = hall();
  mesh::RoomMesh a = h.plain, b = h.plain;
  bake_relief(a);
  bake_relief(b);
  for (size_t v = 0; v < a.vertex_count(); ++v) {
    ASSERT_EQ(a.positions[v].x, b.positions[v].x);
    ASSERT_EQ(a.positions[v].y, b.positions[v].y);
    ASSERT_EQ(a.positions[v].z, b.positions[v].z);
  }
}

}  // namespace
}  // namespace grotto::relief
