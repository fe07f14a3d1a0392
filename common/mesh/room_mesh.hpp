// Room meshes (thesis §3.1.3-3.1.7): a donor sphere per room, deformed onto Hermite splines
// between its portal rims with world-space noise, cut at each portal and stitched to the
// portal's canonical rim loop, with smoothed normals and per-vertex detail channels.
//
// The work is split so that the deformation can run on an OpenCL device between two CPU steps:
//   prepare_room  -> DeformInput  (the room and portal records, the donor sphere)
//   deform        -> positions and clearances per donor vertex   (CPU: deform_cpu; kernels/)
//   assemble_room -> RoomMesh     (cut, stitch, compact, normals, channels)
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/mesh/context.hpp"
#include "common/mesh/donor.hpp"
#include "common/mesh/rim.hpp"

namespace grotto::mesh {

struct RoomMesh {
  cave::RoomId id = cave::RoomId::interior({}, 0);
  Lod lod = Lod::kDetail;
  Vec3 origin;                          // on the grid; positions are offsets from it
  std::vector<core::float3> positions;  // metres from origin (exact for rim vertices)
  std::vector<core::float3> normals;    // unit, facing the inside of the cave
  std::vector<float> roughness;         // 0-1, steers GPU displacement
  std::vector<float> mineral;           // 0-1, mineral/glow mask
  std::vector<int8_t> rim_portal;       // index into the room's portals, or -1
  std::vector<uint16_t> rim_index;      // position on that portal's canonical loop
  std::vector<uint32_t> indices;        // triangles, counter-clockwise seen from inside the cave

  size_t vertex_count() const { return positions.size(); }
  size_t triangle_count() const { return indices.size() / 3; }
  Vec3 world_position(size_t i) const {
    return origin + Vec3{positions[i].x, positions[i].y, positions[i].z};
  }
};

// Everything the deformation of one room needs, in the layout the device uses.
struct DeformInput {
  cave::Room room;
  Lod lod = Lod::kDetail;
  Vec3 origin;
  core::GrottoRoom record{};
  std::vector<core::GrottoPortal> portals;
  std::shared_ptr<const DonorSphere> donor;
  // The world's detail-channel frequencies as detail_channels uses them (roughness, three times
  // roughness, mineral), for a device that computes the channels with the deformation.
  std::array<float, 3> channel_frequencies{};
};

DeformInput prepare_room(const MeshContext& ctx, const cave::Room& room, Lod lod);

// The deformation on the CPU: one position and clearance per donor vertex (spans of the donor's
// size). Runs four vertices at a time in SIMD lanes; every result is bit-identical to
// deform_reference's, and to the OpenCL kernel's (common/kernels/deform.hpp).
void deform_cpu(const MeshContext& ctx, const DeformInput& input, std::span<core::float3> positions,
                std::span<float> clearance);
// The scalar reference of the deformation (the core one vertex per call), for tests.
void deform_reference(const MeshContext& ctx, const DeformInput& input,
                      std::span<core::float3> positions, std::span<float> clearance);

// The detail channels of vertices at origin + positions[i] (world-space fields, so rim vertices
// agree across rooms): roughness and mineral, spans of positions' size. SIMD lanes, bit-identical
// to detail_channels_reference.
void detail_channels(const MeshContext& ctx, Vec3 origin, std::span<const core::float3> positions,
                     std::span<float> roughness, std::span<float> mineral);
// A finished mesh's roughness and mineral, sized to its vertices (assemble_room's last stage, and
// what a caller that took ChannelsBy::kCaller runs when its device cannot).
void fill_detail_channels(const MeshContext& ctx, RoomMesh& mesh);
void detail_channels_reference(const MeshContext& ctx, Vec3 origin,
                               std::span<const core::float3> positions, std::span<float> roughness,
                               std::span<float> mineral);

// Why a room could not be assembled; counted, never silent.
struct AssembleStats {
  int loops_stitched = 0;
  int pinches_removed = 0;    // boundary vertices where holes touch, cut away
  int pinches_kept = 0;       // ... where the holes of two portals meet, kept in both loops
  int fragments_dropped = 0;  // triangles outside the main component
  // Seconds per stage, for the thesis's stage table (Figure 3-10).
  double cut_seconds = 0;       // wrong-side removal and hole boundaries ("fix triangles")
  double stitch_seconds = 0;    // rim loops and the zipper ("weld verts")
  double normals_seconds = 0;   // compaction and normals ("create normals")
  double channels_seconds = 0;  // roughness and mineral fields
};

// Where assemble_room's last stage, the detail channels, runs: here, or by the caller, who gets
// the mesh with roughness and mineral empty and fills them (kernels::RoomBuilder on several
// threads, in pieces any thread takes; the same bits).
enum class ChannelsBy { kAssemble, kCaller };

// Every donor vertex's detail channels, computed with its deformation (a device's launch, from
// the positions it returns: the bits detail_channels gives them). With them assemble_room takes
// the kept donor vertices' and computes only the rim vertices' own.
struct DonorChannels {
  std::span<const float> roughness, mineral;  // one per donor vertex, or both empty
};

Result<RoomMesh> assemble_room(const MeshContext& ctx, const DeformInput& input,
                               std::span<const core::float3> positions,
                               std::span<const float> clearance, AssembleStats* stats = nullptr,
                               ChannelsBy channels = ChannelsBy::kAssemble,
                               DonorChannels donor_channels = {});

// prepare + deform_cpu + assemble.
Result<RoomMesh> build_room_mesh(const MeshContext& ctx, const cave::Room& room, Lod lod);

}  // namespace grotto::mesh
