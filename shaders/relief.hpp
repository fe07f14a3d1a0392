// The C++ face of shaders/relief.glsl: the same source, compiled as C++ over GLM, so the CPU
// (collision) evaluates the relief the GPU draws. Float32 on both sides; the results differ by
// the drivers' rounding only (GLSL may contract a * b + c into a fused multiply-add).
#pragma once

#include <glm/glm.hpp>

namespace grotto::relief {

// The shared source is written in GLSL's vocabulary (vec3, floor, mix, ...): GLM's names.
using namespace glm;

#define RELIEF_FN inline
#include "shaders/relief.glsl"
#undef RELIEF_FN

}  // namespace grotto::relief
