// The C++ face of shaders/relief.glsl: the same source, compiled as C++ over GLM, so the CPU
// (collision) evaluates the relief the GPU draws. Float32 on both sides; the results differ by
// the drivers' rounding only (GLSL may contract a * b + c into a fused multiply-add).
#pragma once

#include <cmath>
#include <glm/glm.hpp>

#include "common/core/vec3.hpp"

namespace grotto::relief {

// The shared source is written in GLSL's vocabulary (vec3, floor, mix, ...): GLM's names.
using namespace glm;

#define RELIEF_FN inline
#include "shaders/relief.glsl"
#undef RELIEF_FN

// The world point frame + offset (frame in world metres, doubles: a room's origin; offset a float
// from it) as the relief evaluates it: the block of kReliefBlock metres holding the frame, exact,
// and the rest as a float. The renderer's anchor is such a block's corner, so the shaders and C++
// round alike.
inline ReliefPos relief_pos_of(Vec3 frame, glm::vec3 offset) {
  const ivec3 block(static_cast<int>(std::floor(frame.x / kReliefBlock)),
                    static_cast<int>(std::floor(frame.y / kReliefBlock)),
                    static_cast<int>(std::floor(frame.z / kReliefBlock)));
  const glm::vec3 from_corner(static_cast<float>(frame.x - block.x * double{kReliefBlock}),
                              static_cast<float>(frame.y - block.y * double{kReliefBlock}),
                              static_cast<float>(frame.z - block.z * double{kReliefBlock}));
  return relief_pos(block, from_corner + offset);
}

}  // namespace grotto::relief
