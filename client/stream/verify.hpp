// Checks on received rooms beyond what decoding already enforces, for grotto-load --verify and the
// tests: a room's mesh agrees with its own descriptor, and two neighbouring rooms close their
// shared portal watertight (PROTOCOL.md "Rims": the same loop, bit for bit, in both rooms).
#pragma once
#include "client/stream/room_store.hpp"
#include "common/core/grid.hpp"
#include "common/core/result.hpp"

namespace grotto::stream {

// How far outside its sphere a vertex may lie: kSphereMarginMetres + kSphereMarginFraction x
// radius. Surface noise pushes walls out by up to the sum of its octave amplitudes (0.78 m patch,
// 0.84 m detail with the default mesh::MeshParams) plus, in rooms of radius >= 6 m, a
// low-frequency octave of 0.12 x radius. Measured on decoded rooms (seeds 1, 7, 42, 99, 2025,
// 123456789; wire lod 0 rooms of sectors [0,1]^3, lod 1 rooms of sectors (0..1, 0, 0); 6,726
// rooms): at most 1.048 m outside (radius 11.25 m), at most 0.51 m in rooms under 6 m, and never
// more than 0.36 of the bound below (~2.8x headroom). A server with stronger noise than the
// defaults needs a larger one.
inline constexpr double kSphereMarginMetres = 1.5;
inline constexpr double kSphereMarginFraction = 0.15;
double vertex_sphere_margin(double radius);

// Rim vertices lie in their portal's plane up to the grid snap (mesh/rim.cpp snaps each loop
// vertex to the 1/256 m grid: at most sqrt(3)/2 steps, 3.4 mm, along the normal). One whole step
// leaves room for rounding; measured at most 3.17 mm on the rooms above.
inline constexpr double kRimPlaneTolerance = grid::kStep;

// The fewest vertices a rim loop may have: a loop needs three. (Grotto's mesher makes at least 8,
// mesh::rim_vertex_count; measured at least 14 at lod 0 and 31 at lod 1. That is the server's
// choice, not the protocol's, so it is not checked here.)
inline constexpr size_t kMinRimVertices = 3;

// One room alone: every vertex within its sphere (plus vertex_sphere_margin) around the centre,
// unit normals (codec::kNormalTolerance), channels in [0, 1], rim slots below the portal count, no
// loop index off a rim, triangle indices in range; and every portal's canonical rim loop present
// once and complete: indices 0..K-1 each on exactly one vertex (K >= kMinRimVertices), each in
// the portal's plane (kRimPlaneTolerance), and each loop edge (k, k+1 mod K) an edge of exactly
// one triangle, so the loop is the boundary of the mesh's hole at that portal (without this check a
// loop that lost its last index would look complete: K is not in the frame). All of this held for
// every rim of every room measured above. Errors (kBadFrame) name the room, the portal and what
// was wrong.
Status verify_room(const ReadyRoom& room);

// Two rooms that share a portal (each lists the other): the portal's two sides agree
// (check_portal_sides in portal_graph.hpp: centre and radius bit for bit, opposite normals), and
// for every loop index k the two rims' vertices decode to the same world position bit for bit
// (compared as values: -0 and +0 are the same point) and the same normal, with the same K on both
// sides. Errors (kBadFrame) name both rooms and the first index
// that differs; kInvalidArgument when neither lists the other, kBadFrame when only one does.
Status verify_seam(const ReadyRoom& a, const ReadyRoom& b);

}  // namespace grotto::stream
