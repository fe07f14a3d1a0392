// The world's geology (common/cave/geology.hpp): a pure function of (world, position) that
// varies slowly by region, and the passage sections it gives portals, every one walkable.
#include "common/cave/geology.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <vector>

#include "common/cave/layout.hpp"

namespace grotto::cave {
namespace {

World world_of(uint64_t seed) {
  return World::create(seed, LayoutParams{}).value();
}

double angle_degrees(Vec3 a, Vec3 b) {
  double c = std::clamp(dot(a, b) / (length(a) * length(b)), -1.0, 1.0);
  return std::acos(c) * 180 / 3.14159265358979323846;
}

TEST(Geology, the_same_point_gives_the_same_rock_in_any_order_and_any_world_object) {
  const World a = world_of(7), b = world_of(7);
  const Vec3 points[] = {{10, 20, 30}, {-500.25, 47, 1200}, {6.0e6, -300, -6.0e6}};
  for (int round = 0; round < 2; ++round) {
    for (int i = round == 0 ? 0 : 2; round == 0 ? i < 3 : i >= 0; i += round == 0 ? 1 : -1) {
      Geology g = geology_at(a, points[i]), h = geology_at(b, points[i]);
      EXPECT_EQ(g.bed, h.bed);
      EXPECT_EQ(g.bedding_normal.x, h.bedding_normal.x);
      EXPECT_EQ(g.bedding_normal.z, h.bedding_normal.z);
      EXPECT_EQ(g.water_level, h.water_level);
      EXPECT_EQ(g.joints[0].normal.x, h.joints[0].normal.x);
    }
  }
  // Another seed is another rock.
  int differ = 0;
  for (const Vec3& p : points)
    differ += geology_at(world_of(8), p).bed != geology_at(a, p).bed;
  EXPECT_GT(differ, 0);
}

TEST(Geology, beds_joints_and_water_stay_within_their_ranges_everywhere) {
  const World w = world_of(95);
  for (int i = 0; i < 400; ++i) {
    const Vec3 p{i * 37.3 - 7000, (i % 23) * 11.1 - 100, i * -19.7 + 3e6};
    const Geology g = geology_at(w, p);
    EXPECT_NEAR(length(g.bedding_normal), 1.0, 1e-12);
    EXPECT_GT(g.bedding_normal.y, std::cos(25 * 3.14159265358979323846 / 180)) << "dip over 25 deg";
    EXPECT_GE(g.bed_thickness, 0.3 - 1e-9);
    EXPECT_LE(g.bed_thickness, 3.0 + 1e-9);
    EXPECT_GE(g.bed_depth, 0);
    EXPECT_LE(g.bed_depth, g.bed_thickness);
    EXPECT_GE(g.bed_hardness, 0);
    EXPECT_LE(g.bed_hardness, 1);
    ASSERT_TRUE(g.joint_count == 2 || g.joint_count == 3);
    for (int j = 0; j < g.joint_count; ++j) {
      EXPECT_NEAR(length(g.joints[j].normal), 1.0, 1e-9);
      EXPECT_EQ(g.joints[j].normal.y, 0) << "joint planes are steep";
      EXPECT_GT(g.joints[j].spacing, 0.3);
    }
    // The first two sets are nearly square to each other.
    EXPECT_NEAR(angle_degrees(g.joints[0].normal, g.joints[1].normal), 90, 16);
    EXPECT_EQ(g.phreatic, p.y < g.water_level);
    const double band = std::floor(p.y / 96.0) * 96.0;
    EXPECT_GE(g.water_level, band + 0.07 * 96 - 1e-9);
    EXPECT_LE(g.water_level, band + 0.77 * 96 + 1e-9);
  }
}

TEST(Geology, the_rock_varies_by_region_but_slowly) {
  const World w = world_of(7);
  // Within a few metres, the beds' pole turns by a fraction of a degree ...
  double most_turn = 0;
  for (int i = 0; i < 200; ++i) {
    const Vec3 p{i * 53.0, 40, i * -31.0};
    most_turn = std::max(most_turn, angle_degrees(geology_at(w, p).bedding_normal,
                                                  geology_at(w, p + Vec3{3, 0, 2}).bedding_normal));
  }
  EXPECT_LT(most_turn, 1.0);
  // ... while over kilometres the dip, the joints' strike and the water level all change.
  std::set<int> dips, strikes, levels;
  for (int i = 0; i < 60; ++i) {
    const Geology g = geology_at(w, {i * 397.0, 40, i * 211.0});
    dips.insert(static_cast<int>(g.dip_degrees / 2));
    strikes.insert(static_cast<int>(angle_degrees(g.joints[0].normal, {1, 0, 0}) / 20));
    levels.insert(static_cast<int>(g.water_level / 8));
  }
  EXPECT_GE(dips.size(), 3u);
  EXPECT_GE(strikes.size(), 4u);
  EXPECT_GE(levels.size(), 3u);
}

TEST(Geology, beds_are_counted_upwards_and_change_within_metres) {
  const World w = world_of(42);
  int64_t last = geology_at(w, {100, 0, 100}).bed;
  int changes = 0;
  for (double y = 0.1; y < 30; y += 0.1) {
    const int64_t bed = geology_at(w, {100, y, 100}).bed;
    EXPECT_GE(bed, last);
    changes += bed != last;
    last = bed;
  }
  // 30 m of rock in beds of 0.3-3 m.
  EXPECT_GE(changes, 10);
  EXPECT_LE(changes, 100);
}

// A portal's section for both of its sides, anywhere: the same shape, walkable, within reach.
TEST(PassageSections, both_sides_agree_and_every_section_is_walkable) {
  const World w = world_of(7);
  for (int i = 0; i < 2000; ++i) {
    const double t = i * 0.61803398875;
    const Vec3 centre{i * 13.7 - 9000, (i % 97) * 2.9, i * 7.3 + 123};
    const Vec3 normal = normalize(Vec3{std::cos(t * 6.28), (i % 7 - 3) * 0.45, std::sin(t * 6.28)});
    const double radius = 1.2 + (i % 9) * 0.25;
    const PassageSection a = passage_section(w, centre, normal, radius);
    const PassageSection b = passage_section(w, centre, -normal, radius);
    ASSERT_EQ(a.kind, b.kind);
    EXPECT_EQ(a.half_width, b.half_width);
    EXPECT_EQ(a.half_height, b.half_height);
    EXPECT_EQ(a.up.x, b.up.x);
    EXPECT_EQ(a.up.y, b.up.y);
    EXPECT_EQ(a.slot_depth, b.slot_depth);
    EXPECT_NEAR(length(a.up), 1.0, 1e-9);
    EXPECT_NEAR(dot(a.up, normal), 0.0, 1e-9) << "the section lies in the portal's plane";
    // The clear height and width with the rim's noise at its narrowest (0.88): a player 1.8 m
    // tall and 0.6 m wide fits.
    const double r = radius * 0.88;
    const double height = r * (a.half_height + std::max(a.half_height, a.slot_depth));
    const double width = 2 * r * std::max(a.half_width, a.slot_width);
    EXPECT_GE(height, 1.8) << section_kind_name(a.kind);
    EXPECT_GE(width, 0.8) << section_kind_name(a.kind);
    if (a.slot_depth > 0) {
      EXPECT_GE(2 * r * a.slot_width, 0.8) << "a slot's floor is wide enough to walk";
    }
    EXPECT_LE(a.half_width, 1.0);
    EXPECT_LE(a.half_height, 1.0);
    EXPECT_LE(section_reach(a), kMaxSectionReach + 1e-9);
    EXPECT_LE(section_narrow(a), 1.0);
    EXPECT_GT(section_perimeter(a), 0.5);
  }
}

// Over a region, level passages take every kind: tall ones (canyons, fissures), wide ones
// (lenses, no lower than about two thirds of their width), round ones; shafts are drawn out
// along the joints.
TEST(PassageSections, a_region_has_every_kind_of_passage) {
  const World w = world_of(95);
  std::map<SectionKind, int> level_kinds;
  int tall = 0, wide = 0, level = 0, long_shafts = 0;
  for (int i = 0; i < 3000; ++i) {
    const double t = i * 0.61803398875;
    const Vec3 centre{std::fmod(i * 37.1, 1500.0), (i % 61) * 3.1, std::fmod(i * 71.9, 1500.0)};
    const Vec3 normal{std::cos(t * 6.28), 0.1, std::sin(t * 6.28)};
    const PassageSection s = passage_section(w, centre, normalize(normal), 2.0);
    ++level;
    ++level_kinds[s.kind];
    tall += section_aspect(s) >= 1.6;
    wide += section_aspect(s) <= 0.76;
    long_shafts += section_aspect(passage_section(w, centre, {0.1, 1, 0}, 2.0)) >= 1.5;
  }
  for (SectionKind k : {SectionKind::kTube, SectionKind::kLens, SectionKind::kCanyon,
                        SectionKind::kKeyhole, SectionKind::kFissure}) {
    EXPECT_GT(level_kinds[k], level / 50) << section_kind_name(k);
  }
  EXPECT_GT(tall, level / 5);
  EXPECT_GT(wide, level / 20);
  EXPECT_GT(long_shafts, 3000 / 5);
}

// A hall's beds: the breaks between packages lie in order within the span, a package apart,
// each the base of a bed geology_at reports there, and they are the same however often asked.
TEST(Geology, bed_breaks_are_the_bases_of_the_beds_in_order_a_package_apart) {
  const World w = world_of(95);
  for (Vec3 p : {Vec3{49.5, 30, 46.5}, Vec3{-800, 12, 310}, Vec3{2000, -60, -75}}) {
    const std::vector<BedBreak> breaks = bed_breaks(w, p, 15, 18, 1.5, 16);
    ASSERT_GE(breaks.size(), 8u) << p.x;
    EXPECT_EQ(breaks.size(), bed_breaks(w, p, 15, 18, 1.5, 16).size());
    const Vec3 pole = geology_at(w, p).bedding_normal;
    for (size_t i = 0; i < breaks.size(); ++i) {
      EXPECT_GT(breaks[i].offset, -15);
      EXPECT_LT(breaks[i].offset, 18);
      EXPECT_GE(breaks[i].hardness, 0);
      EXPECT_LE(breaks[i].hardness, 1);
      if (i > 0) {
        EXPECT_GE(breaks[i].offset - breaks[i - 1].offset, 1.5 * 0.99);
      }
      // Either side of a break lie two beds (the planes through p leave the folded beds by a
      // few centimetres at the span's ends).
      const Geology above = geology_at(w, p + pole * (breaks[i].offset + 0.1));
      const Geology below = geology_at(w, p + pole * (breaks[i].offset - 0.1));
      EXPECT_NE(above.bed, below.bed) << i;
    }
  }
  EXPECT_LE(bed_breaks(w, {0, 0, 0}, 40, 40, 0.3, 16).size(), 16u);
}

}  // namespace
}  // namespace grotto::cave
