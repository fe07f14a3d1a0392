// The GPU's relief baked into a room mesh (grotto-layout --bake-relief; header-only beside
// relief.hpp, so tools and tests share it): every vertex moved as
// shaders/room.tese moves a tessellated point, through the same function (shaders/relief.glsl,
// compiled as C++ by common/relief/relief.hpp): the rock and flowstone along the normal. An engine
// that imports the file gets the rock the client draws, at the mesh's resolution: the detail
// level's 0.25-0.3 m spacing holds the metre-scale rock, not the 15 cm octave, which only the GPU's
// tessellation (or relief.hpp evaluated where needed) resolves. The formations are instances of
// their own (common/formations/formations.hpp), not baked into the rock.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/mesh/room_mesh.hpp"
#include "common/relief/relief.hpp"

namespace grotto::relief {

struct BakeStats {
  size_t moved = 0;    // vertices displaced (all but the rims')
  double largest = 0;  // the largest displacement, metres
};

// Displaces `mesh` by the relief at full strength and replaces its normals by the
// displaced surface's. Rim vertices stay bit for bit (the relief is zero on a rim, so the seams
// between rooms stay closed); the relief fades in over `rim_fade` metres from the nearest rim
// vertex, as the GPU's fades over a patch triangle.
inline BakeStats bake_relief(mesh::RoomMesh& mesh, double rim_fade = 0.56) {
  BakeStats stats;
  std::vector<Vec3> rim;
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.rim_portal[v] >= 0) rim.push_back(mesh.world_position(v));
  }
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.rim_portal[v] >= 0) continue;
    double nearest = rim_fade;
    const Vec3 at = mesh.world_position(v);
    for (const Vec3& r : rim)
      nearest = std::min(nearest, distance(at, r));
    // The GPU interpolates the rim weight across a patch triangle: 1 at a rim vertex, 0 a
    // triangle away.
    const float rim_weight = static_cast<float>(1.0 - nearest / rim_fade);
    const glm::vec3 p{mesh.positions[v].x, mesh.positions[v].y, mesh.positions[v].z};
    const glm::vec3 n{mesh.normals[v].x, mesh.normals[v].y, mesh.normals[v].z};
    const Relief r =
        relief_at(relief_pos_of(mesh.origin, p), n, mesh.roughness[v], rim_weight, 1.0f);
    const glm::vec3 moved = relief_displace(p, n, r);
    const glm::vec3 normal = relief_normal(n, r.gradient);
    mesh.positions[v] = {moved.x, moved.y, moved.z};
    mesh.normals[v] = {normal.x, normal.y, normal.z};
    ++stats.moved;
    stats.largest = std::max(stats.largest, static_cast<double>(glm::length(moved - p)));
  }
  return stats;
}

}  // namespace grotto::relief
