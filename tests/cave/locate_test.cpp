#include <gtest/gtest.h>

#include <limits>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "common/cave/layout.hpp"

namespace grotto::cave {
namespace {

World test_world() {
  return World::create(31, LayoutParams{}).value();
}

TEST(Locate, a_room_centre_locates_to_its_room) {
  World world = test_world();
  Region region = generate_region(world, {-1, 0, 0}, {0, 1, 0});
  for (size_t i = 0; i < region.rooms.size(); i += 7) {
    const Room& r = region.rooms[i];
    auto found = locate(world, r.sphere.centre);
    ASSERT_TRUE(found.has_value()) << r.id.to_string();
    EXPECT_EQ(*found, r.id);
  }
}

TEST(Locate, points_beside_a_portal_belong_to_the_rooms_it_joins) {
  World world = test_world();
  Region region = generate_region(world, {0, 0, 0}, {0, 0, 0});
  int checked = 0;
  for (const Room& r : region.rooms) {
    for (const Portal& p : r.portals) {
      EXPECT_EQ(locate(world, p.centre - p.normal * 0.01), r.id) << r.id.to_string();
      EXPECT_EQ(locate(world, p.centre + p.normal * 0.01), p.neighbour) << r.id.to_string();
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(Locate, points_outside_every_room_find_nothing) {
  World world = test_world();
  double s = world.params().sector_size;
  // Sector corners: rooms keep off the faces and gates keep off the edges.
  EXPECT_FALSE(locate(world, {0, 0, 0}).has_value());
  EXPECT_FALSE(locate(world, {s, -s, 2 * s}).has_value());
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(locate(world, {std::numeric_limits<double>::quiet_NaN(), 0, 0}).has_value());
  EXPECT_FALSE(locate(world, {inf, 0, 0}).has_value());
  EXPECT_FALSE(locate(world, {1e15, 0, 0}).has_value()) << "beyond the sector range";
  EXPECT_FALSE(in_range(sector_of(world, {std::numeric_limits<double>::quiet_NaN(), 0, 0})));
  EXPECT_FALSE(in_range(sector_of(world, {-1e300, 0, 0})));
}

TEST(Locate, spawn_is_deterministic_and_inside_its_room) {
  World world = test_world();
  RoomId spawn = spawn_room(world);
  EXPECT_EQ(spawn_room(test_world()), spawn);
  EXPECT_EQ(spawn.sector(), (SectorCoord{0, 0, 0}));
  EXPECT_FALSE(spawn.is_gate());
  auto r = room(world, spawn);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(locate(world, r->sphere.centre), spawn);
}

TEST(RoomAt, over_a_region_answers_as_locate_does) {
  World world = test_world();
  Region region = generate_region(world, {0, 0, 0}, {1, 0, 0});
  int checked = 0;
  for (const Room& r : region.rooms) {
    if (r.id.sector() != SectorCoord{0, 0, 0}) continue;
    std::vector<Vec3> points{r.sphere.centre};
    for (const Portal& p : r.portals) {
      if (!region.find(p.neighbour)) continue;  // beyond the block: locate sees a room we lack
      points.push_back(p.centre - p.normal * 0.01);
      points.push_back(p.centre + p.normal * 0.01);
      points.push_back(p.centre);  // on the plane: the smaller id's
    }
    for (Vec3 point : points) {
      const Room* found = room_at(region.rooms, point);
      std::optional<RoomId> want = locate(world, point);
      ASSERT_EQ(found != nullptr, want.has_value()) << r.id.to_string();
      if (found) {
        EXPECT_EQ(found->id, *want) << r.id.to_string();
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(RoomAt, a_room_without_its_neighbour_gives_up_the_cap_beyond_the_portal) {
  Region region = generate_region(test_world(), {0, 0, 0}, {0, 0, 0});
  const Room& r = region.rooms.front();
  ASSERT_FALSE(r.portals.empty());
  const Portal& p = r.portals.front();
  std::vector<Room> alone{r};
  EXPECT_EQ(room_at(alone, p.centre - p.normal * 0.01), &alone[0]);
  // Inside r's sphere but beyond its portal: the neighbour's space, and the neighbour is absent.
  EXPECT_EQ(room_at(alone, p.centre + p.normal * 0.01), nullptr);
  // A projection reads rooms held in other records.
  std::map<RoomId, std::pair<int, Room>> held{{r.id, {7, r}}};
  const Room* found =
      room_at(held, r.sphere.centre, [](const auto& e) -> const Room& { return e.second.second; });
  ASSERT_NE(found, nullptr);
  EXPECT_EQ(found->id, r.id);
}

TEST(RoomAt, overlapping_spaces_go_to_the_smallest_id) {
  // Two rooms with no portals between them overlap everywhere in their lens: the smaller id wins
  // whatever order the rooms come in.
  Room a{RoomId::interior({0, 0, 0}, 3), Sphere{{0, 0, 0}, 4}, {}};
  Room b{RoomId::interior({0, 0, 0}, 1), Sphere{{3, 0, 0}, 4}, {}};
  std::vector<Room> rooms{a, b};
  ASSERT_NE(room_at(rooms, {1.5, 0, 0}), nullptr);
  EXPECT_EQ(room_at(rooms, {1.5, 0, 0})->id, b.id);
  EXPECT_EQ(room_at(rooms, {-3, 0, 0})->id, a.id);
  EXPECT_EQ(room_at(rooms, {20, 0, 0}), nullptr);
  std::vector<Room> none;
  EXPECT_EQ(room_at(none, {0, 0, 0}), nullptr);
}

// A cache hands the cave its layouts through a SectorSource: the answers are the World forms'.
TEST(SectorSourceTest, room_locate_and_spawn_through_a_source_match_the_world_forms) {
  World world = test_world();
  std::map<SectorCoord, std::shared_ptr<const SectorLayout>> kept;
  int calls = 0;
  SectorSource source = [&](SectorCoord s) {
    ++calls;
    auto& layout = kept[s];
    if (!layout) layout = std::make_shared<const SectorLayout>(generate_sector(world, s));
    return layout;
  };
  Region region = generate_region(world, {0, 0, 0}, {0, 0, 0});
  std::vector<RoomId> ids;
  for (const Room& r : region.rooms)
    ids.push_back(r.id);
  ids.push_back(RoomId::interior({0, 0, 0}, kMaxInteriorRooms - 1));
  ids.push_back(RoomId::gate({0, 0, 0}, 2, kMaxGatesPerFace - 1));
  ids.push_back(RoomId::gate({kSectorCoordLimit, 0, 0}, 0, 0));
  for (RoomId id : ids) {
    auto want = room(world, id);
    auto got = room(world, id, source);
    ASSERT_EQ(want.ok(), got.ok()) << id.to_string();
    if (!want.ok()) {
      EXPECT_EQ(got.error().code, want.error().code);
      EXPECT_EQ(got.error().message, want.error().message);
      continue;
    }
    std::vector<unsigned char> a, b;
    append_bytes(*want, a);
    append_bytes(*got, b);
    EXPECT_EQ(a, b) << id.to_string();
    EXPECT_EQ(locate(world, got->sphere.centre, source), locate(world, got->sphere.centre));
  }
  EXPECT_GT(calls, static_cast<int>(region.rooms.size()));
  Spawn s = spawn(world, source);
  EXPECT_EQ(s.room, spawn_room(world));
  EXPECT_EQ(s.position, interior_point(room(world, s.room).value()));
  EXPECT_EQ(locate(world, s.position), s.room);
}

TEST(Room, ids_that_name_no_room_are_not_found) {
  World world = test_world();
  auto missing = room(world, RoomId::interior({2, 2, 2}, kMaxInteriorRooms - 1));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("2.2.2.r4095"), std::string::npos)
      << missing.error().message;
  auto gate = room(world, RoomId::gate({0, 0, 0}, 1, kMaxGatesPerFace - 1));
  ASSERT_FALSE(gate.ok());
  EXPECT_EQ(gate.error().code, ErrorCode::kNotFound);
  // The face beyond the last sector has no gates: the world ends there.
  auto edge = room(world, RoomId::gate({kSectorCoordLimit, 0, 0}, 0, 0));
  EXPECT_FALSE(edge.ok());
}

TEST(Room, gates_join_rooms_of_both_sectors) {
  World world = test_world();
  auto gate = room(world, RoomId::gate({0, 0, 0}, 0, 0));
  ASSERT_TRUE(gate.ok()) << gate.error().message;
  bool lower = false, upper = false;
  for (const Portal& p : gate->portals) {
    lower |= p.neighbour.sector() == SectorCoord{0, 0, 0};
    upper |= p.neighbour.sector() == SectorCoord{1, 0, 0};
  }
  EXPECT_TRUE(lower && upper) << "a gate is reachable from both of its sectors";
}

}  // namespace
}  // namespace grotto::cave
