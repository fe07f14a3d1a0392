// A room mesh built on the world grid (grid::kStepLog2) made encodable on a coarser world grid
// (codec::EncodeOptions::grid_step_log2 < grid::kStepLog2), for measuring what that grid would
// cost without changing the mesh stage (docs/BENCHMARKS.md, "Room codec"). encode_room refuses a
// room whose origin or rim vertices are off its grid, and on 1/32 m about 7 in 8 of the rooms'
// origins and rim vertices built on 1/64 m are (98 of 116 origins, 4,005 of 4,523 rim vertices in
// seed 42's sector 0,0,0), so the encoder's grid cannot change alone: the origin and the rims are
// snapped first. Rims are then snapped twice (1/64 m, then 1/32 m): up to 35 mm off their portal's
// plane, where the mesh stage on 1/32 m would leave at most 27 mm. Both are snapped in world
// coordinates, as the mesh stage snaps them (grid::snap, ties away from zero), so a rim vertex two
// rooms share moves to the same point in both and rims stay bit-identical; every other vertex keeps
// its world position (to float32 rounding of the new offset) for the encoder to quantize. Normals
// and channels are the server's, unchanged.
#pragma once

#include <cassert>
#include <cmath>

#include "common/core/grid.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::bench {

// v on the world grid of step 2^-step_log2 m, ties away from zero (grid::snap's rule).
inline double snap_to(double v, int step_log2) {
  const double scale = static_cast<double>(1 << step_log2);
  return std::round(v * scale) / scale;
}
inline Vec3 snap_to(Vec3 v, int step_log2) {
  return {snap_to(v.x, step_log2), snap_to(v.y, step_log2), snap_to(v.z, step_log2)};
}

// `m` with its origin and rim vertices on the world grid of step 2^-step_log2 m (at most
// grid::kStepLog2: a finer grid would not move them). The identity at grid::kStepLog2.
inline mesh::RoomMesh on_coarser_grid(const mesh::RoomMesh& m, int step_log2) {
  assert(step_log2 >= 0 && step_log2 <= grid::kStepLog2);
  mesh::RoomMesh out = m;
  out.origin = snap_to(m.origin, step_log2);
  const Vec3 shift = m.origin - out.origin;  // exact: both are grid multiples
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    const Vec3 offset = m.rim_portal[v] >= 0
                            ? snap_to(m.world_position(v), step_log2) - out.origin
                            : Vec3{m.positions[v].x, m.positions[v].y, m.positions[v].z} + shift;
    out.positions[v] = {static_cast<float>(offset.x), static_cast<float>(offset.y),
                        static_cast<float>(offset.z)};
  }
  return out;
}

}  // namespace grotto::bench
