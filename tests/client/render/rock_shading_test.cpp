// The rock's shading up close on llvmpipe under Xvfb: the fine detail
// (shaders/relief.glsl's relief_fine: grain, pits, joints) shows on a wall 1.5 m away and fades
// out far away, the ambient occlusion darkens the crease at a stalagmite's root, a drapery lit
// from behind lets the light through, a stalagmite in front of a flare is veiled by its haze, a
// stalactite in a lit hall's passage gets the hall's spill, and glow-worms seen from metres away
// are dots. Poses in seed 7's hall 0.0.0.r0, found from its patch mesh, the relief's C++ face
// (common/relief/relief.hpp) and the formations' placement (common/formations/formations.hpp), not
// hard-coded.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <optional>
#include <tuple>
#include <vector>

#include "common/formations/formations.hpp"
#include "common/relief/relief.hpp"
#include "tests/client/render/render_scene.hpp"

namespace grotto::render {
namespace {

using namespace test;  // render_scene.hpp

namespace rl = grotto::relief;

// The biggest room of seed 7's sector (0,0,0): its hall.
const stream::ReadyRoom& hall() {
  const stream::ReadyRoom* best = nullptr;
  for (const stream::ReadyRoom& r : sector_rooms(7))
    if (!r.room.id.is_gate() && (!best || r.room.sphere.radius > best->room.sphere.radius))
      best = &r;
  return *best;
}

// The hall's formations as every client places them (common/formations/formations.hpp), and a point
// of the hall's frame in world metres.
std::vector<formations::FormationShape> hall_formations() {
  const stream::ReadyRoom& room = hall();
  return formations::place(formations::surface_of(room.mesh, room.origin, room.room.sphere.radius));
}
Vec3 in_world(glm::vec3 p) {
  return hall().origin + Vec3{p.x, p.y, p.z};
}

// Of `all`, the stalagmite `shortest` to `longest` metres tall whose root is nearest the hall's
// centre (horizontally), or none.
// The stalagmite of length shortest-longest nearest the hall's centre; with `alone`, only one that
// stands on the floor itself: not a drip line's flowstone mound (twice as wide as tall) and not
// on one (the stalagmites of a line stand on its mound, their roots inside it).
const formations::FormationShape* stalagmite_near_centre(
    const std::vector<formations::FormationShape>& all, float shortest, float longest,
    bool alone = false) {
  const Vec3 centre = hall().room.sphere.centre;
  const auto mound = [](const formations::FormationShape& g) {
    return g.kind == formations::kFormationStalagmite && g.radius > 0.5f * g.length;
  };
  const formations::FormationShape* found = nullptr;
  double nearest = 1e300;
  for (const formations::FormationShape& f : all) {
    if (f.kind != formations::kFormationStalagmite || f.length < shortest || f.length > longest)
      continue;
    if (alone && (mound(f) || std::any_of(all.begin(), all.end(), [&](const auto& g) {
                    return mound(g) && std::hypot(g.root.x - f.root.x, g.root.z - f.root.z) <
                                           g.radius * (1.0f + g.flare);
                  })))
      continue;
    const Vec3 at = in_world(f.root);
    const double d = std::hypot(at.x - centre.x, at.z - centre.z);
    if (d < nearest) nearest = d, found = &f;
  }
  return found;
}

// The level unit vector from `at` towards the hall's centre (any level one at the centre).
Vec3 towards_centre(Vec3 at) {
  const Vec3 centre = hall().room.sphere.centre;
  const Vec3 out{centre.x - at.x, 0, centre.z - at.z};
  const double l = std::hypot(out.x, out.z);
  return l > 1e-3 ? Vec3{out.x / l, 0, out.z / l} : Vec3{1, 0, 0};
}

// A player's flare (grotto-client's colour, a 0.3 m source) at `position`, reaching `range` m.
Light flare_at(Vec3 position, float range) {
  Light flare;
  flare.kind = "flare";
  flare.position = position;
  flare.colour = glm::vec3(3.0f, 2.4f, 1.8f);
  flare.range = range;
  flare.source_radius = 0.3f;
  flare.glow = 3;
  return flare;
}

// Frames lit by the test's own lights alone: no headlamp, no haze, no bloom; MaxTess 8.
RenderOptions own_lights_only() {
  RenderOptions o;
  o.max_tess = 8;
  o.bloom = false;
  o.headlamp = false;
  o.haze = 0;
  return o;
}

struct Hit {
  double t = 0;         // metres along the ray
  glm::vec3 normal{0};  // the triangle's interpolated vertex normal
  float roughness = 0;
};

// The first crossing of the ray from `from` along unit `dir` with the room's patch mesh
// (Moller-Trumbore), or none.
std::optional<Hit> cast(const stream::ReadyRoom& room, Vec3 from, Vec3 dir) {
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
  const stream::ReadyRoom& room = hall();
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

// The crease where a stalagmite's root flares into the floor holds less of the sky
// (formation.vert's t_occlusion, 0.8 at the root): seen from 1.5 m away and 0.9 m up, the
// picture's centre (the root) is darker with the ambient occlusion than without, by 5 % at least.
// A stalagmite of the hall 0.3-1.5 m tall, found by formations::place (not hard-coded). Fails
// with the occlusion off (room.frag ignoring t_occlusion: the same pictures).
TEST(RockShading, ambient_occlusion_darkens_the_crease_at_a_stalagmites_root) {
  REQUIRE_GL();
  const std::vector<formations::FormationShape> all = hall_formations();
  const formations::FormationShape* found = stalagmite_near_centre(all, 0.1f, 1.5f, true);
  ASSERT_NE(found, nullptr) << "no stalagmite of 0.1-1.5 m on the hall's floor";
  const Vec3 root = in_world(found->root);
  const Vec3 out = towards_centre(root);  // from the hall's centre's side
  const double r = formations::formation_radius(*found, 0.02f, 0.0f);
  const Vec3 target = root + out * r + Vec3{0, 0.02, 0};
  const Vec3 eye = root + out * 1.5 + Vec3{0, 0.9, 0};
  const Camera camera = aim(eye, target);
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  RenderOptions with;
  with.max_tess = 8;
  with.bloom = false;
  with.fine_detail = 0;  // the occlusion alone
  with.exposure = 0.5f;  // below the tone curve's shoulder
  RenderOptions without = with;
  without.ambient_occlusion = false;
  const double lit_with = centre_luma(scene.draw(camera, with), 3);
  const double lit_without = centre_luma(scene.draw(camera, without), 3);
  std::printf("root of a %.2f m stalagmite: centre luma %.1f with the occlusion, %.1f without\n",
              found->length, lit_with, lit_without);
  EXPECT_GT(lit_without, 10.0) << "the root is not lit: the pose misses it";
  EXPECT_LT(lit_with, 0.95 * lit_without) << "the occlusion does not darken the root";
}

// A drapery's sheet is a few centimetres of calcite: a light behind it shows through (room.frag's
// `through`, lights.glsl): seen from 1.5 m in front of the hall's biggest drapery, the headlamp
// off and no haze, the sheet's middle is lit with a flare 0.8 m behind it and stays dark without.
// Fails with the sheet opaque (through 0: the face towards the eye faces away from the flare and
// gets nothing of it: centre luma 16.3 with the flare and without; 204 with the light through).
TEST(RockShading, a_drapery_lit_from_behind_lets_the_light_through) {
  REQUIRE_GL();
  const stream::ReadyRoom& room = hall();
  const std::vector<formations::FormationShape> all = hall_formations();
  const formations::FormationShape* found = nullptr;
  for (const formations::FormationShape& f : all)
    if (f.kind == formations::kFormationDrapery &&
        (!found || f.radius * f.length > found->radius * found->length))
      found = &f;
  ASSERT_NE(found, nullptr) << "no drapery in the hall";
  const formations::FormationShape& f = *found;
  const glm::vec3 across = formations::drapery_across(f);
  // The middle of its drop, on each face (theta pi/2: the +across face).
  const float half_pi = 1.5707963f;
  const Vec3 face[2] = {in_world(formations::drapery_point(f, 0.0f, half_pi)),
                        in_world(formations::drapery_point(f, 0.0f, 3.0f * half_pi))};
  const Vec3 out[2] = {Vec3{across.x, 0, across.z}, Vec3{-across.x, 0, -across.z}};
  // The eye on a side with 1.6 m of air before the rock, the flare on the other with 1 m.
  auto air = [&](Vec3 from, Vec3 dir, double need) {
    const auto hit = cast(room, from, dir);
    return !hit || hit->t > need;
  };
  int side = -1;
  for (int k = 0; k < 2 && side < 0; ++k)
    if (air(face[k], out[k], 1.6) && air(face[1 - k], out[1 - k], 1.0)) side = k;
  ASSERT_GE(side, 0) << "no side of the drapery has air for the eye and the other for the flare";
  const Camera camera = aim(face[side] + out[side] * 1.5, face[side]);
  const Light flare = flare_at(face[1 - side] + out[1 - side] * 0.8, 6);
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  const RenderOptions options = own_lights_only();
  const double behind = centre_luma(scene.draw(camera, options, nullptr, nullptr, {&flare, 1}), 3);
  const double dark = centre_luma(scene.draw(camera, options), 3);
  std::printf("a %.2f m wide, %.2f m drapery: centre luma %.1f with a flare behind, %.1f without\n",
              2 * f.radius, f.length, behind, dark);
  EXPECT_GT(behind, 20.0) << "no light through the sheet";
  EXPECT_GT(behind, 3.0 * dark + 10.0) << "the flare behind barely lights the sheet";
}

// A formation stands in the lit haze as the rock does (lights.glsl's lights_haze, per vertex in
// formation.vert with its room's hazing lights): a flare hanging between the eye and a
// stalagmite of the hall, 0.3 m above the line of sight, veils the stalagmite's middle with the
// light its haze scatters, so the middle is brighter with the haze than without (158 against 133
// with a haze of 0.1 a metre). Fails with the formations given no hazing lights (the formation
// pass's u_haze_count 0, as before the formations were lit room by room: 133 with the haze and
// without).
TEST(RockShading, a_formation_in_front_of_a_flare_is_veiled_by_its_haze) {
  REQUIRE_GL();
  const stream::ReadyRoom& room = hall();
  const std::vector<formations::FormationShape> all = hall_formations();
  const formations::FormationShape* found = stalagmite_near_centre(all, 0.5f, 2.0f);
  ASSERT_NE(found, nullptr) << "no stalagmite of 0.5-2 m in the hall";
  const formations::FormationShape& f = *found;
  const Vec3 root = in_world(f.root);
  const Vec3 out = towards_centre(root);
  // Its middle, on the side towards the hall's centre; the eye 2 m out and 1.2 m above it, the
  // flare 0.3 m above the line of sight, 0.9 m from the eye.
  const double r = formations::formation_radius(f, 0.5f * f.length, 0.0f);
  const Vec3 target = root + out * r + Vec3{0, 0.5 * f.length, 0};
  const Vec3 eye = target + out * 2.0 + Vec3{0, 1.2, 0};
  const Vec3 to_target = target - eye;
  const auto hit = cast(room, eye, to_target * (1.0 / length(to_target)));
  ASSERT_FALSE(hit && hit->t < length(to_target)) << "rock between the eye and the stalagmite";
  const Camera camera = aim(eye, target);
  const Light flare = flare_at(eye + to_target * 0.4 + Vec3{0, 0.3, 0}, 8);
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  RenderOptions with = own_lights_only();
  with.exposure = 0.5f;  // below the tone curve's shoulder
  with.haze = 0.1f;      // thicker than the default 0.03: the veil well above the picture's noise
  RenderOptions without = with;
  without.haze = 0;
  RenderOptions bare = without;
  bare.formations = false;
  const double hazed = centre_luma(scene.draw(camera, with, nullptr, nullptr, {&flare, 1}), 2);
  const double clear = centre_luma(scene.draw(camera, without, nullptr, nullptr, {&flare, 1}), 2);
  const double rock = centre_luma(scene.draw(camera, bare, nullptr, nullptr, {&flare, 1}), 2);
  std::printf(
      "a %.2f m stalagmite behind a flare: centre luma %.1f with the haze, %.1f without, "
      "%.1f without the formations\n",
      f.length, hazed, clear, rock);
  EXPECT_GT(std::abs(clear - rock), 5.0) << "the pose misses the stalagmite";
  EXPECT_GT(hazed, clear + 3.0) << "the flare's haze does not veil the stalagmite";
}

// A light's spill (lights.glsl's kLightSpill) reaches the formations of the rooms through its
// room's portals as it reaches their rock: a formation a few metres past the hall's wall, in a
// passage off it, is lit by a light hung inside the hall's mouth to that passage (bounded by the
// hall's sphere, the hall its room), seen from 1.5 m on the side facing it, the headlamp off.
// Fails with the formations lit as if in the light's own room (u_light_next_door 0, as before the
// formations were lit room by room: its bound stops the light at the hall's wall and the
// formation stays as dark as without the light, a black shard against the lit rock: luma 17
// against 182).
TEST(RockShading, a_formation_through_a_lit_halls_portal_gets_its_spill) {
  REQUIRE_GL();
  const stream::ReadyRoom& lit = hall();
  const Vec3 centre = lit.room.sphere.centre;
  const double bound = lit.room.sphere.radius;
  struct Pick {
    Vec3 middle, light, eye;
    float length = 0;
    double past = 0;  // metres past the bound
  };
  std::optional<Pick> pick;
  for (const cave::Portal& portal : lit.room.portals) {
    const stream::ReadyRoom* next = nullptr;
    for (const stream::ReadyRoom& r : sector_rooms(7))
      if (r.room.id == portal.neighbour) next = &r;
    if (next == nullptr) continue;
    for (const formations::FormationShape& f : formations::place(
             formations::surface_of(next->mesh, next->origin, next->room.sphere.radius))) {
      if (f.kind == formations::kFormationDrapery || f.length < 0.3f) continue;
      const float half = 0.5f * f.length;
      const Vec3 middle =
          next->origin +
          Vec3{f.root.x, f.root.y + formations::formation_direction(f) * half, f.root.z};
      const double past = length(middle - centre) - bound;
      if (past < 0.5 || past > 4.0 || (pick && past >= pick->past)) continue;
      const Vec3 light = portal.centre - portal.normal * 1.5;  // in the hall, before its mouth
      Vec3 dir{light.x - middle.x, 0, light.z - middle.z};
      const double l = std::hypot(dir.x, dir.z);
      if (l < 0.5) continue;
      dir = dir * (1.0 / l);
      const Vec3 surface = middle + dir * formations::formation_radius(f, half, 0.0f);
      const auto hit = cast(*next, surface, dir);
      if (hit && hit->t < 1.6) continue;  // no air before it on that side
      pick = Pick{surface, light, surface + dir * 1.5, f.length, past};
    }
  }
  ASSERT_TRUE(pick.has_value()) << "no formation 0.5-4 m past the hall's wall with air before it";
  const Camera camera = aim(pick->eye, pick->middle);
  Light glow;
  glow.kind = "seam";
  glow.position = pick->light;
  glow.colour = glm::vec3(20.0f, 16.0f, 10.0f);
  glow.range = 25;
  glow.source_radius = 1.0f;
  glow.glow = 1;
  glow.bound_centre = centre;
  glow.bound_radius = static_cast<float>(bound);
  glow.room = lit.room.id;
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  const RenderOptions options = own_lights_only();
  RenderOptions bare = options;
  bare.formations = false;
  const double spilt = centre_luma(scene.draw(camera, options, nullptr, nullptr, {&glow, 1}), 2);
  const double dark = centre_luma(scene.draw(camera, options), 2);
  const double rock = centre_luma(scene.draw(camera, bare, nullptr, nullptr, {&glow, 1}), 2);
  std::printf(
      "a %.2f m formation %.1f m past the hall's wall: centre luma %.1f with the hall's "
      "light, %.1f without, %.1f without the formations\n",
      pick->length, pick->past, spilt, dark, rock);
  EXPECT_GT(std::abs(spilt - rock), 3.0) << "the pose misses the formation";
  EXPECT_GT(spilt, dark + 10.0) << "the hall's light does not spill onto the formation";
}

// A glow-worm colony seen from a few metres is a field of separate points of light, each a dot of
// one to four pixels (lights.glsl's glow_worms: a larva's light spread over at most the pixel's
// footprint), not a cross of five: a colony on the hall's roof 3 m above the eye (1.4 cm pixels,
// the larvae 7 cm apart), the headlamp off, bloom off: of the lit spots (4-connected pixels of
// luma over 160) in the middle third of the picture, at most 15 % are wider than 2 pixels (12 of
// 215: two larvae in neighbouring cells can touch). Fails with the larvae as Gaussians a footprint
// wide (exp(-d^2 / s^2), their peak clipped: 158 of 182 spots wider, crosses and blocks up to 12
// pixels).
TEST(RockShading, far_glow_worms_are_dots_not_crosses) {
  REQUIRE_GL();
  const stream::ReadyRoom& room = hall();
  const Vec3 centre = room.room.sphere.centre;
  const auto roof = cast(room, centre, Vec3{0, 1, 0});
  ASSERT_TRUE(roof.has_value()) << "no roof above the hall's centre";
  const Vec3 top = centre + Vec3{0, roof->t, 0};
  Light colony;
  colony.kind = "glow_worms";
  colony.position = top - Vec3{0, 0.3, 0};
  colony.colour = glm::vec3(0.4f, 1.6f, 1.4f);
  colony.range = 20;
  colony.size = 4;
  colony.source_radius = 1.5f;
  colony.glow = 0;
  const Camera camera = aim(top - Vec3{0.3, 3.0, 0}, top);
  Scene scene(7);
  ASSERT_TRUE(scene.ok());
  RenderOptions options = own_lights_only();
  options.formations = false;  // the roof alone (larvae on a stalactite's flank crowd together)
  const Image image = scene.draw(camera, options, nullptr, nullptr, {&colony, 1});
  // The middle third of the picture, where the roof faces the eye (at a grazing angle the larvae
  // crowd together on screen).
  std::vector<bool> lit(static_cast<size_t>(kWidth * kHeight));
  for (int y = kHeight / 3; y < 2 * kHeight / 3; ++y)
    for (int x = kWidth / 3; x < 2 * kWidth / 3; ++x) {
      const size_t i = static_cast<size_t>(y) * kWidth + static_cast<size_t>(x);
      lit[i] = 0.2126 * image.rgb[3 * i] + 0.7152 * image.rgb[3 * i + 1] +
                   0.0722 * image.rgb[3 * i + 2] >
               160;
    }
  int spots = 0, big = 0, widest = 0;
  std::vector<bool> seen(lit.size());
  for (size_t start = 0; start < lit.size(); ++start) {
    if (!lit[start] || seen[start]) continue;
    int x0 = kWidth, x1 = -1, y0 = kHeight, y1 = -1;
    std::vector<size_t> todo{start};
    seen[start] = true;
    while (!todo.empty()) {
      const size_t i = todo.back();
      todo.pop_back();
      const int x = static_cast<int>(i % kWidth), y = static_cast<int>(i / kWidth);
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
      const int near[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
      for (const auto& [nx, ny] : near) {
        if (nx < 0 || ny < 0 || nx >= kWidth || ny >= kHeight) continue;
        const size_t k = static_cast<size_t>(ny) * kWidth + static_cast<size_t>(nx);
        if (lit[k] && !seen[k]) seen[k] = true, todo.push_back(k);
      }
    }
    ++spots;
    const int extent = std::max(x1 - x0, y1 - y0) + 1;
    widest = std::max(widest, extent);
    big += extent > 2;
  }
  std::printf("glow-worms 3 m away: %d lit spots, %d wider than 2 pixels (the widest %d)\n", spots,
              big, widest);
  EXPECT_GT(spots, 20) << "the colony's larvae are not drawn";
  EXPECT_LE(big, 0.15 * spots) << "larvae drawn as crosses or blocks, not dots";
}

}  // namespace
}  // namespace grotto::render
