// Device choice and fail-soft context creation on the real OpenCL stack (PoCL on CI).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <vector>

#include "common/kernels/cl_context.hpp"
#include "tests/kernels/test_support.hpp"

namespace grotto::kernels {
namespace {

using testing::ScopedEnv;
using testing::TempDir;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::string upper(std::string text) {
  for (char& c : text) {
    c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return text;
}

TEST(ComputeContext, creates_a_cpu_context_and_describes_it) {
  auto ctx = ComputeContext::create({.device = "cpu"});
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;
  const DeviceInfo& info = ctx->info();
  EXPECT_EQ(info.device_type, "cpu");
  EXPECT_FALSE(info.platform_name.empty());
  EXPECT_FALSE(info.device_name.empty());
  EXPECT_FALSE(info.driver_version.empty());
  EXPECT_GT(info.compute_units, 0u);
  EXPECT_GT(info.global_mem_bytes, 0u);
  EXPECT_NE(ctx->queue()(), nullptr);
  const std::string line = ctx->describe();
  EXPECT_TRUE(contains(line, "platform=\"" + info.platform_name + "\"")) << line;
  EXPECT_TRUE(contains(line, "device=\"" + info.device_name + "\"")) << line;
  EXPECT_TRUE(contains(line, "type=cpu")) << line;
  EXPECT_TRUE(contains(line, "driver=\"" + info.driver_version + "\"")) << line;
}

TEST(ComputeContext, gpu_request_gets_a_gpu_or_an_error_listing_the_devices) {
  auto ctx = ComputeContext::create({.device = "gpu"});
  if (ctx.ok()) {
    EXPECT_EQ(ctx->info().device_type, "gpu");
    return;
  }
  EXPECT_EQ(ctx.error().code, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(ctx.error().message, "'gpu'")) << ctx.error().message;
  EXPECT_TRUE(contains(ctx.error().message, "cpu")) << ctx.error().message;  // what was found
}

TEST(ComputeContext, none_in_the_environment_disables_opencl) {
  ScopedEnv env("GROTTO_OPENCL_DEVICE", "none");
  auto ctx = ComputeContext::create({});
  ASSERT_FALSE(ctx.ok());
  EXPECT_EQ(ctx.error().code, ErrorCode::kUnavailable);
  EXPECT_TRUE(contains(ctx.error().message, "disabled by configuration")) << ctx.error().message;
}

TEST(ComputeContext, config_device_overrides_the_environment) {
  ScopedEnv env("GROTTO_OPENCL_DEVICE", "none");
  auto ctx = ComputeContext::create({.device = "auto"});
  EXPECT_TRUE(ctx.ok()) << ctx.error().message;
}

TEST(ComputeContext, unknown_device_name_is_named_in_the_error) {
  auto cpu = ComputeContext::create({.device = "cpu"});
  ASSERT_TRUE(cpu.ok()) << cpu.error().message;
  ScopedEnv env("GROTTO_OPENCL_DEVICE", "no-such-device-7f3a");
  auto ctx = ComputeContext::create({});
  ASSERT_FALSE(ctx.ok());
  EXPECT_EQ(ctx.error().code, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(ctx.error().message, "'no-such-device-7f3a'")) << ctx.error().message;
  EXPECT_TRUE(contains(ctx.error().message, cpu->info().device_name)) << ctx.error().message;
}

TEST(ComputeContext, device_name_substring_selects_a_device_ignoring_case) {
  auto cpu = ComputeContext::create({.device = "cpu"});
  ASSERT_TRUE(cpu.ok()) << cpu.error().message;
  const std::string name = cpu->info().device_name;
  ASSERT_GE(name.size(), 4u);
  const std::string part = name.substr(name.size() / 2 - 2, 4);
  auto ctx = ComputeContext::create({.device = upper(part)});
  ASSERT_TRUE(ctx.ok()) << part << ": " << ctx.error().message;
  EXPECT_TRUE(contains(upper(ctx->info().device_name), upper(part))) << ctx->info().device_name;
}

// Meaningful on its own (create() either gives a described device or an error naming the cause)
// and the child half of the no-platform test below, which reads the line it prints.
TEST(ComputeContext, create_reports_its_outcome) {
  auto ctx = ComputeContext::create({});
  if (ctx.ok()) {
    EXPECT_FALSE(ctx->info().device_name.empty());
    EXPECT_TRUE(contains(ctx->describe(), ctx->info().device_name));
    std::printf("create_outcome=ok %s\n", ctx->describe().c_str());
  } else {
    EXPECT_FALSE(ctx.error().message.empty());
    EXPECT_TRUE(ctx.error().code == ErrorCode::kUnavailable ||
                ctx.error().code == ErrorCode::kNotFound);
    std::printf("create_outcome=error code=%s message=%s\n", error_code_name(ctx.error().code),
                ctx.error().message.c_str());
  }
  std::fflush(stdout);
}

// With no ICD registered, clGetPlatformIDs finds nothing; create() must say so, not crash.
// The ICD loader reads its vendor list once per process, hence the child process: this test
// binary itself, pointed at an empty vendors folder.
TEST(ComputeContext, no_opencl_platform_fails_soft_in_a_child_process) {
  testing::ChildRun child =
      testing::run_self_without_opencl("ComputeContext.create_reports_its_outcome");
  const std::string& output = child.output;
  ASSERT_TRUE(child.exited) << output;
  EXPECT_EQ(child.exit_code, 0) << output;
  EXPECT_TRUE(contains(output, "create_outcome=error code=unavailable")) << output;
  EXPECT_TRUE(contains(output, "no OpenCL platform")) << output;
}

// The memory a deformation's results land in: a device buffer's read arrives in it, and it moves
// (the deform kernel grows it by replacing it) with its contents; empty ones are refused.
TEST(PinnedHost, receives_a_read_and_keeps_it_through_a_move) {
  auto ctx = ComputeContext::create(DeviceConfig{.device = "auto"});
  ASSERT_TRUE(ctx.ok()) << ctx.error().message;
  const std::vector<float> values = {1.5f, -2.0f, 3.25f, 1e-7f};
  auto device = make_buffer(*ctx, CL_MEM_READ_WRITE, values.data(), values.size());
  ASSERT_TRUE(device.ok()) << device.error().message;
  auto pinned = PinnedHost::create(*ctx, values.size() * sizeof(float));
  ASSERT_TRUE(pinned.ok()) << pinned.error().message;
  EXPECT_EQ(pinned->bytes(), values.size() * sizeof(float));
  auto* out = static_cast<float*>(pinned->data());
  ASSERT_TRUE(read_buffer(*ctx, *device, out, values.size()).ok());
  PinnedHost moved = std::move(pinned).value();
  ASSERT_EQ(moved.data(), out);
  EXPECT_EQ(std::vector<float>(out, out + values.size()), values);
  PinnedHost replaced;
  replaced = std::move(moved);
  EXPECT_EQ(replaced.data(), out);
  EXPECT_EQ(moved.data(), nullptr);
  EXPECT_EQ(moved.bytes(), 0u);
  EXPECT_FALSE(PinnedHost::create(*ctx, 0).ok());
}

}  // namespace
}  // namespace grotto::kernels
