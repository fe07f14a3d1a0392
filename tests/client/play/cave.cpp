#include "cave.hpp"

#include <gtest/gtest.h>

#include "../ready_room.hpp"
#include "client/play/flythrough.hpp"
#include "codec/room_codec.hpp"
#include "mesh/room_mesh.hpp"

namespace grotto::play::test {
namespace {

constexpr auto ready = client::test::ready_room;

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
  // The interior room nearest the sector's centre, its interior point.
  const double half = 0.5 * world.params().sector_size;
  const Vec3 centre{half, half, half};
  const cave::Room* best = nullptr;
  for (const cave::Room& r : region.sectors.front().rooms)
    if (!best ||
        length_squared(r.sphere.centre - centre) < length_squared(best->sphere.centre - centre))
      best = &r;
  c.spawn_room = best->id;
  c.spawn = cave::interior_point(*best);
  return c;
}

}  // namespace

const Cave& sector_zero() {
  static const Cave cave = build();
  return cave;
}

}  // namespace grotto::play::test
