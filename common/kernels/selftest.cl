// The self-test kernel: a few of each IEEE-754 operation the mesh kernels rely on (multiply,
// add, divide, square root), so one launch shows whether this device, with
// kDeterministicOptions, gives the same bits as the scalar C++ reference (selftest.cpp).
#pragma OPENCL FP_CONTRACT OFF

// Prepended by the host as -DGROTTO_SELFTEST_BIAS=...; the default keeps the file buildable alone.
#ifndef GROTTO_SELFTEST_BIAS
#define GROTTO_SELFTEST_BIAS 2.0f
#endif

__kernel void grotto_selftest(const float a, __global const float* x, __global const float* y,
                              __global float* out, const uint n) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  // Same order of operations as selftest_reference(); with FP_CONTRACT OFF a * x[i] + ... is a
  // rounded multiply then a rounded add, never an fma.
  out[i] = a * x[i] + sqrt(y[i]) / (x[i] + GROTTO_SELFTEST_BIAS);
}
