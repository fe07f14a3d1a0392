#include "client/play/collision.hpp"

#include <algorithm>
#include <cmath>

#include "common/formations/formations.hpp"
#include "common/mesh/rim.hpp"
#include "common/relief/relief.hpp"

namespace grotto::play {
namespace {

// The wall's radius over a portal of this radius: out to the farthest its rim can reach (the rim
// moves with the surface noise, mesh::rim_reach, for the default world's mesh parameters), and
// kPortalWallMargin beyond.
double portal_wall_radius(double portal_radius) {
  static const mesh::MeshParams params;
  return mesh::rim_reach(params, portal_radius) + kPortalWallMargin;
}

constexpr double kCell = 1.0;  // metres: a patch triangle spans about one to three cells

bool boxes_overlap(Vec3 lo_a, Vec3 hi_a, Vec3 lo_b, Vec3 hi_b) {
  for (int i = 0; i < 3; ++i)
    if (hi_a[i] < lo_b[i] || hi_b[i] < lo_a[i]) return false;
  return true;
}

}  // namespace

Vec3 closest_point(const Triangle& t, Vec3 p) {
  const Vec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return t.a;
  const Vec3 bp = p - t.b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return t.b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return t.a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - t.c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return t.c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return t.a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denominator = va + vb + vc;
  if (!(denominator > 0)) return t.a;  // degenerate: the vertex cases above cover it
  return t.a + ab * (vb / denominator) + ac * (vc / denominator);
}

Vec3 closest_point(const Disc& d, Vec3 p) {
  const Vec3 in_plane = p - d.normal * dot(p - d.centre, d.normal);
  const Vec3 from_centre = in_plane - d.centre;
  const double r = length(from_centre);
  if (r <= d.radius) return in_plane;
  return d.centre + from_centre * (d.radius / r);
}

Vec3 unit_normal(const Triangle& t) {
  const Vec3 n = cross(t.b - t.a, t.c - t.a);
  const double l = length(n);
  return l > 0 ? n / l : Vec3{};
}

bool segment_crosses(const Triangle& t, Vec3 p, Vec3 q) {
  // Möller-Trumbore on the segment's parameter range [0, 1].
  const Vec3 dir = q - p, e1 = t.b - t.a, e2 = t.c - t.a;
  const Vec3 h = cross(dir, e2);
  const double det = dot(e1, h);
  if (std::abs(det) < 1e-18) return false;  // parallel (or a zero-length segment)
  const Vec3 s = p - t.a;
  const double u = dot(s, h) / det;
  if (u < 0 || u > 1) return false;
  const Vec3 qv = cross(s, e1);
  const double v = dot(dir, qv) / det;
  if (v < 0 || u + v > 1) return false;
  const double along = dot(e2, qv) / det;
  return along >= 0 && along <= 1;
}

bool segment_crosses(const Disc& d, Vec3 p, Vec3 q) {
  const double sp = dot(p - d.centre, d.normal), sq = dot(q - d.centre, d.normal);
  if ((sp > 0 && sq > 0) || (sp < 0 && sq < 0) || sp == sq) return false;
  const Vec3 x = p + (q - p) * (sp / (sp - sq));
  return length_squared(x - d.centre) <= d.radius * d.radius;
}

void CollisionWorld::add(const stream::ReadyRoom& ready,
                         std::span<const formations::FormationShape> placed) {
  evict(ready.room.id);
  Room r;
  r.room = ready.room;
  r.origin = ready.origin;
  const auto& mesh = ready.mesh;
  r.positions.reserve(mesh.vertex_count() * 3);
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const auto& v : mesh.positions) {
    r.positions.insert(r.positions.end(), {v.x, v.y, v.z});
    const Vec3 d{v.x, v.y, v.z};
    for (int i = 0; i < 3; ++i)
      lo[i] = std::min(lo[i], d[i]), hi[i] = std::max(hi[i], d[i]);
  }
  r.normals.reserve(mesh.vertex_count() * 3);
  for (const auto& n : mesh.normals)
    r.normals.insert(r.normals.end(), {n.x, n.y, n.z});
  // A decoded room has every channel (codec validation); anything short reads as 0.
  r.normals.resize(mesh.vertex_count() * 3, 0.0f);
  r.roughness = mesh.roughness;
  r.roughness.resize(mesh.vertex_count(), 0.0f);
  r.rim.reserve(mesh.vertex_count());
  for (int8_t slot : mesh.rim_portal)
    r.rim.push_back(slot >= 0 ? 1.0f : 0.0f);
  r.rim.resize(mesh.vertex_count(), 0.0f);
  r.indices = mesh.indices;
  r.relief_reach = relief::relief_bound(relief_strength_);
  r.refined_at.assign(r.indices.size() / 3, 0);
  r.refined_count.assign(r.indices.size() / 3, 0);
  if (mesh.vertex_count() == 0) lo = hi = Vec3{};
  r.bound_centre = r.origin + (lo + hi) * 0.5;
  r.bound_radius = length(hi - lo) * 0.5;

  for (int i = 0; i < 3; ++i) {
    r.grid_lo[i] = static_cast<int>(std::floor(lo[i] / kCell));
    r.dims[i] = static_cast<int>(std::floor(hi[i] / kCell)) - r.grid_lo[i] + 1;
  }
  const size_t cells = static_cast<size_t>(r.dims[0]) * r.dims[1] * r.dims[2];
  const uint32_t triangles = static_cast<uint32_t>(r.indices.size() / 3);
  // Two passes over the triangles' cell ranges: count, then fill (compressed rows).
  auto for_each_cell = [&](uint32_t t, auto&& visit) {
    int c_lo[3], c_hi[3];
    for (int i = 0; i < 3; ++i) {
      float mn = r.positions[3 * r.indices[3 * t] + i], mx = mn;
      for (int k = 1; k < 3; ++k) {
        const float x = r.positions[3 * r.indices[3 * t + k] + i];
        mn = std::min(mn, x), mx = std::max(mx, x);
      }
      c_lo[i] = static_cast<int>(std::floor(mn / kCell)) - r.grid_lo[i];
      c_hi[i] = static_cast<int>(std::floor(mx / kCell)) - r.grid_lo[i];
    }
    for (int x = c_lo[0]; x <= c_hi[0]; ++x)
      for (int y = c_lo[1]; y <= c_hi[1]; ++y)
        for (int z = c_lo[2]; z <= c_hi[2]; ++z)
          visit((static_cast<size_t>(x) * r.dims[1] + y) * r.dims[2] + z);
  };
  r.cell_start.assign(cells + 1, 0);
  for (uint32_t t = 0; t < triangles; ++t)
    for_each_cell(t, [&](size_t c) { ++r.cell_start[c + 1]; });
  for (size_t c = 0; c < cells; ++c)
    r.cell_start[c + 1] += r.cell_start[c];
  r.cell_triangles.resize(r.cell_start[cells]);
  std::vector<uint32_t> fill(r.cell_start.begin(), r.cell_start.end() - 1);
  for (uint32_t t = 0; t < triangles; ++t)
    for_each_cell(t, [&](size_t c) { r.cell_triangles[fill[c]++] = t; });
  rooms_.emplace(ready.room.id, std::move(r));
  set_formations(ready.room.id, placed);
}

void CollisionWorld::add(const stream::ReadyRoom& ready) {
  std::vector<formations::FormationShape> placed;
  if (relief_strength_ > 0 && formations_)
    placed = formations::place(
        formations::surface_of(ready.mesh, ready.origin, ready.room.sphere.radius));
  add(ready, placed);
}

void CollisionWorld::set_formations(cave::RoomId id,
                                    std::span<const formations::FormationShape> placed) {
  auto it = rooms_.find(id);
  if (it == rooms_.end()) return;
  Room& r = it->second;
  r.formations.clear();
  if (!(relief_strength_ > 0 && formations_)) return;
  // The formations as simple shapes: each a six-sided hull round what is drawn.
  for (const formations::FormationShape& f : placed) {
    Formation hull;
    const std::vector<glm::vec3> points = formations::collision_hull(f);
    hull.lo = hull.hi = r.origin + Vec3{points[0].x, points[0].y, points[0].z};
    for (size_t i = 0; i + 2 < points.size(); i += 3) {
      Triangle t;
      Vec3* corner[3] = {&t.a, &t.b, &t.c};
      for (int k = 0; k < 3; ++k) {
        const glm::vec3& q = points[i + static_cast<size_t>(k)];
        *corner[k] = r.origin + Vec3{q.x, q.y, q.z};
        for (int a = 0; a < 3; ++a)
          hull.lo[a] = std::min(hull.lo[a], (*corner[k])[a]),
          hull.hi[a] = std::max(hull.hi[a], (*corner[k])[a]);
      }
      // A triangle without area (a hull's edge that closes to a point, as a drapery's ends do)
      // has no side to push a walker out of: its closest point divides by zero.
      if (length_squared(cross(t.b - t.a, t.c - t.a)) < 1e-16) continue;
      hull.triangles.push_back(t);
    }
    r.formations.push_back(std::move(hull));
  }
}

void CollisionWorld::evict(cave::RoomId id) {
  rooms_.erase(id);
}

std::span<const Triangle> CollisionWorld::refined(const Room& room, uint32_t t) const {
  if (room.refined_at[t] != 0)
    return {&room.refined[room.refined_at[t] - 1], room.refined_count[t]};
  glm::vec3 p[3], n[3];
  float rough[3], rim[3];
  for (int k = 0; k < 3; ++k) {
    const uint32_t v = room.indices[3 * t + k];
    p[k] = {room.positions[3 * v], room.positions[3 * v + 1], room.positions[3 * v + 2]};
    n[k] = {room.normals[3 * v], room.normals[3 * v + 1], room.normals[3 * v + 2]};
    rough[k] = room.roughness[v];
    rim[k] = room.rim[v];
  }
  const bool planar = n[0] == n[1] && n[1] == n[2];
  room.refined_at[t] = static_cast<uint32_t>(room.refined.size() + 1);
  if (planar && relief_strength_ == 0) {
    // Flat and without relief: the patch triangle is the surface; pieces would only add edges.
    room.refined.push_back({room.origin + Vec3{p[0].x, p[0].y, p[0].z},
                            room.origin + Vec3{p[1].x, p[1].y, p[1].z},
                            room.origin + Vec3{p[2].x, p[2].y, p[2].z}});
    room.refined_count[t] = 1;
    return {&room.refined.back(), 1};
  }
  // The drawn surface at barycentric (i, j, kRefine - i - j) / kRefine, as room.tese makes it
  // with PN triangles: the patch point, then the relief along the interpolated normal.
  Vec3 grid[kRefine + 1][kRefine + 1];
  for (int i = 0; i <= kRefine; ++i) {
    for (int j = 0; i + j <= kRefine; ++j) {
      const glm::vec3 w{static_cast<float>(i) / kRefine, static_cast<float>(j) / kRefine,
                        static_cast<float>(kRefine - i - j) / kRefine};
      const glm::vec3 at = relief::relief_pn_point(p[0], p[1], p[2], n[0], n[1], n[2], w);
      const glm::vec3 normal = glm::normalize(n[0] * w.x + n[1] * w.y + n[2] * w.z);
      const float roughness = rough[0] * w.x + rough[1] * w.y + rough[2] * w.z;
      const float rim_weight = rim[0] * w.x + rim[1] * w.y + rim[2] * w.z;
      const relief::Relief r = relief::relief_at(relief::relief_pos_of(room.origin, at), normal,
                                                 roughness, rim_weight, relief_strength_);
      // The flat interpolation in double, then the PN bulge and the relief as float offsets
      // from it: a flat triangle far from the origin stays exact. (Equal normals make the PN
      // patch the flat triangle; float rounding would only add noise.)
      const glm::vec3 flat = p[0] * w.x + p[1] * w.y + p[2] * w.z;
      const glm::vec3 bulge = planar ? glm::vec3(0.0f) : at - flat;
      // relief_displace's offset: the rock along the normal.
      const glm::vec3 q = bulge + normal * r.height;
      Vec3 base{};
      for (int k = 0; k < 3; ++k)
        base = base + Vec3{p[k].x, p[k].y, p[k].z} * static_cast<double>(w[k]);
      grid[i][j] = room.origin + base + Vec3{q.x, q.y, q.z};
    }
  }
  for (int i = 0; i < kRefine; ++i) {
    for (int j = 0; i + j < kRefine; ++j) {
      room.refined.push_back({grid[i][j], grid[i + 1][j], grid[i][j + 1]});
      if (i + j + 1 < kRefine)
        room.refined.push_back({grid[i + 1][j], grid[i + 1][j + 1], grid[i][j + 1]});
    }
  }
  room.refined_count[t] = kRefine * kRefine;
  return {&room.refined[room.refined_at[t] - 1], room.refined_count[t]};
}

void CollisionWorld::gather(Vec3 lo, Vec3 hi, Neighbourhood& out) const {
  out.triangles.clear();
  out.walls.clear();
  for (const auto& [id, room] : rooms_) {
    for (const cave::Portal& portal : room.room.portals) {
      if (contains(portal.neighbour)) continue;
      const double reach = portal_wall_radius(portal.radius);
      const Vec3 extent{reach, reach, reach};
      if (boxes_overlap(lo, hi, portal.centre - extent, portal.centre + extent))
        out.walls.push_back({portal.centre, portal.normal, reach});
    }
    for (const Formation& f : room.formations) {
      if (!boxes_overlap(lo, hi, f.lo, f.hi)) continue;
      for (const Triangle& t : f.triangles)
        out.triangles.push_back(t);
    }
    // The relief moves the surface up to relief_reach from the patch triangles the grid holds.
    const double reach = room.relief_reach;
    const Vec3 extent{room.bound_radius + reach, room.bound_radius + reach,
                      room.bound_radius + reach};
    if (!boxes_overlap(lo, hi, room.bound_centre - extent, room.bound_centre + extent)) continue;
    int c_lo[3], c_hi[3];
    for (int i = 0; i < 3; ++i) {
      c_lo[i] = std::max(0, static_cast<int>(std::floor((lo[i] - reach - room.origin[i]) / kCell)) -
                                room.grid_lo[i]);
      c_hi[i] = std::min(
          room.dims[i] - 1,
          static_cast<int>(std::floor((hi[i] + reach - room.origin[i]) / kCell)) - room.grid_lo[i]);
    }
    seen_.clear();
    for (int x = c_lo[0]; x <= c_hi[0]; ++x)
      for (int y = c_lo[1]; y <= c_hi[1]; ++y)
        for (int z = c_lo[2]; z <= c_hi[2]; ++z) {
          const size_t c = (static_cast<size_t>(x) * room.dims[1] + y) * room.dims[2] + z;
          seen_.insert(seen_.end(), room.cell_triangles.begin() + room.cell_start[c],
                       room.cell_triangles.begin() + room.cell_start[c + 1]);
        }
    std::sort(seen_.begin(), seen_.end());
    seen_.erase(std::unique(seen_.begin(), seen_.end()), seen_.end());
    for (uint32_t t : seen_) {
      for (const Triangle& f : refined(room, t)) {
        Vec3 f_lo = f.a, f_hi = f.a;
        for (const Vec3& v : {f.b, f.c})
          for (int i = 0; i < 3; ++i)
            f_lo[i] = std::min(f_lo[i], v[i]), f_hi[i] = std::max(f_hi[i], v[i]);
        if (boxes_overlap(lo, hi, f_lo, f_hi)) out.triangles.push_back(f);
      }
    }
  }
}

const cave::Room* CollisionWorld::room_at(Vec3 p) const {
  return cave::room_at(rooms_, p,
                       [](const auto& entry) -> const cave::Room& { return entry.second.room; });
}

}  // namespace grotto::play
