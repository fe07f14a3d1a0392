// build_program() on the real device: the in-process cache, the disk cache and its fallbacks,
// and build errors. Every test gets its own GROTTO_CACHE_DIR. Source builds are kept few: each
// costs about a second on PoCL when PoCL's own kernel cache is cold.
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>

#include "common/core/random.hpp"
#include "common/kernels/binary_cache.hpp"
#include "common/kernels/cl_context.hpp"
#include "common/kernels/selftest.hpp"
#include "tests/kernels/test_support.hpp"

namespace grotto::kernels {
namespace {

using testing::ScopedEnv;
using testing::TempDir;

class ProgramCache : public ::testing::Test {
 protected:
  // A fresh context has an empty in-process cache, like a new server process. Throws (which
  // GoogleTest reports as a failure with the message) when there is no device.
  static ComputeContext fresh_context() {
    auto ctx = ComputeContext::create({.device = "auto"});
    if (!ctx.ok()) throw std::runtime_error(ctx.error().message);
    return std::move(ctx).value();
  }

  std::filesystem::path entry_path(uint64_t key) const {
    return cache_.path() / cache_file_name(key);
  }

  TempDir cache_;
  ScopedEnv cache_env_{"GROTTO_CACHE_DIR", cache_.path().c_str()};
};

// The cached binary must not only load but compute the same bits as the scalar reference.
void expect_selftest_is_exact(ComputeContext& ctx) {
  std::vector<float> x(257), y(257);
  Rng rng(99);
  for (size_t i = 0; i < x.size(); ++i) {
    x[i] = static_cast<float>(rng.next_u64() >> 40) / 16777216.0f * 2.0f - 1.0f;
    y[i] = static_cast<float>(rng.next_u64() >> 40) / 16777216.0f * 100.0f;
  }
  auto out = run_selftest(ctx, 0.75f, x, y);
  ASSERT_TRUE(out.ok()) << out.error().message;
  const auto expected = selftest_reference(0.75f, x, y);
  EXPECT_EQ(std::memcmp(out->data(), expected.data(), expected.size() * sizeof(float)), 0);
}

TEST_F(ProgramCache, second_context_loads_the_program_from_the_disk_cache) {
  ComputeContext first = fresh_context();
  EXPECT_EQ(first.cache_dir(), cache_.path());
  auto built = build_program(first, selftest_source(), selftest_options());
  ASSERT_TRUE(built.ok()) << built.error().message;
  EXPECT_EQ(built->origin(), BuildOrigin::kSource);
  EXPECT_TRUE(std::filesystem::exists(entry_path(built->cache_key())));

  auto again = build_program(first, selftest_source(), selftest_options());
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(again->origin(), BuildOrigin::kMemoryCache);
  EXPECT_EQ(again->get()(), built->get()());  // the very same cl_program
  EXPECT_EQ(first.stats().source_builds, 1u);
  EXPECT_EQ(first.stats().memory_cache_hits, 1u);

  auto missing = built->kernel("no_such_kernel");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("clCreateKernel(\"no_such_kernel\")"), std::string::npos)
      << missing.error().message;

  ComputeContext second = fresh_context();
  auto loaded = build_program(second, selftest_source(), selftest_options());
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->origin(), BuildOrigin::kDiskCache);
  EXPECT_EQ(loaded->cache_key(), built->cache_key());
  expect_selftest_is_exact(second);
  EXPECT_EQ(second.stats().source_builds, 0u);
  EXPECT_EQ(second.stats().disk_cache_hits, 1u);
}

TEST_F(ProgramCache, corrupt_entries_fall_back_to_a_source_build_and_are_rewritten) {
  uint64_t key = 0;
  {
    ComputeContext ctx = fresh_context();
    auto built = build_program(ctx, selftest_source(), selftest_options());
    ASSERT_TRUE(built.ok()) << built.error().message;
    key = built->cache_key();
  }
  const std::vector<unsigned char> good = testing::read_bytes(entry_path(key));
  ASSERT_GT(good.size(), kCacheHeaderSize);

  std::vector<unsigned char> garbage(good.size());
  Rng rng(7);
  for (unsigned char& b : garbage) {
    b = static_cast<unsigned char>(rng.next_u64());
  }
  const struct {
    const char* what;
    std::vector<unsigned char> bytes;
    bool run_after;
  } damages[] = {
      {"truncated", std::vector<unsigned char>(good.begin(), good.begin() + good.size() / 2),
       false},
      {"garbage", garbage, false},
      // Passes our checks, so the driver itself has to reject it (CL_INVALID_BINARY).
      {"not a binary", encode_cache_entry(key, std::vector<unsigned char>(4096, 0x5a)), true},
  };
  for (const auto& damage : damages) {
    SCOPED_TRACE(damage.what);
    testing::write_bytes(entry_path(key), damage.bytes);
    ComputeContext ctx = fresh_context();
    auto built = build_program(ctx, selftest_source(), selftest_options());
    ASSERT_TRUE(built.ok()) << built.error().message;
    EXPECT_EQ(built->origin(), BuildOrigin::kSource);
    EXPECT_TRUE(read_cache_entry(cache_.path(), key).ok()) << "entry not rewritten";
    if (damage.run_after) expect_selftest_is_exact(ctx);
  }
}

TEST_F(ProgramCache, different_options_are_different_entries) {
  const std::string options_a = selftest_options();
  const std::string options_b = selftest_options() + " -DGROTTO_UNUSED_DEFINE=1";
  ComputeContext first = fresh_context();
  auto a = build_program(first, selftest_source(), options_a);
  auto b = build_program(first, selftest_source(), options_b);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_NE(a->cache_key(), b->cache_key());
  EXPECT_EQ(b->origin(), BuildOrigin::kSource);
  EXPECT_EQ(testing::count_files(cache_.path()), 2u);

  ComputeContext second = fresh_context();
  auto b_again = build_program(second, selftest_source(), options_b);
  ASSERT_TRUE(b_again.ok()) << b_again.error().message;
  EXPECT_EQ(b_again->origin(), BuildOrigin::kDiskCache);
  EXPECT_EQ(b_again->cache_key(), b->cache_key());
}

TEST_F(ProgramCache, cache_write_failure_is_a_warning_not_an_error) {
  const std::filesystem::path file = cache_.path() / "plain-file";
  testing::write_bytes(file, {1});
  ScopedEnv unusable("GROTTO_CACHE_DIR", (file / "cl").c_str());
  ComputeContext ctx = fresh_context();
  auto built = build_program(ctx, selftest_source(), selftest_options());
  ASSERT_TRUE(built.ok()) << built.error().message;
  EXPECT_EQ(built->origin(), BuildOrigin::kSource);
  EXPECT_EQ(testing::count_files(cache_.path()), 1u);  // only the plain file
}

TEST_F(ProgramCache, build_failure_carries_the_build_log) {
  ComputeContext ctx = fresh_context();
  const char* broken =
      "__kernel void broken(__global float* out) { out[0] = grotto_undeclared_name; }\n";
  auto built = build_program(ctx, broken, "");
  ASSERT_FALSE(built.ok());
  const std::string& message = built.error().message;
  EXPECT_EQ(built.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find("CL_BUILD_PROGRAM_FAILURE"), std::string::npos) << message;
  EXPECT_NE(message.find("CL_PROGRAM_BUILD_LOG"), std::string::npos) << message;
  // Only the compiler's log can name the identifier: the source is not echoed.
  EXPECT_NE(message.find("error"), std::string::npos) << message;
  EXPECT_NE(message.find("grotto_undeclared_name"), std::string::npos) << message;
  EXPECT_EQ(ctx.stats().failures, 1u);
  EXPECT_EQ(testing::count_files(cache_.path()), 0u);
}

}  // namespace
}  // namespace grotto::kernels
