// client/stream's room store: the memory a room is charged, replacement, and eviction by distance
// to the sphere's surface under a byte budget, sparing the rooms the plan wants.
#include <gtest/gtest.h>

#include <memory>

#include "client/stream/room_store.hpp"

namespace grotto::stream {
namespace {

cave::RoomId rid(int index) {
  return cave::RoomId::interior({}, index);
}

// A room at `centre` whose mesh holds `vertices` vertices and one triangle.
std::shared_ptr<const ReadyRoom> room(int index, Vec3 centre, double radius, size_t vertices = 10) {
  auto r = std::make_shared<ReadyRoom>();
  r->room.id = rid(index);
  r->room.sphere = {centre, radius};
  r->mesh.positions.resize(vertices);
  r->mesh.normals.resize(vertices);
  r->mesh.roughness.resize(vertices);
  r->mesh.mineral.resize(vertices);
  r->mesh.rim_portal.resize(vertices, -1);
  r->mesh.rim_index.resize(vertices);
  r->mesh.indices = {0, 1, 2};
  return r;
}

TEST(ReadyRoom, memory_bytes_counts_each_array_by_capacity_and_the_descriptor) {
  ReadyRoom r;
  const size_t empty = r.memory_bytes();
  EXPECT_GE(empty, sizeof(ReadyRoom));
  r.mesh.positions.reserve(100);
  r.mesh.normals.reserve(100);
  r.mesh.roughness.reserve(100);
  r.mesh.mineral.reserve(100);
  r.mesh.rim_portal.reserve(100);
  r.mesh.rim_index.reserve(100);
  r.mesh.indices.reserve(300);
  r.room.portals.reserve(4);
  // Reserved but unused capacity counts: it is what the allocator holds.
  const size_t f3 = sizeof(mesh::core::float3);
  const size_t expected = r.mesh.positions.capacity() * f3 + r.mesh.normals.capacity() * f3 +
                          r.mesh.roughness.capacity() * 4 + r.mesh.mineral.capacity() * 4 +
                          r.mesh.rim_portal.capacity() * 1 + r.mesh.rim_index.capacity() * 2 +
                          r.mesh.indices.capacity() * 4 +
                          r.room.portals.capacity() * sizeof(cave::Portal);
  EXPECT_EQ(r.memory_bytes(), empty + expected);
  EXPECT_GE(expected, 100u * (2 * f3 + 4 + 4 + 1 + 2) + 300u * 4);
}

TEST(RoomStore, insert_find_erase_and_clear_keep_the_byte_count) {
  RoomStore store(1 << 20);
  auto a = room(1, {0, 0, 0}, 3, 10), b = room(2, {10, 0, 0}, 3, 50);
  store.insert(a);
  store.insert(b);
  EXPECT_EQ(store.size(), 2u);
  EXPECT_EQ(store.bytes(), a->memory_bytes() + b->memory_bytes());
  EXPECT_EQ(store.find(rid(1)), a);
  EXPECT_TRUE(store.contains(rid(2)));
  EXPECT_EQ(store.find(rid(3)), nullptr);
  EXPECT_EQ(store.ids(), (std::vector<cave::RoomId>{rid(1), rid(2)}));
  store.erase(rid(1));
  EXPECT_FALSE(store.contains(rid(1)));
  EXPECT_EQ(store.bytes(), b->memory_bytes());
  store.erase(rid(1));  // absent: nothing happens
  EXPECT_EQ(store.bytes(), b->memory_bytes());
  store.clear();
  EXPECT_EQ(store.size(), 0u);
  EXPECT_EQ(store.bytes(), 0u);
}

TEST(RoomStore, insert_replaces_the_room_with_the_same_id) {
  RoomStore store(1 << 20);
  auto small = room(1, {0, 0, 0}, 3, 10), big = room(1, {0, 0, 0}, 3, 1000);
  store.insert(small);
  store.insert(big);
  EXPECT_EQ(store.size(), 1u);
  EXPECT_EQ(store.find(rid(1)), big);
  EXPECT_EQ(store.bytes(), big->memory_bytes());
}

TEST(RoomStore, evict_removes_the_farthest_rooms_first_until_within_budget) {
  const size_t each = room(0, {}, 1)->memory_bytes();
  RoomStore store(2 * each);  // room for two
  for (int i = 1; i <= 4; ++i)
    store.insert(room(i, {10.0 * i, 0, 0}, 1));
  auto evicted = store.evict({0, 0, 0}, {});
  EXPECT_EQ(evicted, (std::vector<cave::RoomId>{rid(4), rid(3)}));
  EXPECT_EQ(store.ids(), (std::vector<cave::RoomId>{rid(1), rid(2)}));
  EXPECT_EQ(store.bytes(), 2 * each);
  EXPECT_TRUE(store.evict({0, 0, 0}, {}).empty());  // within budget: nothing
  // From the other end, the near rooms are the far ones.
  store.insert(room(4, {40, 0, 0}, 1));
  EXPECT_EQ(store.evict({45, 0, 0}, {}), (std::vector<cave::RoomId>{rid(1)}));
}

TEST(RoomStore, evict_measures_to_the_sphere_surface_not_the_centre) {
  const size_t each = room(0, {}, 1)->memory_bytes();
  RoomStore store(each);
  store.insert(room(1, {30, 0, 0}, 1));   // surface 29 m away
  store.insert(room(2, {35, 0, 0}, 10));  // centre farther, surface 25 m away
  EXPECT_EQ(store.evict({0, 0, 0}, {}), (std::vector<cave::RoomId>{rid(1)}));
  EXPECT_TRUE(store.contains(rid(2)));
}

TEST(RoomStore, evict_breaks_distance_ties_by_id) {
  const size_t each = room(0, {}, 1)->memory_bytes();
  RoomStore store(each);
  store.insert(room(7, {0, 20, 0}, 2));
  store.insert(room(3, {20, 0, 0}, 2));
  store.insert(room(5, {0, 0, -20}, 2));
  EXPECT_EQ(store.evict({0, 0, 0}, {}), (std::vector<cave::RoomId>{rid(3), rid(5)}));
  EXPECT_EQ(store.ids(), (std::vector<cave::RoomId>{rid(7)}));
}

TEST(RoomStore, evict_never_removes_kept_rooms_even_over_budget) {
  const size_t each = room(0, {}, 1)->memory_bytes();
  RoomStore store(each);
  for (int i = 1; i <= 4; ++i)
    store.insert(room(i, {10.0 * i, 0, 0}, 1));
  auto evicted = store.evict({0, 0, 0}, {rid(4), rid(2)});
  EXPECT_EQ(evicted, (std::vector<cave::RoomId>{rid(3), rid(1)}));
  EXPECT_EQ(store.ids(), (std::vector<cave::RoomId>{rid(2), rid(4)}));
  EXPECT_EQ(store.bytes(), 2 * each);  // over budget: the plan wants both
  EXPECT_TRUE(store.evict({0, 0, 0}, {rid(4), rid(2)}).empty());
}

TEST(RoomStore, an_evicted_room_stays_usable_by_whoever_holds_it) {
  RoomStore store(0);
  store.insert(room(1, {0, 0, 0}, 1, 100));
  std::shared_ptr<const ReadyRoom> held = store.find(rid(1));
  EXPECT_EQ(store.evict({0, 0, 0}, {}), (std::vector<cave::RoomId>{rid(1)}));
  EXPECT_EQ(store.size(), 0u);
  EXPECT_EQ(store.bytes(), 0u);
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(held->mesh.vertex_count(), 100u);
}

}  // namespace
}  // namespace grotto::stream
