#include "client/render/room_cache.hpp"

#include <algorithm>
#include <cstddef>

#include <glm/glm.hpp>

namespace grotto::render {

std::vector<RoomVertex> room_vertices(const codec::DecodedRoom& mesh) {
  std::vector<RoomVertex> out(mesh.vertex_count());
  for (size_t i = 0; i < out.size(); ++i) {
    RoomVertex& v = out[i];
    v.position[0] = mesh.positions[i].x;
    v.position[1] = mesh.positions[i].y;
    v.position[2] = mesh.positions[i].z;
    v.normal[0] = mesh.normals[i].x;
    v.normal[1] = mesh.normals[i].y;
    v.normal[2] = mesh.normals[i].z;
    v.roughness = i < mesh.roughness.size() ? mesh.roughness[i] : 0.0f;
    v.mineral = i < mesh.mineral.size() ? mesh.mineral[i] : 0.0f;
    v.rim = i < mesh.rim_portal.size() && mesh.rim_portal[i] >= 0 ? 1.0f : 0.0f;
  }
  return out;
}

float median_edge_length(const codec::DecodedRoom& mesh) {
  std::vector<float> lengths;
  lengths.reserve(mesh.indices.size());
  const auto at = [&](uint32_t i) {
    const mesh::core::float3& p = mesh.positions[i];
    return glm::vec3(p.x, p.y, p.z);
  };
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    for (int k = 0; k < 3; ++k)
      lengths.push_back(glm::distance(at(mesh.indices[t + k]), at(mesh.indices[t + (k + 1) % 3])));
  }
  if (lengths.empty()) return 0;
  auto mid = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
  std::nth_element(lengths.begin(), mid, lengths.end());
  return *mid;
}

void GpuRoomCache::upload(const stream::ReadyRoom& room) {
  upload(room, formations::place(
                   formations::surface_of(room.mesh, room.origin, room.room.sphere.radius)));
}

void GpuRoomCache::set_formations(cave::RoomId id,
                                  std::vector<formations::FormationShape> formations) {
  if (auto it = rooms_.find(id); it != rooms_.end()) it->second.formations = std::move(formations);
}

void GpuRoomCache::upload(const stream::ReadyRoom& room,
                          std::vector<formations::FormationShape> formations) {
  evict(room.room.id);
  GpuRoom g;
  g.room = room.room;
  g.origin = room.origin;
  const std::vector<RoomVertex> vertices = room_vertices(room.mesh);
  g.vertex_array = make_vertex_array();
  glBindVertexArray(g.vertex_array.get());
  g.vertices =
      make_static_buffer(GL_ARRAY_BUFFER, vertices.data(), vertices.size() * sizeof(RoomVertex));
  g.indices = make_static_buffer(GL_ELEMENT_ARRAY_BUFFER, room.mesh.indices.data(),
                                 room.mesh.indices.size() * sizeof(uint32_t));
  const GLsizei stride = sizeof(RoomVertex);
  auto attribute = [&](GLuint location, GLint components, size_t offset) {
    glEnableVertexAttribArray(location);
    glVertexAttribPointer(location, components, GL_FLOAT, GL_FALSE, stride,
                          reinterpret_cast<const void*>(offset));
  };
  attribute(0, 3, offsetof(RoomVertex, position));
  attribute(1, 3, offsetof(RoomVertex, normal));
  attribute(2, 1, offsetof(RoomVertex, roughness));
  attribute(3, 1, offsetof(RoomVertex, mineral));
  attribute(4, 1, offsetof(RoomVertex, rim));
  glBindVertexArray(0);
  g.index_count = static_cast<GLsizei>(room.mesh.indices.size());
  g.patch_edge = median_edge_length(room.mesh);
  g.formations = std::move(formations);
  g.bytes = vertices.size() * sizeof(RoomVertex) + room.mesh.indices.size() * sizeof(uint32_t);
  bytes_ += g.bytes;
  rooms_.emplace(room.room.id, std::move(g));
}

void GpuRoomCache::evict(cave::RoomId id) {
  auto it = rooms_.find(id);
  if (it == rooms_.end()) return;
  bytes_ -= it->second.bytes;
  rooms_.erase(it);
}

}  // namespace grotto::render
