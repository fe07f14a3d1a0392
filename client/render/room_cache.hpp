// The rooms on the GPU: one vertex array per ReadyRoom, uploaded when client/stream delivers it
// and freed when the stream evicts it. Vertices stay in their room's frame (float offsets from
// the room origin, exact for grid points); the renderer adds the room's offset from a render
// anchor near the camera, so world coordinates of ~10^4 m never pass through float32.
//
// Needs a current GL context for its whole life (it owns GL objects). Not thread-safe.
#pragma once

#include <cstddef>
#include <map>
#include <vector>

#include "client/render/gl.hpp"
#include "client/stream/room_store.hpp"
#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"
#include "common/formations/formations.hpp"

namespace grotto::render {

// The interleaved vertex the room shaders read (shaders/room.vert, locations 0-4).
struct RoomVertex {
  float position[3];  // metres from the room origin
  float normal[3];
  float roughness;
  float mineral;
  float rim;  // 1 on a portal rim (shared with the neighbour: never displaced), else 0
};
static_assert(sizeof(RoomVertex) == 9 * sizeof(float));

// The vertices of a decoded room in RoomVertex layout (pure: testable without a GPU).
std::vector<RoomVertex> room_vertices(const codec::DecodedRoom& mesh);

// The median length of the room's triangle edges, metres (0 for no triangles): the step of the
// tessellation at level 1, from which room.tese knows the step the relief is drawn at.
float median_edge_length(const codec::DecodedRoom& mesh);

struct GpuRoom {
  cave::Room room;  // descriptor: sphere and portals (fog caps, culling)
  Vec3 origin;      // on the grid
  VertexArray vertex_array;
  Buffer vertices;
  Buffer indices;
  GLsizei index_count = 0;
  float patch_edge = 0;  // median_edge_length of its mesh
  // Its speleothems (formations::place over its patch mesh), roots in its frame: the renderer
  // streams the ones it draws each frame as instances.
  std::vector<formations::FormationShape> formations;
  size_t bytes = 0;  // GPU bytes of both buffers
};

class GpuRoomCache {
 public:
  // Uploads the room, replacing one with the same id, with its formations placed here
  // (formations::place: a hall's takes milliseconds) or given (placed elsewhere, or to come
  // through set_formations).
  void upload(const stream::ReadyRoom& room);
  void upload(const stream::ReadyRoom& room, std::vector<formations::FormationShape> formations);
  // The room's formations, when they were placed apart from its upload; nothing when it is gone.
  void set_formations(cave::RoomId id, std::vector<formations::FormationShape> formations);
  void evict(cave::RoomId id);
  void clear() { rooms_.clear(), bytes_ = 0; }
  bool contains(cave::RoomId id) const { return rooms_.count(id) != 0; }
  const std::map<cave::RoomId, GpuRoom>& rooms() const { return rooms_; }
  size_t size() const { return rooms_.size(); }
  size_t bytes() const { return bytes_; }

 private:
  std::map<cave::RoomId, GpuRoom> rooms_;
  size_t bytes_ = 0;
};

}  // namespace grotto::render
