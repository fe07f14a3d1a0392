// A region's rooms as one glTF 2.0 binary file (grotto-layout --glb; docs/INTEGRATION.md,
// "Exporting to glTF").
//
// Each room is a node (named by its id, translated by its origin minus the file's anchor, portals
// in its extras) holding a mesh of one triangle primitive; the world's lights in it are its child
// nodes (KHR_lights_punctual), and so are its formations (one node, one mesh of them all,
// material "calcite", each instance's shape in extras.formations), listed after every room's
// node. The primitive carries
// KHR_draco_mesh_compression whose bufferView is the room's Draco payload exactly as a server
// streams it to a protocol version 1 client (codec::encode_room with default options: normals
// included, which glTF readers expect), and, since the extension is used but not
// required, plain accessors written from that payload decoded again (codec::decode_room): the same
// vertices in the same order as the Draco data (Draco's edgebreaker reorders them).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/cave/lights.hpp"
#include "common/core/result.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::tools {

// What the file says about where it comes from.
struct GlbSource {
  std::string generator;  // asset.generator, e.g. "grotto-layout 0.3.0"
  uint64_t seed = 0;
  double sector_size = 0;
  cave::SectorCoord lo, hi;  // the block of sectors
  mesh::Lod lod = mesh::Lod::kPatch;
  // World metres that every node's translation is relative to (the scene's extras say it), so
  // that float32 translations keep the grid's precision.
  Vec3 anchor;
  // Each room's formations (common/formations/formations.hpp) as a child node: one mesh of them all
  // at kGlbFormationLod (the speleothems a primitive in calcite, a hall's boulders one in rock),
  // each instance's shape in its extras.
  bool formations = true;
  // The world, when the rooms' extras should say what its rock made of them (each portal's
  // section, the room's geology: proto::room_json with a world). Not owned.
  const cave::World* world = nullptr;
};

// The level of detail formations are written at (formations::kLodSides / kLodRings: 10 x 16).
inline constexpr int kGlbFormationLod = 1;

// One room of the file: its layout and its mesh, or why it has none (its node then has no mesh
// and says the reason in extras.mesh_error).
struct GlbRoom {
  const cave::Room* room = nullptr;      // not null
  const mesh::RoomMesh* mesh = nullptr;  // null when the room could not be meshed
  std::string mesh_error;                // why, when mesh is null
  // The world's lights in the room (cave::room_lights): each a child node of the room's node with
  // a KHR_lights_punctual point light (colour, intensity, range as cave/lights.hpp defines them)
  // and its kind, facing and glowing-patch size in extras.
  std::vector<cave::WorldLight> lights;
};

// The glTF names of the payload's attributes besides POSITION and NORMAL (application-specific
// attributes start with an underscore): roughness and mineral, and the rim (portal slot + 1 or 0,
// index on the portal's canonical loop).
inline constexpr const char* kChannelsAttribute = "_CHANNELS";
inline constexpr const char* kRimAttribute = "_RIM";

// The file's bytes. Fails when a room's mesh cannot be encoded or its payload does not decode
// (the message names the room); a room without a mesh is not a failure.
Result<std::vector<uint8_t>> region_glb(const GlbSource& source, std::span<const GlbRoom> rooms);

// Writes `bytes` to `path` through a temporary file in the same directory and a rename, so the
// path holds the old file or the whole new one, never a torn one.
Status write_file_replacing(const std::string& path, std::span<const uint8_t> bytes);

}  // namespace grotto::tools
