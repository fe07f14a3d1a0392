// client/stream's area check (area.hpp): "are all rooms within R metres of p, along the portal
// graph, held at lod <= L?", on a hand-made corridor whose distances are worked out by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include "client/stream/area.hpp"
#include "common/cave/layout.hpp"

namespace grotto::stream {
namespace {

using cave::Room;
using cave::RoomId;

RoomId rid(int index) {
  return RoomId::interior({}, index);
}

// A corridor along +x: r0 (centre 0, radius 4) - r1 - r2 - r3, portal centres at x = 2, 6 and
// 11, so from the origin r1 is 2 m away, r2 6 m and r3 11 m.
std::map<int, Room> corridor() {
  std::map<int, Room> rooms;
  const double centres[] = {0, 4, 8, 14};
  const double radii[] = {4, 3, 3, 4};
  for (int i = 0; i < 4; ++i) {
    rooms[i].id = rid(i);
    rooms[i].sphere = {{centres[i], 0, 0}, radii[i]};
  }
  const double portals[] = {2, 6, 11};
  for (int i = 0; i < 3; ++i) {
    // The two sides' normals are negations bit for bit (-0.0 included), as the layout makes them.
    const Vec3 n{1, 0, 0};
    rooms[i].portals.push_back({{portals[i], 0, 0}, n, 1.0, rid(i + 1)});
    rooms[i + 1].portals.push_back({{portals[i], 0, 0}, -n, 1.0, rid(i)});
    std::sort(
        rooms[i + 1].portals.begin(), rooms[i + 1].portals.end(),
        [](const cave::Portal& a, const cave::Portal& b) { return a.neighbour < b.neighbour; });
  }
  return rooms;
}

// The client's view: descriptors of `known`, and `held` rooms stored at `lod`.
struct Client {
  PortalGraph graph;
  RoomStore store{size_t{1} << 30};

  Client(std::initializer_list<int> known, std::initializer_list<int> held, uint8_t lod = 0) {
    auto rooms = corridor();
    for (int i : known)
      EXPECT_TRUE(graph.add(rooms.at(i)).ok()) << i;
    for (int i : held)
      hold(i, lod);
  }
  void hold(int i, uint8_t lod = 0) {
    auto r = std::make_shared<ReadyRoom>();
    r->room = corridor().at(i);
    r->lod = lod;
    store.insert(r);
  }
  AreaStatus area(double radius_m, uint32_t max_lod = 0, Vec3 p = {}) const {
    return area_status(graph, store, p, radius_m, max_lod);
  }
};

TEST(AreaStatus, a_room_within_the_radius_not_yet_held_is_not_ready) {
  Client c({0, 1, 2}, {0, 1});
  AreaStatus a = c.area(7.0);  // r0, r1 (2 m), r2 (6 m); r3 is 11 m away
  EXPECT_TRUE(a.located);
  EXPECT_FALSE(a.ready);
  EXPECT_EQ(a.rooms, 3u);
  EXPECT_EQ(a.missing, 1u);
  EXPECT_EQ(a.first_missing, rid(2));
  c.hold(2);
  a = c.area(7.0);
  EXPECT_TRUE(a.ready);
  EXPECT_EQ(a.missing, 0u);
  EXPECT_FALSE(a.first_missing.has_value());
}

TEST(AreaStatus, a_room_known_only_as_a_neighbours_portal_is_missing) {
  // r1's frame has not come: only r0's portal names it, and what lies behind it is unknown.
  Client c({0}, {0});
  AreaStatus a = c.area(3.0);
  EXPECT_FALSE(a.ready);
  EXPECT_EQ(a.rooms, 2u);
  EXPECT_EQ(a.first_missing, rid(1));
  EXPECT_TRUE(c.area(1.9).ready) << "r1's portal is 2 m away";
}

TEST(AreaStatus, distance_runs_along_the_portal_graph) {
  // r3's sphere reaches within 10 m of the origin in a straight line, but the path through the
  // portals is 11 m: at 10.5 m it is outside the area, at 11 m inside.
  Client c({0, 1, 2, 3}, {0, 1, 2});
  EXPECT_TRUE(c.area(10.5).ready);
  EXPECT_EQ(c.area(10.5).rooms, 3u);
  EXPECT_FALSE(c.area(11.0).ready);
  EXPECT_EQ(c.area(11.0).first_missing, rid(3));
  c.hold(3);
  EXPECT_TRUE(c.area(11.0).ready);
}

TEST(AreaStatus, a_room_held_above_max_lod_is_missing) {
  Client c({0, 1}, {0});
  c.hold(1, 1);
  EXPECT_FALSE(c.area(3.0, 0).ready);
  EXPECT_EQ(c.area(3.0, 0).first_missing, rid(1));
  Client d({0, 1}, {0, 1}, 1);
  EXPECT_TRUE(d.area(3.0, 1).ready);
  EXPECT_FALSE(d.area(3.0, 0).ready);
}

TEST(AreaStatus, a_point_no_known_room_holds_is_not_ready) {
  Client c({0, 1}, {0, 1});
  AreaStatus a = c.area(1.0, 0, {100, 0, 0});
  EXPECT_FALSE(a.located);
  EXPECT_FALSE(a.ready);
  EXPECT_EQ(a.rooms, 0u);
  EXPECT_FALSE(Client({}, {}).area(1.0).ready);
}

TEST(AreaStatus, a_negative_or_nan_radius_is_the_room_holding_the_point_alone) {
  Client c({0, 1}, {0});
  EXPECT_TRUE(c.area(-1.0).ready);
  EXPECT_EQ(c.area(-1.0).rooms, 1u);
  EXPECT_TRUE(c.area(std::nan("")).ready);
  EXPECT_EQ(c.area(std::nan("")).rooms, 1u);
  EXPECT_FALSE(Client({0, 1}, {1}).area(-1.0).ready) << "the room holding the point is not held";
}

}  // namespace
}  // namespace grotto::stream
