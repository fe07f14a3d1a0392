// The disk cache's key, location and file format, checked without a device.
#include "common/kernels/binary_cache.hpp"

#include <gtest/gtest.h>

#include <set>

#include "tests/kernels/test_support.hpp"

namespace grotto::kernels {
namespace {

using testing::ScopedEnv;
using testing::TempDir;

std::vector<unsigned char> sample_binary() {
  std::vector<unsigned char> bytes(200);
  for (size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<unsigned char>(i * 37 + 11);
  }
  return bytes;
}

DeviceInfo sample_device() {
  DeviceInfo d;
  d.platform_name = "Portable Computing Language";
  d.platform_version = "OpenCL 3.0 PoCL 3.1";
  d.device_name = "cpu-haswell";
  d.device_version = "OpenCL 3.0";
  d.driver_version = "3.1";
  return d;
}

TEST(BinaryCache, entry_round_trips) {
  const auto binary = sample_binary();
  const auto file = encode_cache_entry(42, binary);
  ASSERT_EQ(file.size(), kCacheHeaderSize + binary.size());
  auto decoded = decode_cache_entry(42, file);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded.value(), binary);
}

// PoCL crashes on a truncated binary, so every prefix must be caught before the driver sees it.
TEST(BinaryCache, every_truncation_is_rejected) {
  const auto file = encode_cache_entry(42, sample_binary());
  for (size_t length = 0; length < file.size(); ++length) {
    std::span<const unsigned char> prefix(file.data(), length);
    EXPECT_FALSE(decode_cache_entry(42, prefix).ok()) << "length " << length;
  }
  auto padded = file;
  padded.push_back(0);
  EXPECT_FALSE(decode_cache_entry(42, padded).ok());
}

TEST(BinaryCache, every_changed_byte_is_rejected) {
  const auto file = encode_cache_entry(42, sample_binary());
  for (size_t i = 0; i < file.size(); ++i) {
    auto damaged = file;
    damaged[i] ^= 0x01;
    EXPECT_FALSE(decode_cache_entry(42, damaged).ok()) << "byte " << i;
  }
}

TEST(BinaryCache, entry_of_another_key_is_rejected) {
  const auto file = encode_cache_entry(42, sample_binary());
  auto decoded = decode_cache_entry(43, file);
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.error().message.find("another key"), std::string::npos);
}

TEST(BinaryCache, key_changes_with_every_field) {
  const DeviceInfo base = sample_device();
  std::set<uint64_t> keys;
  keys.insert(program_cache_key("kernel", "-DA", base));
  keys.insert(program_cache_key("kernel2", "-DA", base));
  keys.insert(program_cache_key("kernel", "-DB", base));
  for (std::string DeviceInfo::*field :
       {&DeviceInfo::platform_name, &DeviceInfo::platform_version, &DeviceInfo::device_name,
        &DeviceInfo::device_version, &DeviceInfo::driver_version}) {
    DeviceInfo changed = base;
    changed.*field += "x";
    keys.insert(program_cache_key("kernel", "-DA", changed));
  }
  EXPECT_EQ(keys.size(), 8u);
  // Fields are length-prefixed: moving bytes between source and options changes the key.
  EXPECT_NE(program_cache_key("ab", "c", base), program_cache_key("a", "bc", base));
  EXPECT_EQ(program_cache_key("kernel", "-DA", base), program_cache_key("kernel", "-DA", base));
}

TEST(BinaryCache, cache_dir_follows_config_then_environment) {
  ScopedEnv grotto("GROTTO_CACHE_DIR", "/tmp/g");
  ScopedEnv xdg("XDG_CACHE_HOME", "/tmp/x");
  ScopedEnv home("HOME", "/tmp/h");
  EXPECT_EQ(resolve_cache_dir("/tmp/c"), "/tmp/c");
  EXPECT_EQ(resolve_cache_dir(""), "/tmp/g");
  {
    ScopedEnv unset("GROTTO_CACHE_DIR", "");  // empty counts as unset
    EXPECT_EQ(resolve_cache_dir(""), "/tmp/x/grotto/cl");
    ScopedEnv unset_xdg("XDG_CACHE_HOME", nullptr);
    EXPECT_EQ(resolve_cache_dir(""), "/tmp/h/.cache/grotto/cl");
    ScopedEnv unset_home("HOME", nullptr);
    EXPECT_TRUE(resolve_cache_dir("").empty());
  }
}

TEST(BinaryCache, write_then_read_leaves_only_the_entry) {
  TempDir dir;
  const std::filesystem::path nested = dir.path() / "a" / "b";
  const auto binary = sample_binary();
  ASSERT_TRUE(write_cache_entry(nested, 7, binary).ok());
  EXPECT_EQ(testing::count_files(nested), 1u);  // no temporary file left behind
  EXPECT_TRUE(std::filesystem::exists(nested / cache_file_name(7)));
  auto read = read_cache_entry(nested, 7);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read.value(), binary);
  // Overwriting an entry replaces it whole.
  ASSERT_TRUE(write_cache_entry(nested, 7, std::vector<unsigned char>(5, 9)).ok());
  EXPECT_EQ(read_cache_entry(nested, 7).value(), std::vector<unsigned char>(5, 9));
}

TEST(BinaryCache, missing_entry_is_not_found) {
  TempDir dir;
  auto read = read_cache_entry(dir.path(), 7);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.error().code, ErrorCode::kNotFound);
}

TEST(BinaryCache, unusable_directory_is_an_error_with_the_path) {
  TempDir dir;
  const std::filesystem::path file = dir.path() / "plain-file";
  testing::write_bytes(file, {1, 2, 3});
  Status written = write_cache_entry(file / "cl", 7, sample_binary());
  ASSERT_FALSE(written.ok());
  EXPECT_EQ(written.error().code, ErrorCode::kUnavailable);
  EXPECT_NE(written.error().message.find("plain-file"), std::string::npos);
}

}  // namespace
}  // namespace grotto::kernels
