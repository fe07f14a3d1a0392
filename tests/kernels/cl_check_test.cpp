// GROTTO_CL_CHECK / GROTTO_CL_TRY and the error names, against the real ICD loader.
#include <gtest/gtest.h>

#include "common/kernels/cl_context.hpp"

namespace grotto::kernels {
namespace {

Result<int> finish_null_queue() {
  GROTTO_CL_TRY(clFinish(nullptr));
  return 1;
}

Status succeed() {
  GROTTO_CL_TRY(CL_SUCCESS);
  return {};
}

TEST(ClCheck, keeps_the_call_text_the_error_name_and_the_place) {
  Status status = GROTTO_CL_CHECK(clFinish(nullptr));
  ASSERT_FALSE(status.ok());
  const std::string& message = status.error().message;
  EXPECT_NE(message.find("clFinish(nullptr) failed"), std::string::npos) << message;
  EXPECT_NE(message.find("CL_INVALID_COMMAND_QUEUE (-36)"), std::string::npos) << message;
  EXPECT_NE(message.find("cl_check_test.cpp:"), std::string::npos) << message;
  EXPECT_TRUE(GROTTO_CL_CHECK(CL_SUCCESS).ok());
}

TEST(ClCheck, try_returns_the_error_from_the_enclosing_function) {
  auto result = finish_null_queue();
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().message.find("clFinish(nullptr)"), std::string::npos);
  EXPECT_TRUE(succeed().ok());
}

TEST(ClCheck, names_codes_and_sorts_them_into_error_kinds) {
  EXPECT_STREQ(cl_error_name(CL_BUILD_PROGRAM_FAILURE), "CL_BUILD_PROGRAM_FAILURE");
  EXPECT_STREQ(cl_error_name(-1001), "CL_PLATFORM_NOT_FOUND_KHR");
  EXPECT_STREQ(cl_error_name(12345), "CL_UNKNOWN_ERROR");
  EXPECT_EQ(cl_error(CL_OUT_OF_RESOURCES, "x").code, ErrorCode::kUnavailable);
  EXPECT_EQ(cl_error(CL_BUILD_PROGRAM_FAILURE, "x").code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(cl_error(CL_INVALID_KERNEL_ARGS, "x").code, ErrorCode::kInternal);
}

}  // namespace
}  // namespace grotto::kernels
