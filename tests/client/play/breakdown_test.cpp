// A hall's breakdown (common/formations/breakdown.cpp): the blocks fallen from its ceiling, as
// formation instances of kind kFormationBoulder, placed over the five largest halls of seeds 7
// and 95 in sectors 0,0,0..1,0,1 as a client holds them (the patch level, round-tripped through
// the room codec). Each hall has ten blocks of half a metre or more; every block rests on the
// floor the client draws, its bottom below the floor all round its edge; none comes within 2 m of
// a portal's rim; blocks barely overlap; a few are big and many small; placement is a pure
// function of the room; walkers collide with the blocks, step over small ones and go round big
// ones; a block has flat faces and a flat top, and its mesh faces outwards.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <optional>
#include <tuple>
#include <vector>

#include "client/play/collision.hpp"
#include "client/play/player.hpp"
#include "common/formations/formations.hpp"
#include "common/mesh/room_mesh.hpp"
#include "tests/client/ready_room.hpp"

namespace grotto::play {
namespace {

namespace fm = grotto::formations;

struct Hall {
  uint64_t seed = 0;
  stream::ReadyRoom room;
  std::vector<fm::FormationShape> placed;  // all its formations
  std::vector<fm::FormationShape> blocks;  // its boulders
};

std::vector<fm::FormationShape> place(const stream::ReadyRoom& room) {
  return fm::place(fm::surface_of(room.mesh, room.origin, room.room.sphere.radius));
}

std::vector<fm::FormationShape> boulders(const std::vector<fm::FormationShape>& all) {
  std::vector<fm::FormationShape> out;
  for (const fm::FormationShape& f : all)
    if (f.kind == fm::kFormationBoulder) out.push_back(f);
  return out;
}

// The rooms with a floor (cave::floor_height: halls, 18-29 m) of sectors 0,0,0..1,0,1 of each
// seed, largest first, built once: one a sector, the next largest rooms (9-12 m) have none.
const std::vector<Hall>& halls() {
  static const std::vector<Hall> all = [] {
    std::vector<Hall> out;
    for (uint64_t seed : {uint64_t{7}, uint64_t{95}}) {
      const cave::LayoutParams params{};
      const cave::World world = cave::World::create(seed, params).value();
      const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
      const cave::Region region = cave::generate_region(world, {0, 0, 0}, {1, 0, 1});
      std::vector<const cave::Room*> floored;
      for (const cave::Room& r : region.rooms)
        if (cave::floor_height(params, r.sphere)) floored.push_back(&r);
      std::sort(floored.begin(), floored.end(), [](const cave::Room* a, const cave::Room* b) {
        return std::tie(b->sphere.radius, a->id) < std::tie(a->sphere.radius, b->id);
      });
      EXPECT_EQ(floored.size(), 4u) << "seed " << seed << ": a hall a sector";
      for (size_t i = 0; i < floored.size(); ++i) {
        auto m = mesh::build_room_mesh(ctx, *floored[i], mesh::Lod::kPatch);
        EXPECT_TRUE(m.ok()) << floored[i]->id.to_string();
        if (!m.ok()) continue;
        Hall h;
        h.seed = seed;
        h.room = stream::test::ready_room(m.value(), *floored[i]);
        h.placed = place(h.room);
        h.blocks = boulders(h.placed);
        out.push_back(std::move(h));
      }
    }
    return out;
  }();
  return all;
}

std::string name(const Hall& h) {
  return "seed " + std::to_string(h.seed) + " " + h.room.room.id.to_string();
}

Vec3 world(const stream::ReadyRoom& room, glm::vec3 p) {
  return room.origin + Vec3{p.x, p.y, p.z};
}

// Where the vertical line through (x, z) meets the triangle, if it does.
std::optional<double> vertical_hit(const Triangle& t, double x, double z) {
  const double d = (t.b.x - t.a.x) * (t.c.z - t.a.z) - (t.c.x - t.a.x) * (t.b.z - t.a.z);
  if (std::abs(d) < 1e-14) return std::nullopt;
  const double u = ((x - t.a.x) * (t.c.z - t.a.z) - (t.c.x - t.a.x) * (z - t.a.z)) / d;
  const double v = ((t.b.x - t.a.x) * (z - t.a.z) - (x - t.a.x) * (t.b.z - t.a.z)) / d;
  // A little over the edges: a point on the edge two triangles share is on both, whatever the
  // rounding.
  if (u < -1e-6 || v < -1e-6 || u + v > 1 + 1e-6) return std::nullopt;
  return t.a.y + u * (t.b.y - t.a.y) + v * (t.c.y - t.a.y);
}

// The drawn floor (collision's surface: PN patches with the relief, no formations) under world
// (x, z) nearest to height y, within `reach` metres of it.
std::optional<double> floor_near(const CollisionWorld& rock, double x, double y, double z,
                                 double reach, Neighbourhood& near) {
  rock.gather({x - 0.01, y - reach, z - 0.01}, {x + 0.01, y + reach, z + 0.01}, near);
  std::optional<double> best;
  for (const Triangle& t : near.triangles)
    if (auto h = vertical_hit(t, x, z); h && std::abs(*h - y) <= reach)
      if (!best || std::abs(*h - y) < std::abs(*best - y)) best = h;
  return best;
}

// The block's plan at world angle a round its axis (boulder_plan is in its own frame).
float plan_at(const fm::FormationShape& f, float a) {
  return fm::boulder_plan(f, a - f.yaw);
}

TEST(Breakdown, every_hall_of_seeds_7_and_95_holds_ten_blocks_of_half_a_metre) {
  ASSERT_EQ(halls().size(), 8u);
  for (const Hall& h : halls()) {
    int big = 0, over_1 = 0, over_2 = 0;
    float largest = 0;
    for (const fm::FormationShape& f : h.blocks) {
      const float across = 2.0f * f.radius;
      big += across >= 0.5f;
      over_1 += across >= 1.0f;
      over_2 += across >= 2.0f;
      largest = std::max(largest, across);
    }
    std::printf(
        "%s (r %.1f m): %zu blocks, %d of 0.5 m or more, %d of 1 m, %d of 2 m, largest "
        "%.2f m\n",
        name(h).c_str(), h.room.room.sphere.radius, h.blocks.size(), big, over_1, over_2, largest);
    EXPECT_GE(big, 10) << name(h);
  }
}

// Few big, many small: of all the halls' blocks, most are under a metre across, and the tail
// reaches past 2 m.
TEST(Breakdown, a_few_blocks_are_big_and_many_small) {
  int small = 0, metre = 0, two = 0, all = 0;
  for (const Hall& h : halls())
    for (const fm::FormationShape& f : h.blocks) {
      const float across = 2.0f * f.radius;
      ++all;
      small += across < 1.0f;
      metre += across >= 1.0f;
      two += across >= 2.0f;
      EXPECT_GE(across, 0.3f - 1e-4f);
      EXPECT_LE(across, 4.0f + 1e-4f);
      // A slab: lower than it is wide.
      EXPECT_LT(f.length, 0.55f * across);
    }
  std::printf("%d blocks: %d under 1 m, %d of 1 m or more, %d of 2 m or more\n", all, small, metre,
              two);
  EXPECT_GT(small, 2 * metre);
  EXPECT_GT(two, 0);
  EXPECT_LT(two, all / 8);
}

// Every block rests on the floor the client draws (collision's surface: the PN patch with the
// relief at full strength, interpolated every ~14 cm, so up to ~8 cm off the exact surface the
// roots sit on): its root within 10 cm of it (a few cm at the median), and its bottom below it
// all round the edge of its plan, so no gap shows under it.
TEST(Breakdown, every_block_rests_on_the_drawn_floor_with_no_gap_under_it) {
  std::vector<double> off;
  size_t edges = 0, gaps = 0;
  for (const Hall& h : halls()) {
    CollisionWorld rock(1.0f, /*formations=*/false);
    rock.add(h.room);
    Neighbourhood near;
    for (const fm::FormationShape& f : h.blocks) {
      const Vec3 root = world(h.room, f.root);
      const std::optional<double> y = floor_near(rock, root.x, root.y, root.z, 0.5, near);
      ASSERT_TRUE(y.has_value()) << name(h) << ": no floor under the block at " << f.root.x << ","
                                 << f.root.z;
      off.push_back(std::abs(*y - root.y));
      EXPECT_LT(off.back(), 0.1) << name(h) << " block at " << f.root.x << "," << f.root.z;
      for (int k = 0; k < 16; ++k) {
        const float a = 6.2831853f * static_cast<float>(k) / 16.0f;
        const float r = 0.97f * plan_at(f, a);
        const Vec3 at = root + Vec3{r * std::cos(a), 0.0, r * std::sin(a)};
        const std::optional<double> ground =
            floor_near(rock, at.x, root.y, at.z, f.embed + f.length, near);
        ++edges;
        if (!ground || *ground < root.y - f.embed) {
          ++gaps;
          ADD_FAILURE() << name(h) << " block at " << f.root.x << "," << f.root.z << " side " << k
                        << ": its bottom (" << f.embed << " m down) is above the floor"
                        << (ground ? " at " + std::to_string(*ground - root.y) : " (none)") << " r "
                        << f.radius << " len " << f.length;
        }
      }
    }
  }
  ASSERT_FALSE(off.empty());
  std::sort(off.begin(), off.end());
  std::printf(
      "%zu blocks: root to the drawn floor median %.3f m, largest %.3f m; %zu of %zu "
      "points of their edges with a gap\n",
      off.size(), off[off.size() / 2], off.back(), gaps, edges);
  EXPECT_LT(off[off.size() / 2], 0.03);
}

// The nearest the hull of any of `blocks` (what walkers collide with, round what is drawn)
// comes to a vertex of one of the hall's portal rims (metres), and the block that does.
std::pair<double, const fm::FormationShape*> nearest_rim(
    const Hall& h, const std::vector<fm::FormationShape>& blocks) {
  std::vector<Vec3> rims;
  for (size_t v = 0; v < h.room.mesh.rim_portal.size(); ++v)
    if (h.room.mesh.rim_portal[v] >= 0) {
      const auto& p = h.room.mesh.positions[v];
      rims.push_back(world(h.room, glm::vec3(p.x, p.y, p.z)));
    }
  EXPECT_FALSE(rims.empty()) << name(h) << " has portals";
  std::pair<double, const fm::FormationShape*> nearest{1e30, nullptr};
  for (const fm::FormationShape& f : blocks) {
    const std::vector<glm::vec3> hull = fm::collision_hull(f);
    const Vec3 root = world(h.room, f.root);
    const double reach = f.radius + f.length + f.embed;
    for (const Vec3& q : rims) {
      if (distance(q, root) - reach > nearest.first) continue;
      for (size_t i = 0; i + 2 < hull.size(); i += 3) {
        const Triangle t{world(h.room, hull[i]), world(h.room, hull[i + 1]),
                         world(h.room, hull[i + 2])};
        const double d = distance(closest_point(t, q), q);
        if (d < nearest.first) nearest = {d, &f};
      }
    }
  }
  return nearest;
}

// Passages stay open: no block comes within 2 m of a portal's rim. A block moved to the floor
// under a rim's lowest vertex is found (the check can fail).
TEST(Breakdown, no_block_comes_within_2_m_of_a_portal_rim) {
  double nearest = 1e30;
  for (const Hall& h : halls()) {
    const auto [d, f] = nearest_rim(h, h.blocks);
    nearest = std::min(nearest, d);
    ASSERT_NE(f, nullptr) << name(h);
    EXPECT_GE(d, 2.0) << name(h) << " block at " << f->root.x << "," << f->root.z;
  }
  std::printf("the nearest any block comes to a portal's rim: %.2f m\n", nearest);

  const Hall& h = halls().front();
  ASSERT_FALSE(h.blocks.empty());
  glm::vec3 lowest(0.0f, 1e30f, 0.0f);
  for (size_t v = 0; v < h.room.mesh.rim_portal.size(); ++v) {
    const auto& p = h.room.mesh.positions[v];
    if (h.room.mesh.rim_portal[v] >= 0 && p.y < lowest.y) lowest = glm::vec3(p.x, p.y, p.z);
  }
  fm::FormationShape planted = h.blocks.front();
  planted.root = glm::vec3(lowest.x, planted.root.y, lowest.z);
  EXPECT_LT(nearest_rim(h, {planted}).first, 2.0) << "a block under a portal's rim";
}

// Blocks lie side by side, not through each other: where two plans overlap (points of a 16 x 16
// grid over one block's plan inside the other's), they share under a tenth of the smaller one.
TEST(Breakdown, blocks_barely_overlap_in_plan) {
  auto inside = [](const fm::FormationShape& f, float x, float z) {
    const float dx = x - f.root.x, dz = z - f.root.z;
    return std::hypot(dx, dz) < plan_at(f, std::atan2(dz, dx));
  };
  double worst = 0;
  for (const Hall& h : halls()) {
    for (size_t i = 0; i < h.blocks.size(); ++i)
      for (size_t j = 0; j < h.blocks.size(); ++j) {
        const fm::FormationShape &a = h.blocks[i], &b = h.blocks[j];
        if (i == j || a.radius > b.radius ||
            std::hypot(a.root.x - b.root.x, a.root.z - b.root.z) > a.radius + b.radius)
          continue;
        int in_a = 0, in_both = 0;
        for (int u = 0; u < 16; ++u)
          for (int v = 0; v < 16; ++v) {
            const float x = a.root.x + a.radius * (static_cast<float>(u) / 7.5f - 1.0f);
            const float z = a.root.z + a.radius * (static_cast<float>(v) / 7.5f - 1.0f);
            if (!inside(a, x, z)) continue;
            ++in_a;
            in_both += inside(b, x, z);
          }
        const double share = in_a > 0 ? static_cast<double>(in_both) / in_a : 0.0;
        worst = std::max(worst, share);
        EXPECT_LT(share, 0.1) << name(h) << " blocks at " << a.root.x << "," << a.root.z << " and "
                              << b.root.x << "," << b.root.z;
      }
  }
  std::printf("the most of a block's plan under another's: %.1f%%\n", 100 * worst);
}

// Placement is a pure function of the room's mesh: the same twice, bit for bit, and the same
// whatever order its triangles and their corners come in (another decoder's, another server's).
TEST(Breakdown, placement_is_the_same_every_time_and_whatever_the_order_of_the_triangles) {
  const auto fields = [](const std::vector<fm::FormationShape>& v) {
    std::vector<std::vector<float>> out;
    for (const fm::FormationShape& f : v)
      out.push_back({f.root.x, f.root.y, f.root.z, f.length, f.radius, f.tip, f.embed,
                     static_cast<float>(f.kind), f.taper, f.flare, f.rings, f.bulbs, f.seed,
                     f.yaw});
    return out;
  };
  for (const Hall& h : halls()) {
    const auto once = fields(h.blocks);
    EXPECT_EQ(once, fields(boulders(place(h.room)))) << name(h);
    if (h.room.room.id != cave::RoomId::interior({1, 0, 1}, 0)) continue;
    stream::ReadyRoom turned = h.room;
    const size_t triangles = turned.mesh.indices.size() / 3;
    ASSERT_EQ(std::gcd(triangles, size_t{7919}), 1u);
    std::vector<uint32_t> indices;
    for (size_t t = 0; t < triangles; ++t) {
      const size_t from = (t * 7919 + triangles / 3) % triangles;  // a permutation
      for (int k = 0; k < 3; ++k)
        indices.push_back(h.room.mesh.indices[3 * from + ((k + 1) % 3)]);
    }
    turned.mesh.indices = indices;
    EXPECT_EQ(once, fields(boulders(place(turned)))) << name(h) << ", its triangles turned";
  }
}

// A block is angular, not a pebble: round its side (a ring of its finest mesh, as formation.vert
// shades it) the normals come in flat faces (at least a third of the neighbouring points share a
// face's normal to within 2 degrees; a cylinder's turn 22.5 degrees each), and its top is flat-ish
// (most of it within 20 degrees of level, a broken corner steeper, nothing past 50 degrees).
TEST(Breakdown, a_block_has_flat_faces_and_a_flat_top) {
  int checked = 0;
  for (const Hall& h : halls())
    for (const fm::FormationShape& f : h.blocks) {
      if (checked++ >= 60) break;
      std::vector<glm::vec3> positions, normals;
      std::vector<uint32_t> indices;
      fm::append_mesh(f, 0, positions, normals, indices);
      const int sides = fm::kLodSides[0], rings = fm::kLodRings[0];
      ASSERT_EQ(positions.size(), static_cast<size_t>((rings + 1) * (sides + 1)));
      // The side: the ring a sixth of the way along (on the side, above the floor for all but
      // the flattest); the top: the rings from 60 % on.
      const int side_ring = rings / 6;
      int flat = 0;
      for (int k = 0; k < sides; ++k) {
        const glm::vec3 a = normals[static_cast<size_t>(side_ring * (sides + 1) + k)];
        const glm::vec3 b = normals[static_cast<size_t>(side_ring * (sides + 1) + k + 1)];
        flat += glm::dot(a, b) > std::cos(2.0f * 3.14159265f / 180.0f);
      }
      EXPECT_GE(flat, sides / 3) << name(h) << " block at " << f.root.x << "," << f.root.z;
      int level = 0, top = 0;
      float steepest = 0;
      for (int i = rings * 6 / 10; i <= rings; ++i)
        for (int k = 0; k < sides; ++k) {
          const float slope =
              std::acos(
                  std::clamp(normals[static_cast<size_t>(i * (sides + 1) + k)].y, -1.0f, 1.0f)) *
              180.0f / 3.14159265f;
          ++top;
          level += slope < 20.0f;
          steepest = std::max(steepest, slope);
        }
      EXPECT_GT(level, top * 6 / 10) << name(h) << " block at " << f.root.x << "," << f.root.z;
      EXPECT_LT(steepest, 50.0f) << name(h) << " block at " << f.root.x << "," << f.root.z;
      // Facing outwards: every triangle with area faces the way its corners' normals do.
      size_t agree = 0, faces = 0;
      for (size_t i = 0; i + 2 < indices.size(); i += 3) {
        const glm::vec3 a = positions[indices[i]], b = positions[indices[i + 1]],
                        c = positions[indices[i + 2]];
        const glm::vec3 n = glm::cross(b - a, c - a);
        if (glm::length(n) < 1e-10f) continue;
        ++faces;
        agree += glm::dot(n, normals[indices[i]] + normals[indices[i + 1]] +
                                 normals[indices[i + 2]]) > 0;
      }
      EXPECT_GT(static_cast<double>(agree), 0.98 * static_cast<double>(faces));
    }
  EXPECT_GT(checked, 30);
}

// Walkers and flares collide with every block (a segment from beside its side, halfway up, to
// its axis meets its hull); a walker steps onto a block lower than its step and over it, and
// goes round one over 0.8 m high or stops at it, never into it or onto it.
TEST(Breakdown, walkers_step_over_small_blocks_and_go_round_big_ones) {
  int tested = 0;
  for (const Hall& h : halls()) {
    CollisionWorld with(1.0f, true);
    with.add(h.room);
    Neighbourhood near;
    for (const fm::FormationShape& f : h.blocks) {
      const glm::vec3 mid = f.root + glm::vec3(0.0f, 0.5f * f.length, 0.0f);
      const glm::vec3 beside(1.5f * plan_at(f, 0.0f) + 0.05f, 0.0f, 0.0f);
      ++tested;
      with.gather(world(h.room, mid), world(h.room, mid + beside), near);
      const bool meets =
          std::any_of(near.triangles.begin(), near.triangles.end(), [&](const auto& t) {
            return segment_crosses(t, world(h.room, mid + beside), world(h.room, mid));
          });
      EXPECT_TRUE(meets) << name(h) << " block at " << f.root.x << "," << f.root.z;
    }
  }
  EXPECT_GT(tested, 100);

  // A walk across a block, from 2 m before its edge to half a metre past it, along a line that no
  // other block or stalagmite comes within 0.7 m of (up to the block's middle, for a big one).
  struct Walk {
    bool found = false;
    double closest = 1e9;   // horizontal metres from the eye to the block's axis
    double highest = -1e9;  // the feet's greatest height over the block's root
    double left = 1e9;      // metres from the far end at the end
  };
  auto walk = [&](const Hall& h, const fm::FormationShape& f, bool big) {
    Walk out;
    const std::vector<fm::FormationShape>& all = h.placed;
    // 32 ways across it: stalagmites gather along drip lines, and a heap's blocks lie close.
    for (int k = 0; k < 32 && !out.found; ++k) {
      const float a = 0.19634954f * static_cast<float>(k);
      const glm::vec2 d(std::cos(a), std::sin(a));
      const glm::vec2 c(f.root.x, f.root.z);
      const glm::vec2 from = c - d * (f.radius + 2.0f), to = c + d * (f.radius + 0.5f);
      // A big block stops the walker: only the way to it need be clear.
      const glm::vec2 until = big ? c : to;
      bool clear = true;
      for (const fm::FormationShape& g : all) {
        if (&g == &f || g.root == f.root || g.kind == fm::kFormationStalactite ||
            g.kind == fm::kFormationDrapery)
          continue;
        const glm::vec2 q(g.root.x, g.root.z);
        const float t = std::clamp(
            glm::dot(q - from, until - from) / glm::dot(until - from, until - from), 0.0f, 1.0f);
        if (glm::distance(q, from + t * (until - from)) < fm::formation_bound_radius(g) + 0.7f)
          clear = false;
      }
      if (!clear) continue;
      CollisionWorld collide(1.0f, true);
      collide.add(h.room);
      const Vec3 start = world(h.room, glm::vec3(from.x, f.root.y + 2.0f, from.y));
      const Vec3 end = world(h.room, glm::vec3(to.x, f.root.y, to.y));
      const Vec3 root = world(h.room, f.root);
      Player p(start);
      for (int i = 0; i < 240 && !p.grounded(); ++i)
        p.step({}, collide);
      // The walk starts on the floor the block rests on, level with its root: not over a shaft
      // in the floor, not on a bank above it (the floor follows the rock, not a plane).
      const double feet = p.spheres()[0].y - p.params().radius - root.y;
      if (!p.grounded() || std::abs(feet) > 0.3) continue;
      out.found = true;
      for (int i = 0; i < 5 * 120; ++i) {
        PlayerInput in;
        in.move = Vec3{end.x - p.eye().x, 0, end.z - p.eye().z};
        if (std::hypot(in.move.x, in.move.z) < 0.3) break;
        p.step(in, collide);
        out.closest = std::min(out.closest, std::hypot(p.eye().x - root.x, p.eye().z - root.z));
        out.highest = std::max(out.highest, p.spheres()[0].y - p.params().radius - root.y);
      }
      out.left = std::hypot(end.x - p.eye().x, end.z - p.eye().z);
    }
    return out;
  };
  int small = 0, big = 0;
  for (const Hall& h : halls()) {
    for (const fm::FormationShape& f : h.blocks) {
      const bool low = f.length + f.taper * f.radius < 0.25f && f.radius > 0.2f;
      const bool tall = f.length > 0.8f;
      if (!(low && small < 3) && !(tall && big < 3)) continue;
      const Walk w = walk(h, f, tall);
      if (!w.found) continue;
      std::printf(
          "%s: a %.2f m block %.2f m high: feet up to %.2f m over its root, the eye "
          "%.2f m from its axis at the closest, %.2f m left\n",
          name(h).c_str(), 2 * f.radius, f.length, w.highest, w.closest, w.left);
      if (low) {
        ++small;
        EXPECT_LT(w.left, 0.5) << "walked over it";
        EXPECT_GT(w.highest, 0.3 * f.length) << "over it, not through it";
      } else {
        ++big;
        // Round it or stopped at it, never into it: the eye (0.5 m of body round it) stays
        // outside the plan's nearest side.
        float inside = 1e9f;
        for (int k = 0; k < 32; ++k)
          inside = std::min(inside, plan_at(f, 6.2831853f * static_cast<float>(k) / 32.0f));
        EXPECT_GT(w.closest, inside + 0.3) << "not through it";
        // A leaning side may lift the body a little; never onto the block's top.
        EXPECT_LT(w.highest, 0.5 * f.length) << "not onto it";
      }
    }
  }
  EXPECT_EQ(small, 3);
  EXPECT_EQ(big, 3);
}

}  // namespace
}  // namespace grotto::play
