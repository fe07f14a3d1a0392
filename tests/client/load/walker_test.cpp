// The walker on a real layout (common/cave), with a fake readiness: stalls, turn-backs, waiting
// for the first room, determinism, and never leaving the rooms' spheres.
#include "client/load/walker.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "common/cave/layout.hpp"

namespace {

using grotto::Vec3;
using grotto::cave::Room;
using grotto::cave::RoomId;
using grotto::load::Walker;
using grotto::load::WalkerOptions;
using grotto::load::WalkerState;
using grotto::load::WorldView;

// The cave as a client that has every room would see it; `blocked` rooms are not ready.
struct Layout {
  grotto::cave::World world = *grotto::cave::World::create(7, {});
  std::map<RoomId, Room> cache;
  std::set<RoomId> blocked;
  bool nothing_ready = false;

  const Room& get(RoomId id) {
    auto it = cache.find(id);
    if (it == cache.end()) it = cache.emplace(id, *grotto::cave::room(world, id)).first;
    return it->second;
  }
  WorldView view() {
    return {[this](RoomId id) -> std::optional<Room> { return get(id); },
            [this](RoomId id) { return !nothing_ready && blocked.count(id) == 0; }};
  }
  RoomId spawn() const { return grotto::cave::spawn_room(world); }
};

WalkerOptions steady() {
  WalkerOptions o;
  o.burst_rate = 0;
  o.turn_back_chance = 0;
  return o;
}

TEST(Walker, waits_for_its_start_room_and_records_time_to_first_room) {
  Layout layout;
  layout.nothing_ready = true;
  Walker w(layout.view(), steady(), 1);
  w.advance(0.05);  // not placed yet: nothing to wait for but time passes
  w.place(layout.spawn(), layout.get(layout.spawn()).sphere.centre);
  for (int i = 0; i < 10; ++i)
    w.advance(0.05);
  EXPECT_EQ(w.state(), WalkerState::kWaiting);
  EXPECT_FALSE(w.stats().first_room_s);
  layout.nothing_ready = false;
  w.advance(0.05);
  EXPECT_EQ(w.state(), WalkerState::kWalking);
  ASSERT_TRUE(w.stats().first_room_s);
  EXPECT_NEAR(*w.stats().first_room_s, 12 * 0.05, 1e-9);
  ASSERT_TRUE(w.target());
}

TEST(Walker, starts_walking_once_the_start_rooms_neighbours_are_ready_or_after_start_wait) {
  Layout layout;
  const RoomId start = layout.spawn();
  const Room& room = layout.get(start);
  ASSERT_FALSE(room.portals.empty());
  layout.blocked.insert(room.portals[0].neighbour);
  WalkerOptions o = steady();
  o.start_wait_s = 1.0;
  Walker w(layout.view(), o, 1);
  w.place(start, room.sphere.centre);
  w.advance(0.1);
  ASSERT_TRUE(w.stats().first_room_s) << "the start room is ready: time to first room is taken";
  EXPECT_EQ(w.state(), WalkerState::kWaiting) << "a neighbour is not ready yet";
  w.advance(0.5);
  EXPECT_EQ(w.state(), WalkerState::kWaiting);
  layout.blocked.clear();  // the neighbour arrives: walk at once
  w.advance(0.05);
  EXPECT_EQ(w.state(), WalkerState::kWalking);

  // A neighbour that never comes holds the player back start_wait_s at most.
  Layout other;
  other.blocked.insert(other.get(start).portals[0].neighbour);
  Walker v(other.view(), o, 1);
  v.place(start, room.sphere.centre);
  for (int i = 0; i < 10; ++i)
    v.advance(0.1);
  EXPECT_EQ(v.state(), WalkerState::kWaiting);
  for (int i = 0; i < 2; ++i)
    v.advance(0.1);
  EXPECT_NE(v.state(), WalkerState::kWaiting);
}

TEST(Walker, a_room_not_ready_stalls_the_walker_at_its_portal_for_as_long_as_it_is_not_ready) {
  Layout layout;
  const RoomId start = layout.spawn();
  const Vec3 centre = layout.get(start).sphere.centre;
  Walker w(layout.view(), steady(), 3);
  w.place(start, centre);
  w.advance(0.05);
  ASSERT_EQ(w.state(), WalkerState::kWalking);
  const RoomId next = *w.target();
  layout.blocked.insert(next);
  const Room& here = layout.get(start);
  const grotto::cave::Portal* portal = nullptr;
  for (const auto& p : here.portals)
    if (p.neighbour == next) portal = &p;
  ASSERT_NE(portal, nullptr);
  // Straight from the centre to the portal's centre at 4 m/s, after the first step's wait.
  const double arrival = 0.05 + grotto::distance(centre, portal->centre) / 4.0;

  int steps = 0;
  while (w.state() != WalkerState::kStalled && steps++ < 10'000)
    w.advance(0.05);
  ASSERT_EQ(w.state(), WalkerState::kStalled);
  EXPECT_EQ(w.pose().position, portal->centre);
  EXPECT_EQ(*w.room(), start);
  for (int i = 0; i < 40; ++i)
    w.advance(0.05);
  EXPECT_EQ(w.state(), WalkerState::kStalled);
  EXPECT_NEAR(w.open_stall_s(), w.time() - arrival, 1e-9);
  EXPECT_TRUE(w.stats().stalls_s.empty());

  layout.blocked.clear();
  w.advance(0.05);
  EXPECT_EQ(w.state(), WalkerState::kWalking);
  EXPECT_EQ(*w.room(), next);
  ASSERT_EQ(w.stats().stalls_s.size(), 1u);
  EXPECT_NEAR(w.stats().stalls_s[0], w.time() - arrival, 1e-9);
  EXPECT_GT(w.stats().stalls_s[0], 2.0);
  EXPECT_EQ(w.stats().rooms_entered, 1u);
}

// A walk of `steps` steps; the rooms entered, in order.
std::vector<RoomId> walk(Layout& layout, Walker& w, int steps, double dt) {
  std::vector<RoomId> rooms;
  w.place(layout.spawn(), layout.get(layout.spawn()).sphere.centre);
  for (int i = 0; i < steps; ++i) {
    w.advance(dt);
    if (w.room() && (rooms.empty() || rooms.back() != *w.room())) rooms.push_back(*w.room());
  }
  return rooms;
}

TEST(Walker, turns_back_part_way_sometimes_and_never_with_chance_zero) {
  Layout layout;
  WalkerOptions o = steady();
  o.turn_back_chance = 0.3;
  Walker w(layout.view(), o, 11);
  auto rooms = walk(layout, w, 3000, 0.1);
  EXPECT_GT(w.stats().turn_backs, 0u);
  // A turn-back shows as A, B, A where B was not a dead end.
  int reversals = 0;
  for (size_t i = 2; i < rooms.size(); ++i) {
    if (rooms[i] == rooms[i - 2] && layout.get(rooms[i - 1]).portals.size() > 1) ++reversals;
  }
  EXPECT_GT(reversals, 0);

  Walker straight(layout.view(), steady(), 11);
  auto rooms2 = walk(layout, straight, 3000, 0.1);
  EXPECT_EQ(straight.stats().turn_backs, 0u);
  for (size_t i = 2; i < rooms2.size(); ++i) {
    if (rooms2[i] == rooms2[i - 2]) {
      EXPECT_EQ(layout.get(rooms2[i - 1]).portals.size(), 1u) << "only dead ends send it back";
    }
  }
  EXPECT_GT(rooms2.size(), 20u);
}

TEST(Walker, same_seed_same_walk_and_another_seed_another) {
  Layout layout;
  Walker a(layout.view(), {}, 5), b(layout.view(), {}, 5), c(layout.view(), {}, 6);
  auto ra = walk(layout, a, 2000, 0.05);
  auto rb = walk(layout, b, 2000, 0.05);
  auto rc = walk(layout, c, 2000, 0.05);
  EXPECT_EQ(ra, rb);
  EXPECT_EQ(a.pose().position, b.pose().position);
  EXPECT_NE(ra, rc);
}

TEST(Walker, stays_inside_the_current_room_and_reports_its_pose) {
  Layout layout;
  Walker w(layout.view(), {}, 9);
  w.place(layout.spawn(), layout.get(layout.spawn()).sphere.centre);
  double walked = 0;
  for (int i = 0; i < 2000; ++i) {
    w.advance(0.05);
    auto pose = w.pose();
    ASSERT_TRUE(pose.room);
    const auto& sphere = layout.get(*pose.room).sphere;
    ASSERT_LE(grotto::distance(pose.position, sphere.centre), sphere.radius * (1 + 1e-9));
    EXPECT_NEAR(grotto::length(pose.forward), 1.0, 1e-9);
    EXPECT_TRUE(pose.speed == 4.0 || pose.speed == 10.0) << pose.speed;
    walked += 0.05;
  }
  // Walking at 4 m/s with sprints at 10 m/s: at least the walking distance.
  EXPECT_GE(w.stats().distance_m, 4.0 * (walked - 0.05) - 1e-6);
  EXPECT_GT(w.stats().bursts, 0u);
  EXPECT_GT(w.stats().rooms_entered, 10u);
}

}  // namespace
