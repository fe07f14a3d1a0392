#include "relief_bake.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "shaders/relief.hpp"

namespace grotto::tools {

BakeStats bake_relief(mesh::RoomMesh& mesh, const cave::Room& room, double rim_fade) {
  BakeStats stats;
  std::vector<Vec3> rim;
  for (size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.rim_portal[v] >= 0) rim.push_back(mesh.world_position(v));
  }
  const glm::vec3 origin{static_cast<float>(mesh.origin.x), static_cast<float>(mesh.origin.y),
                         static_cast<float>(mesh.origin.z)};
  const float radius = static_cast<float>(room.sphere.radius);
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
    const relief::Relief r =
        relief::relief_at(p + origin, n, mesh.roughness[v], rim_weight, radius, 1.0f);
    const glm::vec3 moved = relief::relief_displace(p, n, r);
    const glm::vec3 normal = relief::relief_displaced_normal(n, r.gradient, r.hang_gradient);
    mesh.positions[v] = {moved.x, moved.y, moved.z};
    mesh.normals[v] = {normal.x, normal.y, normal.z};
    ++stats.moved;
    stats.largest = std::max(stats.largest, static_cast<double>(glm::length(moved - p)));
    stats.largest_hang = std::max(stats.largest_hang, static_cast<double>(std::abs(r.hang)));
  }
  return stats;
}

}  // namespace grotto::tools
