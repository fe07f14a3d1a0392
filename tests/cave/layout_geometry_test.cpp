// Geometry of rooms and portals (thesis §3.1.2, Figure 3-2), checked from first principles over
// 2x2x2 blocks of sectors for several seeds (two of them once broke gate and face rules), across
// sector faces included.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "common/cave/layout.hpp"

namespace grotto::cave {
namespace {

class LayoutGeometry : public ::testing::TestWithParam<uint64_t> {
 protected:
  void SetUp() override {
    static std::map<uint64_t, std::pair<World, Region>> cache;
    auto it = cache.find(GetParam());
    if (it == cache.end()) {
      World w = World::create(GetParam(), LayoutParams{}).value();
      Region r = generate_region(w, {0, 0, 0}, {1, 1, 1});
      it = cache.emplace(GetParam(), std::pair{w, std::move(r)}).first;
    }
    world_ = &it->second.first;
    region_ = &it->second.second;
  }

  // Pairs of rooms whose spheres come within `reach` metres of each other.
  template <typename F>
  void for_each_close_pair(double reach, F&& f) const {
    const double cell = 32.0;
    std::map<std::tuple<int, int, int>, std::vector<const Room*>> grid;
    auto key = [&](Vec3 p) {
      return std::tuple<int, int, int>{static_cast<int>(std::floor(p.x / cell)),
                                       static_cast<int>(std::floor(p.y / cell)),
                                       static_cast<int>(std::floor(p.z / cell))};
    };
    for (const Room& r : region_->rooms)
      grid[key(r.sphere.centre)].push_back(&r);
    for (const Room& a : region_->rooms) {
      auto [kx, ky, kz] = key(a.sphere.centre);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            auto it = grid.find({kx + dx, ky + dy, kz + dz});
            if (it == grid.end()) continue;
            for (const Room* b : it->second) {
              if (!(a.id < b->id)) continue;
              double d = distance(a.sphere.centre, b->sphere.centre);
              if (d < a.sphere.radius + b->sphere.radius + reach) f(a, *b, d);
            }
          }
    }
  }

  static const Portal* portal_to(const Room& r, RoomId id) {
    for (const Portal& p : r.portals) {
      if (p.neighbour == id) return &p;
    }
    return nullptr;
  }

  const World* world_ = nullptr;
  const Region* region_ = nullptr;
};

INSTANTIATE_TEST_SUITE_P(Seeds, LayoutGeometry, ::testing::Values(2024u, 40u, 154u));

TEST_P(LayoutGeometry, region_is_substantial) {
  EXPECT_GT(region_->rooms.size(), 500u);
  size_t gates = 0;
  for (const Room& r : region_->rooms)
    gates += r.id.is_gate();
  EXPECT_GT(gates, 30u);
}

TEST_P(LayoutGeometry, portal_is_the_intersection_circle_of_the_two_spheres) {
  size_t checked = 0;
  for (const Room& r : region_->rooms) {
    for (const Portal& p : r.portals) {
      const Room* n = region_->find(p.neighbour);
      if (!n) continue;  // leads out of the block
      Vec3 v = n->sphere.centre - r.sphere.centre;
      double d = length(v);
      double r1 = r.sphere.radius, r2 = n->sphere.radius;
      double pd = (d * d + r1 * r1 - r2 * r2) / (2 * d);  // cosine rule
      Vec3 centre = r.sphere.centre + v * (pd / d);
      double radius = std::sqrt(r1 * r1 - pd * pd);
      EXPECT_NEAR(distance(p.centre, centre), 0.0, 1e-9);
      EXPECT_NEAR(p.radius, radius, 1e-9);
      EXPECT_NEAR(distance(p.normal, v / d), 0.0, 1e-12);
      // Every point of the rim lies on both spheres.
      EXPECT_NEAR(p.radius * p.radius + length_squared(p.centre - r.sphere.centre), r1 * r1, 1e-8);
      EXPECT_NEAR(p.radius * p.radius + length_squared(p.centre - n->sphere.centre), r2 * r2, 1e-8);
      // The neighbour sees the same disc, bit for bit, facing the other way.
      const Portal* back = portal_to(*n, r.id);
      ASSERT_NE(back, nullptr) << r.id.to_string() << " -> " << n->id.to_string();
      EXPECT_EQ(back->centre, p.centre);
      EXPECT_EQ(back->radius, p.radius);
      EXPECT_EQ(back->normal, -p.normal);
      ++checked;
    }
  }
  EXPECT_GT(checked, 500u);
}

TEST_P(LayoutGeometry, portals_respect_the_minimum_radius_and_count) {
  for (const Room& r : region_->rooms) {
    EXPECT_LE(r.portals.size(), static_cast<size_t>(kMaxPortalsPerRoom)) << r.id.to_string();
    for (const Portal& p : r.portals) {
      EXPECT_GE(p.radius, world_->params().min_portal_radius) << r.id.to_string();
    }
  }
}

TEST_P(LayoutGeometry, no_point_of_a_portal_comes_within_the_gap_of_a_third_sphere) {
  const double gap = world_->params().portal_gap;
  size_t pairs = 0;
  auto disc_distance = [](Vec3 q, const Portal& p) {
    Vec3 rel = q - p.centre;
    double h = dot(rel, p.normal);
    double radial = std::max(0.0, length(rel - p.normal * h) - p.radius);
    return std::sqrt(h * h + radial * radial);
  };
  for (const Room& r : region_->rooms) {
    for (const Portal& p : r.portals) {
      if (!(r.id < p.neighbour)) continue;
      for (const Room& k : region_->rooms) {
        if (k.id == r.id || k.id == p.neighbour) continue;
        if (distance(k.sphere.centre, p.centre) > k.sphere.radius + p.radius + 1.0) continue;
        ++pairs;
        EXPECT_GT(disc_distance(k.sphere.centre, p), k.sphere.radius + gap - 1e-9)
            << "portal " << r.id.to_string() << "/" << p.neighbour.to_string() << " touches "
            << k.id.to_string();
      }
    }
  }
  RecordProperty("third_sphere_candidates", static_cast<int>(pairs));
}

TEST_P(LayoutGeometry, portals_of_one_room_are_disjoint_with_wall_between) {
  const double gap = world_->params().portal_gap;
  size_t pairs = 0;
  for (const Room& r : region_->rooms) {
    const double R = r.sphere.radius;
    for (size_t i = 0; i < r.portals.size(); ++i) {
      for (size_t j = i + 1; j < r.portals.size(); ++j) {
        const Portal& a = r.portals[i];
        const Portal& b = r.portals[j];
        Vec3 ua = normalize(a.centre - r.sphere.centre), ub = normalize(b.centre - r.sphere.centre);
        double angle = std::acos(std::clamp(dot(ua, ub), -1.0, 1.0));
        double half_a = std::asin(std::min(1.0, a.radius / R));
        double half_b = std::asin(std::min(1.0, b.radius / R));
        EXPECT_GT(angle, half_a + half_b + std::asin(std::min(1.0, gap / R)) - 1e-9)
            << r.id.to_string() << " portals to " << a.neighbour.to_string() << " and "
            << b.neighbour.to_string();
        ++pairs;
      }
    }
  }
  EXPECT_GT(pairs, 50u);
}

TEST_P(LayoutGeometry, spheres_either_share_a_portal_or_keep_clear) {
  const double clearance = world_->params().wall_clearance;
  size_t overlapping = 0;
  for_each_close_pair(clearance, [&](const Room& a, const Room& b, double d) {
    bool overlap = d < a.sphere.radius + b.sphere.radius;
    EXPECT_TRUE(overlap) << a.id.to_string() << " and " << b.id.to_string() << " nearly touch: gap "
                         << d - a.sphere.radius - b.sphere.radius;
    if (overlap) {
      ++overlapping;
      EXPECT_NE(portal_to(a, b.id), nullptr) << a.id.to_string() << " / " << b.id.to_string();
      EXPECT_NE(portal_to(b, a.id), nullptr) << b.id.to_string() << " / " << a.id.to_string();
    }
  });
  EXPECT_GT(overlapping, 400u);
}

TEST_P(LayoutGeometry, rooms_stay_in_their_sector_and_gates_on_their_face) {
  const double size = world_->params().sector_size;
  for (const Room& r : region_->rooms) {
    SectorCoord s = r.id.sector();
    for (int a = 0; a < 3; ++a) {
      double lo = s[a] * size, hi = lo + size;
      if (r.id.is_gate() && a == r.id.gate_axis()) {
        EXPECT_EQ(r.sphere.centre[a], hi) << r.id.to_string();
      } else {
        EXPECT_GE(r.sphere.centre[a] - r.sphere.radius, lo) << r.id.to_string();
        EXPECT_LE(r.sphere.centre[a] + r.sphere.radius, hi) << r.id.to_string();
      }
    }
  }
}

// Big rooms have floors (the mesh rests their wall on a plane), so the layout opens no portal of
// theirs below it: a passage leaving a hall starts above its floor.
TEST_P(LayoutGeometry, no_portal_opens_below_a_floor) {
  int floored = 0;
  for (const Room& r : region_->rooms) {
    std::optional<double> floor = floor_height(world_->params(), r.sphere);
    if (!floor) {
      EXPECT_LT(r.sphere.radius, world_->params().floor_min_radius) << r.id.to_string();
      continue;
    }
    ++floored;
    EXPECT_NEAR(*floor, r.sphere.centre.y - world_->params().floor_depth * r.sphere.radius, 1e-9);
    for (const Portal& p : r.portals) {
      double lowest =
          p.centre.y - p.radius * std::sqrt(std::max(0.0, 1.0 - p.normal.y * p.normal.y));
      EXPECT_GE(lowest, *floor + world_->params().wall_clearance)
          << r.id.to_string() << " -> " << p.neighbour.to_string();
    }
  }
  EXPECT_GT(floored, 0) << "the region should hold rooms with floors";
}

// ... and ceilings (the mesh lowers the wall above the spring onto a low dome), so no portal of
// theirs reaches above the spring: a rim stays where the layout put it.
TEST_P(LayoutGeometry, no_portal_opens_above_a_ceilings_spring) {
  int ceilinged = 0;
  for (const Room& r : region_->rooms) {
    std::optional<Ceiling> ceiling = room_ceiling(world_->params(), r.sphere);
    EXPECT_EQ(ceiling.has_value(), floor_height(world_->params(), r.sphere).has_value())
        << r.id.to_string();
    if (!ceiling) continue;
    ++ceilinged;
    for (const Portal& p : r.portals) {
      double highest =
          p.centre.y + p.radius * std::sqrt(std::max(0.0, 1.0 - p.normal.y * p.normal.y));
      EXPECT_LE(highest, ceiling->spring) << r.id.to_string() << " -> " << p.neighbour.to_string();
    }
  }
  EXPECT_GT(ceilinged, 0) << "the region should hold rooms with ceilings";
}

// The ceiling's profile: the sphere below the spring untouched, its top at ceiling_rise x radius
// above the centre, a smooth shoulder (the ramp's slope is continuous at both ends of the bend)
// and heights kept in order (the dome never folds over).
TEST(Ceiling, lowers_the_cap_onto_a_dome_of_the_rise_asked_for) {
  LayoutParams params;
  Sphere hall{{10, 50, -20}, 30};
  std::optional<Ceiling> c = room_ceiling(params, hall);
  ASSERT_TRUE(c.has_value());
  EXPECT_DOUBLE_EQ(c->spring, 50 + params.ceiling_spring * 30);
  EXPECT_DOUBLE_EQ(c->lower(c->spring), c->spring);
  EXPECT_DOUBLE_EQ(c->lower(40.0), 40.0);
  EXPECT_NEAR(c->lower(80.0), 50 + params.ceiling_rise * 30, 1e-9);
  double last = c->lower(c->spring - 1);
  for (double y = c->spring - 1; y <= 80.0; y += 0.01) {
    double lowered = c->lower(y);
    EXPECT_GE(lowered, last - 1e-12) << y;
    EXPECT_LE(lowered, y) << y;
    last = lowered;
  }
  const double h = 1e-6;
  for (double joint : {c->spring, c->spring + c->bend}) {
    double below = (c->lower(joint) - c->lower(joint - h)) / h;
    double above = (c->lower(joint + h) - c->lower(joint)) / h;
    EXPECT_NEAR(below, above, 1e-4) << joint;
  }
  // Rooms without floors have none; ceiling_rise >= 1 turns them off.
  EXPECT_FALSE(room_ceiling(params, Sphere{{0, 0, 0}, params.floor_min_radius - 1}));
  params.ceiling_rise = 1;
  EXPECT_FALSE(room_ceiling(params, hall));
}

// The cavern character links every sector's gates through a hall: its hub is a room of the
// hall radii, with a floor, joined to the cave.
TEST(Halls, every_cavern_sector_is_linked_through_a_hall) {
  const Character caverns = LayoutParams::default_characters()[2];
  ASSERT_EQ(caverns.hall_probability, 1.0);
  World w = World::create(7, LayoutParams::uniform(caverns)).value();
  for (int x = 0; x < 4; ++x) {
    SectorLayout s = generate_sector(w, {x, 0, -x});
    ASSERT_FALSE(s.rooms.empty());
    const Room& hub = s.rooms[0];
    EXPECT_GE(hub.sphere.radius, caverns.hall_radius_min) << hub.id.to_string();
    EXPECT_LE(hub.sphere.radius, caverns.hall_radius_max) << hub.id.to_string();
    EXPECT_TRUE(floor_height(w.params(), hub.sphere).has_value());
    EXPECT_GE(hub.portals.size(), 1u) << hub.id.to_string();
  }
}

// Without halls the hub is one of the character's big rooms.
TEST(Halls, a_character_without_halls_has_none) {
  Character maze = LayoutParams::default_characters()[0];
  maze.hall_probability = 0.0;
  World w = World::create(7, LayoutParams::uniform(maze)).value();
  for (int x = 0; x < 4; ++x) {
    SectorLayout s = generate_sector(w, {x, 0, 0});
    for (const Room& r : s.rooms)
      EXPECT_LE(r.sphere.radius, maze.big_radius_max);
  }
}

}  // namespace
}  // namespace grotto::cave
