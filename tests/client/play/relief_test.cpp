// The rock's relief through common/relief/relief.hpp (the C++ face of the shader's source): the
// speleothem lattice's candidates grow in rows along cracks, octaves too fine for the mesh move to
// the shading, the values are pinned to the world digest's version, nothing moves on a portal rim,
// flowstone drowns the rock, the fine detail fades and everything stays within the bound the
// renderer and collision cull with. (The formations themselves: formations_test.cpp.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <glm/glm.hpp>
#include <map>
#include <vector>

#include "common/core/random.hpp"
#include "common/core/vec3.hpp"
#include "common/relief/relief.hpp"
#include "proto/world_digest.hpp"

namespace grotto::play {
namespace {

namespace rl = grotto::relief;
constexpr float kHall = 20.0f;  // metres of room radius: the longest speleothems
const glm::vec3 kSlopeNormal = glm::normalize(glm::vec3(0.0f, -1.0f, 1.0f));

// A point near the origin as the relief takes it (block 0: world = local).
rl::ReliefPos at(glm::vec3 p) {
  return rl::relief_pos(glm::ivec3(0), p);
}

rl::Relief relief(glm::vec3 p, glm::vec3 n, float rim = 0.0f) {
  return rl::relief_at(at(p), n, 0.0f, rim, 1.0f);
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
  // Where each stands in the lattice's frame: its cell's corner and its offset.
  auto where = [](std::pair<int, int> cell, const rl::Speleothem& s) {
    return glm::vec2(static_cast<float>(cell.first), static_cast<float>(cell.second)) + s.offset;
  };
  for (const auto& [cell, s] : all) {
    double nearest = 1e9;
    for (const auto& [other, t] : all)
      if (other != cell)
        nearest =
            std::min(nearest, static_cast<double>(glm::length(where(cell, s) - where(other, t))));
    close += nearest < 2.0;
  }
  EXPECT_GT(close, static_cast<int>(0.8 * static_cast<double>(all.size())));
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
    const rl::Relief exact = rl::relief_at(at(p), down, roughness, 0.0f, 1.0f);
    EXPECT_EQ(rl::relief_rock_detail(at(p), exact.warp, exact.rock, 0.0f, 1e-4f), glm::vec3(0.0f));
    for (float spacing : {0.06f, 0.12f, 0.4f}) {
      const rl::Relief drawn = rl::relief_at_sampled(at(p), down, roughness, 0.0f, 1.0f, spacing);
      const glm::vec3 detail =
          rl::relief_rock_detail(at(p), drawn.warp, drawn.rock, spacing, 1e-4f);
      const glm::vec3 sum = drawn.gradient + detail;
      EXPECT_NEAR(sum.x, exact.gradient.x, 1e-4f) << "spacing " << spacing;
      EXPECT_NEAR(sum.y, exact.gradient.y, 1e-4f) << "spacing " << spacing;
      EXPECT_NEAR(sum.z, exact.gradient.z, 1e-4f) << "spacing " << spacing;
      finest = std::max(finest, static_cast<double>(glm::length(detail)));
    }
    // Sampled every 0.4 m, octaves 2 and 3 (0.31 and 0.15 m) are not in the shape at all: the
    // height is what the two broad octaves alone give.
    const rl::Relief coarse = rl::relief_at_sampled(at(p), down, roughness, 0.0f, 1.0f, 0.4f);
    const glm::vec3 q = p + coarse.warp;
    const glm::vec4 o0 = rl::relief_noise_at(at(q), rl::kReliefOctave0K, glm::vec3(0.0f)),
                    o1 = rl::relief_ridge_noise(at(q));
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
    const rl::Relief r = rl::relief_at(at(p), n, roughness, rim, 1.0f);
    put(r.height, 1e-4f);
    for (float v : {r.gradient.x, r.gradient.y, r.gradient.z, r.cavity, r.spike, r.occlusion})
      put(v, 1e-3f);
  }
  const uint64_t digest = fnv1a64(bytes.data(), bytes.size());
  // One row a version: a new relief adds a row (and moves proto::kReliefVersion), never edits one.
  const std::map<std::string_view, uint64_t> pinned = {
      {"grotto.relief.v1", 0x3ce883fafaec6c06ull},
      {"grotto.relief.v2", 0x493b6ced8188ba3dull},  // stalagmites from cones to candles
      // The formations out of the relief (common/formations/formations.hpp), every noise at whole
      // cycles per block (the same precision 6,000 km out).
      {"grotto.relief.v3", 0x1d8b82e08bfa825cull},
      // Flowstone sheets' edges bent by the rock's warp and scalloped by a finer octave (a
      // value-noise cell thresholded cut a rectangle of bare rock out of a sheet).
      {"grotto.relief.v4", 0xc2e4e4a5483daf32ull},
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
          const rl::Relief r = rl::relief_at(at(p), n, 1.0f, rim, 1.0f);
          ASSERT_EQ(r.height, 0.0f);
          ASSERT_EQ(rl::relief_displace(p, n, r), p);
          ++checked;
        }
      }
  EXPECT_GT(checked, 10000);
}

TEST(Relief, flowstone_sheets_cover_part_of_the_walls_and_smooth_the_rock_beneath) {
  const glm::vec3 n{1, 0, 0};
  int covered = 0, bare = 0, samples = 0;
  double covered_roughness = 0, bare_roughness = 0;
  for (float y = -20; y <= 20; y += 0.25f)
    for (float z = -20; z <= 20; z += 0.25f) {
      const glm::vec3 p{0, y, z};
      // Roughness 1: the rock at its roughest, so the sheet's smoothing shows.
      const rl::Relief r = rl::relief_at(at(p), n, 1.0f, 0.0f, 1.0f);
      const rl::Relief rx = rl::relief_at(at(p + glm::vec3(0, 0.05f, 0)), n, 1.0f, 0.0f, 1.0f);
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
  // None on a level floor.
  int on_floor = 0;
  for (float x = -20; x <= 20; x += 0.25f)
    for (float z = -20; z <= 20; z += 0.25f) {
      const rl::Relief r = rl::relief_at(at({x, 0, z}), {0, 1, 0}, 1.0f, 0.0f, 1.0f);
      on_floor += r.spike > 0.0f;
    }
  EXPECT_EQ(on_floor, 0);
}

// relief_fine (shading below 5 cm) leaves nothing where a pixel covers more than half of its
// coarsest octave (the joints' 27.5 cm), and gives grain, pits and joints where pixels are
// millimetres; the relief's ambient occlusion is 1 without relief and within its bounds with it.
TEST(Relief, fine_detail_vanishes_under_coarse_pixels_and_occlusion_stays_in_bounds) {
  int detailed = 0;
  for (int i = 0; i < 400; ++i) {
    const glm::vec3 p{0.37f * i, 1.3f + 0.011f * i, -0.23f * i};
    const rl::ReliefFine coarse = rl::relief_fine(at(p), {0, 0, 1}, 0.14f, 1, 1, 1);
    EXPECT_EQ(coarse.gradient, glm::vec3(0.0f));
    EXPECT_EQ(coarse.tint, 1.0f);
    EXPECT_EQ(coarse.cavity, 1.0f);
    const rl::ReliefFine fine = rl::relief_fine(at(p), {0, 0, 1}, 0.002f, 1, 1, 1);
    detailed += glm::length(fine.gradient) > 0.01f && fine.tint != 1.0f;
    EXPECT_GT(fine.cavity, 0.0f);
    EXPECT_LE(fine.cavity, 1.0f);
    EXPECT_EQ(rl::relief_at(at(p), {0, 1, 0}, 0.5f, 0, 0).occlusion, 1.0f);
    for (const glm::vec3& n : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0)}) {
      const float o = relief(p, n).occlusion;
      EXPECT_GE(o, rl::kReliefOcclusionMin);
      EXPECT_LE(o, 1.0f);
    }
  }
  EXPECT_GT(detailed, 350);
}

// A joint is a fracture plane's trace: on a ceiling it is a line, straight over its run, never the
// loops and meanders of a noise's zero line (those read as hairs on the lens).
// relief_fine's joints alone, on 8 x 8 m of ceiling sampled every 1 cm: every crack (8-connected
// samples the joints darken) 30 cm long or more is thin for its length, the spread across it
// at most a fifth of the spread along it (the square root of the ratio of its points'
// covariance's eigenvalues), and there are several. Fails with joints along a noise's zero lines
// (the look before: 18 of 25 cracks curl past it; 24, none curled, now).
TEST(Relief, joints_on_a_ceiling_are_straight_lines) {
  constexpr int kSide = 800;
  constexpr float kStep = 0.01f;
  std::vector<uint8_t> crack(kSide * kSide);
  for (int i = 0; i < kSide; ++i)
    for (int j = 0; j < kSide; ++j) {
      const glm::vec3 p{3.1f + kStep * static_cast<float>(i), 7.4f,
                        -5.3f + kStep * static_cast<float>(j)};
      crack[static_cast<size_t>(i) * kSide + static_cast<size_t>(j)] =
          rl::relief_fine(at(p), {0, -1, 0}, kStep, 0, 0, 1).cavity < 0.9f;
    }
  std::vector<uint8_t> seen(crack.size());
  int long_cracks = 0, curled = 0;
  for (size_t start = 0; start < crack.size(); ++start) {
    if (!crack[start] || seen[start]) continue;
    std::vector<size_t> todo{start}, points;
    seen[start] = 1;
    while (!todo.empty()) {
      const size_t k = todo.back();
      todo.pop_back();
      points.push_back(k);
      const int i = static_cast<int>(k / kSide), j = static_cast<int>(k % kSide);
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const int a = i + di, b = j + dj;
          if (a < 0 || b < 0 || a >= kSide || b >= kSide) continue;
          const size_t m = static_cast<size_t>(a) * kSide + static_cast<size_t>(b);
          if (crack[m] && !seen[m]) seen[m] = 1, todo.push_back(m);
        }
    }
    double mx = 0, my = 0;
    for (size_t k : points)
      mx += static_cast<double>(k / kSide), my += static_cast<double>(k % kSide);
    mx /= static_cast<double>(points.size()), my /= static_cast<double>(points.size());
    double sxx = 0, syy = 0, sxy = 0;
    for (size_t k : points) {
      const double x = static_cast<double>(k / kSide) - mx, y = static_cast<double>(k % kSide) - my;
      sxx += x * x, syy += y * y, sxy += x * y;
    }
    const double n = static_cast<double>(points.size());
    sxx /= n, syy /= n, sxy /= n;
    const double mid = 0.5 * (sxx + syy),
                 half = std::sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy);
    const double along = mid + half, across = std::max(mid - half, 0.0);
    // A segment of length L has a spread along of L^2 / 12.
    const double length_m = std::sqrt(12.0 * along) * kStep;
    if (length_m < 0.3) continue;
    ++long_cracks;
    const double ratio = std::sqrt(across / along);
    if (ratio > 0.2) {
      ++curled;
      std::printf("a crack %.2f m long curls: spread across / along %.2f\n", length_m, ratio);
    }
  }
  std::printf("%d cracks of 30 cm or more on 8 x 8 m of ceiling, %d curled\n", long_cracks, curled);
  EXPECT_GE(long_cracks, 10) << "hardly any joints on the ceiling";
  EXPECT_EQ(curled, 0) << "joints meander instead of following a plane";
}

// The same look everywhere: 6,240 km out (sector 65000,0,65000), where a
// float's step is 0.5 m, the relief evaluated from a block and an offset (relief_pos_of, as the
// renderer's anchor and collision give it) varies as smoothly and as much as near the origin:
// along a 2 m line in 1 cm steps no two neighbouring samples are equal, and the height's spread
// and its steps' are those of the origin's within a factor of 1.5. A position formed in float
// world coordinates there (what the shaders did before) is flat in 0.5 m steps: caught below.
TEST(Relief, six_thousand_km_out_it_is_as_fine_as_at_the_origin) {
  struct Line {
    double spread = 0, step = 0;
    int flat = 0;  // neighbouring samples with the same height
  };
  auto line = [](Vec3 frame, bool split) {
    std::vector<float> h;
    for (int i = 0; i <= 200; ++i) {
      const glm::vec3 off(0.01f * static_cast<float>(i), 0.3f, 0.2f);
      const rl::ReliefPos p =
          split ? rl::relief_pos_of(frame, off)
                : rl::relief_pos(glm::ivec3(0),
                                 glm::vec3(static_cast<float>(frame.x), static_cast<float>(frame.y),
                                           static_cast<float>(frame.z)) +
                                     off);
      h.push_back(rl::relief_at(p, {0, 0, 1}, 1.0f, 0.0f, 1.0f).height);
    }
    Line out;
    double mean = 0;
    for (float v : h)
      mean += v;
    mean /= static_cast<double>(h.size());
    for (size_t i = 0; i < h.size(); ++i) {
      out.spread += (h[i] - mean) * (h[i] - mean);
      if (i > 0) {
        out.step += std::abs(h[i] - h[i - 1]);
        out.flat += h[i] == h[i - 1];
      }
    }
    out.spread = std::sqrt(out.spread / static_cast<double>(h.size()));
    out.step /= static_cast<double>(h.size() - 1);
    return out;
  };
  double near_spread = 0, near_step = 0, far_spread = 0, far_step = 0;
  int far_flat = 0, float_flat = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3 near{37.0 * k, 3.5, -11.0 * k};
    const Vec3 far{65000 * 96.0 + 37.0 * k, 3.5, 65000 * 96.0 - 11.0 * k};
    const Line a = line(near, true), b = line(far, true), c = line(far, false);
    near_spread += a.spread, near_step += a.step;
    far_spread += b.spread, far_step += b.step;
    far_flat += b.flat;
    float_flat += c.flat;
  }
  std::printf(
      "spread %.4f near, %.4f far; mean step %.5f near, %.5f far; flat steps far %d, in "
      "float world coordinates %d of 1600\n",
      near_spread / 8, far_spread / 8, near_step / 8, far_step / 8, far_flat, float_flat);
  EXPECT_EQ(far_flat, 0);
  EXPECT_GT(far_step, near_step / 1.5);
  EXPECT_LT(far_step, near_step * 1.5);
  EXPECT_GT(far_spread, near_spread / 1.5);
  EXPECT_LT(far_spread, near_spread * 1.5);
  EXPECT_GT(float_flat, 1000)
      << "the float world coordinates were not coarse: the test shows nothing";
}

// The renderer culls rooms and portals and collision gathers triangles with relief_bound: the
// relief moves a point along its normal by no more, on every kind of surface (rough walls,
// slopes, ceilings, floors), and by far less than the 3.5 m the formations' displacement needed.
TEST(Relief, the_displacement_stays_within_its_bound_of_under_a_metre) {
  const glm::vec3 normals[] = {{0, -1, 0},
                               {0, 1, 0},
                               kSlopeNormal,
                               glm::normalize(glm::vec3(1, 0.2f, 0)),
                               glm::normalize(glm::vec3(0.5f, -0.8f, 0.2f)),
                               glm::normalize(glm::vec3(-0.3f, 0.9f, 0.1f)),
                               {1, 0, 0}};
  const float bound = rl::relief_bound(1.0f);
  EXPECT_LT(bound, 1.0f);
  float worst = 0;
  for (const glm::vec3& n : normals)
    for (float roughness : {0.0f, 1.0f})
      for (float a = -12; a <= 12; a += 0.09f)
        for (float b = -12; b <= 12; b += 0.37f) {
          const glm::vec3 p{a, 3.0f + 0.2f * b, b};
          const rl::Relief r = rl::relief_at(at(p), n, roughness, 0.0f, 1.0f);
          worst = std::max(worst, std::abs(r.height));
        }
  std::printf("along the normal %.2f of %.2f m\n", worst, bound);
  EXPECT_LE(worst, bound);
  EXPECT_GT(worst, 0.4f * bound) << "the samples reach the roughest rock";
}

}  // namespace
}  // namespace grotto::play
