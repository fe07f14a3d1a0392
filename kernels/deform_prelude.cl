/* Prepended to common/mesh/deform_core.h when the deformation kernel is built: maps the core's
 * portability macros to OpenCL C. No contraction into fma, so results match the C++ reference
 * (which is compiled with -ffp-contract=off); the host adds -cl-fp32-correctly-rounded-divide-sqrt.
 */
#pragma OPENCL FP_CONTRACT OFF
#define GROTTO_FN inline __attribute__((always_inline))
#define GROTTO_CONSTANT __constant
#define GROTTO_F3(x, y, z) ((float3)((x), (y), (z)))
#define grotto_sqrt sqrt
#define grotto_floor floor
