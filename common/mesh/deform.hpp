// The C++ face of the shared deformation core (deform_core.h): the CPU reference that the OpenCL
// kernel (common/kernels/deform.cl) must match bit for bit.
#pragma once

#include <cmath>
#include <cstdint>

#include "common/cave/layout.hpp"

namespace grotto::mesh::core {

typedef unsigned int uint;

// A float triple; the core does its arithmetic with its own grotto_add, grotto_scale, ...
struct float3 {
  float x, y, z;
};
inline float grotto_sqrt(float x) {
  return std::sqrt(x);
}
inline float grotto_floor(float x) {
  return std::floor(x);
}

// One lane: the reference deforms one vertex per call.
typedef float gfloat;
typedef uint guint;
typedef bool gmask;
typedef float3 gfloat3;

#define GROTTO_FN inline
#define GROTTO_CONSTANT
#define GROTTO_WRAP256(f) static_cast<guint>(static_cast<int>(f) & 255)
#define GROTTO_SPLAT(x) (x)
#include "common/mesh/deform_core.h"
#undef GROTTO_SPLAT
#undef GROTTO_WRAP256
#undef GROTTO_CONSTANT
#undef GROTTO_FN

// The core keeps per-portal values in arrays of GROTTO_MAX_PORTALS.
static_assert(cave::kMaxPortalsPerRoom <= GROTTO_MAX_PORTALS,
              "the deformation core must hold every portal a room can have");
static_assert(sizeof(GrottoPortal) == 96 && sizeof(GrottoRoom) == 108 + 8 * GROTTO_MAX_BEDS &&
                  sizeof(GrottoShape) == 128,
              "host and device struct layouts must match");

}  // namespace grotto::mesh::core
