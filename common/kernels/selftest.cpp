// The self-test kernel's host side and its scalar C++ reference.
#include "common/kernels/selftest.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "embedded_cl/selftest.hpp"

namespace grotto::kernels {
namespace {

// Passed to the kernel as a -D define, so the self-test also covers the "defines prepended by the
// caller" path. Written as a hex float literal (%a) so host and device see exactly one value.
constexpr float kSelftestBias = 2.0f;

}  // namespace

std::string_view selftest_source() {
  return source_selftest();
}

std::string selftest_options() {
  char bias[48];
  std::snprintf(bias, sizeof bias, "%af", static_cast<double>(kSelftestBias));
  return std::string(kDeterministicOptions) + " -DGROTTO_SELFTEST_BIAS=" + bias;
}

std::vector<float> selftest_reference(float a, const std::vector<float>& x,
                                      const std::vector<float>& y) {
  assert(x.size() == y.size());
  std::vector<float> out(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    out[i] = a * x[i] + std::sqrt(y[i]) / (x[i] + kSelftestBias);
  }
  return out;
}

Result<std::vector<float>> run_selftest(ComputeContext& ctx, float a, const std::vector<float>& x,
                                        const std::vector<float>& y) {
  if (x.size() != y.size() || x.empty()) {
    return invalid_argument("run_selftest: x and y must be non-empty and of equal size");
  }
  if (x.size() > std::numeric_limits<cl_uint>::max()) {
    return invalid_argument("run_selftest: more elements than a cl_uint counts");
  }
  auto program = build_program(ctx, selftest_source(), selftest_options());
  if (!program.ok()) return program.error();
  auto kernel = program->kernel("grotto_selftest");
  if (!kernel.ok()) return kernel.error();

  auto x_buf = make_buffer(ctx, CL_MEM_READ_ONLY, x.data(), x.size());
  if (!x_buf.ok()) return x_buf.error();
  auto y_buf = make_buffer(ctx, CL_MEM_READ_ONLY, y.data(), y.size());
  if (!y_buf.ok()) return y_buf.error();
  auto out_buf = make_buffer<float>(ctx, CL_MEM_WRITE_ONLY, x.size());
  if (!out_buf.ok()) return out_buf.error();

  const cl_uint n = static_cast<cl_uint>(x.size());
  Status status =
      set_kernel_args(kernel.value(), a, x_buf.value(), y_buf.value(), out_buf.value(), n);
  if (!status.ok()) return status.error();
  status = enqueue_1d(ctx, kernel.value(), x.size());
  if (!status.ok()) return status.error();
  std::vector<float> out(x.size());
  status = read_buffer(ctx, out_buf.value(), out.data(), out.size());
  if (!status.ok()) return status.error();
  return out;
}

}  // namespace grotto::kernels
