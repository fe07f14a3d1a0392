// Canonical portal rims: the loop of vertices where two rooms meet, computed
// only from the portal, the seed and the level of detail, so that both rooms, built anywhere,
// stitch to the same vertices in the same cyclic order, bit for bit.
#pragma once

#include <vector>

#include "common/cave/layout.hpp"
#include "common/mesh/context.hpp"
#include "common/mesh/deform.hpp"

namespace grotto::mesh {

struct RimLoop {
  Vec3 centre;                        // the portal disc's centre (world)
  Vec3 normal;                        // canonical: from the lower room id towards the higher
  Vec3 e1, e2;                        // canonical in-plane basis, e2 = normal x e1
  std::vector<Vec3> positions;        // world, on the grid, counter-clockwise about `normal`
  std::vector<core::float3> normals;  // unit, towards the portal's axis (into the cave)
};

// The canonical frame of a portal: its centre, its normal from the lower room id towards the
// higher, and an in-plane basis. The same for both rooms of the portal; no noise, no vertices.
RimLoop rim_frame(const cave::Room& room, const cave::Portal& portal);

// Vertices on a rim of this radius: about one per edge length, at least 8.
int rim_vertex_count(double radius, double edge_length);

// The record the deformation core reads for `portal`, a portal of `room`, in the frame of
// `origin` (world): its disc, its canonical basis, and its passage's section from the world's
// geology (cave::passage_section), the same for both rooms of the portal.
core::GrottoPortal portal_record(const MeshContext& ctx, const cave::Room& room,
                                 const cave::Portal& portal, Vec3 origin);

// The loop of `portal`, a portal of `room`. Identical for the two rooms of a portal.
RimLoop canonical_rim(const MeshContext& ctx, const cave::Room& room, const cave::Portal& portal,
                      Lod lod);

// The farthest a rim vertex of a portal of this radius can lie from the portal's centre, at any
// level of detail (metres): the irregular radius drawn out to the farthest a passage's section
// reaches (cave::kMaxSectionReach), plus the surface octaves that move the rim (deform_core.h,
// grotto_rim_noise; gradient noise stays within [-1, 1]), plus their soft limit's offset. What
// covers a whole opening (fog caps, portal culling) must reach this far.
double rim_reach(const MeshParams& params, double portal_radius);

}  // namespace grotto::mesh
