// The scripted flythrough on real layout descriptors: it goes from the spawn point through
// neighbouring rooms by portal centres, never visits a room twice, depends on the descriptors
// only, waits for a descriptor it lacks, and its poses move continuously along the path.
#include <gtest/gtest.h>

#include <set>

#include "client/play/collision.hpp"
#include "client/play/flythrough.hpp"
#include "client/play/player.hpp"
#include "tests/client/play/cave.hpp"

namespace grotto::play {
namespace {

Flythrough::Lookup lookup_in(const test::Cave& cave) {
  return [&cave](cave::RoomId id) -> std::optional<cave::Room> {
    auto it = cave.rooms.find(id);
    if (it == cave.rooms.end()) return std::nullopt;
    return it->second.room;
  };
}

TEST(Flythrough, goes_from_room_to_neighbouring_room_through_portal_centres) {
  const test::Cave& cave = test::sector_zero();
  Flythrough f = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 4);
  ASSERT_EQ(f.rooms().size(), 5u) << "sector (0,0,0) has paths of four hops from the spawn";
  EXPECT_EQ(f.rooms().front(), cave.spawn_room);
  EXPECT_EQ(f.waypoints().size(), 1 + 2 * 4u);
  EXPECT_FALSE(f.waiting_for());
  EXPECT_EQ(std::set<cave::RoomId>(f.rooms().begin(), f.rooms().end()).size(), f.rooms().size());
  for (size_t i = 1; i < f.rooms().size(); ++i) {
    const cave::Room& from = cave.rooms.at(f.rooms()[i - 1]).room;
    bool linked = false;
    for (const cave::Portal& p : from.portals)
      linked = linked || (p.neighbour == f.rooms()[i] && p.centre == f.waypoints()[2 * i - 1]);
    EXPECT_TRUE(linked) << from.id.to_string() << " -> " << f.rooms()[i].to_string();
  }
  // Same descriptors, same path.
  Flythrough again = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 4);
  EXPECT_EQ(again.waypoints(), f.waypoints());
}

TEST(Flythrough, stops_at_a_room_whose_descriptor_is_not_known_and_names_it) {
  const test::Cave& cave = test::sector_zero();
  Flythrough full = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 4);
  ASSERT_GE(full.rooms().size(), 3u);
  const cave::RoomId missing = full.rooms()[2];
  auto partial_lookup = [&](cave::RoomId id) -> std::optional<cave::Room> {
    if (id == missing) return std::nullopt;
    return lookup_in(cave)(id);
  };
  Flythrough partial = Flythrough::plan(cave.spawn, cave.spawn_room, partial_lookup, 6);
  EXPECT_EQ(partial.waiting_for(), missing);
  EXPECT_EQ(partial.rooms().size(), 2u);
}

TEST(Flythrough, poses_move_continuously_there_and_back) {
  const test::Cave& cave = test::sector_zero();
  Flythrough f = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 4);
  ASSERT_GT(f.length(), 10);
  EXPECT_EQ(f.at(0).position, cave.spawn);
  Vec3 last = f.at(0).position;
  for (double s = 0.05; s < 2 * f.length(); s += 0.05) {
    const PathPose pose = f.at(s);
    EXPECT_LT(distance(pose.position, last), 0.051) << s;
    EXPECT_NEAR(length(pose.forward), 1, 1e-9);
    // A step across the turn at the far end travels both ways: no direction to follow.
    const bool turns = s - 0.05 < f.length() && s > f.length();
    if (!turns) {
      EXPECT_GT(dot(pose.forward, pose.position - last), -1e-9)
          << "forward follows the travel at " << s << " of " << f.length();
    }
    last = pose.position;
  }
  EXPECT_LT(distance(f.at(2 * f.length()).position, cave.spawn), 1e-6);
  const Vec3 end = f.waypoints().back();
  EXPECT_LT(distance(f.at(f.length()).position, end), 1e-6);
}

TEST(Flythrough, keeps_clear_of_the_walls) {
  // Portal centres and room interior points: the path stays in open cave, at least the player's
  // radius from every patch triangle (sector (0,0,0) of seed 7: 1.0 m at the closest).
  const test::Cave& cave = test::sector_zero();
  CollisionWorld world(0);  // flat shapes: no relief
  for (const auto& [id, room] : cave.rooms)
    world.add(room);
  Flythrough f = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 6);
  ASSERT_GT(f.length(), 10);
  Neighbourhood near;
  for (double s = 0; s <= f.length(); s += 0.25) {
    const Vec3 p = f.at(s).position, reach{3, 3, 3};
    world.gather(p - reach, p + reach, near);
    for (const Triangle& t : near.triangles)
      ASSERT_GE(distance(closest_point(t, p), p), PlayerParams{}.radius) << s;
  }
}

// How far a ray from p along the unit direction d runs before it meets a triangle (in whole metres,
// capped at `cap`).
double free_run(const CollisionWorld& world, Vec3 p, Vec3 d, int cap) {
  Neighbourhood near;
  const Vec3 reach{static_cast<double>(cap), static_cast<double>(cap), static_cast<double>(cap)};
  world.gather(p - reach, p + reach, near);
  for (int metres = 1; metres <= cap; ++metres) {
    for (const Triangle& t : near.triangles)
      if (segment_crosses(t, p, p + d * metres)) return metres - 1;
  }
  return cap;
}

TEST(Flythrough, looks_down_the_passage_not_at_the_walls) {
  // The gaze leads the path (4 m ahead), so the camera sees open cave ahead where the tangent
  // looked at the outer wall of a bend: along the whole path, the rock in front of the camera is
  // further on average, and rarely within 4 m (seed 7: 6.9 m on average and never within 4 m
  // ahead of the gaze; 5.6 m and 13 of 59 poses along the tangent; since the halls' ceilings,
  // 6.9 m and 7 of 124 poses within 4 m, 6.1 m and 26 along the tangent).
  const test::Cave& cave = test::sector_zero();
  CollisionWorld world(0);  // flat shapes: no relief
  for (const auto& [id, room] : cave.rooms)
    world.add(room);
  Flythrough f = Flythrough::plan(cave.spawn, cave.spawn_room, lookup_in(cave), 6);
  ASSERT_GT(f.length(), 10);
  constexpr int kCap = 8;
  double gaze_sum = 0, tangent_sum = 0;
  int poses = 0, gaze_close = 0, tangent_close = 0;
  for (double s = 0; s + 0.05 <= f.length(); s += 0.5) {
    const PathPose pose = f.at(s);
    const Vec3 tangent = normalize(f.at(s + 0.05).position - pose.position);
    const double gaze = free_run(world, pose.position, pose.forward, kCap);
    const double along = free_run(world, pose.position, tangent, kCap);
    gaze_sum += gaze;
    tangent_sum += along;
    gaze_close += gaze < 4;
    tangent_close += along < 4;
    ++poses;
  }
  std::printf(
      "%d poses: rock %.1f m ahead of the gaze on average (%d within 4 m), %.1f m along "
      "the tangent (%d within 4 m)\n",
      poses, gaze_sum / poses, gaze_close, tangent_sum / poses, tangent_close);
  EXPECT_GT(gaze_sum, tangent_sum);
  EXPECT_LE(gaze_close, poses / 15);
  EXPECT_LT(gaze_close, tangent_close / 2);
}

}  // namespace
}  // namespace grotto::play
