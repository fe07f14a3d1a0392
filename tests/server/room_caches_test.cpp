// The generator's two caches alone: encoded room frames in an LRU bounded in bytes
// (server/room_cache.hpp), and sector layouts shared by the open worlds (server/sector_cache.hpp).
#include <gtest/gtest.h>

#include <memory>
#include <utility>
#include <vector>

#include "server/room_cache.hpp"
#include "server/sector_cache.hpp"

namespace grotto::server {
namespace {

const cave::World& test_world() {
  static const cave::World world = cave::World::create(42, cave::LayoutParams{}).value();
  return world;
}

// Interior rooms that exist, sector by sector along +x, in order.
std::vector<cave::RoomId> existing_rooms(size_t n) {
  std::vector<cave::RoomId> out;
  for (int x = 0; out.size() < n; ++x) {
    cave::SectorLayout s = cave::generate_sector(test_world(), {x, 0, 0});
    for (const cave::Room& r : s.rooms) {
      if (out.size() < n) out.push_back(r.id);
    }
  }
  return out;
}

// ---- cache ----

TEST(RoomCacheTest, lru_bound_in_bytes) {
  auto room = [](int i, size_t bytes) {
    auto r = std::make_shared<EncodedRoom>();
    r->key = {cave::RoomId::interior({0, 0, 0}, i), 0};
    r->frame.assign(bytes, 0);
    return RoomPtr(r);
  };
  RoomCache cache(1000);
  cache.insert(room(0, 400));
  cache.insert(room(1, 400));
  EXPECT_TRUE(cache.find(room(0, 0)->key));  // 0 becomes the most recent
  cache.insert(room(2, 400));                // evicts 1
  EXPECT_EQ(cache.bytes(), 800u);
  EXPECT_FALSE(cache.find(room(1, 0)->key));
  EXPECT_TRUE(cache.find(room(0, 0)->key));
  cache.insert(room(3, 1001));  // larger than the bound: not kept, nothing evicted
  EXPECT_EQ(cache.entries(), 2u);
  cache.insert(room(2, 100));  // replaces
  EXPECT_EQ(cache.bytes(), 500u);
  RoomCache off(0);
  off.insert(room(0, 1));
  EXPECT_EQ(off.entries(), 0u);
}

// ---- layout side ----

TEST(SectorCacheTest, rooms_locate_and_spawn_match_the_layout_functions) {
  SectorCache cache(test_world(), 4);
  std::vector<cave::RoomId> ids = existing_rooms(40);
  cave::SectorLayout s0 = cave::generate_sector(test_world(), {0, 0, 0});
  for (const cave::Room& g : s0.gates)
    ids.push_back(g.id);
  ids.push_back(cave::RoomId::interior({0, 0, 0}, 4000));
  ids.push_back(cave::RoomId::gate({0, 0, 0}, 2, 15));
  for (cave::RoomId id : ids) {
    auto want = cave::room(test_world(), id);
    auto got = cache.room(id);
    ASSERT_EQ(want.ok(), got.ok()) << id.to_string();
    if (!want.ok()) {
      EXPECT_EQ(got.error().code, want.error().code);
      continue;
    }
    std::vector<unsigned char> a, b;
    cave::append_bytes(*want, a);
    cave::append_bytes(*got, b);
    EXPECT_EQ(a, b) << id.to_string();
  }
  EXPECT_LE(cache.size(), 4u);
  EXPECT_GT(cache.hits(), 0u);
  for (const cave::Room& r : s0.rooms) {
    EXPECT_EQ(cache.locate(r.sphere.centre), cave::locate(test_world(), r.sphere.centre));
  }
  cave::Spawn spawn = cache.spawn();
  EXPECT_EQ(spawn.room, cave::spawn_room(test_world()));
  EXPECT_EQ(cave::locate(test_world(), spawn.position), spawn.room);
}

// Two worlds in one store: the same sector coordinates of each world stay
// apart, each answer is its own world's, and one capacity bounds both together
// (least recently used goes first).
TEST(SectorCacheTest, worlds_sharing_a_store_keep_their_own_layouts_within_one_bound) {
  const cave::World other = cave::World::create(43, cave::LayoutParams{}).value();
  auto store = std::make_shared<SectorStore>(4);
  SectorCache a(test_world(), store);
  SectorCache b(other, store);
  for (int round = 0; round < 2; ++round) {
    for (int step = 0; step < 3; ++step) {
      int x = round == 0 ? step : 2 - step;  // back again: the last four are kept
      for (const auto& [cache, world] :
           {std::pair<SectorCache*, const cave::World*>{&a, &test_world()}, {&b, &other}}) {
        cave::SectorLayout want = cave::generate_sector(*world, {x, 0, 0});
        auto got = cache->sector({x, 0, 0});
        ASSERT_EQ(got->rooms.size(), want.rooms.size());
        std::vector<unsigned char> p, q;
        for (size_t i = 0; i < want.rooms.size(); ++i) {
          cave::append_bytes(want.rooms[i], p);
          cave::append_bytes(got->rooms[i], q);
        }
        EXPECT_EQ(p, q) << "world " << world->seed() << " sector " << x;
      }
    }
  }
  // Round 1: six misses, sectors 1 and 2 of both worlds kept. Round 2 (2, 1,
  // 0): four hits, then sector 0 of each world missed again.
  EXPECT_EQ(store->size(), 4u);
  EXPECT_EQ(store->hits(), 4u);
  EXPECT_EQ(store->misses(), 8u);
  EXPECT_NE(a.spawn().position, b.spawn().position);
}

}  // namespace
}  // namespace grotto::server
