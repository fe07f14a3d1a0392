#include "tests/client/play/cave.hpp"

#include <gtest/gtest.h>

#include "client/play/flythrough.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"
#include "tests/client/ready_room.hpp"

namespace grotto::play::test {
namespace {

constexpr auto ready = stream::test::ready_room;

Cave build() {
  Cave c;
  const cave::World world = cave::World::create(7, cave::LayoutParams{}).value();
  const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  const cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  for (const cave::Room& r : region.rooms) {
    auto m = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
    EXPECT_TRUE(m.ok()) << r.id.to_string();
    if (m.ok()) c.rooms.emplace(r.id, ready(m.value(), r));
  }
  // Where the server spawns a player (cave::spawn).
  const cave::Room& spawn = *region.find(cave::spawn_room(world));
  c.spawn_room = spawn.id;
  c.spawn = cave::interior_point(spawn);
  c.spawn_radius = spawn.sphere.radius;
  return c;
}

}  // namespace

const Cave& sector_zero() {
  static const Cave cave = build();
  return cave;
}

}  // namespace grotto::play::test
