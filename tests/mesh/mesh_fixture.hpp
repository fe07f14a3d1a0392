// Shared test fixture: a world and every room of a block built as patch meshes, each by its own
// call, in shuffled order.
#pragma once

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "common/core/random.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::mesh::testing {

struct BuiltBlock {
  cave::Region region;
  std::map<cave::RoomId, RoomMesh> meshes;
  std::vector<std::string> failures;  // "room: why" for each room that did not build
};

inline BuiltBlock build_block(const MeshContext& ctx, cave::SectorCoord lo, cave::SectorCoord hi,
                              Lod lod, uint64_t order_seed) {
  BuiltBlock out{cave::generate_region(ctx.world(), lo, hi), {}, {}};
  std::vector<const cave::Room*> order;
  for (const cave::Room& r : out.region.rooms)
    order.push_back(&r);
  Rng rng(order_seed);
  for (size_t i = order.size(); i > 1; --i) {
    std::swap(order[i - 1], order[rng.below(static_cast<uint32_t>(i))]);
  }
  for (const cave::Room* r : order) {
    auto mesh = build_room_mesh(ctx, *r, lod);
    if (mesh.ok()) {
      out.meshes.emplace(r->id, std::move(mesh).value());
    } else {
      out.failures.push_back(r->id.to_string() + ": " + mesh.error().message);
    }
  }
  return out;
}

// The rim of portal `slot` of a mesh, in canonical order: world positions and normals.
struct Rim {
  std::vector<Vec3> positions;
  std::vector<core::float3> normals;
};
inline Rim rim_of(const RoomMesh& m, int slot) {
  std::vector<std::pair<uint16_t, size_t>> at;
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    if (m.rim_portal[v] == slot) at.push_back({m.rim_index[v], v});
  }
  std::sort(at.begin(), at.end());
  Rim rim;
  for (auto [k, v] : at) {
    rim.positions.push_back(m.world_position(v));
    rim.normals.push_back(m.normals[v]);
  }
  return rim;
}

}  // namespace grotto::mesh::testing
