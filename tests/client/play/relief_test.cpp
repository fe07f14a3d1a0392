// The relief's speleothems through shaders/relief.hpp (the C++ face of the shader's source): they
// hang plumb on a sloping ceiling, their lengths run from soda straws to metres, they grow in rows
// with bare rock between, nothing moves on a portal rim, the normals follow the displaced surface,
// and collision meets the displaced surface.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <map>
#include <vector>

#include "client/play/collision.hpp"
#include "client/play/player.hpp"
#include "core/random.hpp"
#include "proto/world_digest.hpp"
#include "shaders/relief.hpp"
#include "shapes.hpp"

namespace grotto::play {
namespace {

namespace rl = grotto::relief;
constexpr float kHall = 20.0f;  // metres of room radius: the longest speleothems
constexpr double kPi = 3.14159265358979323846;

// A 45-degree ceiling through (0, 10, 0): its normal faces down into the cave and towards +z.
const glm::vec3 kSlopeNormal = glm::normalize(glm::vec3(0.0f, -1.0f, 1.0f));
const glm::vec3 kSlopeU{1.0f, 0.0f, 0.0f};
const glm::vec3 kSlopeW = glm::normalize(glm::vec3(0.0f, 1.0f, 1.0f));
const glm::vec3 kSlopeOrigin{0.0f, 10.0f, 0.0f};

rl::Relief relief(glm::vec3 p, glm::vec3 n, float rim = 0.0f) {
  return rl::relief_at(p, n, 0.0f, rim, kHall, 1.0f);
}

glm::vec3 plumb(glm::vec3 p, glm::vec3 n) {
  return rl::relief_displace(p, n, relief(p, n));
}

// The same heights with the speleothem pushed out along the normal, as before they hung plumb.
glm::vec3 along_normal(glm::vec3 p, glm::vec3 n) {
  const rl::Relief r = relief(p, n);
  return p + n * (r.height + std::abs(r.hang));
}

// The point of the sloping ceiling (within 8 m of its origin) under the longest stalactite.
glm::vec3 longest_stalactite_root(float& hang) {
  hang = 0;
  glm::vec3 best = kSlopeOrigin;
  for (float a = -8; a <= 8; a += 0.04f)
    for (float b = -8; b <= 8; b += 0.04f) {
      const glm::vec3 p = kSlopeOrigin + a * kSlopeU + b * kSlopeW;
      const float h = relief(p, kSlopeNormal).hang;
      if (h < hang) hang = h, best = p;
    }
  return best;
}

// The angle from vertical, in degrees, of the line from the centroid of a stalactite's ring at a
// quarter of its length to its tip, on the surface `displace` makes.
template <typename Displace>
double axis_tilt_deg(glm::vec3 root, float tip_hang, Displace displace) {
  glm::dvec3 centroid{0.0};
  constexpr int kAngles = 64;
  for (int i = 0; i < kAngles; ++i) {
    const double t = 2 * kPi * i / kAngles;
    const glm::vec3 e =
        static_cast<float>(std::cos(t)) * kSlopeU + static_cast<float>(std::sin(t)) * kSlopeW;
    float s = 0;
    while (s < 2 && relief(root + s * e, kSlopeNormal).hang < 0.25f * tip_hang)
      s += 0.002f;
    centroid += glm::dvec3(displace(root + s * e, kSlopeNormal));
  }
  centroid /= kAngles;
  const glm::dvec3 axis = glm::dvec3(displace(root, kSlopeNormal)) - centroid;
  return std::atan2(std::hypot(axis.x, axis.z), std::abs(axis.y)) * 180 / kPi;
}

TEST(Relief, a_stalactite_on_a_45_degree_ceiling_hangs_within_3_degrees_of_vertical) {
  float hang = 0;
  const glm::vec3 root = longest_stalactite_root(hang);
  ASSERT_LT(hang, -1.0f) << "no stalactite a metre long on 256 square metres of ceiling";
  const double tilt = axis_tilt_deg(root, hang, plumb);
  EXPECT_LT(tilt, 3.0) << "length " << -hang << " m";
  // The tip is straight below the root, the rock's height along the normal aside.
  const rl::Relief r = relief(root, kSlopeNormal);
  const glm::vec3 tip = plumb(root, kSlopeNormal) - kSlopeNormal * r.height;
  EXPECT_NEAR(tip.x, root.x, 1e-5);
  EXPECT_NEAR(tip.z, root.z, 1e-5);
  EXPECT_NEAR(tip.y, root.y + hang, 1e-5);
  // The measurement sees a fang: displaced along the normal the same spike leans 45 degrees.
  EXPECT_GT(axis_tilt_deg(root, hang, along_normal), 30.0);
}

// A point of the speleothem lattice's turned frame (relief_turn) in world space, at height y.
glm::vec3 lattice_to_world(glm::vec2 t, float y) {
  return {rl::kReliefTurnCos * t.x + rl::kReliefTurnSin * t.y, y,
          -rl::kReliefTurnSin * t.x + rl::kReliefTurnCos * t.y};
}

// The lattice's speleothems over 60 x 60 cells (one per 1 m cell at most) in the longest room.
std::map<std::pair<int, int>, rl::Speleothem> speleothems(float longest) {
  std::map<std::pair<int, int>, rl::Speleothem> out;
  for (int z = -30; z < 30; ++z)
    for (int x = -30; x < 30; ++x) {
      const rl::Speleothem s = rl::relief_speleothem(glm::ivec2(x, z), longest);
      if (s.len > 0) out[{x, z}] = s;
    }
  return out;
}

TEST(Relief, lengths_run_from_soda_straws_to_metres_with_max_over_median_at_least_5) {
  const float longest = rl::relief_spike_length(kHall);
  EXPECT_GE(longest, 3.0f);
  const auto all = speleothems(longest);
  ASSERT_GT(all.size(), 100u);
  std::vector<float> lengths;
  for (const auto& [cell, s] : all)
    lengths.push_back(s.len);
  std::sort(lengths.begin(), lengths.end());
  const float median = lengths[lengths.size() / 2];
  std::printf("speleothems: %zu in 3600 cells, %.3f-%.2f m, median %.3f m, max/median %.1f\n",
              lengths.size(), lengths.front(), lengths.back(), median, lengths.back() / median);
  EXPECT_NEAR(lengths.front(), 0.05f, 1e-6) << "the shortest are soda straws";
  EXPECT_GE(lengths.back(), 2.5f) << "the longest are metres long in a hall";
  EXPECT_GE(lengths.back() / median, 5.0f);
  // Stalagmites are thicker and blunter than the stalactite above: the relief's own shape round
  // the centre of the longest, on a ceiling 8 m up and on the floor.
  // (The longest with no column within two cells: a column's sides reach their levels.)
  auto near_a_column = [&](std::pair<int, int> cell) {
    for (int dz = -2; dz <= 2; ++dz)
      for (int dx = -2; dx <= 2; ++dx) {
        auto it = all.find({cell.first + dx, cell.second + dz});
        if (it != all.end() && it->second.level >= 0) return true;
      }
    return false;
  };
  const rl::Speleothem* big = nullptr;
  for (const auto& [cell, s] : all)
    if (!near_a_column(cell) && (!big || s.len > big->len)) big = &s;
  const glm::vec3 at = lattice_to_world(big->centre, 0.0f);
  auto hang = [&](float dx, bool ceiling) {
    return ceiling ? -relief(at + glm::vec3(dx, 8, 0), glm::vec3(0, -1, 0)).hang
                   : relief(at + glm::vec3(dx, 0, 0), glm::vec3(0, 1, 0)).hang;
  };
  auto radius = [&](bool ceiling) {
    float r = 0;
    while (r < 1 && hang(r, ceiling) > 0)
      r += 0.005f;
    return r;
  };
  const float tite = hang(0, true), mite = hang(0, false);
  EXPECT_GE(tite, 0.45f * big->len * 0.999f) << "the variety field shortens by 0.45 at most";
  EXPECT_GT(mite, 0.0f);
  EXPECT_LT(mite, tite) << "a stalagmite is shorter than its stalactite";
  const float tite_r = radius(true), mite_r = radius(false);
  EXPECT_GT(mite_r, 1.5f * tite_r) << "a stalagmite is thicker than its stalactite";
  // Blunt: half way out a stalagmite keeps over half its height, a stalactite under a third.
  EXPECT_GT(hang(0.5f * mite_r, false), 0.5f * mite);
  EXPECT_LT(hang(0.5f * tite_r, true), 0.33f * tite);
}

TEST(Relief, speleothems_grow_in_rows_along_cracks_with_bare_rock_between) {
  const auto all = speleothems(rl::relief_spike_length(kHall));
  // Bare rock: most cells hold none.
  EXPECT_LT(all.size(), 3600u / 2);
  // Clustered: counts in 6 x 6 cell blocks vary far more than scattered (Poisson) ones would,
  // whose variance equals their mean.
  std::map<std::pair<int, int>, int> blocks;
  for (int bz = -5; bz < 5; ++bz)
    for (int bx = -5; bx < 5; ++bx)
      blocks[{bx, bz}] = 0;
  for (const auto& [cell, s] : all)
    ++blocks[{static_cast<int>(std::floor(cell.first / 6.0)),
              static_cast<int>(std::floor(cell.second / 6.0))}];
  double mean = 0, var = 0;
  for (const auto& [b, n] : blocks)
    mean += n;
  mean /= static_cast<double>(blocks.size());
  for (const auto& [b, n] : blocks)
    var += (n - mean) * (n - mean);
  var /= static_cast<double>(blocks.size());
  std::printf("blocks: mean %.2f variance %.2f\n", mean, var);
  EXPECT_GT(var, 1.5 * mean);
  // In rows: a speleothem's nearest neighbour is usually close (within 2 cells).
  int close = 0;
  for (const auto& [cell, s] : all) {
    double nearest = 1e9;
    for (const auto& [other, t] : all)
      if (other != cell)
        nearest = std::min(nearest, static_cast<double>(glm::length(s.centre - t.centre)));
    close += nearest < 2.0;
  }
  EXPECT_GT(close, static_cast<int>(0.8 * static_cast<double>(all.size())));
}

// Stalagmites come in forms: bell-shaped cones that keep under 60 % of their height at 0.6 of
// their radius (41 % for the bell (1 - s^2)^2), and candles, steep-sided with a rounded top, that
// keep over 80 % there. Stalagmites on a level floor, not columns, measured where no other
// reaches.
TEST(Relief, stalagmites_range_from_cones_to_candles) {
  const glm::vec3 up{0.0f, 1.0f, 0.0f};
  // Each stalagmite of 60 x 60 cells as relief_at makes it: the room's longest, shorter in bare
  // zones (the variety field), and its footprint's radius.
  struct Mite {
    glm::vec2 centre;
    float rf;
  };
  std::vector<Mite> mites;
  for (int z = -30; z < 30; ++z)
    for (int x = -30; x < 30; ++x) {
      const rl::Speleothem probe = rl::relief_speleothem(glm::ivec2(x, z), 1.0f);
      if (!(probe.len > 0) || probe.level >= 0) continue;
      const float longest =
          rl::relief_spike_length(kHall) *
          glm::mix(0.45f, 1.0f,
                   glm::smoothstep(0.3f, 0.75f,
                                   rl::relief_variety(lattice_to_world(probe.centre, 0.0f))));
      const rl::Speleothem sp = rl::relief_speleothem(glm::ivec2(x, z), longest);
      mites.push_back({sp.centre, glm::mix(2.0f, 1.55f, sp.form) * sp.radius});
    }
  // The share of its height a stalagmite keeps at 0.6 of its radius, out where no other reaches.
  int cones = 0, candles = 0, measured = 0;
  for (const Mite& m : mites) {
    const auto clear = [&](glm::vec2 p) {
      for (const Mite& o : mites)
        if (&o != &m && glm::length(p - o.centre) < o.rf + 0.02f) return false;
      return true;
    };
    if (!clear(m.centre)) continue;
    for (int k = 0; k < 8; ++k) {
      const float a = 0.785398f * static_cast<float>(k);
      const glm::vec2 flank = m.centre + 0.6f * m.rf * glm::vec2(std::cos(a), std::sin(a));
      if (!clear(flank)) continue;
      const float top =
          rl::relief_at(lattice_to_world(m.centre, 0.0f), up, 0.0f, 0.0f, kHall, 1.0f).hang;
      const float side =
          rl::relief_at(lattice_to_world(flank, 0.0f), up, 0.0f, 0.0f, kHall, 1.0f).hang;
      ASSERT_GT(top, 0.0f);
      cones += side / top < 0.6f;
      candles += side / top > 0.8f;
      ++measured;
      break;
    }
  }
  std::printf("stalagmites measured %d: cones %d, candles %d\n", measured, cones, candles);
  ASSERT_GE(measured, 50);
  EXPECT_GE(cones, measured / 6);
  EXPECT_GE(candles, measured / 5);
}

// A stalactite drawn from a mesh sampled every `spacing` metres (room.tese passes the
// tessellation's step) is widened to two steps across and shortened so that its volume stays: at
// level 8 a far patch steps 0.3-0.7 m, and a spike drawn as it was became one vertex pulled down,
// a shard.
// Stalactites under a level ceiling, not columns, whose neighbours stand 0.95 m off or more (so
// no other, widened to the lattice's bound of 0.45 m, reaches into the disc weighed).
TEST(Relief, sampled_coarsely_a_spike_is_drawn_two_steps_across_and_keeps_its_volume) {
  const glm::vec3 down{0.0f, -1.0f, 0.0f};
  const auto all = speleothems(rl::relief_spike_length(kHall));
  std::vector<glm::vec3> roots;
  for (const auto& [cell, s] : all) {
    if (s.level >= 0 || std::abs(cell.first) >= 29 || std::abs(cell.second) >= 29) continue;
    float nearest = 1e9f;
    for (const auto& [other, t] : all)
      if (other != cell) nearest = std::min(nearest, glm::length(s.centre - t.centre));
    if (nearest < 0.95f) continue;
    roots.push_back(lattice_to_world(s.centre, 10.0f));
  }
  struct Drawn {
    double volume = 0;  // cubic metres below the ceiling
    float support = 0;  // metres from the root where it hangs 1 % of its length or more
    float peak = 0;     // the deepest hang, metres (negative)
  };
  constexpr float kStep = 0.01f;
  const auto drawn = [&](glm::vec3 root, float spacing) {
    std::vector<std::pair<float, float>> samples;  // (distance from the root, hang)
    Drawn d;
    for (float a = -0.47f; a <= 0.47f; a += kStep)
      for (float b = -0.47f; b <= 0.47f; b += kStep) {
        if (std::hypot(a, b) > 0.47f) continue;
        const glm::vec3 p = root + glm::vec3(a, 0.0f, b);
        const float hang = rl::relief_at_sampled(p, down, 0.0f, 0.0f, kHall, 1.0f, spacing).hang;
        if (spacing == 0.0f) {
          EXPECT_EQ(hang, rl::relief_at(p, down, 0.0f, 0.0f, kHall, 1.0f).hang);
        }
        d.volume += std::max(-hang, 0.0f) * kStep * kStep;
        d.peak = std::min(d.peak, hang);
        samples.emplace_back(std::hypot(a, b), hang);
      }
    for (const auto& [r, hang] : samples)
      if (hang < 0.01f * d.peak) d.support = std::max(d.support, r);
    return d;
  };
  int checked = 0;
  for (const glm::vec3& root : roots) {
    const Drawn exact = drawn(root, 0.0f);
    if (exact.support < 0.05f) continue;  // a straw: too thin for a 1 cm grid to weigh
    for (float spacing : {0.05f, 0.12f, 0.2f}) {
      const Drawn d = drawn(root, spacing);
      SCOPED_TRACE(::testing::Message()
                   << "root " << root.x << " " << root.z << " spacing " << spacing << ": radius "
                   << exact.support << " -> " << d.support << ", length " << -exact.peak << " -> "
                   << -d.peak);
      EXPECT_LE(d.peak, 0.0f);
      EXPECT_GT(d.peak, exact.peak);  // shorter
      EXPECT_GE(d.support, 0.85f * std::min(spacing, 0.45f));
      EXPECT_GE(d.support, exact.support - kStep);
      // Its volume stays while its radius is within the lattice's bound (0.45 m).
      const float r = std::hypot(exact.support, spacing);
      if (r < 0.4f) {
        EXPECT_NEAR(d.volume, exact.volume, 0.06 * exact.volume);
      }
      ++checked;
    }
  }
  EXPECT_GE(checked, 15) << roots.size() << " isolated stalactites";
}

// The rock's octaves that a coarse mesh cannot carry leave its shape for the shading: under a
// ceiling (no flowstone there) the sampled gradient and room.frag's relief_rock_detail add up to
// the exact gradient, nothing lost and nothing counted twice; sampled exactly, the detail is
// zero; sampled every 0.4 m the shape keeps none of the two finest octaves.
TEST(Relief, octaves_too_fine_for_the_mesh_move_from_its_shape_to_the_shading) {
  const glm::vec3 down{0.0f, -1.0f, 0.0f};
  Rng rng(30);
  double finest = 0;  // the largest gradient the detail carries
  for (int i = 0; i < 500; ++i) {
    const glm::vec3 p(static_cast<float>(rng.uniform(-50, 50)), 10.0f,
                      static_cast<float>(rng.uniform(-50, 50)));
    const float roughness = static_cast<float>(rng.uniform());
    const rl::Relief exact = rl::relief_at(p, down, roughness, 0.0f, kHall, 1.0f);
    EXPECT_EQ(rl::relief_rock_detail(p, exact.warp, exact.rock, 0.0f, 1e-4f), glm::vec3(0.0f));
    for (float spacing : {0.06f, 0.12f, 0.4f}) {
      const rl::Relief drawn =
          rl::relief_at_sampled(p, down, roughness, 0.0f, kHall, 1.0f, spacing);
      const glm::vec3 detail = rl::relief_rock_detail(p, drawn.warp, drawn.rock, spacing, 1e-4f);
      const glm::vec3 sum = drawn.gradient + detail;
      EXPECT_NEAR(sum.x, exact.gradient.x, 1e-4f) << "spacing " << spacing;
      EXPECT_NEAR(sum.y, exact.gradient.y, 1e-4f) << "spacing " << spacing;
      EXPECT_NEAR(sum.z, exact.gradient.z, 1e-4f) << "spacing " << spacing;
      finest = std::max(finest, static_cast<double>(glm::length(detail)));
    }
    // Sampled every 0.4 m, octaves 2 and 3 (0.31 and 0.15 m) are not in the shape at all: the
    // height is what the two broad octaves alone give.
    const rl::Relief coarse = rl::relief_at_sampled(p, down, roughness, 0.0f, kHall, 1.0f, 0.4f);
    const glm::vec3 q = p + coarse.warp;
    const glm::vec4 o0 = rl::relief_noise(q * 0.7f), o1 = rl::relief_ridge_noise(q);
    const float soft = std::sqrt(o1.x * o1.x + 0.05f);
    const float kept1 = rl::relief_octave_kept(rl::kReliefRidgeSize, 0.4f);
    const float broad = 0.45f * o0.x + kept1 * 0.28f * (2.0f * (1 - soft) * (1 - soft) - 1.0f);
    EXPECT_NEAR(coarse.height, coarse.rock * broad, 1e-5f);
  }
  EXPECT_GT(finest, 0.05) << "the detail never tilted the normal";
}

// The relief is part of the world: relief_at's values at 4,000 fixed points (every normal, slope,
// roughness, rim weight and room size), rounded to 0.1 mm (a thousandth for the unitless parts)
// and hashed, are pinned to the relief version the world digest folds (proto::kReliefVersion).
// A change of the relief fails this until the version moves on (every client's cache and every
// engine's baked collision then see a new world); a change of how it is drawn does not.
TEST(Relief, its_values_are_pinned_to_the_version_in_the_world_digest) {
  std::vector<uint8_t> bytes;
  const auto put = [&](float v, float unit) {
    const int64_t q = std::llround(static_cast<double>(v) / unit);
    for (int k = 0; k < 8; ++k)
      bytes.push_back(static_cast<uint8_t>(static_cast<uint64_t>(q) >> (8 * k)));
  };
  Rng rng(27);
  const auto next = [&] { return static_cast<float>(rng.uniform()); };
  for (int i = 0; i < 4000; ++i) {
    const glm::vec3 p{200.0f * next() - 100.0f, 60.0f * next() - 30.0f, 200.0f * next() - 100.0f};
    const glm::vec3 n =
        glm::normalize(glm::vec3(next() - 0.5f, 2.0f * next() - 1.0f, next() - 0.5f));
    const float roughness = next(), rim = next() < 0.1f ? next() : 0.0f;
    const float radius = 2.0f + 30.0f * next();
    const rl::Relief r = rl::relief_at(p, n, roughness, rim, radius, 1.0f);
    for (float v : {r.height, r.hang})
      put(v, 1e-4f);
    for (float v : {r.gradient.x, r.gradient.y, r.gradient.z, r.hang_gradient.x, r.hang_gradient.y,
                    r.hang_gradient.z, r.cavity, r.spike, r.occlusion})
      put(v, 1e-3f);
  }
  const uint64_t digest = fnv1a64(bytes.data(), bytes.size());
  // One row a version: a new relief adds a row (and moves proto::kReliefVersion), never edits one.
  const std::map<std::string_view, uint64_t> pinned = {
      {"grotto.relief.v1", 0x3ce883fafaec6c06ull},
      {"grotto.relief.v2", 0x493b6ced8188ba3dull},  // stalagmites from cones to candles
  };
  ASSERT_TRUE(pinned.count(proto::kReliefVersion)) << proto::kReliefVersion << " has no row";
  EXPECT_EQ(digest, pinned.at(proto::kReliefVersion))
      << "relief_at's values changed (now 0x" << std::hex << digest << "): that is a new world. "
      << "Move proto::kReliefVersion on (proto/world_digest.hpp) and add its row here.";
}

TEST(Relief, nothing_moves_on_a_portal_rim) {
  const glm::vec3 normals[] = {glm::vec3(0, -1, 0), glm::vec3(0, 1, 0), kSlopeNormal,
                               glm::normalize(glm::vec3(1, 0.1f, 0)),
                               glm::normalize(glm::vec3(0.2f, 0.9f, -0.3f))};
  int checked = 0;
  for (const glm::vec3& n : normals)
    for (float a = -6; a <= 6; a += 0.13f)
      for (float b = -6; b <= 6; b += 0.17f) {
        const glm::vec3 p{a, 3.0f + 0.37f * b, b};
        for (float rim : {1.0f, 0.99995f}) {
          const rl::Relief r = rl::relief_at(p, n, 1.0f, rim, kHall, 1.0f);
          ASSERT_EQ(r.height, 0.0f);
          ASSERT_EQ(r.hang, 0.0f);
          ASSERT_EQ(rl::relief_displace(p, n, r), p);
          ++checked;
        }
      }
  EXPECT_GT(checked, 10000);
}

TEST(Relief, the_normal_follows_the_plumb_displaced_surface) {
  float hang = 0;
  const glm::vec3 root = longest_stalactite_root(hang);
  ASSERT_LT(hang, -1.0f);
  // Points on the stalactite's flank: the analytic normal against the displaced surface's own
  // (central differences of relief_displace).
  int checked = 0;
  double worst = 0;
  for (int i = 0; i < 16; ++i) {
    const double t = 2 * kPi * i / 16;
    const glm::vec3 e =
        static_cast<float>(std::cos(t)) * kSlopeU + static_cast<float>(std::sin(t)) * kSlopeW;
    for (float s : {0.03f, 0.06f}) {
      const glm::vec3 p = root + s * e;
      const rl::Relief r = relief(p, kSlopeNormal);
      if (r.hang > 0.3f * hang) continue;  // off the flank
      const glm::vec3 analytic =
          rl::relief_displaced_normal(kSlopeNormal, r.gradient, r.hang_gradient);
      constexpr float h = 1e-3f;
      const glm::vec3 du =
          plumb(p + h * kSlopeU, kSlopeNormal) - plumb(p - h * kSlopeU, kSlopeNormal);
      const glm::vec3 dw =
          plumb(p + h * kSlopeW, kSlopeNormal) - plumb(p - h * kSlopeW, kSlopeNormal);
      const glm::vec3 numeric = glm::normalize(glm::cross(du, dw));
      const double angle =
          std::acos(std::clamp(static_cast<double>(glm::dot(analytic, numeric)), -1.0, 1.0)) * 180 /
          kPi;
      worst = std::max(worst, angle);
      ++checked;
    }
  }
  EXPECT_GT(checked, 8);
  EXPECT_LT(worst, 5.0) << "degrees between the analytic and the displaced surface's normal";
}

// Collision is the drawn surface: on a 45-degree ceiling it reaches the stalactite's tip, which
// hangs straight below its root; on a floor the player lands on a stalagmite, not the floor.
TEST(Relief, collision_meets_the_plumb_stalactite_and_stands_on_the_stalagmite) {
  float hang = 0;
  const glm::vec3 root = longest_stalactite_root(hang);
  ASSERT_LT(hang, -1.0f);
  // The ceiling round the root as 0.25 m quads (the collision refines each into 6 cm pieces).
  std::vector<test::Quad> ceiling;
  auto at = [&](float a, float b) {
    const glm::vec3 p = root + a * kSlopeU + b * kSlopeW;
    return Vec3{p.x, p.y, p.z};
  };
  for (float a = -1.5f; a < 1.5f; a += 0.25f)
    for (float b = -1.5f; b < 1.5f; b += 0.25f)
      ceiling.push_back({at(a, b), at(a, b + 0.25f), at(a + 0.25f, b + 0.25f), at(a + 0.25f, b)});
  test::Quad& first = ceiling.front();
  const Vec3 e1 = first.b - first.a, e2 = first.c - first.a;
  if (dot(cross(e1, e2), Vec3{kSlopeNormal.x, kSlopeNormal.y, kSlopeNormal.z}) < 0)
    for (test::Quad& q : ceiling)
      std::swap(q.b, q.d);  // wound to face the cave, as the mesh stage winds them
  CollisionWorld world(1.0f);
  client::ReadyRoom room = test::shape_room(0, ceiling);
  room.room.sphere.radius = kHall;
  world.add(room);
  auto nearest = [&](glm::vec3 q) {
    const Vec3 p{q.x, q.y, q.z};
    Neighbourhood n;
    world.gather(p - Vec3{0.3, 0.3, 0.3}, p + Vec3{0.3, 0.3, 0.3}, n);
    double best = 1e9;
    for (const Triangle& t : n.triangles)
      best = std::min(best, length(closest_point(t, p) - p));
    return best;
  };
  EXPECT_LT(nearest(plumb(root, kSlopeNormal)), 0.08) << "the tip hanging plumb";
  EXPECT_GT(nearest(along_normal(root, kSlopeNormal)), 0.3) << "where a fang's tip would be";

  // A floor of 0.25 m tiles round the tallest stalagmite near the origin.
  glm::vec3 top{0.0f};
  float tallest = 0;
  for (float x = -8; x <= 8; x += 0.04f)
    for (float z = -8; z <= 8; z += 0.04f) {
      const float h = relief(glm::vec3(x, 0, z), glm::vec3(0, 1, 0)).hang;
      if (h > tallest) tallest = h, top = glm::vec3(x, 0, z);
    }
  ASSERT_GT(tallest, 0.5f);
  std::vector<test::Quad> floor;
  for (float a = -2; a < 2; a += 0.25f)
    for (float b = -2; b < 2; b += 0.25f)
      floor.push_back(test::floor_quad(0, 0.125, top.x + a + 0.125, top.z + b + 0.125));
  CollisionWorld ground(1.0f);
  client::ReadyRoom floor_room = test::shape_room(0, floor);
  floor_room.room.sphere.radius = kHall;
  ground.add(floor_room);
  Player p({top.x, tallest + 3.0, top.z});
  for (int i = 0; i < 600 && !p.grounded(); ++i)
    p.step({}, ground);
  ASSERT_TRUE(p.grounded());
  const double feet_y = p.eye().y - p.params().eye_height - p.params().skin / 2;
  EXPECT_GT(feet_y, 0.5 * tallest) << "the player fell through the stalagmite to the floor";
  EXPECT_LT(feet_y, plumb(top, glm::vec3(0, 1, 0)).y + 0.05);
}

// The column cells of the lattice over 40 x 40 m, as world points at their centres.
std::vector<glm::vec3> column_centres() {
  std::vector<glm::vec3> out;
  const float longest = rl::relief_spike_length(kHall);
  for (int z = -20; z < 20; ++z)
    for (int x = -20; x < 20; ++x) {
      const rl::Speleothem s = rl::relief_speleothem(glm::ivec2(x, z), longest);
      if (s.len > 0 && s.level >= 0) {
        out.push_back(lattice_to_world(s.centre, 0.0f));
      }
    }
  return out;
}

// In a synthetic room with a level floor at y = 0 and a level ceiling `gap` metres above it: at
// each column cell's centre, whether the stalagmite's top reaches the stalactite's tip, so the
// displaced surface runs unbroken from floor to ceiling there.
double share_joined(float gap, const std::vector<glm::vec3>& centres) {
  const glm::vec3 up{0, 1, 0}, down{0, -1, 0};
  int joined = 0;
  for (const glm::vec3& c : centres) {
    const glm::vec3 floor_top = plumb(c, up);
    const glm::vec3 ceiling_tip = plumb(c + glm::vec3(0, gap, 0), down);
    joined += floor_top.y >= ceiling_tip.y;
  }
  return static_cast<double>(joined) / static_cast<double>(centres.size());
}

TEST(Relief, columns_join_floor_and_ceiling_where_the_room_is_low_and_stay_pairs_in_halls) {
  const std::vector<glm::vec3> centres = column_centres();
  ASSERT_GT(centres.size(), 10u);
  std::printf("column cells: %zu in 1600\n", centres.size());
  // Up to 2.5 m only the cells whose level falls in a side's fade window (kReliefColumnFade at
  // each end of the span) may stay apart; higher up, a level over kReliefColumnRise above the
  // floor leaves the stalagmite short and the pair apart.
  for (float gap : {1.8f, 2.5f, 3.0f, 3.5f, 4.5f, 5.5f}) {
    const double joined = share_joined(gap, centres);
    std::printf("gap %.1f m: %.0f%% joined\n", gap, 100 * joined);
    EXPECT_GE(joined, gap <= 2.5f ? 0.8 : gap <= 3.5f ? 0.4 : 0.0) << "gap " << gap;
  }
  // A hall's 20 m: at most a long pair, no column (two levels fit between).
  const double in_hall = share_joined(20.0f, centres);
  std::printf("gap 20 m: %.0f%% joined\n", 100 * in_hall);
  EXPECT_LT(in_hall, 0.1);
  // Without relief nothing joins: the check can fail.
  int joined_flat = 0;
  for (const glm::vec3& c : centres)
    joined_flat += rl::relief_at(c, {0, 1, 0}, 0, 0, kHall, 0).hang >= 2.5f;
  EXPECT_EQ(joined_flat, 0);
}

TEST(Relief, a_column_surface_is_continuous_across_a_sloping_ceiling_and_its_level_switch) {
  // A ceiling at 3 m sloping 12 degrees along x (level enough for columns; its height crosses
  // a meeting level somewhere over 40 m, where a side's reach switches to the next level): the
  // displaced surface along lines 1 mm apart never jumps.
  const glm::vec3 n = glm::normalize(glm::vec3(0.21f, -1.0f, 0.0f));
  const std::vector<glm::vec3> centres = column_centres();
  double worst = 0;
  int lines = 0, columns = 0;
  for (const glm::vec3& c : centres) {
    glm::vec3 last{0};
    float deepest = 0;
    for (float x = -0.6f; x <= 0.6f; x += 0.001f) {
      glm::vec3 p{c.x + x, 0, c.z};
      p.y = 3.0f + 0.21f * p.x;  // on the plane through (0, 3, 0) with normal n
      const glm::vec3 q = plumb(p, n);
      if (x > -0.6f) worst = std::max(worst, static_cast<double>(glm::length(q - last)));
      deepest = std::min(deepest, relief(p, n).hang);
      last = q;
    }
    ++lines;
    columns += deepest < -1.0f;
  }
  std::printf("%d lines, %d with a side over 1 m, largest step %.3f m per mm\n", lines, columns,
              worst);
  EXPECT_GT(columns, lines / 2) << "most column cells reach their level";
  EXPECT_LT(worst, 0.05);
}

// A 45-degree ceiling through (0, 10, 0) whose fall line (horizontally) is `fall` (unit): its
// normal points down and along the fall line, and it rises against it.
struct Slope {
  glm::vec3 fall, across, normal;
  float tilt;  // 1 for 45 degrees, 0 for a level ceiling
  glm::vec3 at(float along, float side) const {
    const glm::vec3 p = along * fall + side * across;
    return {p.x, 10.0f + tilt * along, p.z};
  }
};

Slope slope_along(float angle, float tilt) {
  const glm::vec3 fall{std::cos(angle), 0.0f, std::sin(angle)};
  return {fall,
          {-fall.z, 0.0f, fall.x},
          glm::normalize(glm::vec3(fall.x * tilt, -1, fall.z * tilt)),
          tilt};
}

// The longest run (metres) along the fall line, on lines 0.1 m apart over 16 x 16 m, where the
// surface hangs more than 0.1 m.
float longest_hanging_run(const Slope& s) {
  float longest = 0;
  for (float side = -8; side <= 8; side += 0.1f) {
    float run = 0;
    for (float along = -8; along <= 8; along += 0.02f) {
      run = relief(s.at(along, side), s.normal).hang < -0.1f ? run + 0.02f : 0.0f;
      longest = std::max(longest, run);
    }
  }
  return longest;
}

TEST(Relief, draperies_hang_under_sloping_ceilings_along_the_fall_line_and_not_under_level_ones) {
  // Draperies run in four world directions, each where it is near the local fall line: a
  // 45-degree ceiling falling along one of them, and a level ceiling measured the same way.
  // Stalactites (and columns) are at most 0.9 m across, and rows of them rarely chain far; a
  // hanging run of 1.8 m is a drapery.
  const Slope sloped = slope_along(rl::kReliefDraperyAngle, 1.0f);
  const Slope level = slope_along(rl::kReliefDraperyAngle, 0.0f);
  const float under_slope = longest_hanging_run(sloped), under_level = longest_hanging_run(level);
  std::printf("longest hanging run: %.2f m under 45 degrees, %.2f m under a level ceiling\n",
              under_slope, under_level);
  EXPECT_GT(under_slope, 1.8f);
  EXPECT_LT(under_level, 1.8f);
  // Thin: where the surface hangs 0.3 m or more and still hangs 0.5 m up and down the fall line
  // (a drapery, not a stalactite), it hangs over less than 0.2 m across it.
  int thin = 0, measured = 0;
  for (float side = -8; side <= 8 && measured < 20; side += 0.05f)
    for (float along = -8; along <= 8 && measured < 20; along += 0.25f) {
      const glm::vec3 p = sloped.at(along, side);
      if (relief(p, sloped.normal).hang > -0.3f) continue;
      bool drapery = true;
      for (float d : {-0.5f, 0.5f})
        drapery = drapery && relief(sloped.at(along + d, side), sloped.normal).hang < -0.05f;
      if (!drapery) continue;
      float width = 0;
      for (float d = -0.5f; d <= 0.5f; d += 0.005f)
        width += relief(sloped.at(along, side + d), sloped.normal).hang < -0.05f ? 0.005f : 0.0f;
      ++measured;
      thin += width < 0.2f;
    }
  EXPECT_GT(measured, 5);
  EXPECT_GE(thin, measured * 3 / 4) << "draperies are thin curtains";
}

TEST(Relief, flowstone_sheets_cover_part_of_the_walls_and_smooth_the_rock_beneath) {
  const glm::vec3 n{1, 0, 0};
  int covered = 0, bare = 0, samples = 0;
  double covered_roughness = 0, bare_roughness = 0;
  for (float y = -20; y <= 20; y += 0.25f)
    for (float z = -20; z <= 20; z += 0.25f) {
      const glm::vec3 p{0, y, z};
      // Roughness 1: the rock at its roughest, so the sheet's smoothing shows.
      const rl::Relief r = rl::relief_at(p, n, 1.0f, 0.0f, kHall, 1.0f);
      const rl::Relief rx = rl::relief_at(p + glm::vec3(0, 0.05f, 0), n, 1.0f, 0.0f, kHall, 1.0f);
      const double bumpiness = std::abs(rx.height - r.height) / 0.05;
      ++samples;
      if (r.spike > 0.44f) ++covered, covered_roughness += bumpiness;
      if (r.spike == 0.0f) ++bare, bare_roughness += bumpiness;
    }
  std::printf("wall: %.0f%% under a full sheet, %.0f%% bare\n", 100.0 * covered / samples,
              100.0 * bare / samples);
  EXPECT_GT(covered, samples / 20) << "sheets on walls";
  EXPECT_GT(bare, samples / 5) << "and bare rock between";
  EXPECT_LT(covered_roughness / covered, 0.6 * bare_roughness / bare)
      << "the sheet drowns the rock's relief";
  // None on a level floor (the floor's calcite is stalagmites').
  int on_floor = 0;
  for (float x = -20; x <= 20; x += 0.25f)
    for (float z = -20; z <= 20; z += 0.25f) {
      const rl::Relief r = rl::relief_at({x, 0, z}, {0, 1, 0}, 1.0f, 0.0f, kHall, 1.0f);
      on_floor += r.spike > 0.0f && r.hang == 0.0f;
    }
  EXPECT_EQ(on_floor, 0);
}

// room.tesc culls a patch that cannot hold a column's side with the margin without the columns'
// reach: on such surfaces the relief stays within it, on level ones relief_level_possible holds.
TEST(Relief, only_level_patches_need_the_columns_margin) {
  constexpr float kSmall = 3.5f;  // a passage's radius: speleothems under 0.7 m, columns 3.25
  const float tight = rl::relief_bound_without_columns(1.0f, kSmall);
  const glm::vec3 tilted[] = {kSlopeNormal, glm::normalize(glm::vec3(1, 0.2f, 0)),
                              glm::normalize(glm::vec3(0.5f, -0.8f, 0.2f)),
                              glm::normalize(glm::vec3(-0.5f, 0.8f, 0.1f))};
  float worst = 0;
  for (const glm::vec3& n : tilted) {
    EXPECT_FALSE(rl::relief_level_possible(n, n, n));
    for (float a = -20; a <= 20; a += 0.07f)
      for (float b = -20; b <= 20; b += 0.31f) {
        const glm::vec3 p{a, 2.0f + 0.3f * b, b};
        const rl::Relief r = rl::relief_at(p, n, 1.0f, 0.0f, kSmall, 1.0f);
        worst = std::max(worst, std::abs(r.height) + std::abs(r.hang));
      }
  }
  std::printf("tilted surfaces: moved %.2f m at most, margin %.2f m\n", worst, tight);
  EXPECT_LE(worst, tight);
  // Level ceilings and floors, and a patch whose normals fan out past the columns' 0.85, may.
  const glm::vec3 up{0, 1, 0}, down{0, -1, 0};
  EXPECT_TRUE(rl::relief_level_possible(up, up, up));
  EXPECT_TRUE(rl::relief_level_possible(down, down, down));
  const glm::vec3 l = glm::normalize(glm::vec3(-0.6f, 0.8f, 0)),
                  r = glm::normalize(glm::vec3(0.6f, 0.8f, 0));
  EXPECT_TRUE(rl::relief_level_possible(l, r, r)) << "their blend points straight up";
  // And there a column reaches past the tight margin.
  float deepest = 0;
  for (const glm::vec3& c : column_centres())
    deepest = std::max(
        deepest,
        std::abs(rl::relief_at(c + glm::vec3(0, 3, 0), down, 0.0f, 0.0f, kSmall, 1.0f).hang));
  EXPECT_GT(deepest, tight);
}

// relief_fine (shading below 5 cm) leaves nothing where a pixel covers more than half of its
// coarsest octave (the joints' 27.5 cm), and gives grain, pits and joints where pixels are
// millimetres; the relief's ambient occlusion is 1 without relief and within its bounds with it.
TEST(Relief, fine_detail_vanishes_under_coarse_pixels_and_occlusion_stays_in_bounds) {
  int detailed = 0;
  for (int i = 0; i < 400; ++i) {
    const glm::vec3 p{0.37f * i, 1.3f + 0.011f * i, -0.23f * i};
    const rl::ReliefFine coarse = rl::relief_fine(p, 0.14f, 1, 1, 1);
    EXPECT_EQ(coarse.gradient, glm::vec3(0.0f));
    EXPECT_EQ(coarse.tint, 1.0f);
    EXPECT_EQ(coarse.cavity, 1.0f);
    const rl::ReliefFine fine = rl::relief_fine(p, 0.002f, 1, 1, 1);
    detailed += glm::length(fine.gradient) > 0.01f && fine.tint != 1.0f;
    EXPECT_GT(fine.cavity, 0.0f);
    EXPECT_LE(fine.cavity, 1.0f);
    EXPECT_EQ(rl::relief_at(p, {0, 1, 0}, 0.5f, 0, kHall, 0).occlusion, 1.0f);
    for (const glm::vec3& n : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0)}) {
      const float o = relief(p, n).occlusion;
      EXPECT_GE(o, rl::kReliefOcclusionMin);
      EXPECT_LE(o, 1.0f);
    }
  }
  EXPECT_GT(detailed, 350);
}

// The renderer culls rooms and portals with the relief's bound split in two (client/render:
// Margin): the part along the normal within relief_normal_bound in any direction, the hanging part
// within relief_hang_bound along y only. Each part holds on its own, for every kind of surface:
// rough walls, slopes, ceilings with the longest speleothems, floors, columns, small rooms and
// halls.
TEST(Relief, the_normal_and_the_hanging_parts_keep_their_own_bounds) {
  const glm::vec3 normals[] = {{0, -1, 0},
                               {0, 1, 0},
                               kSlopeNormal,
                               glm::normalize(glm::vec3(1, 0.2f, 0)),
                               glm::normalize(glm::vec3(0.5f, -0.8f, 0.2f)),
                               glm::normalize(glm::vec3(-0.3f, 0.9f, 0.1f)),
                               {1, 0, 0}};
  const float along = rl::relief_normal_bound(1.0f);
  for (float radius : {3.5f, 8.0f, kHall}) {
    const float hanging = rl::relief_hang_bound(1.0f, radius);
    float worst_height = 0, worst_hang = 0;
    for (const glm::vec3& n : normals)
      for (float roughness : {0.0f, 1.0f})
        for (float a = -12; a <= 12; a += 0.09f)
          for (float b = -12; b <= 12; b += 0.37f) {
            const glm::vec3 p{a, 3.0f + 0.2f * b, b};
            const rl::Relief r = rl::relief_at(p, n, roughness, 0.0f, radius, 1.0f);
            worst_height = std::max(worst_height, std::abs(r.height));
            worst_hang = std::max(worst_hang, std::abs(r.hang));
          }
    std::printf("radius %.1f m: along the normal %.2f of %.2f m, hanging %.2f of %.2f m\n", radius,
                worst_height, along, worst_hang, hanging);
    EXPECT_LE(worst_height, along) << radius;
    EXPECT_LE(worst_hang, hanging) << radius;
    EXPECT_GT(worst_hang, 0.5f * hanging) << "the samples reach the long formations";
  }
}

}  // namespace
}  // namespace grotto::play
