// The player on hand-made geometry: gravity, resting height, walls it slides along, ledges it
// steps onto, the walkable slope limit, fly mode, portal walls over rooms not loaded, and rooms
// far from the origin.
#include <gtest/gtest.h>

#include <cmath>

#include "client/play/player.hpp"
#include "tests/client/play/shapes.hpp"

namespace grotto::play {
namespace {

using test::floor_quad;
using test::Quad;
using test::shape_room;
using test::wall_x;

constexpr double kEps = 1e-6;

// Runs the player for `seconds` of simulated time with one input.
void run(Player& p, const CollisionWorld& world, double seconds, const PlayerInput& in = {}) {
  const int steps = static_cast<int>(std::lround(seconds / p.params().timestep));
  for (int i = 0; i < steps; ++i)
    p.step(in, world);
}

// Where the eye rests above a floor at height y: feet sphere centre at radius + skin / 2.
double rest_eye(const PlayerParams& params, double floor_y) {
  return floor_y + params.eye_height + params.skin / 2;
}

TEST(Player, gravity_brings_a_player_in_mid_air_to_the_floor) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0)}));
  Player p({1, 6, 2});
  p.step({}, world);
  EXPECT_FALSE(p.grounded());
  run(p, world, 3);
  EXPECT_TRUE(p.grounded());
  EXPECT_NEAR(p.eye().y, rest_eye(p.params(), 0), kEps);
  EXPECT_EQ(p.eye().x, 1);
  EXPECT_EQ(p.eye().z, 2);
  EXPECT_EQ(p.velocity().y, 0);
  const Vec3 rested = p.eye();
  run(p, world, 1);
  EXPECT_EQ(p.eye(), rested) << "standing still must not creep";
}

TEST(Player, a_jump_leaves_the_ground_and_lands_again) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0)}));
  Player p({0, 1.6, 0});
  run(p, world, 1);
  ASSERT_TRUE(p.grounded());
  PlayerInput jump;
  jump.up = true;
  p.step(jump, world);
  double top = p.eye().y;
  for (int i = 0; i < 240; ++i) {
    p.step({}, world);
    top = std::max(top, p.eye().y);
  }
  const double h = p.params().jump_speed * p.params().jump_speed / (2 * p.params().gravity);
  EXPECT_NEAR(top - rest_eye(p.params(), 0), h, 0.05);
  EXPECT_TRUE(p.grounded());
  EXPECT_NEAR(p.eye().y, rest_eye(p.params(), 0), kEps);
}

TEST(Player, walking_into_a_wall_stops_there_and_slides_along_it) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}));
  Player p({0, 1.6, 0});
  PlayerInput in;
  in.move = {1, 0, 1};  // 45 degrees into the wall
  run(p, world, 3, in);
  EXPECT_NEAR(p.eye().x, 3 - p.params().radius - p.params().skin / 2, p.params().skin / 2);
  // Along the wall it keeps the input's tangential speed: 4 / sqrt(2) m/s for ~3 s.
  EXPECT_GT(p.eye().z, 7.5);
  EXPECT_TRUE(p.grounded());
}

TEST(Player, running_never_tunnels_through_a_thin_wall) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}));
  PlayerParams fast;
  fast.speed = 60;  // 150 m/s with run: 1.25 m per step, more than twice the radius
  Player p({0, 1.6, 0}, fast);
  PlayerInput in;
  in.move = {1, 0, 0};
  in.run = true;
  run(p, world, 1, in);
  EXPECT_LT(p.eye().x, 3 - fast.radius);
}

// A ledge of height h from x = 2 on.
CollisionWorld ledge(double h) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0),
                           {{2, 0, -50}, {2, h, -50}, {2, h, 50}, {2, 0, 50}},
                           {{2, h, -50}, {2, h, 50}, {60, h, 50}, {60, h, -50}}}));
  return world;
}

TEST(Player, walking_steps_onto_a_low_ledge_but_not_onto_a_high_one) {
  PlayerInput in;
  in.move = {1, 0, 0};
  CollisionWorld low = ledge(0.3);
  Player a({0, 1.6, 0});
  run(a, low, 2, in);
  EXPECT_GT(a.eye().x, 4);
  EXPECT_NEAR(a.eye().y, rest_eye(a.params(), 0.3), kEps);

  CollisionWorld high = ledge(0.6);
  Player b({0, 1.6, 0});
  run(b, high, 2, in);
  EXPECT_LT(b.eye().x, 2);
  EXPECT_NEAR(b.eye().y, rest_eye(b.params(), 0), b.params().skin);
}

// A ramp rising along +x at `degrees` from x = 1.
CollisionWorld ramp(double degrees) {
  const double rise = std::tan(degrees * 3.14159265358979323846 / 180) * 20;
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(
      0, {floor_quad(0, 50, -49), {{1, 0, -50}, {1, 0, 50}, {21, rise, 50}, {21, rise, -50}}}));
  return world;
}

TEST(Player, walks_up_a_gentle_slope_but_not_up_a_steep_one) {
  PlayerInput in;
  in.move = {1, 0, 0};
  CollisionWorld gentle = ramp(30);
  Player a({0, 1.6, 0});
  run(a, gentle, 3, in);
  EXPECT_GT(a.eye().y, rest_eye(a.params(), 0) + 3);
  EXPECT_TRUE(a.grounded());
  // Standing on the slope it does not slide down.
  const Vec3 stood = a.eye();
  run(a, gentle, 1);
  EXPECT_EQ(a.eye(), stood);

  CollisionWorld steep = ramp(60);
  Player b({0, 1.6, 0});
  run(b, steep, 3, in);
  EXPECT_LT(b.eye().y, rest_eye(b.params(), 0) + 1);
}

TEST(Player, fly_mode_does_not_fall_and_still_collides) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}));
  Player p({0, 5, 0});
  p.set_mode(Mode::kFly);
  run(p, world, 2);
  EXPECT_EQ(p.eye(), (Vec3{0, 5, 0}));
  PlayerInput down;
  down.down = true;
  run(p, world, 3, down);
  EXPECT_NEAR(p.eye().y, rest_eye(p.params(), 0), kEps);
  PlayerInput ahead;
  ahead.move = {1, 0.2, 0};
  run(p, world, 3, ahead);
  EXPECT_NEAR(p.eye().x, 3 - p.params().radius - p.params().skin / 2, kEps);
}

TEST(Player, noclip_passes_through_walls) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}));
  Player p({0, 1.6, 0});
  p.set_noclip(true);
  PlayerInput in;
  in.move = {1, 0, 0};
  run(p, world, 2, in);
  EXPECT_GT(p.eye().x, 7);
}

TEST(Player, a_portal_to_a_room_not_loaded_is_a_wall_until_the_room_arrives) {
  const cave::RoomId next = cave::RoomId::interior({0, 0, 0}, 1);
  cave::Portal portal{{3, 1.5, 0}, {1, 0, 0}, 2.0, next};
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0)}, {}, {portal}));
  Player p({0, 1.6, 0});
  PlayerInput in;
  in.move = {1, 0, 0};
  run(p, world, 2, in);
  EXPECT_NEAR(p.eye().x, 3 - p.params().radius - p.params().skin / 2, kEps);

  world.add(shape_room(1, {floor_quad(0, 50, 53)}));
  run(p, world, 2, in);
  EXPECT_GT(p.eye().x, 5);
  world.evict(next);
  EXPECT_FALSE(world.contains(next));
}

TEST(Player, collides_as_exactly_ten_kilometres_from_the_origin) {
  // Room-frame floats plus a grid origin: the resting height is as exact far away as at 0.
  const Vec3 origin{10240.5, -7168.25, 20480.75};
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}, origin));
  Player p(origin + Vec3{0, 1.6, 0});
  PlayerInput in;
  in.move = {1, 0, 0};
  run(p, world, 2, in);
  EXPECT_NEAR(p.eye().y - origin.y, rest_eye(p.params(), 0), kEps);
  EXPECT_NEAR(p.eye().x - origin.x, 3 - p.params().radius - p.params().skin / 2, kEps);
}

TEST(Player, advance_runs_fixed_steps_and_keeps_the_remainder) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0)}));
  Player p({0, 1.6, 0});
  EXPECT_EQ(p.advance(0.6 / 120, {}, world), 0);
  EXPECT_EQ(p.advance(0.6 / 120, {}, world), 1);
  EXPECT_EQ(p.advance(10, {}, world), 30) << "a long stall runs at most a quarter second";
}

}  // namespace
}  // namespace grotto::play
