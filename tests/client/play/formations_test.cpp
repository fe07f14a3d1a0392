// The formations as instanced geometry (shaders/formations.hpp, issue 43), placed over real rooms
// of seed 7 as a client holds them (sector 0,0,0 at the patch level, round-tripped through the
// room codec; its room r0 is a hall): every root meets the rock it grows from (no gap), each
// hangs or stands plumb, stalagmites stand under their drip points and differ, lengths run from
// soda straws to metres, placement is a pure function of the room, walkers collide with them and
// a stalactite 3 m away gets a fine mesh.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <tuple>
#include <vector>

#include "cave.hpp"
#include "client/play/collision.hpp"
#include "shaders/formations.hpp"

namespace grotto::play {
namespace {

namespace fm = grotto::formations;

std::vector<fm::FormationShape> place(const client::ReadyRoom& room) {
  return fm::place(fm::surface_of(room.mesh, room.origin, room.room.sphere.radius));
}

const client::ReadyRoom& hall() {
  return test::sector_zero().rooms.at(cave::RoomId::interior({0, 0, 0}, 0));
}

Vec3 world(const client::ReadyRoom& room, glm::vec3 p) {
  return room.origin + Vec3{p.x, p.y, p.z};
}

// Whether p lies behind the nearest rock (the rock's normals face into the cave): inside it.
bool in_rock(const CollisionWorld& rock, Vec3 p, Neighbourhood& near) {
  rock.gather(p - Vec3{1, 1, 1}, p + Vec3{1, 1, 1}, near);
  double best = 1e300;
  bool inside = false;
  for (const Triangle& t : near.triangles) {
    const Vec3 c = closest_point(t, p);
    const double d = length_squared(p - c);
    if (d < best) best = d, inside = dot(p - c, unit_normal(t)) < 0;
  }
  return inside;
}

// No root floats. On the axis, the rock the client draws (collision's surface: the PN patch with
// the relief at full strength, no formations) lies between the mesh's end inside the rock
// (-embed) and the tip; round the root, where the flare is widest (eight sides), every point at
// the root's level that is in the cave has rock between it and the mesh's end: otherwise the
// open end would show in the air. (Collision's surface interpolates the relief every ~14 cm, so
// it lies up to ~8 cm off the exact surface the roots sit on: the tip of a 5 cm straw may end
// inside it: fewer than a tenth end more than kInterpolation inside it.)
constexpr float kInterpolation = 0.1f;
TEST(Formations, every_root_meets_the_rock_it_grows_from) {
  size_t checked = 0, gaps = 0, buried = 0;
  for (const auto& [id, room] : test::sector_zero().rooms) {
    CollisionWorld rock(1.0f, /*formations=*/false);
    rock.add(room);
    Neighbourhood near;
    auto crosses = [&](Vec3 a, Vec3 b) {
      const Vec3 lo{std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
      const Vec3 hi{std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
      rock.gather(lo, hi, near);
      return std::any_of(near.triangles.begin(), near.triangles.end(),
                         [&](const Triangle& t) { return segment_crosses(t, a, b); });
    };
    for (const fm::FormationShape& f : place(room)) {
      const float dir = fm::formation_direction(f);
      const glm::vec3 end = glm::vec3(0.0f, -dir * f.embed, 0.0f);
      for (int k = 0; k <= 8; ++k) {
        ++checked;
        bool meets = true;
        if (k == 8) {
          // Rock anywhere past the mesh's end: none floats. Past the tip (and collision's
          // interpolation): buried, counted.
          meets = crosses(world(room, f.root + end),
                          world(room, f.root + glm::vec3(0.0f, dir * (f.length + 1.0f), 0.0f)));
          buried += !crosses(
              world(room, f.root + end),
              world(room, f.root + glm::vec3(0.0f, dir * (f.length + kInterpolation), 0.0f)));
        } else {
          const float theta = 6.2831853f * static_cast<float>(k) / 8.0f;
          const float r = 0.95f * fm::formation_radius(f, 0.0f, theta);
          const glm::vec3 at =
              f.root + glm::vec3(r * std::cos(theta + f.yaw), 0.0f, r * std::sin(theta + f.yaw));
          if (!in_rock(rock, world(room, at), near))
            meets = crosses(world(room, at + end), world(room, at));
        }
        if (!meets) {
          ++gaps;
          ADD_FAILURE() << "room " << id.to_string() << " kind " << f.kind << " root " << f.root.x
                        << "," << f.root.y << "," << f.root.z << " radius " << f.radius << " side "
                        << k << ": no rock within " << f.embed << " m of its root";
          if (gaps > 5) return;
        }
      }
    }
  }
  std::printf("%zu root samples, %zu gaps; %zu of %zu formations end inside collision's rock\n",
              checked, gaps, buried, checked / 9);
  EXPECT_GT(checked, 9u * 100u) << "sector 0 has a hundred formations at least";
  EXPECT_LT(buried, checked / 9 / 10) << "a tenth of the formations or more are buried";
}

// The axis through the centroids of the rings stays within 3 degrees of vertical: the lobes and
// rings that make each its own do not lean it.
TEST(Formations, each_hangs_or_stands_within_3_degrees_of_plumb) {
  const std::vector<fm::FormationShape> all = place(hall());
  ASSERT_FALSE(all.empty());
  double worst = 0;
  for (const fm::FormationShape& f : all) {
    auto centroid = [&](float s) {
      glm::vec3 c(0.0f);
      for (int k = 0; k < 64; ++k)
        c += fm::formation_point(f, s, 6.2831853f * static_cast<float>(k) / 64.0f);
      return c / 64.0f;
    };
    const glm::vec3 a = centroid(0.05f * f.length), b = centroid(0.85f * f.length);
    const glm::vec3 d = b - a;
    const double tilt = std::atan2(std::hypot(d.x, d.z), std::abs(d.y)) * 180.0 / 3.14159265358979;
    worst = std::max(worst, tilt);
  }
  std::printf("%zu formations, the most tilted %.3f degrees\n", all.size(), worst);
  EXPECT_LT(worst, 3.0);
}

TEST(Formations, lengths_run_from_soda_straws_to_metres_in_a_hall) {
  std::vector<float> lengths;
  int straws = 0, columns = 0, stalagmites = 0;
  for (const fm::FormationShape& f : place(hall())) {
    if (f.kind == fm::kFormationStalactite) {
      lengths.push_back(f.length);
      straws += f.radius < 0.005f && f.tip == f.radius;
    }
    columns += f.kind == fm::kFormationColumn;
    stalagmites += f.kind == fm::kFormationStalagmite;
  }
  ASSERT_GT(lengths.size(), 50u);
  std::sort(lengths.begin(), lengths.end());
  const float median = lengths[lengths.size() / 2], longest = lengths.back();
  std::printf(
      "hall: %zu stalactites (%d soda straws, median %.2f m, longest %.2f m), %d "
      "stalagmites, %d columns\n",
      lengths.size(), straws, median, longest, stalagmites, columns);
  EXPECT_GE(longest / median, 5.0f);
  EXPECT_GT(longest, 1.0f);
  EXPECT_GT(straws, 5);
  EXPECT_GT(stalagmites, 10);
}

// A stalagmite grows where its stalactite drips: same x and z. Neighbours are not copies: their
// heights spread (coefficient of variation over 0.3) and their forms differ.
TEST(Formations, stalagmites_stand_under_their_drip_points_and_neighbours_differ) {
  const std::vector<fm::FormationShape> all = place(hall());
  std::map<std::pair<float, float>, int> tites;
  for (const fm::FormationShape& f : all)
    if (f.kind == fm::kFormationStalactite) ++tites[{f.root.x, f.root.z}];
  int under = 0, mites = 0;
  std::vector<double> heights, tapers;
  for (const fm::FormationShape& f : all) {
    if (f.kind != fm::kFormationStalagmite) continue;
    ++mites;
    under += tites.count({f.root.x, f.root.z}) > 0;
    heights.push_back(f.length);
    tapers.push_back(f.taper);
  }
  ASSERT_GT(mites, 10);
  EXPECT_GT(under, mites * 3 / 4) << "most stand under a stalactite (the rest are lone ones)";
  auto spread = [](const std::vector<double>& v) {
    double mean = 0, var = 0;
    for (double x : v)
      mean += x;
    mean /= static_cast<double>(v.size());
    for (double x : v)
      var += (x - mean) * (x - mean);
    return std::sqrt(var / static_cast<double>(v.size())) / mean;
  };
  std::printf("%d stalagmites, %d under a stalactite; height spread %.2f, form spread %.2f\n",
              mites, under, spread(heights), spread(tapers));
  EXPECT_GT(spread(heights), 0.3);
  EXPECT_GT(spread(tapers), 0.15);
}

// Placement is a pure function of the room's mesh: the same twice, and the same whatever order
// its triangles come in (another decoder's, another server's).
TEST(Formations, placement_is_the_same_whatever_the_order_of_the_triangles) {
  const client::ReadyRoom& room = hall();
  const auto key = [](const fm::FormationShape& f) {
    return std::make_tuple(f.root.x, f.root.z, f.kind, f.root.y, f.length, f.radius, f.seed);
  };
  auto sorted = [&](std::vector<fm::FormationShape> v) {
    std::vector<decltype(key(v[0]))> out;
    for (const auto& f : v)
      out.push_back(key(f));
    std::sort(out.begin(), out.end());
    return out;
  };
  const auto once = sorted(place(room));
  EXPECT_EQ(once, sorted(place(room)));
  client::ReadyRoom turned = room;
  const size_t triangles = turned.mesh.indices.size() / 3;
  std::vector<uint32_t> indices;
  for (size_t t = 0; t < triangles; ++t) {
    const size_t from = (t * 7919 + triangles / 3) % triangles;  // 7919 is prime: a permutation
    for (int k = 0; k < 3; ++k)
      indices.push_back(room.mesh.indices[3 * from + ((k + 1) % 3)]);
  }
  turned.mesh.indices = indices;
  ASSERT_EQ(std::gcd(triangles, size_t{7919}), 1u);
  EXPECT_EQ(once, sorted(place(turned)));
}

// Walkers and flares collide with formations: a segment from beside a formation's body to its
// axis, at half its length, meets its hull.
TEST(Formations, walkers_collide_with_them) {
  const client::ReadyRoom& room = hall();
  CollisionWorld with(1.0f, true);
  with.add(room);
  int hit = 0, tested = 0;
  Neighbourhood near;
  for (const fm::FormationShape& f : place(room)) {
    if (f.kind == fm::kFormationStalactite || f.radius < 0.1f) continue;
    const float s = 0.5f * f.length;
    const glm::vec3 mid = f.root + glm::vec3(0.0f, fm::formation_direction(f) * s, 0.0f);
    const float r = fm::formation_radius(f, s, 0.0f);
    const Vec3 a = world(room, mid + glm::vec3(1.5f * r + 0.05f, 0.0f, 0.0f));
    const Vec3 b = world(room, mid);
    ++tested;
    with.gather(a - Vec3{0.1, 0.1, 0.1}, b + Vec3{0.1, 0.1, 0.1}, near);
    const bool meets = std::any_of(near.triangles.begin(), near.triangles.end(),
                                   [&](const Triangle& t) { return segment_crosses(t, a, b); });
    hit += meets;
  }
  ASSERT_GT(tested, 5);
  EXPECT_EQ(hit, tested);
}

// What the renderer draws at 1080p (70 degrees of view: 771 pixels a metre at 1 m): a 1 m
// stalactite 3 m away gets its finest mesh, 24 triangles or more whatever its size, and a
// centimetre straw 200 m away is not drawn at all.
TEST(Formations, a_stalactite_3_m_away_is_drawn_with_at_least_24_triangles) {
  const float pixel_scale = 1080.0f / (2.0f * std::tan(0.5f * 1.2217305f));
  int checked = 0;
  for (const fm::FormationShape& f : place(hall())) {
    if (f.kind != fm::kFormationStalactite || f.length < 0.3f) continue;
    const int lod = fm::lod_for(f, 3.0f, pixel_scale);
    ASSERT_GE(lod, 0);
    EXPECT_GE(fm::lod_triangles(lod), 24);
    if (f.length > 1.0f) {
      EXPECT_EQ(lod, 0);
    }
    ++checked;
    EXPECT_EQ(fm::lod_for(f, 5000.0f, pixel_scale), -1);
  }
  EXPECT_GT(checked, 10);
  EXPECT_GE(fm::lod_triangles(fm::kLods - 1), 24);
}

}  // namespace
}  // namespace grotto::play
