// The placement's view of a room's drawn surface: where a vertical line meets the patch triangles,
// the drawn surface there (PN triangle and relief, as relief_at gives it) and how deep a root must
// reach to meet it all round. Internal to common/formations.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>
#include <vector>

#include "common/formations/formations.hpp"
#include "common/relief/relief.hpp"

namespace grotto::formations::detail {

// Where the surface faces, by its triangle's normal: relief.glsl's zones (`under` starts at
// n.y < -0.3, `ground` at n.y > 0.55).
constexpr float kCeiling = -0.3f;
constexpr float kFloor = 0.55f;
// Closer than this to a portal's rim (the rim weight interpolated over a patch triangle), or on a
// triangle with a corner on a rim, nothing grows: a portal is no ceiling, and its neighbour does
// not draw the room's formations.
constexpr float kRimClear = 0.02f;

// Where a vertical line through room-frame (x, z) meets one patch triangle.
struct Hit {
  float y = 0;   // metres, room frame, on the flat triangle
  vec3 w{0.0f};  // barycentric
  uint32_t tri = 0;
  float facing = 0;  // the triangle's normal's y
};

// The drawn surface (PN triangle, then the relief along the interpolated normal, exactly as
// relief_at gives it) at barycentric w of triangle t: position (room frame) and whether it is
// clear of portal rims.
struct SurfacePoint {
  vec3 position{0.0f};
  vec3 normal{0.0f, 1.0f, 0.0f};
  bool clear = false;
};

class Placer {
 public:
  explicit Placer(const Surface& s) : s_(s) {
    // The triangles over a grid of kGrid-metre cells of the room's xz plane (each in every cell
    // its box meets), for the heights round a root.
    const size_t triangles = s.indices.size() / 3;
    vec2 lo(1e30f), hi(-1e30f);
    for (const auto& p : s.positions) {
      lo = min(lo, vec2(p.x, p.z));
      hi = max(hi, vec2(p.x, p.z));
    }
    if (triangles == 0) return;
    grid_lo_ = lo;
    dims_ = ivec2((hi - lo) / kGrid) + ivec2(1);
    cells_.resize(static_cast<size_t>(dims_.x) * static_cast<size_t>(dims_.y));
    for (uint32_t t = 0; t < triangles; ++t) {
      vec2 a(1e30f), b(-1e30f);
      for (int k = 0; k < 3; ++k) {
        const vec3 p = position(s.indices[3 * t + k]);
        a = min(a, vec2(p.x, p.z));
        b = max(b, vec2(p.x, p.z));
      }
      const ivec2 ca = cell_of(a), cb = cell_of(b);
      for (int z = ca.y; z <= cb.y; ++z)
        for (int x = ca.x; x <= cb.x; ++x)
          cells_[static_cast<size_t>(z) * static_cast<size_t>(dims_.x) + static_cast<size_t>(x)]
              .push_back(t);
    }
  }

  ivec2 cell_of(vec2 xz) const {
    return clamp(ivec2(floor((xz - grid_lo_) / kGrid)), ivec2(0), dims_ - ivec2(1));
  }

  // The highest floor (a patch triangle facing up more than kFloor) under room-frame (x, z) and
  // below height `below`: false where there is none. Half-open on the triangles' edges, as the
  // speleothems' hits are, so whatever order the triangles come in the same one answers.
  bool floor_under(vec2 xz, float below, Hit& out) const {
    if (cells_.empty()) return false;
    bool found = false;
    Hit h;
    for (uint32_t t : cell_triangles(xz)) {
      if (!hit(t, xz, h) || !(h.facing > kFloor)) continue;
      if (!(h.y < below) || (found && !(h.y > out.y))) continue;
      found = true;
      out = h;
    }
    return found;
  }

  // Every patch triangle a vertical line through room-frame (x, z) meets, lowest first (none
  // nearly vertical: a vertical line does not meet one once). Half-open on the triangles' edges,
  // so whatever order the triangles come in, each sheet of rock answers once.
  std::vector<Hit> vertical_hits(vec2 xz) const {
    std::vector<Hit> out;
    if (cells_.empty()) return out;
    Hit h;
    for (uint32_t t : cell_triangles(xz)) {
      if (hit(t, xz, h) && std::abs(h.facing) >= 0.05f) out.push_back(h);
    }
    std::sort(out.begin(), out.end(), [](const Hit& a, const Hit& b) {
      return std::tie(a.y, a.facing) < std::tie(b.y, b.facing);
    });
    return out;
  }

  // The triangles whose boxes meet the grid cell of room-frame (x, z).
  const std::vector<uint32_t>& cell_triangles(vec2 xz) const {
    const ivec2 c = cell_of(xz);
    return cells_[static_cast<size_t>(c.y) * static_cast<size_t>(dims_.x) +
                  static_cast<size_t>(c.x)];
  }

  // Where the vertical line through room-frame (x, z) meets triangle t, half-open on its edges
  // (so that a line on a shared edge meets one of the two): false where it misses, or where the
  // triangle has no area.
  bool hit(uint32_t t, vec2 xz, Hit& out) const {
    const vec3 w = barycentric(t, xz);
    if (!(w.x >= 0.0f && w.y >= 0.0f && w.z > 0.0f)) return false;
    const std::array<uint32_t, 3> k = corners(t);
    const vec3 a = position(k[0]), b = position(k[1]), d = position(k[2]);
    const vec3 face = cross(b - a, d - a);
    const float len = length(face);
    if (!(len > 1e-9f)) return false;
    out.y = dot(w, vec3(a.y, b.y, d.y));
    out.w = w;
    out.tri = t;
    out.facing = face.y / len;
    return true;
  }

  // The height of the drawn surface straight above or below room-frame (x, z), on the sheet of
  // rock nearest to height `near`: NaN where no triangle lies over (x, z).
  float height_near(vec2 xz, float near) const {
    if (cells_.empty()) return std::nanf("");
    // The nearest sheet by the flat triangles; the drawn surface (a relief_at) of that one only.
    bool found = false;
    uint32_t best = 0;
    vec3 best_w(0.0f);
    float gap = 1e30f;
    for (uint32_t t : cell_triangles(xz)) {
      const vec3 w = barycentric(t, xz);
      if (!(w.x >= -1e-4f && w.y >= -1e-4f && w.z >= -1e-4f)) continue;
      const std::array<uint32_t, 3> k = corners(t);
      const float flat = dot(w, vec3(position(k[0]).y, position(k[1]).y, position(k[2]).y));
      if (!(std::abs(flat - near) < gap)) continue;
      gap = std::abs(flat - near);
      found = true;
      best = t;
      best_w = w;
    }
    return found ? surface(best, best_w).position.y : std::nanf("");
  }

  // Grows f's embedding until the rock round its root (and a column's far end), at the widest
  // its flare reaches, lies within it: no side of the root shows its end in the air. False where
  // that would take more than kMaxEmbed (a root on a fold or a pocket's rim) or where the flare
  // reaches over a portal's opening: no formation there.
  bool fit_embed(FormationShape& f) const {
    if (f.kind == kFormationDrapery) return fit_drapery(f);
    const float reach = formation_bound_radius(f);
    const float dir = formation_direction(f);
    float need = f.embed;
    const int ends = f.kind == kFormationColumn ? 2 : 1;
    for (int e = 0; e < ends; ++e) {
      // The root end grows from rock on the far side of dir; a column's far end the other way.
      const float y0 = f.root.y + (e == 0 ? 0.0f : dir * f.length);
      const float into = e == 0 ? -dir : dir;  // the direction of the rock from that end
      for (int k = 0; k < 8; ++k) {
        const float a = 0.7853982f * static_cast<float>(k);
        const vec2 at = vec2(f.root.x, f.root.z) + reach * vec2(std::cos(a), std::sin(a));
        const float y = height_near(at, y0);
        if (std::isnan(y)) return false;  // beyond the mesh's edge: a portal's opening
        need = std::max(need, into * (y - y0) + 0.05f);
      }
    }
    if (need > kMaxEmbed) return false;
    f.embed = need;
    return true;
  }

  // A drapery's line follows its ceiling (the slope between the ceiling's heights half its
  // width either side of the root), and its top edge, all along the line and either side of its
  // folds, lies in the rock.
  bool fit_drapery(FormationShape& f) const {
    const vec3 half = drapery_along(f) * (0.5f * f.radius);
    const float up = height_near(vec2(f.root.x + half.x, f.root.z + half.z), f.root.y);
    const float down = height_near(vec2(f.root.x - half.x, f.root.z - half.z), f.root.y);
    if (std::isnan(up) || std::isnan(down)) return false;
    f.rings = std::clamp((up - down) / f.radius, -1.5f, 1.5f);
    float need = f.embed;
    const float side = f.taper + 2.0f * f.tip;
    // Every eighth of the line: a ceiling that steps along its beds can rise between quarters.
    for (int k = -8; k <= 8; ++k) {
      for (int j = -1; j <= 1; j += 2) {
        const vec3 at = drapery_line(f, f.radius * static_cast<float>(k) / 8.0f) +
                        drapery_across(f) * (side * static_cast<float>(j));
        const float y = height_near(vec2(at.x, at.z), at.y);
        if (std::isnan(y)) return false;
        // Past the mesh's ceiling by as much as the relief may hollow it (root_embed).
        need = std::max(need, y - at.y + root_embed() + 0.05f);
      }
    }
    if (need > kMaxEmbed) return false;
    f.embed = need;
    return true;
  }

  static constexpr float kGrid = 1.0f;
  static constexpr float kMaxEmbed = 3.0f;
  vec2 grid_lo_{0.0f};
  ivec2 dims_{0};
  std::vector<std::vector<uint32_t>> cells_;

  // Triangle t's corners, turned (keeping the winding) so that the lexicographically smallest
  // position comes first: the same arithmetic whatever order a decoder gave the triangle's
  // corners in (room.tese orders an edge's ends the same way).
  std::array<uint32_t, 3> corners(uint32_t t) const {
    std::array<uint32_t, 3> c = {s_.indices[3 * t], s_.indices[3 * t + 1], s_.indices[3 * t + 2]};
    auto before = [&](uint32_t a, uint32_t b) {
      const auto &p = s_.positions[a], &q = s_.positions[b];
      return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
    };
    int first = 0;
    for (int k = 1; k < 3; ++k)
      if (before(c[static_cast<size_t>(k)], c[static_cast<size_t>(first)])) first = k;
    std::rotate(c.begin(), c.begin() + first, c.end());
    return c;
  }

  vec3 position(uint32_t v) const {
    const auto& p = s_.positions[v];
    return {p.x, p.y, p.z};
  }
  vec3 normal(uint32_t v) const {
    const auto& n = s_.normals[v];
    return {n.x, n.y, n.z};
  }

  SurfacePoint surface(uint32_t t, vec3 w) const {
    SurfacePoint out;
    vec3 p[3], n[3];
    float rough = 0, rim = 0, rim_corner = 0;
    const std::array<uint32_t, 3> c = corners(t);
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = c[static_cast<size_t>(k)];
      p[k] = position(v);
      n[k] = normal(v);
      rough += w[k] * (v < s_.roughness.size() ? s_.roughness[v] : 0.0f);
      const float on_rim = v < s_.rim_portal.size() && s_.rim_portal[v] >= 0 ? 1.0f : 0.0f;
      rim += w[k] * on_rim;
      rim_corner = std::max(rim_corner, on_rim);
    }
    const vec3 at = relief::relief_pn_point(p[0], p[1], p[2], n[0], n[1], n[2], w);
    const vec3 nn = normalize(n[0] * w.x + n[1] * w.y + n[2] * w.z);
    const relief::Relief r =
        relief::relief_at(relief::relief_pos_of(s_.origin, at), nn, rough, rim, 1.0f);
    out.position = at + nn * r.height;
    out.normal = nn;
    // Not on a triangle that touches a rim: its neighbour across the rim is the portal's opening,
    // which the PN bulge and the relief can move the surface out over.
    out.clear = rim < kRimClear && rim_corner == 0.0f;
    return out;
  }

  // The surface of triangle t straight above or below room-frame (x, z): the flat triangle's
  // barycentric corrected up to three times for the PN bulge's and the relief's sideways shift.
  SurfacePoint surface_at(const Hit& h, vec2 xz) const {
    SurfacePoint sp = surface(h.tri, h.w);
    vec3 w = h.w;
    for (int i = 0; i < 3; ++i) {
      const vec2 drift = vec2(sp.position.x, sp.position.z) - xz;
      const vec3 moved = barycentric(h.tri, xz - drift);
      if (!(moved.x >= -0.25f && moved.y >= -0.25f && moved.z >= -0.25f)) break;
      w = moved;
      sp = surface(h.tri, w);
    }
    // Where the surface leans too far to find the point over (x, z) on this triangle (a steep
    // fold whose relief moves it sideways), no root.
    if (!(length(vec2(sp.position.x, sp.position.z) - xz) < 0.02f)) sp.clear = false;
    return sp;
  }

  // Barycentric coordinates of room-frame (x, z) in triangle t's projection on the xz plane.
  vec3 barycentric(uint32_t t, vec2 q) const {
    const std::array<uint32_t, 3> k = corners(t);
    const vec3 a = position(k[0]), b = position(k[1]), c = position(k[2]);
    const vec2 v0 = vec2(b.x - a.x, b.z - a.z), v1 = vec2(c.x - a.x, c.z - a.z),
               v2 = vec2(q.x - a.x, q.y - a.z);
    const float den = v0.x * v1.y - v1.x * v0.y;
    if (!(std::abs(den) > 1e-9f)) return vec3(-1.0f);
    const float wb = (v2.x * v1.y - v1.x * v2.y) / den;
    const float wc = (v0.x * v2.y - v2.x * v0.y) / den;
    return vec3(1.0f - wb - wc, wb, wc);
  }

  const Surface& s_;
};

// The fallen blocks of a breakdown chamber (breakdown.cpp) on the floor of a hall, appended to
// `out` (the speleothems placed so far: a block keeps off the columns and buries the stalagmites
// under it, which are taken out).
void place_breakdown(const Placer& placer, const Surface& surface,
                     std::vector<FormationShape>& out);

}  // namespace grotto::formations::detail
