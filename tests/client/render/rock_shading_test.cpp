// The rock's shading up close (issue 27, items 4 and 5) on llvmpipe under Xvfb: the fine detail
// (shaders/relief.glsl's relief_fine: grain, pits, joints) shows on a wall 1.5 m away and fades
// out far away, and the relief's ambient occlusion (Relief::occlusion) darkens the floor at a
// stalagmite's foot. Poses in seed 7's hall 0.0.0.r0, found from its patch mesh and the relief's
// C++ face (shaders/relief.hpp), not hard-coded.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>

#include "render_scene.hpp"
#include "shaders/relief.hpp"

namespace grotto::render {
namespace {

using namespace test;  // render_scene.hpp

namespace rl = grotto::relief;

// The biggest room of seed 7's sector (0,0,0): its hall.
const client::ReadyRoom& hall() {
  const client::ReadyRoom* best = nullptr;
  for (const client::ReadyRoom& r : sector_rooms(7))
    if (!r.room.id.is_gate() && (!best || r.room.sphere.radius > best->room.sphere.radius))
      best = &r;
  return *best;
}

struct Hit {
  double t = 0;         // metres along the ray
  glm::vec3 normal{0};  // the triangle's interpolated vertex normal
  float roughness = 0;
};

// The first crossing of the ray from `from` along unit `dir` with the room's patch mesh
// (Moller-Trumbore), or none.
std::optional<Hit> cast(const client::ReadyRoom& room, Vec3 from, Vec3 dir) {
  const auto& m = room.mesh;
  std::optional<Hit> best;
  const glm::dvec3 o{from.x - room.origin.x, from.y - room.origin.y, from.z - room.origin.z};
  const glm::dvec3 d{dir.x, dir.y, dir.z};
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    const uint32_t ia = m.indices[i], ib = m.indices[i + 1], ic = m.indices[i + 2];
    auto at = [&](uint32_t k) {
      return glm::dvec3{m.positions[k].x, m.positions[k].y, m.positions[k].z};
    };
    const glm::dvec3 a = at(ia), e1 = at(ib) - a, e2 = at(ic) - a;
    const glm::dvec3 p = glm::cross(d, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-12) continue;
    const glm::dvec3 s = o - a;
    const double u = glm::dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const glm::dvec3 q = glm::cross(s, e1);
    const double v = glm::dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    const double t = glm::dot(e2, q) / det;
    if (t <= 1e-4 || (best && t >= best->t)) continue;
    auto normal = [&](uint32_t k) {
      return glm::vec3{m.normals[k].x, m.normals[k].y, m.normals[k].z};
    };
    const float w0 = static_cast<float>(1 - u - v), w1 = static_cast<float>(u),
                w2 = static_cast<float>(v);
    best = Hit{t, glm::normalize(normal(ia) * w0 + normal(ib) * w1 + normal(ic) * w2),
               m.roughness[ia] * w0 + m.roughness[ib] * w1 + m.roughness[ic] * w2};
  }
  return best;
}

// A camera at `eye` looking at `target`.
Camera aim(Vec3 eye, Vec3 target) {
  const Vec3 d = target - eye;
  Camera c;
  c.position = eye;
  c.yaw = std::atan2(d.x, -d.z);
  c.pitch = std::asin(d.y / length(d));
  return c;
}

// Mean luma over the (2k+1)^2 pixels round the image's centre.
double centre_luma(const Image& image, int k) {
  double sum = 0;
  int n = 0;
  for (int y = kHeight / 2 - k; y <= kHeight / 2 + k; ++y)
    for (int x = kWidth / 2 - k; x <= kWidth / 2 + k; ++x) {
      const size_t i = 3 * (static_cast<size_t>(y) * kWidth + static_cast<size_t>(x));
      sum += 0.2126 * image.rgb[i] + 0.7152 * image.rgb[i + 1] + 0.0722 * image.rgb[i + 2];
      ++n;
    }
  return sum / n;
}

// The mean absolute difference of luma between horizontally neighbouring pixels: how much fine
// contrast a picture holds.
double edge_energy(const Image& image) {
  double sum = 0;
  auto luma = [&](size_t i) {
    return 0.2126 * image.rgb[i] + 0.7152 * image.rgb[i + 1] + 0.0722 * image.rgb[i + 2];
  };
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x + 1 < kWidth; ++x) {
      const size_t i = 3 * (static_cast<size_t>(y) * kWidth + static_cast<size_t>(x));
      sum += std::abs(luma(i + 3) - luma(i));
    }
  return sum / (kHeight * (kWidth - 1));
}

// Fine detail is shading below the tessellation's reach, faded by the pixel's footprint: on a
// wall 1 m away (6 mm pixels at 320x240) the grain, pits and joints change 30 % of the pixels or
// more and add 30 % to the fine contrast (edge_energy); 12 m away (7 cm pixels: grain and pits
// under 2 pixels, only the box-filtered joints left) at most 3 % change and the fine contrast
// grows by at most 5 %. Fails with the detail off (relief_fine returning nothing: the close
// pictures are the same); checked to fail with the fade off (relief_fine_fade always 1: far
// away 35 % of the pixels change and the fine contrast is 1.9x).
TEST(RockShading, fine_detail_shows_up_close_and_fades_out_far_away) {
  REQUIRE_GL();
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  const client::ReadyRoom& room = hall();
  const Vec3 centre = room.room.sphere.centre;
  // A level look at the wall, from the hall's centre, at the first yaw whose wall is far enough
  // for both poses.
  std::optional<Vec3> dir;
  double wall = 0;
  for (double yaw : {0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0}) {
    const double a = yaw * 3.14159265358979323846 / 180;
    const Vec3 d{std::sin(a), 0, -std::cos(a)};
    const auto hit = cast(room, centre, d);
    if (hit && hit->t > 13.5) {
      dir = d, wall = hit->t;
      break;
    }
  }
  ASSERT_TRUE(dir) << "no wall 13.5 m from the hall's centre";
  RenderOptions on;
  on.max_tess = 8;
  on.bloom = false;
  RenderOptions off = on;
  off.fine_detail = 0;
  double changed[2], edges_on[2], edges_off[2];
  const double away[2] = {1.0, 12.0};
  for (int i = 0; i < 2; ++i) {
    const Vec3 eye = centre + *dir * (wall - away[i]);
    const Camera camera = aim(eye, eye + *dir);
    const Image a = scene.draw(camera, on), b = scene.draw(camera, off);
    changed[i] = static_cast<double>(pixels_differing_by_more_than(a, b, 2)) / (kWidth * kHeight);
    edges_on[i] = edge_energy(a);
    edges_off[i] = edge_energy(b);
    std::printf(
        "fine detail: wall %.1f m away: %.1f %% of pixels change by > 2/255, fine "
        "contrast %.2f with it, %.2f without (mean luma %.1f, %.1f)\n",
        away[i], 100 * changed[i], edges_on[i], edges_off[i], a.mean_luma(), b.mean_luma());
  }
  EXPECT_GE(changed[0], 0.3) << "the close wall shows no fine detail";
  EXPECT_GE(edges_on[0], 1.3 * edges_off[0]) << "the close wall's fine contrast hardly grows";
  EXPECT_LE(changed[1], 0.03) << "the fine detail does not fade out far away";
  EXPECT_LE(edges_on[1], 1.05 * edges_off[1]) << "far away the detail adds contrast (aliasing)";
}

// The relief's ambient occlusion darkens the floor round a stalagmite's foot: a stalagmite of
// the hall's floor 0.6-2 m tall, the floor where it rises out of it (its height under 5 % of
// the stalagmite's), seen from 2.2 m away and 1.6 m up: the relief's C++ face puts the
// occlusion there under 0.8 and over 0.9 a metre out on open floor, and the picture's centre
// (the foot) is darker with the occlusion than without by 10 % at least (14 %: luma 119.1
// against 138.6 at exposure 0.5, in the hall of the ceilings and the 64 m fog). Fails with the
// occlusion off (room.frag ignoring t_occlusion: the same pictures).
TEST(RockShading, ambient_occlusion_darkens_the_floor_at_a_stalagmites_foot) {
  REQUIRE_GL();
  const client::ReadyRoom& room = hall();
  const float radius = static_cast<float>(room.room.sphere.radius);
  const Vec3 centre = room.room.sphere.centre;
  auto relief = [&](glm::vec3 p, glm::vec3 n, float roughness) {
    return rl::relief_at(p, n, roughness, 0.0f, radius, 1.0f);
  };
  auto to_glm = [](Vec3 v) {
    return glm::vec3{static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
  };
  // Stalagmites of the lattice within 0.6 radii of the centre (in plan), nearest the centre first.
  struct Found {
    glm::vec3 axis;  // the floor point under its tip
    glm::vec3 normal;
    float roughness = 0;
    float tall = 0;
  };
  std::optional<Found> found;
  const int reach = static_cast<int>(0.6 * radius);
  for (int ring = 0; ring <= reach && !found; ++ring)
    for (int cz = -ring; cz <= ring && !found; ++cz)
      for (int cx = -ring; cx <= ring && !found; ++cx) {
        if (std::max(std::abs(cx), std::abs(cz)) != ring) continue;
        // A lattice cell round the centre's (the turned frame of relief_turn).
        const glm::vec2 here = rl::relief_turn(to_glm(centre));
        const glm::ivec2 cell = glm::ivec2(glm::floor(here)) + glm::ivec2(cx, cz);
        const rl::Speleothem sp = rl::relief_speleothem(cell, 1.0f);
        if (!(sp.len > 0) || sp.level >= 0) continue;  // none, or a column cell
        const float u = sp.centre.x, v = sp.centre.y;
        const Vec3 top{rl::kReliefTurnCos * u + rl::kReliefTurnSin * v, centre.y,
                       -rl::kReliefTurnSin * u + rl::kReliefTurnCos * v};
        const auto hit = cast(room, top, {0, -1, 0});
        if (!hit || hit->normal.y < 0.97f) continue;
        const glm::vec3 floor = to_glm(top) - glm::vec3(0, static_cast<float>(hit->t), 0);
        const float tall = relief(floor, hit->normal, hit->roughness).hang;
        if (tall < 0.6f || tall > 2.0f) continue;
        found = Found{floor, hit->normal, hit->roughness, tall};
      }
  ASSERT_TRUE(found) << "no stalagmite of 0.6-2 m near the hall's centre";
  // Towards the hall's centre (open floor, the camera's side): the foot is where the
  // stalagmite's height falls under 5 % of its top's.
  glm::vec3 out = to_glm(centre) - found->axis;
  out.y = 0;
  out = glm::length(out) > 1e-3f ? glm::normalize(out) : glm::vec3(1, 0, 0);
  float at = 0.02f;
  while (at < 1.0f &&
         relief(found->axis + at * out, found->normal, found->roughness).hang > 0.05f * found->tall)
    at += 0.01f;
  const glm::vec3 foot_plane = found->axis + at * out;
  const rl::Relief foot = relief(foot_plane, found->normal, found->roughness);
  const rl::Relief open = relief(found->axis + (at + 1.0f) * out, found->normal, found->roughness);
  std::printf(
      "stalagmite %.2f m tall at %.1f, %.1f, %.1f: foot %.2f m from its axis, occlusion "
      "%.2f there, %.2f a metre out\n",
      found->tall, found->axis.x, found->axis.y, found->axis.z, at, foot.occlusion, open.occlusion);
  EXPECT_LT(foot.occlusion, 0.8f);
  EXPECT_GT(open.occlusion, foot.occlusion + 0.1f);

  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  const glm::vec3 target = rl::relief_displace(foot_plane, found->normal, foot);
  const glm::vec3 eye = found->axis + 2.2f * out + glm::vec3(0, 1.6f, 0);
  const Camera camera = aim({eye.x, eye.y, eye.z}, {target.x, target.y, target.z});
  RenderOptions with;
  with.max_tess = 8;
  with.bloom = false;
  with.fine_detail = 0;  // the occlusion alone
  // Below the tone curve's shoulder, where a darker light reads darker: with the fog at 64 m the
  // hall's lights reach the foot too, and at exposure 1 its luma sat at ~170-180 of 255.
  with.exposure = 0.5f;
  RenderOptions without = with;
  without.ambient_occlusion = false;
  const double lit_with = centre_luma(scene.draw(camera, with), 5);
  const double lit_without = centre_luma(scene.draw(camera, without), 5);
  std::printf("foot of the stalagmite: centre luma %.1f with the occlusion, %.1f without\n",
              lit_with, lit_without);
  EXPECT_GT(lit_without, 10.0) << "the foot is not lit: the pose misses it";
  EXPECT_LT(lit_with, 0.9 * lit_without) << "the occlusion does not darken the foot";
}

}  // namespace
}  // namespace grotto::render
