// The world-aligned quantization grid every stage agrees on (DESIGN decision 2). Positions that
// two rooms share (portal rims) are snapped to it in the mesh stage, and the Draco codec quantizes
// on the same grid, so shared vertices decode bit-identically whichever room carried them.
//
// The step is a power of two, so a snapped coordinate is an exact binary fraction: differences of
// snapped coordinates within kFrameSize of each other are exact in float32, and a room can store
// its vertices as float32 offsets from a snapped origin without losing a bit.
#pragma once

#include <cmath>

#include "core/vec3.hpp"

namespace grotto::grid {

inline constexpr int kStepLog2 = 8;                      // 1/256 m, about 4 mm
inline constexpr double kStep = 1.0 / (1 << kStepLog2);  // metres
// Offsets from a room's origin stay below this (2^(24 - kStepLog2) m) to be exact in float32.
inline constexpr double kFrameSize = static_cast<double>(1 << (24 - kStepLog2));

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

}  // namespace grotto::grid
