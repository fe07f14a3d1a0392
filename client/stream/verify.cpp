#include "client/stream/verify.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "client/stream/portal_graph.hpp"
#include "common/core/grid.hpp"

namespace grotto::stream {
namespace {

Error bad_frame(std::string message) {
  return {ErrorCode::kBadFrame, std::move(message)};
}

std::string format_vec(Vec3 v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.17g, %.17g, %.17g)", v.x, v.y, v.z);
  return buf;
}

Vec3 world_position(const ReadyRoom& r, size_t v) {
  const mesh::core::float3 p = r.mesh.positions[v];
  return r.origin + Vec3{p.x, p.y, p.z};
}

std::string portal_name(const ReadyRoom& r, size_t slot) {
  return "room " + r.room.id.to_string() + " portal " + std::to_string(slot) + " (to " +
         r.room.portals[slot].neighbour.to_string() + ")";
}

// The rim of one portal slot: the vertex of each loop index, in index order.
struct RimVertex {
  uint16_t k = 0;
  size_t vertex = 0;
};
std::vector<RimVertex> rim_of(const ReadyRoom& r, int slot) {
  std::vector<RimVertex> rim;
  for (size_t v = 0; v < r.mesh.rim_portal.size(); ++v)
    if (r.mesh.rim_portal[v] == slot) rim.push_back({r.mesh.rim_index[v], v});
  std::sort(rim.begin(), rim.end(),
            [](const RimVertex& a, const RimVertex& b) { return a.k < b.k; });
  return rim;
}

// The per-vertex arrays have one entry a vertex (decode_room guarantees it; a hand-made ReadyRoom
// might not, and every check below indexes them by vertex).
bool arrays_agree(const codec::DecodedRoom& m) {
  const size_t n = m.vertex_count();
  return m.normals.size() == n && m.roughness.size() == n && m.mineral.size() == n &&
         m.rim_portal.size() == n && m.rim_index.size() == n;
}

}  // namespace

double vertex_sphere_margin(double radius) {
  return kSphereMarginMetres + kSphereMarginFraction * radius;
}

Status verify_room(const ReadyRoom& r) {
  const codec::DecodedRoom& m = r.mesh;
  const std::string name = "room " + r.room.id.to_string();
  const size_t n = m.vertex_count();
  if (!arrays_agree(m)) return bad_frame(name + ": per-vertex arrays of different lengths");
  if (m.indices.size() % 3 != 0) return bad_frame(name + ": index count not a multiple of 3");
  for (size_t i = 0; i < m.indices.size(); ++i)
    if (m.indices[i] >= n)
      return bad_frame(name + ": triangle index " + std::to_string(i) + " out of range");

  const cave::Sphere& sphere = r.room.sphere;
  const double limit = sphere.radius + vertex_sphere_margin(sphere.radius);
  for (size_t v = 0; v < n; ++v) {
    const Vec3 p = world_position(r, v);
    const double d = distance(p, sphere.centre);
    if (!(d <= limit))
      return bad_frame(name + ": vertex " + std::to_string(v) + " at " + format_vec(p) + " is " +
                       std::to_string(d - sphere.radius) + " m outside its sphere (margin " +
                       std::to_string(limit - sphere.radius) + " m)");
    const mesh::core::float3 nv = m.normals[v];
    const double len = length(Vec3{nv.x, nv.y, nv.z});
    if (!(std::abs(len - 1.0) <= codec::kNormalTolerance))
      return bad_frame(name + ": vertex " + std::to_string(v) + " normal length " +
                       std::to_string(len));
    if (!(m.roughness[v] >= 0.0f && m.roughness[v] <= 1.0f && m.mineral[v] >= 0.0f &&
          m.mineral[v] <= 1.0f))
      return bad_frame(name + ": vertex " + std::to_string(v) + " channel outside [0, 1]");
    if (m.rim_portal[v] < -1 || m.rim_portal[v] >= static_cast<int>(r.room.portals.size()))
      return bad_frame(name + ": vertex " + std::to_string(v) + " names rim slot " +
                       std::to_string(m.rim_portal[v]) + " of " +
                       std::to_string(r.room.portals.size()) + " portals");
    if (m.rim_portal[v] == -1 && m.rim_index[v] != 0)
      return bad_frame(name + ": vertex " + std::to_string(v) + " has a loop index but no rim");
  }

  // Per portal: the loop's vertices by index, complete and each index once, in the portal plane.
  const size_t portal_count = r.room.portals.size();
  std::vector<std::vector<RimVertex>> rims(portal_count);
  for (size_t s = 0; s < portal_count; ++s) {
    const cave::Portal& portal = r.room.portals[s];
    std::vector<RimVertex>& rim = rims[s];
    rim = rim_of(r, static_cast<int>(s));
    if (rim.size() < kMinRimVertices)
      return bad_frame(portal_name(r, s) + ": rim has " + std::to_string(rim.size()) +
                       " vertices, fewer than " + std::to_string(kMinRimVertices));
    // Sorted by k: once each, and then complete means rim[k].k == k for every k.
    for (size_t i = 1; i < rim.size(); ++i)
      if (rim[i].k == rim[i - 1].k)
        return bad_frame(portal_name(r, s) + ": loop index " + std::to_string(rim[i].k) +
                         " on two vertices");
    for (size_t k = 0; k < rim.size(); ++k)
      if (rim[k].k != k)
        return bad_frame(portal_name(r, s) + ": loop index " + std::to_string(k) + " missing (" +
                         std::to_string(rim.size()) + " rim vertices)");
    for (const RimVertex& rv : rim) {
      const Vec3 p = world_position(r, rv.vertex);
      const double off = std::abs(dot(p - portal.centre, portal.normal));
      if (!(off <= kRimPlaneTolerance))
        return bad_frame(portal_name(r, s) + ": rim vertex k=" + std::to_string(rv.k) + " is " +
                         std::to_string(off) + " m off the portal plane");
    }
  }

  // The loop closes the mesh's hole at the portal: each edge (k, k+1 mod K) is an edge of exactly
  // one triangle. Without this, a loop that lost its last index (K-1) would still look complete.
  std::vector<std::vector<int>> edge_uses(portal_count);
  for (size_t s = 0; s < portal_count; ++s)
    edge_uses[s].assign(rims[s].size(), 0);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const uint32_t va = m.indices[t + e], vb = m.indices[t + (e + 1) % 3];
      const int s = m.rim_portal[va];
      if (s < 0 || m.rim_portal[vb] != s) continue;
      const size_t loop = rims[s].size();
      const size_t ka = m.rim_index[va], kb = m.rim_index[vb];
      if ((ka + 1) % loop == kb)
        ++edge_uses[s][ka];
      else if ((kb + 1) % loop == ka)
        ++edge_uses[s][kb];
    }
  }
  for (size_t s = 0; s < portal_count; ++s) {
    const size_t loop = rims[s].size();
    for (size_t k = 0; k < loop; ++k)
      if (edge_uses[s][k] != 1)
        return bad_frame(portal_name(r, s) + ": rim edge k=" + std::to_string(k) +
                         " to k=" + std::to_string((k + 1) % loop) + " is an edge of " +
                         std::to_string(edge_uses[s][k]) + " triangles, not 1");
  }
  return {};
}

Status verify_seam(const ReadyRoom& a, const ReadyRoom& b) {
  const std::string names = "rooms " + a.room.id.to_string() + " and " + b.room.id.to_string();
  int slot_a = -1, slot_b = -1;
  for (size_t i = 0; i < a.room.portals.size(); ++i)
    if (a.room.portals[i].neighbour == b.room.id) slot_a = static_cast<int>(i);
  for (size_t i = 0; i < b.room.portals.size(); ++i)
    if (b.room.portals[i].neighbour == a.room.id) slot_b = static_cast<int>(i);
  if (slot_a < 0 && slot_b < 0) return invalid_argument(names + " are not neighbours");
  if (!arrays_agree(a.mesh) || !arrays_agree(b.mesh))
    return bad_frame(names + ": per-vertex arrays of different lengths");
  if (slot_a < 0 || slot_b < 0)
    return bad_frame(names + ": only " + (slot_a < 0 ? b : a).room.id.to_string() +
                     " has a portal to the other");

  if (Status sides = check_portal_sides(a.room, static_cast<size_t>(slot_a), b.room); !sides)
    return bad_frame(names + ": " + sides.error().message);

  std::vector<RimVertex> ra = rim_of(a, slot_a), rb = rim_of(b, slot_b);
  const size_t common = std::min(ra.size(), rb.size());
  for (size_t i = 0; i < common; ++i) {
    if (ra[i].k != rb[i].k)
      return bad_frame(names + ": loop index " + std::to_string(std::min(ra[i].k, rb[i].k)) +
                       " is on one side only");
    const Vec3 wa = world_position(a, ra[i].vertex), wb = world_position(b, rb[i].vertex);
    // Values, not bits: both sides add a grid-exact float offset to a grid origin, and the
    // one difference bits could show beyond values (-0 against +0) is the same point.
    if (!(wa == wb))
      return bad_frame(names + ": rim vertex k=" + std::to_string(ra[i].k) + " at " +
                       format_vec(wa) + " and " + format_vec(wb));
    const mesh::core::float3 na = a.mesh.normals[ra[i].vertex], nb = b.mesh.normals[rb[i].vertex];
    if (!(na.x == nb.x && na.y == nb.y && na.z == nb.z))
      return bad_frame(names + ": rim vertex k=" + std::to_string(ra[i].k) +
                       " has different normals");
  }
  if (ra.size() != rb.size())
    return bad_frame(names + ": loop index " + std::to_string(common) + " is on one side only (" +
                     std::to_string(ra.size()) + " and " + std::to_string(rb.size()) +
                     " rim vertices)");
  return {};
}

}  // namespace grotto::stream
