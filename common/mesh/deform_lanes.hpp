// The shared deformation core (deform_core.h) a second time, with four vertices per call in SIMD
// lanes (GCC/Clang vector extensions), for the CPU: the same scheme as the OpenCL kernel's float8
// lanes on PoCL (deform_core.h, "Lanes"). Every lane performs exactly the scalar reference's
// operations (+ - * / and sqrt are IEEE per lane; -ffp-contract=off covers vector code too;
// floor is made exact below), so each lane is bit-identical to core::grotto_deform_vertex and
// core::grotto_noise. Private to grotto::mesh (room_mesh.cpp and its tests).
#pragma once

#include <cstdint>
#include <cstring>

#include "common/mesh/deform.hpp"

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

// On a function that runs the lanes: also compile it for AVX2 and pick at load time (GCC's and
// Clang's function multiversioning). AVX2 has the 32-bit multiply and the blend that SSE2 lacks
// (the lattice hash and every per-lane choice): half the instructions. No FMA: AVX2 alone does not
// include it, and FP contraction is off anyway, so every clone gives the same bits.
#if defined(__x86_64__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define GROTTO_LANES_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#endif
#ifndef GROTTO_LANES_CLONES
#define GROTTO_LANES_CLONES
#endif

namespace grotto::mesh::core::lanes {

inline constexpr int kLanes = 4;

// 16-byte vectors: SSE2 registers on every x86-64, NEON on AArch64, without ABI warnings.
typedef float gfloat __attribute__((vector_size(16)));
typedef uint guint __attribute__((vector_size(16)));
typedef int gmask __attribute__((vector_size(16)));
struct gfloat3 {
  gfloat x, y, z;
};

inline __attribute__((always_inline)) gfloat grotto_sqrt(gfloat x) {
#if defined(__SSE__)
  __m128 r = _mm_sqrt_ps(reinterpret_cast<__m128>(x));  // correctly rounded, as std::sqrt
  return reinterpret_cast<gfloat>(r);
#else
  for (int i = 0; i < kLanes; ++i)
    x[i] = std::sqrt(x[i]);
  return x;
#endif
}

// std::floor in every lane, bit for bit: below 2^23 by truncation (exact) and a step down for
// negative fractions, keeping the sign of a zero (floor(-0) is -0); from 2^23 up, and for
// infinities and NaN, x itself.
inline __attribute__((always_inline)) gfloat grotto_floor(gfloat x) {
  const gmask sign_bit = {INT32_MIN, INT32_MIN, INT32_MIN, INT32_MIN};
  gfloat t = __builtin_convertvector(__builtin_convertvector(x, gmask), gfloat);
  t = t > x ? t - 1.0f : t;
  gmask bits = reinterpret_cast<gmask>(t) | (reinterpret_cast<gmask>(x) & sign_bit);
  t = t == 0.0f ? reinterpret_cast<gfloat>(bits) : t;
  gfloat ax = reinterpret_cast<gfloat>(reinterpret_cast<gmask>(x) & ~sign_bit);
  return ax < 8388608.0f ? t : x;  // NaN compares false: x
}

// Scalars into lanes, for the calls the core makes with per-room floats (OpenCL converts these
// implicitly); each is the same operation in every lane.
// A broadcast, not 0 + x, which would turn -0 into +0.
inline __attribute__((always_inline)) gfloat splat(float x) {
  return gfloat{x, x, x, x};
}
inline __attribute__((always_inline)) gfloat load(const float* p) {
  gfloat v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline __attribute__((always_inline)) gfloat3 grotto_v3(float x, float y, float z) {
  return {splat(x), splat(y), splat(z)};
}
inline __attribute__((always_inline)) gfloat3 grotto_scale(gfloat3 a, float s) {
  return {a.x * s, a.y * s, a.z * s};
}

// Inlined into the callers, so that GROTTO_LANES_CLONES below reaches the whole core.
#define GROTTO_FN inline __attribute__((always_inline))
#define GROTTO_CONSTANT
#define GROTTO_WRAP256(f) (reinterpret_cast<guint>(__builtin_convertvector((f), gmask) & 255))
#define GROTTO_SPLAT(x) splat(x)
#include "common/mesh/deform_core.h"
#undef GROTTO_SPLAT
#undef GROTTO_WRAP256
#undef GROTTO_CONSTANT
#undef GROTTO_FN

// The tables are defined here a second time (a distinct type, so that overloads of core's and
// these functions never meet); callers copy core's into them, byte for byte.
static_assert(sizeof(GrottoPortal) == sizeof(core::GrottoPortal) &&
                  sizeof(GrottoRoom) == sizeof(core::GrottoRoom) &&
                  sizeof(GrottoShape) == sizeof(core::GrottoShape),
              "the lanes' tables must be core's");
template <class To, class From>
To table(const From& from) {
  static_assert(sizeof(To) == sizeof(From));
  To to;
  std::memcpy(&to, &from, sizeof to);
  return to;
}

}  // namespace grotto::mesh::core::lanes
