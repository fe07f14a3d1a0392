// The embedded self-test kernel: the embedding is byte-exact, and the device computes the same
// bits as the scalar C++ reference (the determinism the mesh kernels depend on).
#include "common/kernels/selftest.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>

#include "common/core/random.hpp"
#include "embedded_cl/embed_fixture.hpp"
#include "tests/kernels/test_support.hpp"

namespace grotto::kernels {
namespace {

using testing::ScopedEnv;
using testing::TempDir;

std::string file_text(const char* path) {
  const auto bytes = testing::read_bytes(path);
  return std::string(bytes.begin(), bytes.end());
}

TEST(Selftest, embedded_source_is_the_cl_file_byte_for_byte) {
  const std::string on_disk = file_text(GROTTO_SELFTEST_CL_PATH);
  ASSERT_FALSE(on_disk.empty());
  EXPECT_EQ(selftest_source(), on_disk);
}

TEST(Selftest, embedding_keeps_content_a_raw_string_would_break) {
  const std::string on_disk = file_text(GROTTO_EMBED_FIXTURE_PATH);
  ASSERT_NE(on_disk.find(")\""), std::string::npos);  // the fixture still holds its traps
  ASSERT_NE(on_disk.find('\r'), std::string::npos);
  EXPECT_EQ(source_embed_fixture(), on_disk);
}

TEST(Selftest, device_matches_scalar_cpp_bit_for_bit) {
  TempDir cache;
  ScopedEnv env("GROTTO_CACHE_DIR", cache.path().c_str());
  auto ctx = ComputeContext::create({.device = "auto"});
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;

  // Random floats over many binades plus edge values; an odd count leaves a partial work-group.
  const size_t n = 4099;
  std::vector<float> x(n), y(n);
  Rng rng(2024);
  for (size_t i = 0; i < n; ++i) {
    const float unit = static_cast<float>(rng.next_u64() >> 40) / 16777216.0f;  // [0, 1)
    const int exponent = static_cast<int>(rng.next_u64() % 40) - 20;
    x[i] = (unit * 2.0f - 1.0f);
    y[i] = std::ldexp(unit + 0.5f, exponent);
  }
  x[0] = -1.0f;
  y[0] = 0.0f;
  x[1] = 1.0f;
  y[1] = 1.0f;
  x[2] = 0.0f;
  y[2] = 2.0f;
  const float a = 1.7f;

  auto out = run_selftest(ctx.value(), a, x, y);
  ASSERT_TRUE(out.ok()) << out.error().message;
  const std::vector<float> expected = selftest_reference(a, x, y);
  ASSERT_EQ(out->size(), n);
  size_t mismatches = 0;
  for (size_t i = 0; i < n; ++i) {
    if (std::bit_cast<uint32_t>((*out)[i]) != std::bit_cast<uint32_t>(expected[i])) {
      if (mismatches++ < 5) {
        ADD_FAILURE() << "i=" << i << " x=" << x[i] << " y=" << y[i] << " device=" << (*out)[i]
                      << " cpu=" << expected[i];
      }
    }
  }
  EXPECT_EQ(mismatches, 0u) << "on " << ctx->describe();
}

TEST(Selftest, mismatched_inputs_are_rejected_before_any_build) {
  ScopedEnv env("GROTTO_OPENCL_DEVICE", nullptr);
  auto ctx = ComputeContext::create({.device = "auto", .disable_disk_cache = true});
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;
  auto out = run_selftest(ctx.value(), 1.0f, {1.0f, 2.0f}, {1.0f});
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(ctx->stats().source_builds + ctx->stats().failures, 0u);
}

}  // namespace
}  // namespace grotto::kernels
