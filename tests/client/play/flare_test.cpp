// Flares (client/play/flare.hpp): thrown, they fall, bounce off the collision surface and come to
// rest on the ground; they never pass through a wall; they burn out; a few burn at once.
#include <gtest/gtest.h>

#include <cstring>

#include "client/play/flare.hpp"
#include "tests/client/play/shapes.hpp"

namespace grotto::play {
namespace {

using test::floor_quad;
using test::shape_room;
using test::wall_x;

// Steps every flare for `seconds` the way grotto-client does (a frame's dt, carried remainder).
void run(std::vector<Flare>& flares, const CollisionWorld& world, double seconds) {
  double carry = 0;
  for (double t = 0; t < seconds; t += 1.0 / 60)
    advance_flares(flares, 1.0 / 60, carry, world);
}

TEST(Flares, a_thrown_flare_falls_bounces_and_comes_to_rest_on_the_floor) {
  CollisionWorld world(0);  // flat shapes: no relief
  world.add(shape_room(0, {floor_quad(0)}));
  std::vector<Flare> flares;
  add_flare(flares, throw_flare({0, 1.5, 0}, {0, 0, -1}));
  run(flares, world, 5);
  ASSERT_EQ(flares.size(), 1u);
  const Flare& f = flares[0];
  EXPECT_TRUE(f.resting);
  EXPECT_GE(f.bounces, 1);
  EXPECT_GE(f.position.y, 0.0);
  EXPECT_LT(f.position.y, 0.1);
  // Thrown along -z at 12 m/s with a lob: it lands metres ahead, not under the thrower.
  EXPECT_LT(f.position.z, -5.0);
  EXPECT_NEAR(f.position.x, 0.0, 1e-9);
  EXPECT_GT(flare_brightness(f), 0.5);
}

TEST(Flares, a_flare_thrown_at_a_wall_bounces_back_and_never_passes_it) {
  CollisionWorld world(0);
  world.add(shape_room(0, {floor_quad(0), wall_x(3)}));
  std::vector<Flare> flares;
  add_flare(flares, throw_flare({0, 1.5, 0}, {1, 0, 0}));
  double carry = 0;
  double farthest = 0;
  for (int i = 0; i < 300; ++i) {
    advance_flares(flares, 1.0 / 60, carry, world);
    ASSERT_EQ(flares.size(), 1u);
    farthest = std::max(farthest, flares[0].position.x);
  }
  EXPECT_LT(farthest, 3.0);
  EXPECT_GT(farthest, 2.8) << "it reached the wall";
  EXPECT_LT(flares[0].position.x, 2.5) << "it bounced back off the wall";
  EXPECT_TRUE(flares[0].resting);
  EXPECT_GE(flares[0].position.y, 0.0);
}

TEST(Flares, flares_burn_out_after_their_time) {
  CollisionWorld world(0);
  world.add(shape_room(0, {floor_quad(0)}));
  const FlareParams params;
  std::vector<Flare> flares;
  add_flare(flares, throw_flare({0, 1.5, 0}, {0, 0, -1}));
  run(flares, world, params.burn_s - 1.0);
  ASSERT_EQ(flares.size(), 1u);
  const double dying = flare_brightness(flares[0]);
  EXPECT_GT(dying, 0.0);
  EXPECT_LT(dying, 0.5) << "it dies down over its last seconds";
  run(flares, world, 1.5);
  EXPECT_TRUE(flares.empty());
}

TEST(Flares, a_few_burn_at_once_and_a_new_one_puts_out_the_oldest) {
  const FlareParams params;
  std::vector<Flare> flares;
  for (int i = 0; i < params.max_flares + 2; ++i) {
    Flare f = throw_flare({0, 1.5, 0}, {0, 0, -1});
    f.age = 10.0 - i;  // the later thrown, the younger
    add_flare(flares, f);
  }
  ASSERT_EQ(flares.size(), static_cast<size_t>(params.max_flares));
  EXPECT_EQ(flares.front().age, 10.0 - 2);
  EXPECT_EQ(flares.back().age, 10.0 - (params.max_flares + 1));
}

TEST(Flares, the_same_throw_lands_in_the_same_place) {
  CollisionWorld world(0);
  world.add(shape_room(0, {floor_quad(0), wall_x(4)}));
  Vec3 landed[2];
  for (Vec3& at : landed) {
    std::vector<Flare> flares;
    add_flare(flares, throw_flare({0, 1.5, 0}, {0.8, 0.1, -0.3}));
    run(flares, world, 4);
    ASSERT_EQ(flares.size(), 1u);
    at = flares[0].position;
  }
  EXPECT_EQ(std::memcmp(&landed[0], &landed[1], sizeof(Vec3)), 0);
}

}  // namespace
}  // namespace grotto::play
