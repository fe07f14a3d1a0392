/* Prepended to common/mesh/deform_core.h when the deformation kernel is built: maps the core's
 * portability macros to OpenCL C. No contraction into fma, so results match the C++ reference
 * (which is compiled with -ffp-contract=off); the host adds -cl-fp32-correctly-rounded-divide-sqrt.
 *
 * GROTTO_LANES (1 or 8, set by the host) is how many vertices of one room a work item deforms:
 * 1 on GPUs, which spread work items over SIMD lanes themselves; 8 on CPU devices, where PoCL does
 * not vectorize this kernel across work items, so the kernel does it in float8 registers. */
#pragma OPENCL FP_CONTRACT OFF
#ifndef GROTTO_LANES
#define GROTTO_LANES 1
#endif
#define GROTTO_FN inline __attribute__((always_inline))
#define GROTTO_CONSTANT __constant
#define grotto_sqrt sqrt
#define grotto_floor floor
#define GROTTO_SPLAT(x) ((gfloat)(x))

#if GROTTO_LANES == 1
typedef float gfloat;
typedef uint guint;
typedef int gmask;
#define GROTTO_WRAP256(f) ((uint)((int)(f)&255))
#define GROTTO_LOAD(p) (*(p))
#define GROTTO_STORE(v, p) (*(p) = (v))
#elif GROTTO_LANES == 8
typedef float8 gfloat;
typedef uint8 guint;
typedef int8 gmask;
#define GROTTO_WRAP256(f) as_uint8(convert_int8(f) & 255)
#define GROTTO_LOAD(p) vload8(0, (p))
#define GROTTO_STORE(v, p) vstore8((v), 0, (p))
#else
#error "GROTTO_LANES must be 1 or 8"
#endif

typedef struct {
  gfloat x, y, z;
} gfloat3;
