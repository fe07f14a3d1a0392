#include "common/cave/params.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

namespace grotto::cave {
namespace {

void expect_rejected(const std::function<void(LayoutParams&)>& spoil, const std::string& field) {
  LayoutParams p;
  spoil(p);
  Status s = validate(p);
  ASSERT_FALSE(s.ok()) << "accepted a spoiled " << field;
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(s.error().message.find(field), std::string::npos) << s.error().message;
}

TEST(LayoutParams, defaults_are_valid) {
  Status s = validate(LayoutParams{});
  EXPECT_TRUE(s.ok()) << s.error().message;
  for (const Character& c : LayoutParams::default_characters()) {
    EXPECT_TRUE(validate(LayoutParams::uniform(c)).ok()) << c.name;
  }
}

TEST(LayoutParams, bad_values_name_the_field) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  expect_rejected([](LayoutParams& p) { p.characters[0].small_radius_min = -2; },
                  "characters[0].small_radius_min");
  expect_rejected([&](LayoutParams& p) { p.characters[1].big_radius_max = nan; },
                  "characters[1].big_radius_max");
  expect_rejected([](LayoutParams& p) { p.characters[2].room_count = 0; },
                  "characters[2].room_count");
  expect_rejected([](LayoutParams& p) { p.characters[0].tunnel_chance = 1.5; },
                  "characters[0].tunnel_chance");
  expect_rejected([&](LayoutParams& p) { p.characters[0].big_probability = nan; },
                  "characters[0].big_probability");
  expect_rejected([](LayoutParams& p) { p.characters[1].big_probability = -0.1; },
                  "characters[1].big_probability");
  expect_rejected([](LayoutParams& p) { p.characters[1].bias = {0, 0, 0}; }, "characters[1].bias");
  expect_rejected(
      [&](LayoutParams& p) {
        p.characters[1].bias = {1, inf, 0};
      },
      "characters[1].bias");
  expect_rejected([](LayoutParams& p) { p.characters[2].big_radius_min = 20; },
                  "characters[2].big_radius_min");
  expect_rejected([](LayoutParams& p) { p.gates_min = 0; }, "gates_min");
  expect_rejected([](LayoutParams& p) { p.gates_max = 99; }, "gates_max");
  expect_rejected([](LayoutParams& p) { p.gate_radius_min = 6; }, "gate_radius_min");
  expect_rejected([&](LayoutParams& p) { p.sector_size = inf; }, "sector_size");
  expect_rejected([](LayoutParams& p) { p.sector_size = 30; }, "sector_size");
  expect_rejected([](LayoutParams& p) { p.min_portal_radius = 0; }, "min_portal_radius");
  expect_rejected([](LayoutParams& p) { p.wall_clearance = -1; }, "wall_clearance");
  expect_rejected([](LayoutParams& p) { p.region_scale = 0; }, "region_scale");
  expect_rejected([](LayoutParams& p) { p.region_sharpness = -1; }, "region_sharpness");
  expect_rejected([](LayoutParams& p) { p.link_radius_min = 0.5; }, "min_portal_radius");
  expect_rejected([](LayoutParams& p) { p.sector_size = 1e6; }, "sector_size must be at most");
  expect_rejected([](LayoutParams& p) { p.region_scale = 1e-20; }, "region_scale");
  expect_rejected([](LayoutParams& p) { p.portal_gap = 3; }, "portal_gap");
  expect_rejected([](LayoutParams& p) { p.min_portal_radius = 1.8; }, "min_portal_radius");
  expect_rejected([](LayoutParams& p) { p.ceiling_bend = 0; }, "ceiling_bend");
  expect_rejected([&](LayoutParams& p) { p.ceiling_spring = nan; }, "ceiling_spring");
  expect_rejected([](LayoutParams& p) { p.ceiling_spring = 0.8; }, "ceiling_spring");
  expect_rejected([](LayoutParams& p) { p.ceiling_rise = 0.3; }, "ceiling_rise");
  expect_rejected([](LayoutParams& p) { p.ceiling_spring = 0; },
                  "between floor and ceiling_spring");
  expect_rejected([](LayoutParams& p) { p.characters[2].hall_radius_max = 40; }, "for these halls");
}

TEST(SectorCharacter, weights_sum_to_one_and_vary_smoothly_over_space) {
  LayoutParams p;
  double max_step = 0, total_step = 0;
  int dominant_changes = 0;
  SectorCharacter previous = sector_character(9, p, {0, 0, 0});
  for (int x = 1; x < 60; ++x) {
    SectorCharacter c = sector_character(9, p, {x, 0, 0});
    double sum = 0;
    for (int k = 0; k < kCharacterCount; ++k) {
      sum += c.weights[k];
      double step = std::abs(c.weights[k] - previous.weights[k]);
      max_step = std::max(max_step, step);
      total_step += step / kCharacterCount;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    if (c.dominant() != previous.dominant()) ++dominant_changes;
    previous = c;
  }
  // Smooth: neighbouring sectors differ by a fraction; varied: the dominant kind changes.
  EXPECT_LT(max_step, 0.8);
  EXPECT_LT(total_step / 59, 0.15);
  EXPECT_GT(dominant_changes, 2);
}

TEST(SectorCharacter, every_kind_of_region_occurs) {
  LayoutParams p;
  int seen[kCharacterCount] = {};
  for (int x = -10; x < 10; ++x) {
    for (int z = -10; z < 10; ++z)
      ++seen[sector_character(3, p, {x, 0, z}).dominant()];
  }
  for (int k = 0; k < kCharacterCount; ++k)
    EXPECT_GT(seen[k], 10) << p.characters[k].name;
}

TEST(SectorCharacter, zero_sharpness_mixes_evenly) {
  LayoutParams p;
  p.region_sharpness = 0;
  SectorCharacter c = sector_character(3, p, {4, 5, 6});
  for (double w : c.weights)
    EXPECT_NEAR(w, 1.0 / kCharacterCount, 1e-12);
}

}  // namespace
}  // namespace grotto::cave
