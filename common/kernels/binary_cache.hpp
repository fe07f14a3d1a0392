// The on-disk program binary cache: its key, its directory and its file format. build_program()
// is the only user in the library; the pieces are public so tests can pin the format down
// without a device.
//
// One file per key, `<16 hex digits of the key>.clbin`:
//
//   offset  size  field
//        0     8  magic "GROTCLB1" (the trailing digit is the format version)
//        8     8  key, little-endian
//       16     8  binary size n, little-endian
//       24     8  FNV-1a 64 of the binary, little-endian
//       32     n  the CL_PROGRAM_BINARIES bytes
//
// The checksum is not decoration: PoCL 3.1 reads out of bounds and crashes on a truncated binary
// passed to clCreateProgramWithBinary, so no byte reaches the driver before it is verified.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/result.hpp"
#include "common/kernels/cl_context.hpp"

namespace grotto::kernels {

inline constexpr size_t kCacheHeaderSize = 32;
// A sanity bound on what is read back; real program binaries are kilobytes to a few megabytes.
inline constexpr uint64_t kMaxCachedBinaryBytes = uint64_t{256} << 20;

// FNV-1a 64 over length-prefixed fields (so "ab"+"c" and "a"+"bc" differ): a format tag, the
// source, the options, the platform name and version, the device name and version and the
// driver version. Anything that can change the compiled code changes the key; a driver update
// therefore misses the cache instead of loading a stale binary.
uint64_t program_cache_key(std::string_view source, std::string_view options,
                           const DeviceInfo& device);

// The cache directory: `configured` if not empty, else $GROTTO_CACHE_DIR, else
// $XDG_CACHE_HOME/grotto/cl, else $HOME/.cache/grotto/cl; empty (cache off) if none is set.
// Empty environment variables count as unset (as the XDG spec says).
std::filesystem::path resolve_cache_dir(std::string_view configured);

// "<key as 16 lowercase hex digits>.clbin"
std::string cache_file_name(uint64_t key);

// The file bytes for `binary` under `key`.
std::vector<unsigned char> encode_cache_entry(uint64_t key, std::span<const unsigned char> binary);

// The binary inside `file` if it is a complete, intact entry for `key`; otherwise an error that
// says which check failed. Safe for any input bytes.
Result<std::vector<unsigned char>> decode_cache_entry(uint64_t key,
                                                      std::span<const unsigned char> file);

// Reads and decodes dir/cache_file_name(key). kNotFound if there is no such file.
Result<std::vector<unsigned char>> read_cache_entry(const std::filesystem::path& dir, uint64_t key);

// Writes the entry atomically: a temporary file in `dir` (created if needed), then rename(2), so
// a reader sees the old entry, no entry or the whole new one, never a torn one.
Status write_cache_entry(const std::filesystem::path& dir, uint64_t key,
                         std::span<const unsigned char> binary);

}  // namespace grotto::kernels
