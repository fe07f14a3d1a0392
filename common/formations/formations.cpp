#include "common/formations/formations.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <tuple>
#include <utility>

#include "common/formations/placer.hpp"
#include "common/relief/relief.hpp"

namespace grotto::formations {
namespace {

using detail::Hit;
using detail::kCeiling;
using detail::kFloor;
using detail::Placer;
using detail::SurfacePoint;

// Drips closer than this to the floor make no formation; below `kColumnGap` metres a column cell
// joins its floor and ceiling.
constexpr float kMinGap = 0.4f;
constexpr float kColumnGap = 4.0f;
// Of the stalactites shorter than kStrawLength, this share are soda straws: hollow tubes as wide
// as the drop (3-4.5 mm radius) that have not yet thickened.
constexpr float kStrawLength = 0.35f;
constexpr float kStrawShare = 0.6f;
// A floor's drip point whose ceiling is no ceiling (a wall's overhang, the rock of a room above)
// still grows a stalagmite with this chance.
constexpr float kLoneStalagmite = 0.1f;
// On a ceiling inclined more than 30 degrees (its normal's y above this), water trickles down
// along a line and deposits a drapery instead of a stalactite with this chance.
constexpr float kDraperyCeiling = -0.87f;
constexpr float kDraperyShare = 0.45f;

// The lattice's own hash of cell c with salt k (relief_hash), 0-1.
float cell_hash(ivec2 c, int salt) {
  return relief::relief_hash(ivec3(c.x, salt, c.y));
}

// A stalactite's or stalagmite's share of its cell's hashes that shapes it (not where it is).
void shape_from_hashes(FormationShape& f, ivec2 c, int salt) {
  f.seed = cell_hash(c, salt + 11);
  f.yaw = 6.2831853f * cell_hash(c, salt + 13);
  f.rings = 0.02f + 0.05f * cell_hash(c, salt + 17);
  const float b = cell_hash(c, salt + 19);
  f.bulbs = b > 0.6f ? 0.25f * (b - 0.6f) : 0.0f;
}

// How far a root's flare `reach` metres wide spans in height on a surface with unit normal n
// (a slope's rise over the flare), for its embedding.
float slope_rise(vec3 n, float reach) {
  return reach * std::sqrt(std::max(1.0f - n.y * n.y, 0.0f)) / std::max(std::abs(n.y), 0.3f);
}

}  // namespace

float root_embed() {
  return relief::relief_normal_bound(1.0f);
}

namespace {

// A stalagmite standing at room-frame (x, z) on `ground`: `height` tall, `radius` wide at its
// root (clamped to 3-90 cm), its form (0 a bell-shaped cone, 1 a candle) from the drip's cell.
FormationShape stalagmite(const SurfacePoint& ground, vec2 xz, float height, float radius,
                          float form) {
  FormationShape g{};
  g.kind = kFormationStalagmite;
  g.root = vec3(xz.x, ground.position.y, xz.y);
  g.length = height;
  g.radius = std::clamp(radius, 0.03f, 0.9f);
  g.tip = 0.0f;
  g.taper = mix(2.0f, 6.0f, form);
  g.flare = 0.35f;
  g.embed = root_embed() + slope_rise(ground.normal, g.radius * (1.0f + g.flare)) + 0.05f;
  return g;
}

// Where water drips: lines of drip points along the cracks in the ceiling (relief.glsl's crack
// field, the rock's joints), a line in some cells of a kClusterCell lattice, more and longer where
// the region is wet. Between the lines the rock stays dry: most of a floor is bare, and the
// formations gather in fringes of stalactites over mounds of stalagmites, as in Carlsbad's and
// Postojna's halls.
constexpr double kClusterCell = 4.0;  // metres (relief_turn's frame): at most one line a cell
constexpr double kWetCell = 24.0;     // metres: the regions that are wet or dry
constexpr float kLineChance = 0.25f;  // a cell's chance of a line where the region is wettest
// Of the other cells, this share has a slow line: water that seeps too slowly to build on the
// floor, a fringe of stalactites and straws over bare floor.
constexpr float kSlowLineChance = 0.3f;
constexpr int kMaxLineDrips = 30;
// Beneath a line's middle the water that ran off its stalagmites built a flowstone mound this
// much wider than it is tall.
constexpr float kMoundWidth = 2.0f;
// ... and no wider than this (metres at its root, above its flare): a boss under the line's
// middle, with the line's outer stalagmites standing on the floor beside it.
constexpr float kMoundRadius = 0.55f;

// A drip point, in relief_turn's frame, with the hashes that shape what grows there.
struct Drip {
  dvec2 at{0.0};
  ivec2 key{0};         // cell_hash's cell: this drip's own hashes
  float size3 = 0;      // its length's share of the longest (size^2: straws to metres)
  float form = 0;       // 0 a bell-shaped cone .. 1 a candle
  bool column = false;  // may join its floor and ceiling below kColumnGap
  bool mound = false;   // the line's flowstone mound, on the floor beneath its middle
  bool drapes = false;  // on an inclined ceiling: may deposit a drapery (every third drip)
  bool slow = false;    // a slow line's: nothing grows on the floor beneath it
  float tint = 0;       // formation_colour's palette: the minerals in its water
  float wet = 0;        // the region's water, 0-1
};

// Value noise over cells `size` metres across at turned-frame point u, 0-1 (its hashes salted).
float region_noise(dvec2 u, double size, int salt) {
  const dvec2 x = u / size;
  const dvec2 cell = floor(x);
  const ivec2 i = ivec2(cell);
  const vec2 f = smoothstep(vec2(0.0f), vec2(1.0f), vec2(x - cell));
  const float h00 = cell_hash(i, salt), h10 = cell_hash(i + ivec2(1, 0), salt);
  const float h01 = cell_hash(i + ivec2(0, 1), salt), h11 = cell_hash(i + ivec2(1, 1), salt);
  return mix(mix(h00, h10, f.x), mix(h01, h11, f.x), f.y);
}

// How wet the region round turned-frame point u is, 0-1.
float wetness(dvec2 u) {
  return region_noise(u, kWetCell, 52711);
}

// The minerals the region's water carries (formation_colour's palette): mostly clean calcite,
// white to cream, with regions of iron (orange, brown) and a few of manganese (grey).
float region_tint(dvec2 u) {
  const float v = region_noise(u, 32.0, 52757);
  return 0.85f * v * v + 0.15f * v;
}

// The drip line of cluster cell c, if it has one: its drips along the crack nearest a point of
// the cell, from one end to the other, then its mound (a slow line has none).
void line_drips(ivec2 c, std::vector<Drip>& out) {
  const dvec2 base = dvec2(c) * kClusterCell;
  const float wet = wetness(base + 0.5 * kClusterCell);
  const bool fast = cell_hash(c, 60013) < kLineChance * (0.3f + 0.7f * smoothstep(0.2f, 0.8f, wet));
  if (!fast && !(cell_hash(c, 60043) < kSlowLineChance)) return;
  dvec2 middle = base + dvec2(0.15 + 0.7 * cell_hash(c, 60017), 0.15 + 0.7 * cell_hash(c, 60019)) *
                            kClusterCell;
  // One Newton step onto the crack (the field's zero line), as relief_speleothem does.
  const ivec2 m = ivec2(floor(middle));
  const vec4 k = relief::relief_crack_noise(m, vec2(middle - dvec2(m)));
  const vec2 g = vec2(k.y, k.w) * relief::relief_frequency(ivec3(relief::kReliefCrackK)).x;
  const float g2 = dot(g, g) + 1e-6f;
  vec2 step = -(k.x / g2) * g;
  if (length(step) > 1.5f) step *= 1.5f / length(step);
  middle += dvec2(step);
  const vec2 along = g2 > 1e-5f ? normalize(vec2(-g.y, g.x)) : vec2(1.0f, 0.0f);
  const vec2 across(-along.y, along.x);
  // A slow line's formations are dusty: a little greyer.
  const float tint = std::clamp(region_tint(base + 0.5 * kClusterCell) +
                                    0.25f * (cell_hash(c, 60047) - 0.5f) + (fast ? 0.0f : 0.1f),
                                0.0f, 1.0f);
  const int n = fast ? std::min(kMaxLineDrips,
                                10 + static_cast<int>(cell_hash(c, 60029) * (6.0f + 16.0f * wet)))
                     : 5 + static_cast<int>(cell_hash(c, 60029) * 8.0f);
  const float spacing = 0.06f + 0.08f * cell_hash(c, 60031);
  const float bend = 0.6f * (cell_hash(c, 60037) - 0.5f);  // the crack curves a little
  for (int i = 0; i < n; ++i) {
    Drip d;
    d.key = ivec2(c.x * 64 + i, c.y * 64 + 1);
    const float t = (static_cast<float>(i) + 0.5f) / static_cast<float>(n) - 0.5f;  // -0.5..0.5
    const float a = t * static_cast<float>(n) * spacing + 0.04f * (cell_hash(d.key, 61001) - 0.5f);
    const float b = bend * (4.0f * t * t - 1.0f) + 0.08f * (cell_hash(d.key, 61003) - 0.5f);
    d.at = middle + dvec2(along * a + across * b);
    // Longest where the line drips most, in its middle; straws to metres along it.
    const float size =
        std::min(1.0f, cell_hash(d.key, 15485863) * (1.3f - 0.9f * std::abs(2.0f * t)));
    d.size3 = std::max(relief::kReliefStraw, size * size);
    d.form = cell_hash(d.key, 2750159);
    d.column = fast && i == n / 2 && cell_hash(c, 60041) < 0.3f;
    d.drapes = i % 3 == 0;
    d.slow = !fast;
    d.tint = std::clamp(tint + 0.12f * (cell_hash(d.key, 61007) - 0.5f), 0.0f, 1.0f);
    d.wet = wet;
    out.push_back(d);
  }
  if (!fast) return;
  Drip mound;
  mound.at = middle;
  mound.key = ivec2(c.x * 64 + 63, c.y * 64 + 1);
  mound.mound = true;
  mound.wet = wet;
  mound.form = 0.0f;
  mound.tint = tint;
  out.push_back(mound);
}

}  // namespace

std::vector<FormationShape> place(const Surface& s) {
  std::vector<FormationShape> out;
  const size_t triangles = s.indices.size() / 3;
  if (triangles == 0 || s.normals.size() < s.positions.size()) return out;
  const Placer placer(s);
  const float longest_here = relief::relief_spike_length(static_cast<float>(s.room_radius));
  const double ct = relief::kReliefTurnCos, st = relief::kReliefTurnSin;

  // The drip lines of every cluster cell near the room's plan (relief_turn's frame), the cells
  // whose lines can reach it: a line's middle lies at most 1.5 m out of its cell, its drips
  // kMaxLineDrips x 0.14 m / 2 from its middle.
  dvec2 lo(1e300), hi(-1e300);
  for (const auto& p : s.positions) {
    const double wx = s.origin.x + p.x, wz = s.origin.z + p.z;
    const dvec2 t(ct * wx - st * wz, st * wx + ct * wz);  // relief_turn
    lo = min(lo, t);
    hi = max(hi, t);
  }
  const double margin = 1.5 + 0.5 * kMaxLineDrips * 0.14;
  const ivec2 first = ivec2(floor((lo - margin) / kClusterCell));
  const ivec2 last = ivec2(floor((hi + margin) / kClusterCell));
  std::vector<Drip> drips;
  for (int cz = first.y; cz <= last.y; ++cz)
    for (int cx = first.x; cx <= last.x; ++cx)
      line_drips(ivec2(cx, cz), drips);

  for (const Drip& drip : drips) {
    const ivec2 c = drip.key;
    const size_t placed = out.size();
    // From the lattice's frame to the world (the turn's inverse), then the room's.
    const double wx = ct * drip.at.x + st * drip.at.y, wz = -st * drip.at.x + ct * drip.at.y;
    const vec2 xz(static_cast<float>(wx - s.origin.x), static_cast<float>(wz - s.origin.z));
    const std::vector<Hit> list = placer.vertical_hits(xz);
    if (list.empty()) continue;
    const float variety =
        relief::relief_variety(relief::relief_pos_of(Vec3{wx, s.origin.y, wz}, vec3(0.0f)));
    const float longest = longest_here * mix(0.45f, 1.0f, smoothstep(0.3f, 0.75f, variety));
    const float size3 = drip.size3;
    for (size_t i = 0; i < list.size(); ++i) {
      const Hit& h = list[i];
      const bool ceiling = h.facing < kCeiling;
      const bool floor = h.facing > kFloor;
      // Inside the cave, a vertical line leaves a floor upwards and meets a ceiling; the surface
      // below a ceiling hit is the one the drip falls on.
      if (ceiling) {
        const Hit* below = i > 0 ? &list[i - 1] : nullptr;
        const SurfacePoint top = placer.surface_at(h, xz);
        if (!top.clear) continue;
        const bool on_floor = below != nullptr && below->facing > kFloor;
        SurfacePoint ground;
        float gap = 1e9f;
        if (on_floor) {
          ground = placer.surface_at(*below, xz);
          gap = top.position.y - ground.position.y;
        } else if (below != nullptr) {
          gap = top.position.y - below->y;
        }
        if (!(gap > kMinGap)) continue;
        if (drip.mound) {
          // The line's mound: broad and low, wetter lines' higher.
          if (!on_floor || !ground.clear) continue;
          const float height =
              std::min((0.2f + 0.4f * drip.wet) * (0.6f + 0.8f * cell_hash(c, 62003)), 0.3f * gap);
          FormationShape g =
              stalagmite(ground, xz, height, std::min(kMoundWidth * height, kMoundRadius), 0.0f);
          g.flare = 0.3f;
          g.embed = root_embed() + slope_rise(ground.normal, g.radius * (1.0f + g.flare)) + 0.05f;
          shape_from_hashes(g, c, 900);
          if (placer.fit_embed(g)) out.push_back(g);
          continue;
        }
        float len = std::max(relief::kReliefStraw, longest * size3);
        const bool straw = len < kStrawLength && cell_hash(c, 31337) < kStrawShare;
        float radius =
            straw ? 0.003f + 0.0015f * cell_hash(c, 4241) : std::min(0.015f + 0.09f * len, 0.4f);
        float len_g = mix(0.5f, 0.65f, drip.form) * len * (0.5f + cell_hash(c, 271));
        const bool column = !drip.slow && on_floor && ground.clear &&
                            ((drip.column && gap < kColumnGap) || len + len_g > 0.8f * gap);
        if (column) {
          FormationShape f{};
          f.kind = kFormationColumn;
          f.root = vec3(xz.x, ground.position.y, xz.y);
          f.length = gap;
          f.radius = std::clamp(0.12f + 0.06f * gap, 0.15f, 0.45f) * (0.8f + 0.4f * drip.form);
          f.tip = f.radius;
          f.taper = 0.3f + 0.5f * cell_hash(c, 977);
          f.flare = 0.8f;
          const float r = f.radius * (1.0f + f.flare);
          f.embed = root_embed() + slope_rise(top.normal, r) + 0.1f;
          shape_from_hashes(f, c, 500);
          if (placer.fit_embed(f)) out.push_back(f);
          continue;
        }
        if (drip.drapes && top.normal.y > kDraperyCeiling && cell_hash(c, 4099) < kDraperyShare) {
          // A drapery along the slope (the water's way down it: the normal's horizontal part).
          FormationShape d{};
          d.kind = kFormationDrapery;
          d.root = vec3(xz.x, top.position.y, xz.y);
          d.length = std::min(std::max(1.3f * len, 0.25f), 0.45f * gap);
          d.radius =
              std::clamp(0.25f + 0.5f * d.length, 0.25f, 1.2f) * (0.7f + 0.6f * cell_hash(c, 4111));
          d.tip = 0.01f + 0.012f * cell_hash(c, 4127);
          d.taper =
              std::min({0.08f + 0.14f * cell_hash(c, 4129), 0.3f * d.radius, 0.25f * d.length});
          // Folds 0.35-0.55 m apart across its width.
          d.flare =
              std::max(2.0f, std::floor(2.0f * d.radius / (0.35f + 0.2f * cell_hash(c, 4133))));
          d.rings = 0.0f;  // its slope: fit_drapery
          d.bulbs = 0.5f + 0.8f * cell_hash(c, 4139);
          d.seed = cell_hash(c, 4153);
          d.yaw = std::atan2(top.normal.z, top.normal.x) + 0.4f * (cell_hash(c, 4157) - 0.5f);
          d.embed = root_embed() + 0.05f;  // fit_drapery grows it over the slope
          if (placer.fit_embed(d)) out.push_back(d);
          continue;
        }
        len = std::min(len, 0.45f * gap);
        FormationShape f{};
        f.kind = kFormationStalactite;
        f.root = vec3(xz.x, top.position.y, xz.y);
        f.length = len;
        f.radius = radius;
        f.tip = straw ? radius : std::min(0.004f + 0.05f * radius, radius);
        f.taper = straw ? 1.0f : mix(1.0f, 1.6f, cell_hash(c, 641));
        f.flare = straw ? 0.3f : 0.25f + 0.3f * cell_hash(c, 643);
        f.embed = root_embed() + slope_rise(top.normal, radius * (1.0f + f.flare)) + 0.05f;
        shape_from_hashes(f, c, 600);
        if (straw) f.bulbs = 0.0f, f.rings *= 0.3f;
        if (placer.fit_embed(f)) out.push_back(f);
        // Its stalagmite, where the drip lands on a floor: broader, blunter, neighbours unlike.
        len_g = std::min(len_g, 0.45f * gap);
        // A slow drip (a long stalactite) builds a stalagmite more often than a straw's.
        const bool builds = cell_hash(c, 1709) < 0.75f + 0.25f * std::min(len / 1.2f, 1.0f);
        if (!drip.slow && on_floor && ground.clear && builds && len_g > 0.03f) {
          FormationShape g = stalagmite(ground, xz, len_g,
                                        mix(2.0f, 1.55f, drip.form) * std::max(radius, 0.02f) *
                                            (0.7f + 0.6f * cell_hash(c, 787)),
                                        drip.form);
          shape_from_hashes(g, c, 700);
          if (placer.fit_embed(g)) out.push_back(g);
        }
      } else if (floor) {
        // A floor whose drip comes from no ceiling of this room (the next surface up is a wall or
        // there is none): sometimes a stalagmite all the same.
        const bool capped = i + 1 < list.size() && list[i + 1].facing < kCeiling;
        if (drip.mound || drip.slow || capped || cell_hash(c, 9173) >= kLoneStalagmite) continue;
        const SurfacePoint ground = placer.surface_at(h, xz);
        if (!ground.clear) continue;
        const float above = i + 1 < list.size() ? list[i + 1].y - ground.position.y : 1e9f;
        const float len_g =
            std::min(0.5f * std::max(relief::kReliefStraw, longest * size3), 0.45f * above);
        if (!(len_g > 0.03f)) continue;
        FormationShape g = stalagmite(ground, xz, len_g, 0.05f + 0.2f * len_g, drip.form);
        shape_from_hashes(g, c, 800);
        if (placer.fit_embed(g)) out.push_back(g);
      }
    }
    // Its minerals' colour, and the water on it: active lines wet, slow ones dry.
    for (size_t k = placed; k < out.size(); ++k) {
      out[k].tint = drip.tint;
      out[k].wet = drip.slow ? 0.0f : 0.3f + 0.7f * drip.wet;
    }
  }
  // The blocks fallen from a hall's ceiling, on its floor (breakdown.cpp).
  detail::place_breakdown(placer, s, out);
  return out;
}

void append_mesh(const FormationShape& f, int lod, std::vector<vec3>& positions,
                 std::vector<vec3>& normals, std::vector<uint32_t>& indices) {
  lod = std::clamp(lod, 0, kLods - 1);
  const int sides = kLodSides[lod], rings = kLodRings[lod];
  const uint32_t base = static_cast<uint32_t>(positions.size());
  const float start = formation_start(f), end = formation_end(f);
  // formation.vert's arithmetic, point for point.
  for (int i = 0; i <= rings; ++i) {
    const float v = static_cast<float>(i) / static_cast<float>(rings);
    const float g = v - 0.6f * std::sin(6.2831853f * v) / 6.2831853f;
    const float s = mix(start, end, g);
    const float ds = std::max(0.002f, 0.004f * (end - start));
    for (int k = 0; k <= sides; ++k) {
      const float theta = 6.2831853f * static_cast<float>(k) / static_cast<float>(sides);
      const vec3 p = formation_point(f, s, theta);
      const vec3 along = formation_point(f, s + ds, theta) - formation_point(f, s - ds, theta);
      const vec3 round =
          formation_point(f, s, theta + 0.02f) - formation_point(f, s, theta - 0.02f);
      vec3 n = cross(along, round);
      const float nl = length(n);
      const vec3 outward = formation_outward(f, s, theta, p);
      n = nl > 1e-9f ? n / nl : normalize(outward);
      if (dot(n, outward) < 0.0f) n = -n;
      positions.push_back(p);
      normals.push_back(n);
    }
  }
  const uint32_t row = static_cast<uint32_t>(sides + 1);
  for (uint32_t i = 0; i < static_cast<uint32_t>(rings); ++i)
    for (uint32_t k = 0; k < static_cast<uint32_t>(sides); ++k) {
      const uint32_t a0 = base + i * row + k, a1 = a0 + 1, b0 = a0 + row, b1 = b0 + 1;
      // Counter-clockwise seen from outside, whichever way the axis runs (a drapery's s runs
      // along its line and theta down its front: as a stalactite's).
      if (formation_direction(f) < 0.0f)
        indices.insert(indices.end(), {a0, b1, b0, a0, a1, b1});
      else
        indices.insert(indices.end(), {a0, b0, b1, a0, b1, a1});
    }
}

namespace {

// A drapery's hull: the prism of its outline (the top edge and the lower edge at `sides` points
// along its line, without the tongues: convex) as thick as its folds reach either side.
std::vector<vec3> drapery_hull(const FormationShape& f, int sides) {
  std::vector<vec3> outline;
  const int n = std::max(sides, 3);
  for (int i = 0; i <= n; ++i) {
    const float x = f.radius * (2.0f * static_cast<float>(i) / static_cast<float>(n) - 1.0f);
    const float e = x / std::max(f.radius, 1e-3f);
    const float drop = std::max(0.85f * f.length * std::sqrt(std::max(1.0f - e * e, 0.0f)), 0.02f);
    outline.push_back(drapery_line(f, x) + vec3(0.0f, -drop, 0.0f));
  }
  const vec3 side = drapery_across(f) * (f.taper + 3.0f * f.tip);
  std::vector<vec3> out;
  for (int i = 0; i < n; ++i) {
    const vec3 a = outline[static_cast<size_t>(i)], b = outline[static_cast<size_t>(i) + 1];
    const vec3 ta = drapery_line(f, dot(a - f.root, drapery_along(f)));
    const vec3 tb = drapery_line(f, dot(b - f.root, drapery_along(f)));
    // Both faces (fans from the top edge), the lower edge's strip, the top edge's strip.
    out.insert(out.end(), {ta + side, a + side, b + side, ta + side, b + side, tb + side});
    out.insert(out.end(), {ta - side, b - side, a - side, ta - side, tb - side, b - side});
    out.insert(out.end(), {a + side, a - side, b - side, a + side, b - side, b + side});
    out.insert(out.end(), {ta + side, tb - side, ta - side, ta + side, tb + side, tb - side});
  }
  return out;
}

// A boulder's hull: its finest mesh's points round the side (kLodSides[0] of them, so each face
// keeps its plane) at the bottom, where the side meets the chamfer and where the chamfer meets
// the top, closed by a fan over the top (a plane). Convex as the block is.
std::vector<vec3> boulder_hull(const FormationShape& f) {
  const int sides = kLodSides[0];
  const float start = formation_start(f), end = formation_end(f);
  // boulder_point's parts: the side to 0.3075 of the span, the chamfer to 0.5, the top.
  const float shares[3] = {0.0f, 0.3074806f, 0.5f};
  std::vector<vec3> ring[3];
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < sides; ++k)
      ring[i].push_back(
          formation_point(f, mix(start, end, shares[i]),
                          6.2831853f * static_cast<float>(k) / static_cast<float>(sides)));
  std::vector<vec3> out;
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < sides; ++k) {
      const int k1 = (k + 1) % sides;
      const auto &a = ring[i], &b = ring[i + 1];
      out.insert(out.end(), {a[k], b[k], b[k1], a[k], b[k1], a[k1]});
    }
  const vec3 top = formation_point(f, end, 0.0f);
  for (int k = 0; k < sides; ++k)
    out.insert(out.end(), {ring[2][k], ring[2][(k + 1) % sides], top});
  return out;
}

}  // namespace

std::vector<vec3> collision_hull(const FormationShape& f, int sides, int rings) {
  std::vector<vec3> out;
  sides = std::max(sides, 3);
  rings = std::max(rings, 1);
  if (f.kind == kFormationDrapery) return drapery_hull(f, 2 * sides);
  if (f.kind == kFormationBoulder) return boulder_hull(f);
  // Rings from the root to the far end, each a polygon of the largest radius at its level
  // (irregularity included), so the hull holds what is drawn near the axis.
  const float start = 0.0f, end = formation_end(f) - (f.kind == kFormationColumn ? f.embed : 0.0f);
  std::vector<std::vector<vec3>> ring(static_cast<size_t>(rings) + 1);
  for (int i = 0; i <= rings; ++i) {
    const float s = start + (end - start) * static_cast<float>(i) / static_cast<float>(rings);
    float r = 0;
    for (int k = 0; k < 12; ++k)
      r = std::max(r, formation_radius(f, s, 6.2831853f * static_cast<float>(k) / 12.0f));
    r = std::max(r, 0.01f);
    for (int k = 0; k < sides; ++k) {
      const float a = 6.2831853f * static_cast<float>(k) / static_cast<float>(sides);
      ring[static_cast<size_t>(i)].push_back(
          f.root + vec3(r * std::cos(a), formation_direction(f) * s, r * std::sin(a)));
    }
  }
  for (int i = 0; i < rings; ++i) {
    const auto& a = ring[static_cast<size_t>(i)];
    const auto& b = ring[static_cast<size_t>(i) + 1];
    for (int k = 0; k < sides; ++k) {
      const int k1 = (k + 1) % sides;
      out.insert(out.end(), {a[k], b[k], b[k1], a[k], b[k1], a[k1]});
    }
  }
  // The far end's cap (the root's end is in the rock).
  const auto& last = ring.back();
  const vec3 tip = f.root + vec3(0.0f, formation_direction(f) * end, 0.0f);
  for (int k = 0; k < sides; ++k)
    out.insert(out.end(), {last[k], last[(k + 1) % sides], tip});
  return out;
}

}  // namespace grotto::formations
