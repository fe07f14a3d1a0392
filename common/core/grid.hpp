// The world-aligned quantization grid every stage agrees on. Positions that
// two rooms share (portal rims) are snapped to it in the mesh stage, and the Draco codec quantizes
// on the same grid, so shared vertices decode bit-identically whichever room carried them.
//
// The step is a power of two, so a snapped coordinate is an exact binary fraction: differences of
// snapped coordinates within kFrameSize of each other are exact in float32, and a room can store
// its vertices as float32 offsets from a snapped origin without losing a bit.
//
// Two grids: the world grid (kStep), which this build snaps and quantizes on, and the wire grid
// (kWireStep, proto/PROTOCOL.md), which receivers check origins and rim vertices against. Any
// power-of-two world step at least as coarse as the wire's lies on the wire grid, so a client
// accepts the rooms of a server on either grid, and an older server's 1/256 m rooms decode too.
#pragma once

#include <cmath>

#include "common/core/vec3.hpp"

namespace grotto::grid {

// 1/64 m (15.6 mm; positions within 7.8 mm per axis of the built mesh). The patch mesh is the
// low-res shape the GPU tessellates and displaces by 5 cm to 1.5 m; its edges are 0.44 m long
// (median; shortest 0.13 m, 1% under 0.21 m). Against the earlier 1/256 m the payload's positions
// and connectivity fall from 22.0 to 16.1 bits a vertex and the room from 2,009 to 1,688 bytes
// (docs/BENCHMARKS.md, "Room codec"). The detail level (lod 1, 0.25 m target edges, not streamed
// by default) gets the same 7.8 mm. Changing it changes every room: the world digest folds it in
// (proto::world_params_digest).
inline constexpr int kStepLog2 = 6;
inline constexpr double kStep = 1.0 / (1 << kStepLog2);  // metres
// Offsets from a room's origin stay below this (2^(24 - kStepLog2) m) to be exact in float32.
inline constexpr double kFrameSize = static_cast<double>(1 << (24 - kStepLog2));

// The wire's finest grid, 1/256 m: protocol version 1 promises origins and rim vertices on it.
inline constexpr int kWireStepLog2 = 8;
inline constexpr double kWireStep = 1.0 / (1 << kWireStepLog2);
static_assert(kStepLog2 <= kWireStepLog2, "the world grid must lie on the wire grid");

// Nearest grid value (ties away from zero); exact for |v| < 2^44 m.
inline double snap(double v) {
  return std::round(v * (1 << kStepLog2)) * kStep;
}
inline Vec3 snap(Vec3 v) {
  return {snap(v.x), snap(v.y), snap(v.z)};
}
inline bool on_grid(double v) {
  return snap(v) == v;
}
// On the grid of step 2^-step_log2 m (step_log2 in 0..kWireStepLog2).
inline bool on_grid(double v, int step_log2) {
  const double scale = static_cast<double>(1 << step_log2);
  return std::round(v * scale) / scale == v;
}
inline bool on_wire_grid(double v) {
  return on_grid(v, kWireStepLog2);
}

}  // namespace grotto::grid
