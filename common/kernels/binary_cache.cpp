// The on-disk binary cache's key, location and file format (see binary_cache.hpp).
#include "common/kernels/binary_cache.hpp"

#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "common/core/bytes.hpp"
#include "common/core/random.hpp"

namespace grotto::kernels {
namespace {

constexpr std::array<unsigned char, 8> kMagic = {'G', 'R', 'O', 'T', 'C', 'L', 'B', '1'};

uint64_t hash_field(uint64_t h, std::string_view field) {
  unsigned char length[8];
  le::store(length, field.size());
  h = fnv1a64(length, sizeof length, h);
  return fnv1a64(reinterpret_cast<const unsigned char*>(field.data()), field.size(), h);
}

std::string env_or_empty(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr ? std::string(value) : std::string();
}

std::string errno_text() {
  return std::strerror(errno);
}

}  // namespace

uint64_t program_cache_key(std::string_view source, std::string_view options,
                           const DeviceInfo& device) {
  uint64_t h = hash_field(0xcbf29ce484222325ull, "grotto-cl-binary-v1");
  for (std::string_view field :
       {source, options, std::string_view(device.platform_name),
        std::string_view(device.platform_version), std::string_view(device.device_name),
        std::string_view(device.device_version), std::string_view(device.driver_version)}) {
    h = hash_field(h, field);
  }
  return h;
}

std::filesystem::path resolve_cache_dir(std::string_view configured) {
  if (!configured.empty()) return std::filesystem::path(configured);
  if (std::string dir = env_or_empty("GROTTO_CACHE_DIR"); !dir.empty()) return dir;
  if (std::string xdg = env_or_empty("XDG_CACHE_HOME"); !xdg.empty()) {
    return std::filesystem::path(xdg) / "grotto" / "cl";
  }
  if (std::string home = env_or_empty("HOME"); !home.empty()) {
    return std::filesystem::path(home) / ".cache" / "grotto" / "cl";
  }
  return {};
}

std::string cache_file_name(uint64_t key) {
  char name[32];
  std::snprintf(name, sizeof name, "%016llx.clbin", static_cast<unsigned long long>(key));
  return name;
}

std::vector<unsigned char> encode_cache_entry(uint64_t key, std::span<const unsigned char> binary) {
  std::vector<unsigned char> file(kCacheHeaderSize + binary.size());
  std::memcpy(file.data(), kMagic.data(), kMagic.size());
  le::store(file.data() + 8, key);
  le::store(file.data() + 16, binary.size());
  le::store(file.data() + 24, fnv1a64(binary.data(), binary.size()));
  if (!binary.empty()) std::memcpy(file.data() + kCacheHeaderSize, binary.data(), binary.size());
  return file;
}

Result<std::vector<unsigned char>> decode_cache_entry(uint64_t key,
                                                      std::span<const unsigned char> file) {
  if (file.size() < kCacheHeaderSize) {
    return invalid_argument("cache entry truncated: " + std::to_string(file.size()) +
                            " bytes, shorter than its header");
  }
  if (std::memcmp(file.data(), kMagic.data(), kMagic.size()) != 0) {
    return invalid_argument("cache entry has the wrong magic (not a Grotto v1 entry)");
  }
  if (le::load(file.data() + 8) != key) {
    return invalid_argument("cache entry belongs to another key");
  }
  const uint64_t size = le::load(file.data() + 16);
  if (size == 0 || size != file.size() - kCacheHeaderSize) {
    return invalid_argument("cache entry truncated or padded: header says " + std::to_string(size) +
                            " bytes, file holds " + std::to_string(file.size() - kCacheHeaderSize));
  }
  std::span<const unsigned char> binary = file.subspan(kCacheHeaderSize);
  if (fnv1a64(binary.data(), binary.size()) != le::load(file.data() + 24)) {
    return invalid_argument("cache entry checksum mismatch (corrupt)");
  }
  return std::vector<unsigned char>(binary.begin(), binary.end());
}

Result<std::vector<unsigned char>> read_cache_entry(const std::filesystem::path& dir,
                                                    uint64_t key) {
  const std::filesystem::path path = dir / cache_file_name(key);
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return not_found("no cache entry " + path.string() + ": " + ec.message());
  if (size > kMaxCachedBinaryBytes + kCacheHeaderSize) {
    return invalid_argument("cache entry " + path.string() + " is implausibly large");
  }
  std::vector<unsigned char> bytes(static_cast<size_t>(size));
  std::ifstream in(path, std::ios::binary);
  if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()))) {
    return invalid_argument("cannot read cache entry " + path.string());
  }
  return decode_cache_entry(key, bytes);
}

Status write_cache_entry(const std::filesystem::path& dir, uint64_t key,
                         std::span<const unsigned char> binary) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return Error{ErrorCode::kUnavailable,
                 "cannot create cache directory " + dir.string() + ": " + ec.message()};
  }
  const std::vector<unsigned char> file = encode_cache_entry(key, binary);
  const std::filesystem::path target = dir / cache_file_name(key);
  // mkstemp gives each writer (thread or process) its own temporary name, so two servers
  // filling the same cache never write into one file; the last rename wins with a whole entry.
  std::string temp = (dir / ("." + cache_file_name(key) + ".XXXXXX")).string();
  const int fd = ::mkstemp(temp.data());
  if (fd < 0) {
    return Error{ErrorCode::kUnavailable,
                 "cannot create a temporary file in " + dir.string() + ": " + errno_text()};
  }
  size_t written = 0;
  while (written < file.size()) {
    const ssize_t n = ::write(fd, file.data() + written, file.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    written += static_cast<size_t>(n);
  }
  // No fsync: after a crash a torn file fails the size or checksum check and is rebuilt, which
  // is cheaper than syncing on every build.
  const bool closed = ::close(fd) == 0;
  if (written != file.size() || !closed) {
    const std::string why = errno_text();
    std::filesystem::remove(temp, ec);
    return Error{ErrorCode::kUnavailable, "cannot write " + temp + ": " + why};
  }
  std::filesystem::rename(temp, target, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    return Error{ErrorCode::kUnavailable,
                 "cannot rename into " + target.string() + ": " + ec.message()};
  }
  return {};
}

}  // namespace grotto::kernels
