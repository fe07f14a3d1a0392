// The world's lights (cave/lights.hpp): a pure function of (seed, room), inside their rooms,
// a few in every hall and rare elsewhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/cave/lights.hpp"

namespace grotto::cave {
namespace {

std::vector<unsigned char> bytes_of(const std::vector<WorldLight>& lights) {
  std::vector<unsigned char> out;
  auto put = [&](double v) {
    unsigned char b[sizeof v];
    std::memcpy(b, &v, sizeof v);
    out.insert(out.end(), b, b + sizeof v);
  };
  for (const WorldLight& l : lights) {
    out.push_back(static_cast<unsigned char>(l.kind));
    for (Vec3 v : {l.position, l.facing, l.colour})
      put(v.x), put(v.y), put(v.z);
    put(l.intensity), put(l.range), put(l.size);
  }
  return out;
}

// Sectors 0,0,0..1,0,1 (the block bench/hall_views.sh checks), for seeds with and without halls.
Region sample(uint64_t seed) {
  return generate_region(World::create(seed, LayoutParams{}).value(), {0, 0, 0}, {1, 0, 1});
}

TEST(WorldLights, same_seed_gives_the_same_lights_in_any_order) {
  const LayoutParams params;
  for (uint64_t seed : {3ull, 7ull, 95ull}) {
    const Region region = sample(seed);
    std::vector<std::vector<unsigned char>> forward, backward;
    for (const Room& r : region.rooms)
      forward.push_back(bytes_of(room_lights(seed, params, r)));
    for (auto it = region.rooms.rbegin(); it != region.rooms.rend(); ++it)
      backward.push_back(bytes_of(room_lights(seed, params, *it)));
    std::reverse(backward.begin(), backward.end());
    EXPECT_EQ(forward, backward) << "seed " << seed;
    // A room fetched on its own (as a server or an engine would) has the same lights.
    const World world = World::create(seed, params).value();
    for (size_t i = 0; i < region.rooms.size(); i += 7) {
      const Room alone = room(world, region.rooms[i].id).value();
      EXPECT_EQ(bytes_of(room_lights(seed, params, alone)), forward[i])
          << region.rooms[i].id.to_string();
    }
  }
}

TEST(WorldLights, another_seed_places_other_lights) {
  const LayoutParams params;
  const Region region = sample(95);
  size_t differ = 0, lit = 0;
  for (const Room& r : region.rooms) {
    const auto a = room_lights(95, params, r), b = room_lights(96, params, r);
    if (a.empty() && b.empty()) continue;
    ++lit;
    differ += bytes_of(a) != bytes_of(b);
  }
  ASSERT_GT(lit, 0u);
  EXPECT_EQ(differ, lit);
}

TEST(WorldLights, every_hall_has_three_to_six_lights_and_most_passages_none) {
  const LayoutParams params;
  int halls = 0, others = 0, lit_others = 0;
  for (uint64_t seed : {3ull, 7ull, 95ull}) {
    // 25 sectors a seed: a few dozen halls.
    const World world = World::create(seed, params).value();
    for (const Room& r : generate_region(world, {-2, 0, -2}, {2, 0, 2}).rooms) {
      const auto lights = room_lights(seed, params, r);
      if (floor_height(params, r.sphere)) {
        ++halls;
        EXPECT_GE(lights.size(), 3u) << r.id.to_string();
        EXPECT_LE(lights.size(), 6u) << r.id.to_string();
      } else {
        ++others;
        EXPECT_LE(lights.size(), 1u) << r.id.to_string();
        lit_others += !lights.empty();
      }
    }
  }
  ASSERT_GT(halls, 10) << "too few halls in the sample: the test checks little";
  std::printf("%d halls, %d other rooms of which %d lit\n", halls, others, lit_others);
  EXPECT_LT(lit_others, others / 5) << "most rooms without a floor stay dark";
}

TEST(WorldLights, lights_lie_inside_their_room_above_its_floor_and_clear_of_portals) {
  const LayoutParams params;
  const LightParams lp;
  size_t checked = 0, under_ceilings = 0;
  for (uint64_t seed : {3ull, 7ull, 95ull}) {
    for (const Room& r : sample(seed).rooms) {
      const auto floor = floor_height(params, r.sphere);
      for (const WorldLight& l : room_lights(seed, params, r)) {
        ++checked;
        EXPECT_TRUE(in_space(r, l.position)) << r.id.to_string();
        EXPECT_LT(distance(l.position, r.sphere.centre), r.sphere.radius) << r.id.to_string();
        if (floor) {
          EXPECT_GE(l.position.y, *floor + lp.floor_lift - 1e-9) << r.id.to_string();
        }
        // Under a hall's dome: below where the ceiling lowered the sphere's cap above it.
        if (const auto ceiling = room_ceiling(params, r.sphere)) {
          Vec3 d = l.position - r.sphere.centre;
          double cap = r.sphere.centre.y +
                       std::sqrt(r.sphere.radius * r.sphere.radius - d.x * d.x - d.z * d.z);
          EXPECT_LT(l.position.y, ceiling->lower(cap)) << r.id.to_string();
          ++under_ceilings;
        }
        for (const Portal& p : r.portals)
          EXPECT_GE(distance(l.position, p.centre), p.radius + lp.portal_clearance);
        EXPECT_NEAR(length(l.facing), 1.0, 1e-9);
        EXPECT_GT(l.intensity, 0);
        EXPECT_GE(l.range, lp.min_range);
        EXPECT_GT(l.size, 0);
        EXPECT_DOUBLE_EQ(std::max({l.colour.x, l.colour.y, l.colour.z}), 1.0);
      }
    }
  }
  EXPECT_GT(checked, 10u);
  EXPECT_GT(under_ceilings, 10u);
}

TEST(WorldLights, glow_worms_hang_on_ceilings_and_crystals_lie_low) {
  const LayoutParams params;
  int kinds[kLightKindCount] = {};
  for (uint64_t seed : {3ull, 7ull, 95ull}) {
    for (const Room& r : sample(seed).rooms) {
      for (const WorldLight& l : room_lights(seed, params, r)) {
        ++kinds[static_cast<int>(l.kind)];
        const double up = (l.position.y - r.sphere.centre.y) / r.sphere.radius;
        if (l.kind == LightKind::kGlowWorms) {
          EXPECT_GT(up, 0.3) << r.id.to_string();
        }
        if (l.kind == LightKind::kCrystals) {
          EXPECT_LT(up, 0.0) << r.id.to_string();
        }
      }
    }
  }
  for (int k = 0; k < kLightKindCount; ++k)
    EXPECT_GT(kinds[k], 0) << light_kind_name(static_cast<LightKind>(k));
}

// The falloff an engine matches (cave/lights.hpp): a hall's seams and crystals are sources metres
// across, so the rock beside one is lit as a wall a few metres from a point would be, not burnt
// white, while the hall's far wall keeps nearly all its light; glow-worm colonies keep their
// patch's width; a light reaches nothing at its range.
TEST(WorldLights,
     a_halls_lights_are_wide_sources_that_light_its_far_wall_and_spare_their_own_rock) {
  int hall_lights = 0;
  for (uint64_t seed : {3ull, 7ull, 95ull}) {
    const LayoutParams layout;
    for (const Room& room : sample(seed).rooms) {
      if (!floor_height(layout, room.sphere)) continue;
      for (const WorldLight& l : room_lights(seed, layout, room)) {
        ASSERT_GT(l.range, 0.0);
        EXPECT_EQ(light_falloff(l, l.range), 0.0);
        EXPECT_EQ(light_falloff(l, 2 * l.range), 0.0);
        for (double d = 0; d < l.range; d += 0.5)
          EXPECT_GE(light_falloff(l, d), light_falloff(l, d + 0.5));
        const double r = light_source_radius(l);
        if (l.kind == LightKind::kGlowWorms) {
          EXPECT_EQ(r, std::max(l.size, 1.0));
          continue;
        }
        ++hall_lights;
        // The light a point source would give at d, windowed alike.
        auto point = [&](double d) { return light_falloff(l, d) * (r * r + d * d) / (1 + d * d); };
        // Beside it (0.5 m), at most a tenth of what a point would burn into the rock...
        EXPECT_LT(light_falloff(l, 0.5), 0.1 * point(0.5)) << "range " << l.range;
        // ...at most 20 times what reaches across the hall, half its range off (a point: 100s of
        // times)...
        const double across = 0.5 * l.range;
        EXPECT_LT(light_falloff(l, 0.5), 20 * light_falloff(l, across)) << "range " << l.range;
        // ...and there the far wall keeps 90 % of a point's light.
        EXPECT_GT(light_falloff(l, across), 0.9 * point(across)) << "range " << l.range;
      }
    }
  }
  EXPECT_GE(hall_lights, 5);
}

}  // namespace
}  // namespace grotto::cave
