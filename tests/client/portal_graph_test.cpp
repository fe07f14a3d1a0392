// client/stream's portal graph: consistency checks on add against real sectors (the layout's two
// sides of a portal are bit-identical with exactly negated normals), room_at, and the prefetch
// plan's costs, worked out by hand on small graphs and on a real sector.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>

#include "client/stream/portal_graph.hpp"
#include "common/cave/layout.hpp"

namespace grotto::stream {
namespace {

using cave::Room;
using cave::RoomId;

RoomId rid(int index) {
  return RoomId::interior({}, index);
}

uint64_t bits(double v) {
  return std::bit_cast<uint64_t>(v);
}

// Hand-made rooms whose portals agree on both sides.
class Rooms {
 public:
  void room(int index, Vec3 centre, double radius) {
    Room& r = rooms_[rid(index)];
    r.id = rid(index);
    r.sphere = {centre, radius};
  }
  // A portal between a and b at `centre`, its normal pointing from a's centre to b's.
  void link(int a, int b, Vec3 centre, double radius = 1.0) {
    Room& ra = rooms_.at(rid(a));
    Room& rb = rooms_.at(rid(b));
    Vec3 n = normalize(rb.sphere.centre - ra.sphere.centre);
    ra.portals.push_back({centre, n, radius, rb.id});
    rb.portals.push_back({centre, -n, radius, ra.id});
    for (Room* r : {&ra, &rb})
      std::sort(
          r->portals.begin(), r->portals.end(),
          [](const cave::Portal& p, const cave::Portal& q) { return p.neighbour < q.neighbour; });
  }
  const Room& operator[](int index) const { return rooms_.at(rid(index)); }
  PortalGraph graph(std::initializer_list<int> known) const {
    PortalGraph g;
    for (int i : known)
      EXPECT_TRUE(g.add((*this)[i]).ok()) << i;
    return g;
  }

 private:
  std::map<RoomId, Room> rooms_;
};

// A corridor along +x from the start room r0 (portal centres at x = 2, 6, 11), a side room r4
// at 90 degrees (portal at y = 3) and a room r5 behind (portal at x = -2).
Rooms corridor() {
  Rooms rs;
  rs.room(0, {0, 0, 0}, 4);
  rs.room(1, {4, 0, 0}, 3);
  rs.room(2, {8, 0, 0}, 3);
  rs.room(3, {14, 0, 0}, 4);
  rs.room(4, {0, 5, 0}, 3);
  rs.room(5, {-4, 0, 0}, 3);
  rs.link(0, 1, {2, 0, 0});
  rs.link(1, 2, {6, 0, 0});
  rs.link(2, 3, {11, 0, 0});
  rs.link(0, 4, {0, 3, 0});
  rs.link(0, 5, {-2, 0, 0});
  return rs;
}

std::map<RoomId, PlannedRoom> by_id(const std::vector<PlannedRoom>& plan) {
  std::map<RoomId, PlannedRoom> out;
  for (const PlannedRoom& p : plan)
    out.emplace(p.id, p);
  return out;
}

void expect_sorted(const std::vector<PlannedRoom>& plan) {
  for (size_t i = 1; i < plan.size(); ++i) {
    EXPECT_TRUE(plan[i - 1].seconds < plan[i].seconds ||
                (plan[i - 1].seconds == plan[i].seconds && plan[i - 1].id < plan[i].id))
        << "entries " << i - 1 << " and " << i;
  }
}

TEST(PortalGraphPlan, costs_are_distances_over_speed_with_the_first_hop_weighted_by_view) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.position = {0, 0, 0};
  pose.forward = {1, 0, 0};
  pose.speed = 2;
  auto plan = g.plan(rid(0), pose, PlanOptions{100.0, 1.0, 100});
  // r1: 2 m straight ahead = 1 s. r5: 2 m straight behind, x2 = 2 s. r4: 3 m at 90 degrees, x1.5 =
  // 2.25 s. r2: r1 + 4 m (portal 2 to portal 6) = 3 s; r3: r2 + 5 m = 5.5 s.
  ASSERT_EQ(plan.size(), 6u);
  const std::vector<std::pair<int, double>> expected = {{0, 0.0},  {1, 1.0}, {5, 2.0},
                                                        {4, 2.25}, {2, 3.0}, {3, 5.5}};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(plan[i].id, rid(expected[i].first)) << i;
    EXPECT_DOUBLE_EQ(plan[i].seconds, expected[i].second) << i;
    EXPECT_TRUE(plan[i].known);
  }
}

TEST(PortalGraphPlan, a_room_behind_the_player_costs_more_and_only_the_first_hop_is_weighted) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.speed = 2;
  pose.forward = {-1, 0, 0};  // facing r5: the corridor is behind
  auto behind = by_id(g.plan(rid(0), pose, {100.0, 1.0, 100}));
  EXPECT_DOUBLE_EQ(behind.at(rid(5)).seconds, 1.0);
  EXPECT_DOUBLE_EQ(behind.at(rid(1)).seconds, 2.0);
  EXPECT_DOUBLE_EQ(behind.at(rid(2)).seconds, 4.0);  // 2 + 4 m / 2, not 2 + 2 x 2
  EXPECT_DOUBLE_EQ(behind.at(rid(3)).seconds, 6.5);

  pose.forward = {-3, 0, 0};  // need not be unit
  EXPECT_DOUBLE_EQ(by_id(g.plan(rid(0), pose, {100.0, 1.0, 100})).at(rid(1)).seconds, 2.0);
  // behind_weight scales the stretch: 1 + 3 x (1 - cos 180)/2 = 4.
  EXPECT_DOUBLE_EQ(by_id(g.plan(rid(0), pose, {100.0, 3.0, 100})).at(rid(1)).seconds, 4.0);
  pose.forward = {0, 0, 0};  // no preference
  auto flat = by_id(g.plan(rid(0), pose, {100.0, 1.0, 100}));
  EXPECT_DOUBLE_EQ(flat.at(rid(1)).seconds, 1.0);
  EXPECT_DOUBLE_EQ(flat.at(rid(5)).seconds, 1.0);
  EXPECT_DOUBLE_EQ(flat.at(rid(4)).seconds, 1.5);
}

TEST(PortalGraphPlan, horizon_keeps_rooms_reachable_within_it_inclusive) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.forward = {1, 0, 0};
  pose.speed = 2;
  auto at3 = g.plan(rid(0), pose, {3.0, 1.0, 100});
  ASSERT_EQ(at3.size(), 5u);  // r3 at 5.5 s is cut
  EXPECT_EQ(at3.back().id, rid(2));
  auto below3 = g.plan(rid(0), pose, {2.999, 1.0, 100});
  ASSERT_EQ(below3.size(), 4u);
  EXPECT_EQ(below3.back().id, rid(4));
  // The start room is in every plan, even with nothing else in reach.
  auto none = g.plan(rid(0), pose, {-1.0, 1.0, 100});
  ASSERT_EQ(none.size(), 1u);
  EXPECT_EQ(none[0].id, rid(0));
  EXPECT_EQ(none[0].seconds, 0.0);
}

TEST(PortalGraphPlan, max_rooms_keeps_the_nearest) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.forward = {1, 0, 0};
  pose.speed = 2;
  auto plan = g.plan(rid(0), pose, {100.0, 1.0, 3});
  ASSERT_EQ(plan.size(), 3u);
  EXPECT_EQ(plan[0].id, rid(0));
  EXPECT_EQ(plan[1].id, rid(1));
  EXPECT_EQ(plan[2].id, rid(5));
}

TEST(PortalGraphPlan, speed_below_the_minimum_counts_as_the_minimum) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.forward = {0, 0, 0};
  pose.speed = 0;
  EXPECT_DOUBLE_EQ(by_id(g.plan(rid(0), pose, {100.0, 1.0, 100})).at(rid(1)).seconds,
                   2.0 / kMinSpeed);
  pose.speed = -3;
  EXPECT_DOUBLE_EQ(by_id(g.plan(rid(0), pose, {100.0, 1.0, 100})).at(rid(1)).seconds,
                   2.0 / kMinSpeed);
}

TEST(PortalGraphPlan, equal_costs_are_ordered_by_id) {
  const Rooms rs = corridor();
  PortalGraph g = rs.graph({0, 1, 2, 3, 4, 5});
  Pose pose;
  pose.forward = {0, 0, 0};  // r1 and r5 both 2 m away
  auto plan = g.plan(rid(0), pose, {100.0, 1.0, 100});
  ASSERT_GE(plan.size(), 3u);
  EXPECT_EQ(plan[1].id, rid(1));
  EXPECT_EQ(plan[2].id, rid(5));
  EXPECT_EQ(plan[1].seconds, plan[2].seconds);
}

TEST(PortalGraphPlan, unknown_rooms_are_leaves) {
  const Rooms rs = corridor();
  // r1 not received yet: r2 and r3 are known but reachable only through it.
  PortalGraph g = rs.graph({0, 2, 3, 4, 5});
  Pose pose;
  pose.forward = {1, 0, 0};
  pose.speed = 2;
  auto plan = by_id(g.plan(rid(0), pose, {100.0, 1.0, 100}));
  ASSERT_TRUE(plan.count(rid(1)));
  EXPECT_FALSE(plan.at(rid(1)).known);
  EXPECT_DOUBLE_EQ(plan.at(rid(1)).seconds, 1.0);
  EXPECT_FALSE(plan.count(rid(2)));
  EXPECT_FALSE(plan.count(rid(3)));
  // Its frame arrives: the next plan goes on through it.
  ASSERT_TRUE(g.add(rs[1]).ok());
  plan = by_id(g.plan(rid(0), pose, {100.0, 1.0, 100}));
  EXPECT_TRUE(plan.at(rid(1)).known);
  EXPECT_DOUBLE_EQ(plan.at(rid(3)).seconds, 5.5);
}

TEST(PortalGraphPlan, an_unknown_start_room_is_planned_alone) {
  PortalGraph g;
  auto plan = g.plan(rid(7), Pose{}, PlanOptions{});
  ASSERT_EQ(plan.size(), 1u);
  EXPECT_EQ(plan[0].id, rid(7));
  EXPECT_EQ(plan[0].seconds, 0.0);
  EXPECT_FALSE(plan[0].known);
}

// A real sector, checked against the contract's formula written out for the first two rings.
class RealSector : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = new cave::World(cave::World::create(42, cave::LayoutParams{}).value());
    region_ = new cave::Region(cave::generate_region(*world_, {0, 0, 0}, {1, 1, 0}));
  }
  static void TearDownTestSuite() {
    delete region_;
    delete world_;
  }
  static PortalGraph whole_graph() {
    PortalGraph g;
    for (const Room& r : region_->rooms)
      EXPECT_TRUE(g.add(r).ok()) << r.id.to_string();
    return g;
  }
  static const cave::Portal& portal_to(const Room& r, RoomId to) {
    for (const cave::Portal& p : r.portals)
      if (p.neighbour == to) return p;
    ADD_FAILURE() << r.id.to_string() << " has no portal to " << to.to_string();
    return r.portals.front();
  }
  static cave::World* world_;
  static cave::Region* region_;
};
cave::World* RealSector::world_ = nullptr;
cave::Region* RealSector::region_ = nullptr;

TEST_F(RealSector, portal_sides_are_bit_identical_with_exactly_negated_normals) {
  int checked = 0;
  for (const Room& r : region_->rooms) {
    for (const cave::Portal& p : r.portals) {
      const Room* n = region_->find(p.neighbour);
      if (!n) continue;  // a boundary gate's portal out of the block
      const cave::Portal& q = portal_to(*n, r.id);
      for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(bits(p.centre[a]), bits(q.centre[a]));
        EXPECT_EQ(bits(p.normal[a]), bits(-q.normal[a]));
      }
      EXPECT_EQ(bits(p.radius), bits(q.radius));
      ++checked;
    }
  }
  EXPECT_GT(checked, 800);  // the block's portals, both sides (872 when last counted)
}

TEST_F(RealSector, every_room_is_accepted_in_any_order) {
  PortalGraph forward = whole_graph();
  EXPECT_EQ(forward.size(), region_->rooms.size());
  PortalGraph backward;
  for (auto it = region_->rooms.rbegin(); it != region_->rooms.rend(); ++it)
    EXPECT_TRUE(backward.add(*it).ok()) << it->id.to_string();
  EXPECT_EQ(backward.size(), region_->rooms.size());
}

// A room with a neighbour known, and the index of its portal to that neighbour.
struct Pair {
  Room room;
  size_t slot;
  Room neighbour;
};

class PortalGraphAdd : public RealSector {
 protected:
  static Pair pair() {
    const Room& r = region_->rooms[region_->rooms.size() / 2];
    const cave::Portal& p = r.portals.front();
    return {r, 0, *region_->find(p.neighbour)};
  }
  // Adding `altered` fails with kBadFrame naming the neighbour, and nothing changes.
  static void expect_refused(const Pair& p, const Room& altered, const std::string& what) {
    PortalGraph g;
    ASSERT_TRUE(g.add(p.neighbour).ok());
    ASSERT_TRUE(g.add(p.room).ok());  // the original, replaced below only on success
    Status s = g.add(altered);
    ASSERT_FALSE(s.ok()) << what;
    EXPECT_EQ(s.error().code, ErrorCode::kBadFrame) << what;
    EXPECT_NE(s.error().message.find(p.neighbour.id.to_string()), std::string::npos)
        << s.error().message;
    EXPECT_EQ(g.size(), 2u);
    ASSERT_NE(g.find(p.room.id), nullptr);
    EXPECT_EQ(bits(g.find(p.room.id)->portals[p.slot].centre.x),
              bits(p.room.portals[p.slot].centre.x));
    EXPECT_EQ(bits(g.find(p.room.id)->portals[p.slot].radius), bits(p.room.portals[p.slot].radius));
    EXPECT_EQ(g.find(p.room.id)->portals.size(), p.room.portals.size());

    PortalGraph fresh;  // and refused as a first arrival too
    ASSERT_TRUE(fresh.add(p.neighbour).ok());
    EXPECT_FALSE(fresh.add(altered).ok()) << what;
    EXPECT_EQ(fresh.size(), 1u);
    EXPECT_EQ(fresh.find(altered.id), nullptr);
  }
};

TEST_F(PortalGraphAdd, refuses_a_portal_centre_one_ulp_off) {
  Pair p = pair();
  Room altered = p.room;
  double& x = altered.portals[p.slot].centre.x;
  x = std::nextafter(x, INFINITY);
  expect_refused(p, altered, "centre");
}

TEST_F(PortalGraphAdd, refuses_a_portal_radius_one_ulp_off) {
  Pair p = pair();
  Room altered = p.room;
  double& r = altered.portals[p.slot].radius;
  r = std::nextafter(r, 0.0);
  expect_refused(p, altered, "radius");
}

TEST_F(PortalGraphAdd, refuses_a_normal_that_is_not_the_exact_negation) {
  Pair p = pair();
  Room altered = p.room;
  double& y = altered.portals[p.slot].normal.y;
  y = std::nextafter(y, INFINITY);
  expect_refused(p, altered, "normal");
  Room same_side = p.room;
  same_side.portals[p.slot].normal = -same_side.portals[p.slot].normal;
  expect_refused(p, same_side, "normal not flipped");
}

TEST_F(PortalGraphAdd, refuses_a_room_that_drops_its_portal_to_a_known_neighbour) {
  Pair p = pair();
  Room altered = p.room;
  altered.portals.erase(altered.portals.begin() + static_cast<long>(p.slot));
  expect_refused(p, altered, "dropped portal");
}

TEST_F(PortalGraphAdd, refuses_a_room_whose_known_neighbour_does_not_list_it_back) {
  Pair p = pair();
  Room stale = p.neighbour;  // a neighbour without its portal to p.room
  std::erase_if(stale.portals, [&](const cave::Portal& q) { return q.neighbour == p.room.id; });
  PortalGraph g;
  ASSERT_TRUE(g.add(stale).ok());
  Status s = g.add(p.room);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kBadFrame);
  EXPECT_NE(s.error().message.find("no portal back"), std::string::npos) << s.error().message;
  EXPECT_EQ(g.size(), 1u);
}

TEST_F(PortalGraphAdd, refuses_a_portal_to_itself_and_two_portals_to_one_room) {
  Pair p = pair();
  Room self = p.room;
  self.portals[p.slot].neighbour = self.id;
  PortalGraph g;
  EXPECT_FALSE(g.add(self).ok());
  Room twice = p.room;
  twice.portals.push_back(twice.portals[p.slot]);
  EXPECT_FALSE(g.add(twice).ok());
  EXPECT_EQ(g.size(), 0u);
}

TEST_F(PortalGraphAdd, replaces_remove_and_clear) {
  Pair p = pair();
  PortalGraph g;
  ASSERT_TRUE(g.add(p.room).ok());
  ASSERT_TRUE(g.add(p.room).ok());  // the same room again replaces it
  EXPECT_EQ(g.size(), 1u);
  ASSERT_TRUE(g.add(p.neighbour).ok());
  EXPECT_EQ(g.size(), 2u);
  g.remove(p.room.id);
  EXPECT_EQ(g.find(p.room.id), nullptr);
  EXPECT_NE(g.find(p.neighbour.id), nullptr);
  g.remove(p.room.id);  // absent: nothing happens
  EXPECT_EQ(g.size(), 1u);
  g.clear();
  EXPECT_EQ(g.size(), 0u);
  EXPECT_EQ(g.find(p.neighbour.id), nullptr);
}

TEST_F(RealSector, room_at_finds_each_room_at_its_interior_point_and_nothing_in_the_void) {
  PortalGraph g = whole_graph();
  for (const Room& r : region_->rooms) {
    auto at = g.room_at(cave::interior_point(r));
    ASSERT_TRUE(at.has_value()) << r.id.to_string();
    EXPECT_EQ(*at, r.id);
  }
  EXPECT_FALSE(g.room_at({-1000, -1000, -1000}).has_value());
  EXPECT_FALSE(PortalGraph().room_at(region_->rooms[0].sphere.centre).has_value());
}

// The cave's rule (cave::room_at): a room's space ends at its portal planes; where spheres
// overlap with no portal between them, the smaller id.
TEST(PortalGraphRoomAt, the_portal_plane_divides_overlapping_rooms) {
  Rooms rs;
  rs.room(0, {0, 0, 0}, 4);
  rs.room(1, {5, 0, 0}, 2);
  rs.room(2, {0, 5, 0}, 2);  // overlaps r0, no portal between them
  rs.link(0, 1, {3.5, 0, 0});
  PortalGraph g = rs.graph({0, 1, 2});
  EXPECT_EQ(g.room_at({3, 0, 0}), rid(0));
  EXPECT_EQ(g.room_at({3.6, 0, 0}), rid(1));  // past the portal: r1, though inside r0's sphere
  EXPECT_EQ(g.room_at({3.5, 0, 0}), rid(0));  // on the plane: the smaller id
  EXPECT_EQ(g.room_at({7, 0, 0}), rid(1));    // on r1's surface only
  EXPECT_EQ(g.room_at({0, 3.5, 0}), rid(0));  // in both spheres, no portal: the smaller id
  EXPECT_FALSE(g.room_at({7.001, 0, 0}).has_value());
  EXPECT_FALSE(g.room_at({0, -4.001, 0}).has_value());
  // r1 not known: the cap beyond r0's portal is still not r0's.
  PortalGraph partial = rs.graph({0});
  EXPECT_FALSE(partial.room_at({3.6, 0, 0}).has_value());
}

TEST_F(RealSector, plan_matches_the_hand_computed_costs_of_two_rings) {
  PortalGraph g = whole_graph();
  const Room& start = *region_->find(cave::spawn_room(*world_));
  Pose pose;
  pose.position = start.sphere.centre;
  pose.forward = {0, 0, 0};
  pose.speed = 4;
  auto plan = g.plan(start.id, pose, {1e9, 1.0, 100000});
  ASSERT_FALSE(plan.empty());
  EXPECT_EQ(plan[0].id, start.id);
  EXPECT_EQ(plan[0].seconds, 0.0);
  expect_sorted(plan);
  auto got = by_id(plan);
  // Every room of the block reachable from the spawn room is planned, known ones marked known.
  for (const PlannedRoom& p : plan)
    EXPECT_EQ(p.known, g.find(p.id) != nullptr) << p.id.to_string();

  // Ring 1: distance from the player to each portal centre over speed.
  std::map<RoomId, double> ring1;
  for (const cave::Portal& p : start.portals)
    ring1[p.neighbour] = distance(start.sphere.centre, p.centre) / 4.0;
  ASSERT_GE(ring1.size(), 2u);
  for (auto [id, seconds] : ring1)
    EXPECT_EQ(got.at(id).seconds, seconds) << id.to_string();
  // Ring 2: through the cheapest ring-1 room, from its entry portal to the next.
  std::map<RoomId, double> ring2;
  for (auto [id, seconds] : ring1) {
    const Room* n = g.find(id);
    ASSERT_NE(n, nullptr);
    const Vec3 entry = portal_to(start, id).centre;
    for (const cave::Portal& p : n->portals) {
      if (p.neighbour == start.id || ring1.count(p.neighbour)) continue;
      const double cost = seconds + distance(entry, p.centre) / 4.0;
      auto [it, fresh] = ring2.try_emplace(p.neighbour, cost);
      if (!fresh) it->second = std::min(it->second, cost);
    }
  }
  ASSERT_GE(ring2.size(), 2u);
  for (auto [id, seconds] : ring2)
    EXPECT_DOUBLE_EQ(got.at(id).seconds, seconds) << id.to_string();
}

TEST_F(RealSector, plan_stretches_rooms_behind_the_view_direction) {
  PortalGraph g = whole_graph();
  const Room& start = *region_->find(cave::spawn_room(*world_));
  ASSERT_GE(start.portals.size(), 2u);
  Pose pose;
  pose.position = start.sphere.centre;
  pose.speed = 4;
  const cave::Portal& ahead = start.portals[0];
  pose.forward = ahead.centre - pose.position;
  auto got = by_id(g.plan(start.id, pose, {1e9, 1.0, 100000}));
  pose.forward = {0, 0, 0};
  auto flat = by_id(g.plan(start.id, pose, {1e9, 1.0, 100000}));
  EXPECT_NEAR(got.at(ahead.neighbour).seconds, flat.at(ahead.neighbour).seconds, 1e-12);
  for (size_t i = 1; i < start.portals.size(); ++i) {
    const cave::Portal& p = start.portals[i];
    const Vec3 f = ahead.centre - start.sphere.centre, d = p.centre - start.sphere.centre;
    const double c = dot(f, d) / (length(f) * length(d));
    ASSERT_LT(c, 0.999);
    const double direct = length(d) / 4.0;
    EXPECT_GT(got.at(p.neighbour).seconds, flat.at(p.neighbour).seconds) << i;
    EXPECT_NEAR(got.at(p.neighbour).seconds, direct * (1 + (1 - c) / 2), 1e-9) << i;
  }
}

}  // namespace
}  // namespace grotto::stream
