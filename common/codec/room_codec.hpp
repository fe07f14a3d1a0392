// The room codec: a room's mesh as a Draco payload, quantized on the world-aligned grid
// (common/core/grid.hpp), and back.
//
// Positions are offsets from the room's grid-snapped origin (the origin itself travels in the room
// frame, proto/PROTOCOL.md "Room payload (Draco)"). They are quantized with an explicit Draco
// quantization whose step is exactly grid::kStep (1/64 m) and whose origin is a grid multiple, so
// a vertex that lies on the grid (every portal rim vertex) decodes to the very same float it was
// encoded from: the two rooms of a portal, each encoded alone, decode bit-identical shared rims.
// Draco's edgebreaker reorders vertices, so rim membership travels as an attribute, never as an
// index. The decoder checks rims against the wire's 1/256 m grid (grid::kWireStep), on which
// every power-of-two world grid from 1/256 m up lies, so rooms of older servers decode too.
//
// Attribute layout (unique ids are part of the format):
//   0  POSITION  float32 x3  explicit quantization: step 2^-EncodeOptions::grid_step_log2 m
//                            (grid::kStep by default), origin a multiple of it
//   1  NORMAL    float32 x3  octahedral, EncodeOptions::normal_bits; protocol version 1 only
//   2  GENERIC   float32 x2  (roughness, mineral), explicit quantization of [0, 1]
//   3  GENERIC   uint16  x2  (portal slot + 1 or 0 off rims, index on the portal's canonical loop)
// Protocol version 2 leaves the normals out (a fifth of the bytes, a third of the decode): the
// receiver derives them from the decoded surface and the frame's portal discs (derive_normals),
// so that the two rooms of a portal get the same rim normals.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/core/grid.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::codec {

// Attribute unique ids in the payload.
inline constexpr uint32_t kPositionId = 0;
inline constexpr uint32_t kNormalId = 1;
inline constexpr uint32_t kChannelsId = 2;
inline constexpr uint32_t kRimId = 3;

// The format's ceilings: encode_room refuses a room over them and decode_room never accepts more,
// whatever DecodeLimits asks. Measured over five sectors (seed 42, 551 room meshes): the largest
// patch room has 4,825 vertices, 9,541 triangles and 15,567 payload bytes; the largest detail room
// 24,734 vertices, 49,224 triangles and 50,896 bytes. The ceilings hold that detail room 2.6x over.
inline constexpr size_t kMaxPayloadBytes = size_t{1} << 18;   // 256 KiB
inline constexpr uint32_t kMaxVertices = uint32_t{1} << 16;   // 65,536
inline constexpr uint32_t kMaxTriangles = uint32_t{1} << 17;  // 131,072
// What a brace-initialized DecodeLimits accepts: the streamed patch level, 3.4x the largest patch
// room (4x its bytes). A client decoding detail payloads (wire lod 1) passes kDetailLimits.
inline constexpr size_t kPatchMaxPayloadBytes = size_t{1} << 16;   // 64 KiB
inline constexpr uint32_t kPatchMaxVertices = uint32_t{1} << 14;   // 16,384
inline constexpr uint32_t kPatchMaxTriangles = uint32_t{1} << 15;  // 32,768
inline constexpr int kMaxPortals = 127;  // rim slots are int8 in mesh::RoomMesh
// Offsets from the room origin stay within this many metres on every axis (rooms are tens of
// metres across; float32 holds grid values exactly to grid::kFrameSize).
inline constexpr double kMaxOffset = 1024.0;
// A decoded normal is accepted when its length is within this of 1.
inline constexpr float kNormalTolerance = 1e-3f;

// Draco settings. Brace-init means the defaults chosen by measurement (docs/BENCHMARKS.md, "Room
// codec", 2026-11-25): speed 3 (valence edgebreaker at every size, parallelogram positions,
// geometric normal prediction: 22% smaller than speed 5, 7 or 9, for 1.5-1.8x their encode and
// decode time, ~0.26 ms and ~0.16 ms for a median room), 8-bit octahedral normals (< 1 degree;
// they cost ~340 bytes a room, a fifth of it, and a third of the decode) and 6-bit channels (half a
// step is 0.8% of [0, 1]; 90 bytes smaller than 7 bits). Whatever the speed, every attribute shares
// the position connectivity (Draco's split_mesh_on_seams): the attributes have one value per
// vertex, so the per-attribute seam tables Draco would otherwise build cost time and no bytes.
struct EncodeOptions {
  int speed = 3;         // Draco encoding and decoding speed, 0 (smallest) to 9; 10 (sequential
                         // connectivity) is refused: the decoder accepts only edgebreaker
  int normal_bits = 8;   // octahedral normal quantization, 2-16
  int channel_bits = 6;  // roughness and mineral quantization over [0, 1], 1-16
  // Positions are quantized on the grid of step 2^-grid_step_log2 m, 0 to grid::kWireStepLog2;
  // the room's origin and rim vertices must lie on it. The world grid by default; a decoded room
  // from another server may need the wire's finest (grid::kWireStepLog2) to encode again.
  int grid_step_log2 = grid::kStepLog2;
  // Write the normal attribute (protocol version 1's layout); false: version 2's, without it.
  bool normals = true;
};

// A room's geometry as spans, the codec's input. Views a mesh::RoomMesh or a DecodedRoom.
struct RoomView {
  Vec3 origin;  // on the encoder's grid (EncodeOptions::grid_step_log2) on every axis
  std::span<const mesh::core::float3> positions;  // metres from origin
  std::span<const mesh::core::float3> normals;    // unit
  std::span<const float> roughness;               // 0-1
  std::span<const float> mineral;                 // 0-1
  std::span<const int8_t> rim_portal;             // portal slot 0..kMaxPortals-1, or -1
  std::span<const uint16_t> rim_index;            // position on that portal's canonical loop
  std::span<const uint32_t> indices;              // triangles
};

// A decoded room: the same per-vertex data as mesh::RoomMesh, in the payload's vertex order.
struct DecodedRoom {
  std::vector<mesh::core::float3> positions;  // metres from the room origin; exact for grid points
  std::vector<mesh::core::float3> normals;    // unit within kNormalTolerance; empty from a version
                                              // 2 payload until derive_normals
  std::vector<float> roughness;               // 0-1
  std::vector<float> mineral;                 // 0-1
  std::vector<int8_t> rim_portal;             // slot below DecodeLimits::portal_count, or -1
  std::vector<uint16_t> rim_index;            // 0 where rim_portal is -1
  std::vector<uint32_t> indices;              // triangles, every index < vertex_count()

  size_t vertex_count() const { return positions.size(); }
  size_t triangle_count() const { return indices.size() / 3; }
};

// What decode_room accepts. Brace-init gives the patch level (kPatch* above); a client passes the
// room's portal count from the frame's descriptor so that rim slots are checked against it. Values
// above the format's ceilings (kMax*) are treated as the ceilings.
struct DecodeLimits {
  size_t max_bytes = kPatchMaxPayloadBytes;
  uint32_t max_vertices = kPatchMaxVertices;
  uint32_t max_triangles = kPatchMaxTriangles;
  int portal_count = kMaxPortals;  // rim slots must be below this
  // The payload carries normals (protocol version 1's layout). False: version 2's layout, without
  // them; decode_room then leaves DecodedRoom::normals empty for derive_normals to fill.
  bool normals = true;
};
// The format's ceilings, for detail payloads.
inline constexpr DecodeLimits kDetailLimits = {kMaxPayloadBytes, kMaxVertices, kMaxTriangles,
                                               kMaxPortals};

// What decode_room may hold at once, Draco's allocations included, within DecodeLimits{} and
// within kDetailLimits: 24 MiB and 96 MiB. Measured, not derived from Draco's source: the
// largest payload known is a mesh at the triangle limit whose three non-position attributes have
// a seam on every edge (a value per corner, 3 x triangles values each, under 2 KB of payload).
// tests/codec/room_codec_alloc_test.cpp decodes one at 31,752 and 129,032 triangles with each of
// Draco's speed settings and holds decode_room to these figures: peaks 18.6 MB and 75.2 MB,
// ~580 bytes a triangle, so ~19.2 MB and ~76.4 MB at the limits; the largest single allocation
// is 1.1 MB and 4.6 MB. The bound rests on the attribute check in decode_room: with only the four
// layouts above, no value is wider than 12 bytes.
inline constexpr int64_t kPatchDecodePeakBytes = int64_t{24} << 20;
inline constexpr int64_t kDetailDecodePeakBytes = int64_t{96} << 20;

// Views of the codec's inputs; the spans point into `mesh` / `room`, which must outlive the view.
RoomView view_of(const mesh::RoomMesh& mesh);
RoomView view_of(const DecodedRoom& room, Vec3 origin = {});

// Encodes a room as a Draco payload. Fails (invalid_argument) when the room breaks a contract of
// RoomView: mismatched array sizes, an off-grid origin, non-finite or out-of-range values, an
// index out of range, a degenerate triangle, an off-grid rim vertex, counts over the kMax*
// ceilings, or a payload that would come out over kMaxPayloadBytes. Deterministic: the same room
// and options give the same bytes. Thread-safe (no shared state).
Result<std::vector<uint8_t>> encode_room(const RoomView& room, const EncodeOptions& options = {});
inline Result<std::vector<uint8_t>> encode_room(const mesh::RoomMesh& mesh,
                                                const EncodeOptions& options = {}) {
  return encode_room(view_of(mesh), options);
}

// What encode_room would write for `room` with the position attribute alone: the payload's
// positions and connectivity, the part the world grid fixes. For measuring (bench/codec_bench
// reports its bits per vertex); decode_room refuses it (three attributes are missing). Fails as
// encode_room does.
Result<std::vector<uint8_t>> encode_geometry_only(const RoomView& room,
                                                  const EncodeOptions& options = {});

// Decodes a payload made by encode_room. Safe for untrusted input, with bounded memory
// (kPatchDecodePeakBytes / kDetailDecodePeakBytes): the size limit and the counts that Draco's
// header declares are checked before Draco allocates anything for them; Draco's edgebreaker
// decoder parses the bytes, and when it reaches the attribute descriptors (after connectivity,
// before any attribute value is allocated) they must be exactly the four of the layout above, or
// decoding stops there; the prediction method at the start of each attribute decoder's data must
// be one Draco defines before Draco reads it (Draco 1.5.5 does not check; see room_codec.cpp);
// then the layout and every value are validated (finite positions within kMaxOffset, rim
// vertices on the 1/256 m wire grid, unit normals, channels in [0, 1], rim slots below
// limits.portal_count, indices in range, no degenerate triangle). Limits over the kMax* ceilings
// count as the ceilings. Every failure is an invalid_argument Error whose message names the
// problem; nothing throws or aborts. Deterministic: the same bytes decode to the same room.
// Thread-safe.
// With limits.normals false, the payload must hold version 2's three attributes and `normals`
// comes back empty.
Result<DecodedRoom> decode_room(std::span<const uint8_t> payload, const DecodeLimits& limits = {});

// A portal disc of the room's frame, world coordinates (proto/PROTOCOL.md, "Binary room frame").
struct PortalDisc {
  Vec3 centre;
  Vec3 normal;  // unit; either orientation gives the same rim normals
};

// Protocol version 2's normals (proto/PROTOCOL.md, "Normals"), written into room.normals:
// a vertex on a rim faces the portal's axis, -normalize(d - (d.n)n) with d = origin + position -
// portal centre, computed in binary64 from values both rooms of the portal share bit for bit
// (world positions of rim vertices, the disc's centre, its normal up to sign), so both derive the
// same rim normals and shading is continuous across the portal; every other vertex takes the
// normalized sum of its triangles' area-weighted face normals (cross(b - a, c - a), facing the
// cave), or (0, 1, 0) when that sum is zero. `portals` are the frame's, in frame order (rim slots
// index them). Errors: invalid_argument when a rim slot has no disc in `portals` or the arrays
// differ in length. About 20 ns a triangle (0.018 ms for a median patch room, codec_bench).
Status derive_normals(DecodedRoom& room, Vec3 origin, std::span<const PortalDisc> portals);

}  // namespace grotto::codec
