// proto/token.hpp: how programs read the shared secret and how the server compares it.
#include "proto/token.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace grotto::proto {
namespace {

class TokenFile : public ::testing::Test {
 protected:
  std::string write(const std::string& bytes) {
    std::ofstream(path_, std::ios::binary) << bytes;
    return path_;
  }
  void TearDown() override { std::filesystem::remove(path_); }
  std::string path_ = (std::filesystem::temp_directory_path() /
                       ("grotto_token_test_" + std::to_string(getpid()) + ".txt"))
                          .string();
};

TEST_F(TokenFile, first_line_trimmed_is_the_token) {
  auto t = resolve_token(write("  s3cret word\t\r\nsecond line\n"), nullptr);
  ASSERT_TRUE(t.ok()) << t.error().message;
  EXPECT_EQ(*t, "s3cret word");
}

TEST_F(TokenFile, file_wins_over_the_environment) {
  auto t = resolve_token(write("from-file"), "from-env");
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(*t, "from-file");
}

TEST_F(TokenFile, empty_unreadable_or_invalid_files_name_the_setting_not_the_token) {
  auto empty = resolve_token(write("   \nsecond"), nullptr);
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("token-file " + path_ + ": the first line is empty"),
            std::string::npos)
      << empty.error().message;
  auto missing = resolve_token(path_ + ".absent", nullptr);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("token-file"), std::string::npos);
  EXPECT_NE(missing.error().message.find("cannot be read"), std::string::npos);
  auto long_token = resolve_token(write(std::string(257, 'k')), nullptr);
  ASSERT_FALSE(long_token.ok());
  EXPECT_NE(long_token.error().message.find("at most 256 bytes"), std::string::npos);
  auto binary = resolve_token(write("abc\x01secret"), nullptr);
  ASSERT_FALSE(binary.ok());
  EXPECT_NE(binary.error().message.find("printable ASCII"), std::string::npos);
  EXPECT_EQ(binary.error().message.find("secret"), std::string::npos) << "echoes the token";
}

TEST(Token, environment_is_used_without_a_file_and_empty_means_none) {
  auto t = resolve_token("", "env-token");
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(*t, "env-token");
  EXPECT_EQ(*resolve_token("", ""), "");
  EXPECT_EQ(*resolve_token("", nullptr), "");
  auto bad = resolve_token("", "tab\tinside");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("GROTTO_TOKEN"), std::string::npos) << bad.error().message;
}

TEST(Token, equality_is_exact) {
  EXPECT_TRUE(token_equals("abc", "abc"));
  EXPECT_FALSE(token_equals("abc", "abd"));
  EXPECT_FALSE(token_equals("abc", "ab"));
  EXPECT_FALSE(token_equals("abc", "abcabc"));  // a repeat of the expected token
  EXPECT_FALSE(token_equals("abc", ""));
  EXPECT_FALSE(token_equals("", ""));  // no token configured matches nothing
}

}  // namespace
}  // namespace grotto::proto
