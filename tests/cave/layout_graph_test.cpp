// The portal graph: connected across sectors, with loops, and shaped by the thesis's parameters.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <map>

#include "common/cave/layout.hpp"

namespace grotto::cave {
namespace {

// Breadth-first distances over portals, staying inside `rooms`.
std::map<RoomId, int> bfs(const std::vector<Room>& rooms, RoomId start) {
  std::map<RoomId, const Room*> by_id;
  for (const Room& r : rooms)
    by_id[r.id] = &r;
  std::map<RoomId, int> dist{{start, 0}};
  std::deque<RoomId> queue{start};
  while (!queue.empty()) {
    RoomId id = queue.front();
    queue.pop_front();
    for (const Portal& p : by_id.at(id)->portals) {
      if (!by_id.count(p.neighbour) || dist.count(p.neighbour)) continue;
      dist[p.neighbour] = dist[id] + 1;
      queue.push_back(p.neighbour);
    }
  }
  return dist;
}

TEST(LayoutGraph, every_room_of_a_4x4x4_block_is_reachable_from_the_spawn) {
  World world = World::create(5, LayoutParams{}).value();
  Region region = generate_region(world, {0, 0, 0}, {3, 3, 3});
  RoomId spawn = spawn_room(world);
  ASSERT_NE(region.find(spawn), nullptr);
  std::map<RoomId, int> reached = bfs(region.rooms, spawn);
  EXPECT_EQ(reached.size(), region.rooms.size());
  for (const Room& r : region.rooms) {
    if (!reached.count(r.id)) ADD_FAILURE() << r.id.to_string() << " is unreachable";
  }
  // Cycle rank E - V + 1 of the connected graph: independent loops, so the cave is a graph and
  // not a tree (thesis §3.1.1).
  size_t edges = 0;
  for (const Room& r : region.rooms) {
    for (const Portal& p : r.portals)
      edges += region.find(p.neighbour) && r.id < p.neighbour;
  }
  long cycle_rank = static_cast<long>(edges) - static_cast<long>(region.rooms.size()) + 1;
  RecordProperty("rooms", static_cast<int>(region.rooms.size()));
  RecordProperty("cycle_rank", static_cast<int>(cycle_rank));
  EXPECT_GT(cycle_rank, 0);
  EXPECT_GT(region.rooms.size(), 64u * 40u);
}

TEST(LayoutGraph, every_sector_links_its_gates_for_many_seeds) {
  int sectors = 0, retried = 0;
  for (uint64_t seed : {1ull, 77ull, 0xdeadbeefull}) {
    World world = World::create(seed, LayoutParams{}).value();
    for (int i = 0; i < 60; ++i) {
      SectorCoord s{i % 5 - 2, (i / 5) % 4 - 2, i / 20 - 1};
      SectorLayout layout = generate_sector(world, s);
      EXPECT_TRUE(layout.connected) << "seed " << seed << " sector " << to_string(s);
      EXPECT_GE(layout.gates.size(), 6u);
      retried += layout.attempts > 1;
      ++sectors;
    }
  }
  RecordProperty("sectors_retried", retried);
  EXPECT_LT(retried, sectors / 4) << "linking should rarely need a second attempt";
}

// Big halls leave chains little room (their portals open only between floor and spring): with
// eight attempts at full size 5 sectors of 3,045 of seed 7 linked none, 37.0.1 among them, found
// by the cluster test. The later attempts shrink the hall, the last two drop it; a scan of 6,045
// sectors of each of seeds 1, 3, 7, 42 and 95 then found every sector linked. These are seed
// 7's five and 1,000 sectors of a random draw.
TEST(LayoutGraph, sectors_with_big_halls_link_their_gates) {
  World world = World::create(7, LayoutParams{}).value();
  std::vector<SectorCoord> sectors = {
      {37, 0, 1}, {324, -134, 492}, {-504, -970, 777}, {-57, -55, -200}, {895, -874, -77}};
  uint64_t x = 1;
  for (int i = 0; i < 1000; ++i) {
    x = x * 6364136223846793005ull + 1442695040888963407ull;
    sectors.push_back({static_cast<int>((x >> 20) % 2001) - 1000,
                       static_cast<int>((x >> 32) % 2001) - 1000,
                       static_cast<int>((x >> 44) % 2001) - 1000});
  }
  int halls_dropped = 0;
  for (SectorCoord s : sectors) {
    SectorLayout layout = generate_sector(world, s);
    EXPECT_TRUE(layout.connected) << to_string(s) << " after " << layout.attempts << " attempts";
    halls_dropped += layout.attempts > 8;
  }
  EXPECT_LT(halls_dropped, 5) << "a hall should rarely give way to a plain hub";
}

TEST(LayoutGraph, the_extremes_validate_accepts_still_connect) {
  LayoutParams p;
  p.sector_size = kMaxSectorSize;
  p.portal_gap = 0.6 * p.link_radius_max;
  p.min_portal_radius = 0.45 * std::min(p.link_radius_min, p.gate_radius_min);
  p.gates_max = 4;
  ASSERT_TRUE(validate(p).ok()) << validate(p).error().message;
  World world = World::create(6, p).value();
  for (int i = 0; i < 4; ++i) {
    SectorLayout layout = generate_sector(world, {i, -i, 1});
    EXPECT_TRUE(layout.connected) << "sector " << i << " after " << layout.attempts << " attempts";
  }
}

// The longest shortest path among a sector's interior rooms, from every room.
int interior_diameter(const SectorLayout& layout) {
  int diameter = 0;
  for (const Room& r : layout.rooms) {
    for (auto& [id, d] : bfs(layout.rooms, r.id))
      diameter = std::max(diameter, d);
  }
  return diameter;
}

LayoutParams one_character(double tunnel_chance, Vec3 bias) {
  Character c = LayoutParams::default_characters()[0];
  c.room_count = 250;
  c.tunnel_chance = tunnel_chance;
  c.bias = bias;
  c.hall_probability = 0.0;  // the growth alone: a hall hub would dominate a sector's extent
  return LayoutParams::uniform(c);
}

TEST(LayoutGraph, a_tiny_bias_grows_like_its_normalized_self) {
  auto rooms = [](double scale) {
    LayoutParams p = one_character(0.5, Vec3{1, 1, 1} * scale);
    return generate_sector(World::create(3, p).value(), {}).rooms.size();
  };
  size_t unit = rooms(1.0), tiny = rooms(1e-7);
  EXPECT_GT(tiny, unit * 9 / 10);
  EXPECT_LT(tiny, unit * 11 / 10);
}

TEST(LayoutGraph, tunnel_chance_makes_longer_passages) {
  int long_total = 0, bushy_total = 0;
  for (uint64_t seed : {3ull, 4ull, 5ull}) {
    World tunnels = World::create(seed, one_character(0.99, {1, 1, 1})).value();
    World bushes = World::create(seed, one_character(0.0, {1, 1, 1})).value();
    long_total += interior_diameter(generate_sector(tunnels, {0, 0, 0}));
    bushy_total += interior_diameter(generate_sector(bushes, {0, 0, 0}));
  }
  RecordProperty("diameter_tunnel_0_99", long_total);
  RecordProperty("diameter_tunnel_0", bushy_total);
  EXPECT_GT(long_total, bushy_total * 5 / 4);
}

// Standard deviation of the grown rooms' centres along one axis.
double spread(const SectorLayout& layout, int axis) {
  double mean = 0, sq = 0, n = 0;
  for (size_t i = layout.link_rooms; i < layout.rooms.size(); ++i, ++n) {
    mean += layout.rooms[i].sphere.centre[axis];
  }
  mean /= n;
  for (size_t i = layout.link_rooms; i < layout.rooms.size(); ++i) {
    sq += std::pow(layout.rooms[i].sphere.centre[axis] - mean, 2);
  }
  return std::sqrt(sq / n);
}

TEST(LayoutGraph, displacement_bias_sets_the_direction_of_growth) {
  double vertical_y = 0, vertical_x = 0, flat_y = 0, flat_x = 0;
  for (uint64_t seed : {3ull, 4ull, 5ull}) {
    LayoutParams up = one_character(0.9, {0.1, 1, 0.1}), across = one_character(0.9, {1, 0.1, 0.1});
    up.characters[0].room_count = across.characters[0].room_count = 40;
    up.characters = {up.characters[0], up.characters[0], up.characters[0]};
    across.characters = {across.characters[0], across.characters[0], across.characters[0]};
    SectorLayout vertical = generate_sector(World::create(seed, up).value(), {});
    SectorLayout along_x = generate_sector(World::create(seed, across).value(), {});
    vertical_y += spread(vertical, 1);
    vertical_x += spread(vertical, 0);
    flat_y += spread(along_x, 1);
    flat_x += spread(along_x, 0);
  }
  RecordProperty("spread_y_with_y_bias", static_cast<int>(vertical_y));
  RecordProperty("spread_y_with_x_bias", static_cast<int>(flat_y));
  EXPECT_GT(vertical_y, flat_y * 1.2) << "bias along y gives a larger vertical extent";
  EXPECT_GT(flat_x, vertical_x * 1.2) << "bias along x gives a larger extent in x";
}

// Independent loops among the interior rooms of a sector and its gates: E - V + components.
int sector_cycle_rank(const SectorLayout& layout) {
  std::vector<Room> rooms = layout.rooms;
  rooms.insert(rooms.end(), layout.gates.begin(), layout.gates.end());
  int edges = 0;
  for (const Room& r : rooms) {
    for (const Portal& p : r.portals)
      edges += r.id < p.neighbour;
  }
  return edges - static_cast<int>(rooms.size()) + 1;
}

TEST(LayoutGraph, loops_add_alternative_routes) {
  auto total_rank = [](int loops) {
    LayoutParams p;
    for (Character& c : p.characters)
      c.loops = loops;
    World world = World::create(12, p).value();
    int rank = 0;
    for (int i = 0; i < 8; ++i)
      rank += sector_cycle_rank(generate_sector(world, {i, 0, 0}));
    return rank;
  };
  int without = total_rank(0), with = total_rank(10);
  RecordProperty("cycle_rank_loops_0", without);
  RecordProperty("cycle_rank_loops_10", with);
  EXPECT_GT(with, without + 8 * 5);
}

TEST(LayoutGraph, big_probability_makes_bigger_rooms) {
  auto mean_radius = [](double p) {
    Character c = LayoutParams::default_characters()[2];
    c.big_probability = p;
    c.room_count = 120;
    SectorLayout s = generate_sector(World::create(8, LayoutParams::uniform(c)).value(), {});
    double sum = 0;
    for (size_t i = s.link_rooms; i < s.rooms.size(); ++i)
      sum += s.rooms[i].sphere.radius;
    return sum / static_cast<double>(s.rooms.size() - s.link_rooms);
  };
  EXPECT_GT(mean_radius(0.9), mean_radius(0.05) * 1.3);
}

}  // namespace
}  // namespace grotto::cave
