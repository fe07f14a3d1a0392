// The wire's level of detail (request.rooms[].lod, the room frame's lod byte, Limits::max_lod)
// and mesh::Lod, the mesher's, are numbered in opposite directions: the wire counts up from the
// coarsest mesh (0 is the streamed patch mesh, so a server with max_lod 0 serves only that, and a
// finer level can be added as a higher number without renumbering), mesh::Lod counts from the
// finest. These two functions are the only mapping; PROTOCOL.md's "Levels of detail" table is the
// same one.
#pragma once

#include <cstdint>
#include <optional>

#include "common/mesh/params.hpp"

namespace grotto::proto {

// The highest wire lod with a mesh::Lod behind it.
inline constexpr uint32_t kMaxWireLod = 1;

// The mesher's lod for a wire lod: 0 -> kPatch, 1 -> kDetail; nullopt above kMaxWireLod.
// Callers still check the value against Limits::max_lod (what this server chose to serve).
constexpr std::optional<mesh::Lod> mesh_lod(uint32_t wire) {
  switch (wire) {
    case 0:
      return mesh::Lod::kPatch;
    case 1:
      return mesh::Lod::kDetail;
    default:
      return std::nullopt;
  }
}

// The wire lod for a mesher's lod; mesh_lod(wire_lod(lod)) == lod.
constexpr uint8_t wire_lod(mesh::Lod lod) {
  static_assert(mesh::kLodCount == 2, "a new mesh::Lod needs a wire lod here and in PROTOCOL.md");
  return lod == mesh::Lod::kPatch ? 0 : 1;
}

}  // namespace grotto::proto
