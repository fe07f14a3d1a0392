// The C++ face of the shared deformation core (deform_core.h): the CPU reference that the OpenCL
// kernel (kernels/deform.cl) must match bit for bit.
#pragma once

#include <cmath>
#include <cstdint>

namespace grotto::mesh::core {

typedef unsigned int uint;

// A float triple with exactly the operators the core uses, evaluated in the core's order.
struct float3 {
  float x, y, z;
};
inline float3 operator+(float3 a, float3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
inline float3 operator-(float3 a, float3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
inline float3 operator-(float3 a) {
  return {-a.x, -a.y, -a.z};
}
inline float3 operator*(float3 a, float s) {
  return {a.x * s, a.y * s, a.z * s};
}
inline float3 operator/(float3 a, float s) {
  return {a.x / s, a.y / s, a.z / s};
}
inline float grotto_sqrt(float x) {
  return std::sqrt(x);
}
inline float grotto_floor(float x) {
  return std::floor(x);
}

#define GROTTO_FN inline
#define GROTTO_CONSTANT
#define GROTTO_F3(x, y, z) \
  float3 {                 \
    x, y, z                \
  }
#include "mesh/deform_core.h"
#undef GROTTO_F3
#undef GROTTO_CONSTANT
#undef GROTTO_FN

static_assert(sizeof(GrottoPortal) == 64 && sizeof(GrottoRoom) == 64 && sizeof(GrottoShape) == 128,
              "host and device struct layouts must match");

}  // namespace grotto::mesh::core
