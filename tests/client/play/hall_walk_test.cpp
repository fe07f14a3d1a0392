// The player on a hall's floor (seed 7's hall 0.0.0.r0, radius 18.3 m, its floor at
// cave::floor_height), colliding with the surface as grotto-client draws it (the patch mesh as PN
// triangles with the relief on top, through common/relief/relief.hpp, as CollisionWorld does by
// default): a walk across the floor from one side to the other, over the floor's bumps and round
// or over its stalagmites, keeps the feet on the drawn surface at every step and gets across; a
// player dropped above the floor lands on it. The same walk and drop without collision fall
// through, which shows the checks can fail.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include "client/play/player.hpp"
#include "tests/client/play/cave.hpp"

namespace grotto::play {
namespace {

constexpr double kPi = 3.14159265358979323846;
const cave::RoomId kHall = cave::RoomId::interior({0, 0, 0}, 0);

CollisionWorld load(const test::Cave& cave) {
  CollisionWorld world;  // relief strength 1: the surface as drawn
  for (const auto& [id, room] : cave.rooms)
    world.add(room);
  return world;
}

struct Hall {
  cave::Sphere sphere;
  double floor = 0;  // cave::floor_height
};

Hall hall(const test::Cave& cave) {
  const cave::Room& room = cave.rooms.at(kHall).room;
  const std::optional<double> floor = cave::floor_height(cave::LayoutParams{}, room.sphere);
  EXPECT_TRUE(floor.has_value()) << "seed 7's 0.0.0.r0 is a hall with a floor";
  EXPECT_GT(room.sphere.radius, 15.0);
  return {room.sphere, floor.value_or(room.sphere.centre.y)};
}

// Where the vertical line through (x, z) meets the triangle, if it does.
std::optional<double> vertical_hit(const Triangle& t, double x, double z) {
  const double d = (t.b.x - t.a.x) * (t.c.z - t.a.z) - (t.c.x - t.a.x) * (t.b.z - t.a.z);
  if (std::abs(d) < 1e-14) return std::nullopt;  // a vertical triangle
  const double u = ((x - t.a.x) * (t.c.z - t.a.z) - (t.c.x - t.a.x) * (z - t.a.z)) / d;
  const double v = ((t.b.x - t.a.x) * (z - t.a.z) - (x - t.a.x) * (t.b.z - t.a.z)) / d;
  if (u < 0 || v < 0 || u + v > 1) return std::nullopt;
  return t.a.y + u * (t.b.y - t.a.y) + v * (t.c.y - t.a.y);
}

// The drawn floor's height under (x, z): the highest surface within 4 m of the hall's floor
// (stalagmites reach 1.75 m, the stalactites of a ceiling 22 m up end far above).
std::optional<double> ground_under(const CollisionWorld& world, const Hall& h, double x, double z) {
  Neighbourhood near;
  world.gather({x - 0.01, h.floor - 4, z - 0.01}, {x + 0.01, h.floor + 4, z + 0.01}, near);
  std::optional<double> top;
  for (const Triangle& t : near.triangles)
    if (auto y = vertical_hit(t, x, z); y && std::abs(*y - h.floor) < 4 && (!top || *y > *top))
      top = y;
  return top;
}

// Why the feet are not on or above the drawn floor, or "": the feet sphere's centre must keep
// (nearly) a radius above the surface under it. `surface` is the collision world with the hall
// (the one collided with may be empty).
std::string below_the_floor(const CollisionWorld& surface, const Hall& h, const Player& p) {
  const Vec3 feet = p.spheres()[0];
  const std::optional<double> ground = ground_under(surface, h, feet.x, feet.z);
  if (!ground)
    return "no floor under the feet at " + std::to_string(feet.x) + "," + std::to_string(feet.z);
  const double clearance = feet.y - *ground;
  if (clearance < p.params().radius - 2 * p.params().skin)
    return "the feet sphere's centre is " + std::to_string(clearance) + " m above the floor";
  return "";
}

struct Crossing {
  std::string failed;        // the first reason, with the time
  double distance_left = 0;  // horizontal metres from the far side at the end
  double highest = 0;        // the feet's greatest height above the hall's floor
  double lowest = 1e9;       // and least
  int jumps = 0;
};

// Walks from `from` to `to` (horizontal points on the hall's floor) for at most 40 s: straight at
// the target, and where the body stops making progress (a stalagmite too tall to step onto) a
// jump and a sidestep, alternately left and right, as a player would.
Crossing cross_the_hall(const test::Cave& cave, const CollisionWorld& collide,
                        const CollisionWorld& surface, const Hall& h, Vec3 from, Vec3 to) {
  Crossing out;
  Player p({from.x, h.floor + 2.0, from.z});
  for (int i = 0; i < 240 && !p.grounded(); ++i)  // settle on the floor
    p.step({}, collide);
  Vec3 last_check = p.eye();
  double side = 1, sidestep = 0;
  const int steps = static_cast<int>(40 / p.params().timestep);
  for (int i = 0; i < steps; ++i) {
    const Vec3 to_target{to.x - p.eye().x, 0, to.z - p.eye().z};
    if (length(to_target) < 1.0) break;
    PlayerInput in;
    in.move = to_target;
    if (sidestep > 0) {
      in.move = Vec3{-to_target.z, 0, to_target.x} * side + to_target * 0.3;
      sidestep -= p.params().timestep;
    }
    if (i % 60 == 59) {  // every half second: stuck?
      const Vec3 d = p.eye() - last_check;
      if (std::hypot(d.x, d.z) < 0.3 && sidestep <= 0) {
        in.up = true, ++out.jumps;
        sidestep = 0.6, side = -side;
      }
      last_check = p.eye();
    }
    p.step(in, collide);
    const double feet = p.spheres()[0].y - p.params().radius - h.floor;
    out.highest = std::max(out.highest, feet);
    out.lowest = std::min(out.lowest, feet);
    const std::string why = below_the_floor(surface, h, p);
    if (!why.empty()) {
      out.failed = why + " at t=" + std::to_string(i * p.params().timestep) + " s";
      break;
    }
    if (distance(p.eye(), cave.spawn) > 200) break;  // fallen out of the world
  }
  out.distance_left = std::hypot(to.x - p.eye().x, to.z - p.eye().z);
  return out;
}

// A chord of the hall's floor through its centre at this yaw: 12 m each side of the centre (the
// floor's edge is ~17.9 m out, where the wall rises).
std::pair<Vec3, Vec3> chord(const Hall& h, double yaw) {
  const Vec3 d{std::sin(yaw), 0, -std::cos(yaw)};
  return {h.sphere.centre - d * 12.0, h.sphere.centre + d * 12.0};
}

TEST(HallWalk, walking_across_the_hall_floor_stays_on_the_drawn_surface_and_gets_across) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave);
  const Hall h = hall(cave);
  double highest = 0;
  for (int k = 0; k < 6; ++k) {
    const double yaw = k * kPi / 6;
    const auto [from, to] = chord(h, yaw);
    const Crossing c = cross_the_hall(cave, world, world, h, from, to);
    std::printf("yaw %3.0f: %s, %.1f m left, feet %.2f..%.2f m over the floor, %d jumps\n",
                yaw * 180 / kPi, c.failed.empty() ? "on the floor" : c.failed.c_str(),
                c.distance_left, c.lowest, c.highest, c.jumps);
    EXPECT_EQ(c.failed, "") << "yaw " << yaw * 180 / kPi;
    EXPECT_LT(c.distance_left, 1.5) << "stuck on the way across at yaw " << yaw * 180 / kPi;
    EXPECT_GT(c.lowest, -0.6) << "the floor is the undulating plane at cave::floor_height";
    highest = std::max(highest, c.highest);
  }
  // The floor is not flat under the relief: somewhere the feet went over bumps or stalagmites.
  EXPECT_GT(highest, 0.25);
}

TEST(HallWalk, the_same_walk_without_collision_falls_through_the_floor) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave), nothing;
  const Hall h = hall(cave);
  const auto [from, to] = chord(h, 0);
  const Crossing c = cross_the_hall(cave, nothing, world, h, from, to);
  std::printf("without collision: %s\n", c.failed.c_str());
  EXPECT_NE(c.failed, "");
}

TEST(HallWalk, a_player_dropped_above_the_hall_floor_lands_on_it) {
  const test::Cave& cave = test::sector_zero();
  const CollisionWorld world = load(cave), nothing;
  const Hall h = hall(cave);
  int landed = 0;
  for (int i = 0; i < 25; ++i) {
    // A 5 x 5 grid over the middle 16 m of the floor, 6 m up.
    const double x = h.sphere.centre.x - 8 + 4 * (i % 5), z = h.sphere.centre.z - 8 + 4 * (i / 5);
    Player p({x, h.floor + 6.0 + 1.5, z});
    for (int s = 0; s < 600 && !p.grounded(); ++s) {
      p.step({}, world);
      ASSERT_EQ(below_the_floor(world, h, p), "") << "dropped at " << x << "," << z;
    }
    EXPECT_TRUE(p.grounded()) << "dropped at " << x << "," << z;
    const std::optional<double> ground = ground_under(world, h, p.eye().x, p.eye().z);
    ASSERT_TRUE(ground.has_value());
    const double feet = p.eye().y - p.params().eye_height - p.params().skin / 2;
    // On the surface under it (or a stalagmite's flank beside it), never under it.
    EXPECT_GE(feet, *ground - 0.05) << "dropped at " << x << "," << z;
    EXPECT_LT(feet, *ground + p.params().radius) << "dropped at " << x << "," << z;
    landed += p.grounded();

    Player falling({x, h.floor + 6.0 + 1.5, z});
    std::string why;
    for (int s = 0; s < 600 && why.empty(); ++s) {
      falling.step({}, nothing);
      why = below_the_floor(world, h, falling);
    }
    EXPECT_NE(why, "") << "without collision the drop goes through the floor";
  }
  EXPECT_EQ(landed, 25);
}

}  // namespace
}  // namespace grotto::play
