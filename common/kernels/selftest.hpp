// The self-test: one tiny real kernel (common/kernels/selftest.cl, embedded at build time) and its
// scalar C++ reference. A server can run it at start-up to decide between the OpenCL path and the
// CPU reference path; the tests use it to check bit-identity and the caches.
#pragma once

#include <string>
#include <vector>

#include "common/core/result.hpp"
#include "common/kernels/cl_context.hpp"

namespace grotto::kernels {

// The self-test kernel's source (common/kernels/selftest.cl) and the options it is built with:
// kDeterministicOptions plus its -D define.
std::string_view selftest_source();
std::string selftest_options();

// out[i] = a * x[i] + sqrt(y[i]) / (x[i] + 2), in float, as scalar C++ computes it.
// Requires x.size() == y.size(); y[i] >= 0 and x[i] != -2 keep every result finite.
std::vector<float> selftest_reference(float a, const std::vector<float>& x,
                                      const std::vector<float>& y);

// The same computation on the context's device (built through build_program, so it uses and
// fills the caches). kInvalidArgument if the sizes differ or are zero; OpenCL failures as errors.
Result<std::vector<float>> run_selftest(ComputeContext& ctx, float a, const std::vector<float>& x,
                                        const std::vector<float>& y);

}  // namespace grotto::kernels
