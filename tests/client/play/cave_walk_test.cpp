// The player in real rooms (sector (0,0,0) of seed 7, patch meshes through the room codec): a
// scripted walk of 60 s with seeded random input (walking, running, jumps, turns straight into
// the nearest wall, spells of flying) stays inside the cave at every step; the same walk without
// collision leaves it, which shows the check can fail; portals to rooms not loaded hold; the
// same inputs give the same position bit for bit.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <string>

#include "client/play/flythrough.hpp"
#include "client/play/player.hpp"
#include "client/stream/verify.hpp"
#include "common/core/random.hpp"
#include "tests/client/play/cave.hpp"

namespace grotto::play {
namespace {

constexpr double kPi = 3.14159265358979323846;

CollisionWorld load(const test::Cave& cave) {
  CollisionWorld world;
  for (const auto& [id, room] : cave.rooms)
    world.add(room);
  return world;
}

// Why the body is outside the cave after moving from `before`, or "" when it is inside: each
// sphere centre lies in some loaded room's sphere (plus the verified vertex margin), keeps at
// least radius - skin from every triangle and portal wall, and its path since the last step
// crossed none of them. Starting inside, a path that never crosses the surface stays inside.
std::string outside(const test::Cave& cave, const CollisionWorld& world, const Player& p,
                    const std::array<Vec3, 3>& before) {
  const std::array<Vec3, 3> now = p.spheres();
  const double r = p.params().radius, min_distance = r - p.params().skin;
  Vec3 lo = now[0], hi = now[0];
  for (const auto& set : {before, now})
    for (Vec3 c : set)
      for (int i = 0; i < 3; ++i)
        lo[i] = std::min(lo[i], c[i] - r), hi[i] = std::max(hi[i], c[i] + r);
  Neighbourhood near;
  world.gather(lo, hi, near);
  for (int k = 0; k < 3; ++k) {
    const std::string sphere = "sphere " + std::to_string(k) + " ";
    bool in_a_room = false;
    for (const auto& [id, room] : cave.rooms) {
      const cave::Sphere& s = room.room.sphere;
      in_a_room = in_a_room ||
                  distance(now[k], s.centre) < s.radius + stream::vertex_sphere_margin(s.radius);
    }
    if (!in_a_room) return sphere + "is in no room's sphere";
    for (const Triangle& t : near.triangles) {
      if (segment_crosses(t, before[k], now[k])) return sphere + "crossed the mesh";
      if (distance(closest_point(t, now[k]), now[k]) < min_distance)
        return sphere + "is " + std::to_string(distance(closest_point(t, now[k]), now[k])) +
               " m from the mesh";
    }
    for (const Disc& wall : near.walls) {
      if (segment_crosses(wall, before[k], now[k]))
        return sphere + "passed a portal to a room not loaded";
      if (distance(closest_point(wall, now[k]), now[k]) < min_distance)
        return sphere + "is inside a portal wall";
    }
  }
  return "";
}

// Seeded input: segments of 0.3-2 s with a heading (a quarter of them straight at the nearest
// wall), running 40% of the time, a jump about every second, flying in 15% of the segments.
class Script {
 public:
  explicit Script(uint64_t seed) : rng_(seed) {}
  PlayerInput next(Player& p, const CollisionWorld& world) {
    left_ -= p.params().timestep;
    if (left_ <= 0) {
      left_ = rng_.uniform(0.3, 2.0);
      p.set_mode(rng_.chance(0.15) ? Mode::kFly : Mode::kWalk);
      in_ = {};
      in_.run = rng_.chance(0.4);
      const double yaw = rng_.uniform(0, 2 * kPi), pitch = rng_.uniform(-0.6, 0.6);
      in_.move = {std::sin(yaw) * std::cos(pitch), std::sin(pitch),
                  -std::cos(yaw) * std::cos(pitch)};
      if (rng_.chance(0.25)) in_.move = towards_nearest_wall(p, world);
      if (p.mode() == Mode::kFly) in_.up = rng_.chance(0.3), in_.down = !in_.up && rng_.chance(0.3);
    }
    PlayerInput in = in_;
    if (p.mode() == Mode::kWalk) in.up = rng_.chance(1.0 / 120);
    return in;
  }

 private:
  static Vec3 towards_nearest_wall(const Player& p, const CollisionWorld& world) {
    const Vec3 eye = p.eye(), reach{8, 8, 8};
    Neighbourhood near;
    world.gather(eye - reach, eye + reach, near);
    Vec3 best{1, 0, 0};
    double best_d = 1e300;
    for (const Triangle& t : near.triangles) {
      const Vec3 q = closest_point(t, eye);
      if (distance(q, eye) < best_d) best_d = distance(q, eye), best = q - eye;
    }
    return best;
  }

  Rng rng_;
  double left_ = 0;
  PlayerInput in_;
};

struct WalkResult {
  std::string left_the_cave;  // the first reason, with the time
  Vec3 eye;
  double travelled = 0;
  std::set<cave::RoomId> rooms;  // rooms the eye was in
};

WalkResult walk(uint64_t seed, double seconds, bool noclip) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave);
  Player p(cave.spawn);
  for (int i = 0; i < 120; ++i)  // a second to settle on the floor before the script starts
    p.step({}, world);
  p.set_noclip(noclip);
  Script script(seed);
  WalkResult result;
  const int steps = static_cast<int>(seconds / p.params().timestep);
  for (int i = 0; i < steps; ++i) {
    const std::array<Vec3, 3> before = p.spheres();
    p.step(script.next(p, world), world);
    result.travelled += distance(before[2], p.eye());
    if (const cave::Room* room = world.room_at(p.eye())) result.rooms.insert(room->id);
    std::string why = outside(cave, world, p, before);
    if (!why.empty()) {
      result.left_the_cave = why + " at t=" + std::to_string(i * p.params().timestep) + " s";
      break;
    }
  }
  result.eye = p.eye();
  return result;
}

TEST(CaveWalk, a_scripted_walk_with_collision_never_leaves_the_cave) {
  for (uint64_t seed : {1u, 2u}) {
    WalkResult r = walk(seed, 60, false);
    EXPECT_EQ(r.left_the_cave, "") << "seed " << seed;
    std::printf("seed %llu: %.0f m travelled through %zu rooms\n",
                static_cast<unsigned long long>(seed), r.travelled, r.rooms.size());
    EXPECT_GT(r.travelled, 60.0) << "the script should move the player";
  }
}

TEST(CaveWalk, the_same_walk_without_collision_leaves_the_cave) {
  WalkResult r = walk(1, 60, true);
  EXPECT_NE(r.left_the_cave, "");
  std::printf("noclip: %s\n", r.left_the_cave.c_str());
}

TEST(CaveWalk, the_same_inputs_give_the_same_position_bit_for_bit) {
  WalkResult a = walk(3, 15, false), b = walk(3, 15, false), c = walk(4, 15, false);
  EXPECT_EQ(std::memcmp(&a.eye, &b.eye, sizeof(Vec3)), 0);
  EXPECT_NE(std::memcmp(&a.eye, &c.eye, sizeof(Vec3)), 0) << "another script goes elsewhere";
}

TEST(CaveWalk, fly_mode_hovers_where_it_is) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave);
  Player p(cave.spawn);
  p.set_mode(Mode::kFly);
  for (int i = 0; i < 240; ++i)
    p.step({}, world);
  const Vec3 settled = p.eye();  // pushed out of a wall at most once
  for (int i = 0; i < 240; ++i)
    p.step({}, world);
  EXPECT_EQ(p.eye(), settled);
  EXPECT_LT(distance(settled, cave.spawn), 1.0);
}

TEST(CaveWalk, walking_from_the_spawn_point_lands_on_the_floor) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave);
  Player p(cave.spawn);
  for (int i = 0; i < 600 && !p.grounded(); ++i)
    p.step({}, world);
  EXPECT_TRUE(p.grounded());
  // On the spawn room's floor: below its centre, less than its radius down.
  EXPECT_LT(p.eye().y, cave.spawn.y);
  EXPECT_LT(distance(p.eye(), cave.spawn), cave.spawn_radius);
}

TEST(CaveWalk, portals_to_rooms_not_loaded_hold_the_player_back) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave);
  int portals = 0;
  for (const auto& [id, room] : cave.rooms) {
    for (const cave::Portal& portal : room.room.portals) {
      if (cave.rooms.count(portal.neighbour)) continue;
      // Fly from inside the room at the portal's centre for 10 s, running.
      Player p(cave::interior_point(room.room));
      p.set_mode(Mode::kFly);
      PlayerInput in;
      in.run = true;
      for (int i = 0; i < 1200; ++i) {
        in.move = portal.centre - p.eye();
        const std::array<Vec3, 3> before = p.spheres();
        p.step(in, world);
        for (int k = 0; k < 3; ++k)
          ASSERT_FALSE(segment_crosses(Disc{portal.centre, portal.normal, portal.radius}, before[k],
                                       p.spheres()[k]))
              << room.room.id.to_string() << " -> " << portal.neighbour.to_string();
      }
      EXPECT_LT(dot(p.eye() - portal.centre, portal.normal), 0);
      ++portals;
    }
  }
  EXPECT_GT(portals, 0) << "the sector's gates lead to sectors not loaded";
}

}  // namespace
}  // namespace grotto::play
