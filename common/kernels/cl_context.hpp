// grotto::kernels — the OpenCL host layer: device choice, one context and queue per device,
// program builds with an in-process cache and an on-disk binary cache, and thin helpers for
// buffers and kernel launches. This header is the module's public face and its manual.
//
// Contracts shared by every function here:
// - No exception crosses these functions. Everything that comes from the OpenCL driver (no
//   platform, no device, a failed build, an out-of-resources launch) returns an Error whose message
//   names the call and the CL error code, so the caller can log it and fall back to the CPU
//   reference path (common/mesh).
// - The OpenCL C++ bindings are used without CL_HPP_ENABLE_EXCEPTIONS: cl:: calls return a
//   cl_int that GROTTO_CL_CHECK / GROTTO_CL_TRY turn into a Status / an early return.
// - A ComputeContext may be shared between threads: build_program() is serialized by the context,
//   and OpenCL API calls are thread-safe (OpenCL 3.0 §A.2) except that one cl::Kernel must not
//   have its arguments set from two threads at once; create a kernel per thread or per launch.
#pragma once

#include <CL/opencl.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

#include "common/core/result.hpp"

namespace grotto::kernels {

// Build options under which float kernels give the bits scalar C++ gives (which Grotto compiles
// with -ffp-contract=off): OpenCL allows `/` 2.5 ulp and `sqrt` 3 ulp of error by default, this
// makes both correctly rounded as IEEE-754 (and C++) requires. The kernel source must also start
// with `#pragma OPENCL FP_CONTRACT OFF`, or the compiler may fuse a*b+c into one fma.
inline constexpr std::string_view kDeterministicOptions = "-cl-fp32-correctly-rounded-divide-sqrt";

// Which device to use and where to cache program binaries. Brace-init means "the defaults", which
// the environment may change, so a server passes its config file's values and a developer can
// still steer a test run with environment variables.
struct DeviceConfig {
  // "auto" (GPU, then accelerator, then CPU such as PoCL), "gpu", "accelerator", "cpu", "none"
  // (no OpenCL: callers use the CPU reference path), or otherwise a case-insensitive substring
  // of the device name. Keywords win over substrings. Empty: $GROTTO_OPENCL_DEVICE, else "auto".
  std::string device{};
  // Directory of the on-disk binary cache. Empty: $GROTTO_CACHE_DIR, else
  // $XDG_CACHE_HOME/grotto/cl, else $HOME/.cache/grotto/cl (created on first write).
  std::string cache_dir{};
  // True: every build_program() in this context compiles from source or the in-process cache.
  bool disable_disk_cache = false;
  // True: the queue records when each command ran (CL_QUEUE_PROFILING_ENABLE), so kernels can
  // report the device's upload, kernel and download times (kernels::LaunchStats). Every OpenCL
  // device must support it (it is the mandated minimum of CL_DEVICE_QUEUE_ON_HOST_PROPERTIES);
  // a device that does not report it gets a plain queue, and ComputeContext::profiling() says so.
  bool profiling = true;
  // With device "none": why OpenCL is off, for the compute path and logs (empty: "disabled by
  // configuration"). grotto-server sets it when its OpenCL probe failed.
  std::string none_reason{};
};

// The device request after the config -> $GROTTO_OPENCL_DEVICE -> "auto" precedence, trimmed.
std::string resolve_device_request(const DeviceConfig& config);
// Whether that request is "none" (any case): no OpenCL, the CPU reference path.
bool opencl_disabled(const DeviceConfig& config);

// What the chosen device is; the strings are exactly what the driver reports.
struct DeviceInfo {
  std::string platform_name;
  std::string platform_version;  // "OpenCL 3.0 PoCL 3.1+debian ..."
  std::string device_name;
  std::string device_type;     // "gpu", "cpu", "accelerator" or "other"
  std::string device_version;  // "OpenCL 3.0 ..."
  std::string driver_version;
  uint32_t compute_units = 0;
  uint64_t global_mem_bytes = 0;
};

// Where a Program came from, so tests and benchmarks can tell a cold build from a cached one.
enum class BuildOrigin {
  kSource,       // compiled from source now (and, if enabled, written to the disk cache)
  kDiskCache,    // loaded from a binary in the disk cache
  kMemoryCache,  // the same cl::Program an earlier build_program() in this context returned
};
const char* build_origin_name(BuildOrigin origin);

// How many build_program() calls of a context ended where; for logs and metrics.
struct BuildStats {
  uint64_t source_builds = 0;
  uint64_t disk_cache_hits = 0;
  uint64_t memory_cache_hits = 0;
  uint64_t failures = 0;
};

// A built program. Cheap to copy (cl::Program is reference-counted).
class Program {
 public:
  Program(cl::Program program, BuildOrigin origin, uint64_t cache_key)
      : program_(std::move(program)), origin_(origin), cache_key_(cache_key) {}

  const cl::Program& get() const { return program_; }
  BuildOrigin origin() const { return origin_; }
  // The 64-bit key of (source, options, platform, device, driver); see binary_cache.hpp.
  uint64_t cache_key() const { return cache_key_; }

  // A new cl::Kernel for the __kernel function `name`; kNotFound if the program has none.
  Result<cl::Kernel> kernel(const char* name) const;

 private:
  cl::Program program_;
  BuildOrigin origin_;
  uint64_t cache_key_;
};

// One OpenCL device with its context and one in-order command queue, plus the program caches.
// Movable, not copyable; a moved-from context may only be destroyed or assigned to.
class ComputeContext {
 public:
  // Picks a device as `config` says and opens a context and queue on it. Fails, never crashes,
  // when there is no OpenCL platform (kUnavailable: "no OpenCL platform ..."), when OpenCL is
  // disabled (kUnavailable: "... disabled by configuration ..."), when no device matches
  // (kNotFound, naming the request and the devices found), or when the driver refuses.
  static Result<ComputeContext> create(const DeviceConfig& config = {});

  ComputeContext(ComputeContext&&) noexcept;
  ComputeContext& operator=(ComputeContext&&) noexcept;
  ~ComputeContext();

  const DeviceInfo& info() const;
  // One log line of key=value fields: platform, device, type, driver, compute units.
  std::string describe() const;
  // Whether queue() records command times (DeviceConfig::profiling and the device allow it):
  // cl::Event::getProfilingInfo on its commands' events then succeeds.
  bool profiling() const;
  // The resolved disk-cache directory; empty when the disk cache is off.
  const std::filesystem::path& cache_dir() const;
  BuildStats stats() const;

  // The underlying handles, for kernel code. They are reference-counted: copies stay valid after
  // this context is gone.
  const cl::Context& context() const;
  const cl::Device& device() const;
  const cl::CommandQueue& queue() const;

  // Opaque outside this module (common/kernels/cl_context_state.hpp).
  struct State;

 private:
  explicit ComputeContext(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;

  friend Result<Program> build_program(ComputeContext&, std::string_view, std::string_view);
};

// Builds `source` with `options` (e.g. kDeterministicOptions plus the caller's "-DNAME=value"
// defines) for the context's device. The same (source, options) in the same context returns the
// same program (kMemoryCache); otherwise a valid disk-cache entry is used (kDiskCache); otherwise
// it compiles from source and rewrites the disk-cache entry (kSource). A missing, corrupt,
// truncated or driver-rejected cache entry only costs a source build; failing to write the cache
// is a logged warning. A compile error returns kInvalidArgument whose message holds
// CL_PROGRAM_BUILD_LOG. Builds in one context run one at a time (a second caller of the same
// program waits and then hits the memory cache).
Result<Program> build_program(ComputeContext& ctx, std::string_view source,
                              std::string_view options);

// --- Errors --------------------------------------------------------------------------------------

// "CL_INVALID_VALUE" for -30, "CL_UNKNOWN_ERROR" for codes it does not know.
const char* cl_error_name(cl_int code);

// The Error for `call` having returned `code`: "<call> failed: CL_X (-n) at file:line". No device
// or resources → kUnavailable; a failed compile → kInvalidArgument; an unknown kernel name →
// kNotFound; anything else → kInternal.
Error cl_error(cl_int code, std::string_view call, const char* file = nullptr, int line = 0);

inline Status cl_status(cl_int code, std::string_view call, const char* file, int line) {
  if (code == CL_SUCCESS) return {};
  return cl_error(code, call, file, line);
}

}  // namespace grotto::kernels

// Status of an OpenCL call that returns cl_int, keeping the call's text for the message.
#define GROTTO_CL_CHECK(call) ::grotto::kernels::cl_status((call), #call, __FILE__, __LINE__)

// Returns the Error from the enclosing function (which returns Status or Result<T>) if `call`
// does not return CL_SUCCESS.
#define GROTTO_CL_TRY(call)                                                           \
  do {                                                                                \
    if (const cl_int grotto_cl_code_ = (call); grotto_cl_code_ != CL_SUCCESS) {       \
      return ::grotto::kernels::cl_error(grotto_cl_code_, #call, __FILE__, __LINE__); \
    }                                                                                 \
  } while (0)

namespace grotto::kernels {

// --- Buffers and launches: thin, so that host code reads as a list of steps ---------------------

// A device buffer holding a copy of data[0, count) (CL_MEM_COPY_HOST_PTR is added to `flags`).
// count must be > 0: OpenCL has no zero-size buffers.
template <typename T>
Result<cl::Buffer> make_buffer(const ComputeContext& ctx, cl_mem_flags flags, const T* data,
                               size_t count) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (count == 0) return invalid_argument("make_buffer: zero elements (no zero-size CL buffers)");
  cl_int code = CL_SUCCESS;
  // COPY_HOST_PTR only reads the host memory; the C API just has no const overload.
  cl::Buffer buffer(ctx.context(), flags | CL_MEM_COPY_HOST_PTR, count * sizeof(T),
                    const_cast<T*>(data), &code);
  if (code != CL_SUCCESS) {
    return cl_error(code, "clCreateBuffer(COPY_HOST_PTR)", __FILE__, __LINE__);
  }
  return buffer;
}

// An uninitialized device buffer of `count` elements of T; count must be > 0.
template <typename T>
Result<cl::Buffer> make_buffer(const ComputeContext& ctx, cl_mem_flags flags, size_t count) {
  if (count == 0) return invalid_argument("make_buffer: zero elements (no zero-size CL buffers)");
  cl_int code = CL_SUCCESS;
  cl::Buffer buffer(ctx.context(), flags, count * sizeof(T), nullptr, &code);
  if (code != CL_SUCCESS) return cl_error(code, "clCreateBuffer", __FILE__, __LINE__);
  return buffer;
}

// Enqueues a copy of data[0, count) into the start of `buffer` and returns without waiting:
// data must stay valid and unchanged until the write has completed (a later blocking read on the
// same in-order queue, or `done`). *done (if given) receives the write's event, for profiling.
template <typename T>
Status enqueue_write(const ComputeContext& ctx, const cl::Buffer& buffer, const T* data,
                     size_t count, cl::Event* done = nullptr) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (count == 0) return {};
  GROTTO_CL_TRY(
      ctx.queue().enqueueWriteBuffer(buffer, CL_FALSE, 0, count * sizeof(T), data, nullptr, done));
  return {};
}

// Read of the first `count` elements of `buffer` into out[0, count), after the commands queued
// before it (the queue is in order). Blocking by default; with blocking = false it returns at once
// and out must stay valid until the read has completed (a later blocking read, or `done`).
// *done (if given) receives the read's event, for profiling.
template <typename T>
Status read_buffer(const ComputeContext& ctx, const cl::Buffer& buffer, T* out, size_t count,
                   bool blocking = true, cl::Event* done = nullptr) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (count == 0) return {};
  GROTTO_CL_TRY(ctx.queue().enqueueReadBuffer(buffer, blocking ? CL_TRUE : CL_FALSE, 0,
                                              count * sizeof(T), out, nullptr, done));
  return {};
}

// Host memory that the device reads into (and writes from) at the bus's full speed where the
// driver pins it (CL_MEM_ALLOC_HOST_PTR, mapped once and kept mapped: NVIDIA's page-locked
// memory; on PoCL's CPU device plain host memory), for the destination of read_buffer on other
// buffers. Move-only; its destructor unmaps and releases it. Empty (bytes() 0) until created.
class PinnedHost {
 public:
  // `bytes` > 0.
  static Result<PinnedHost> create(const ComputeContext& ctx, size_t bytes);

  PinnedHost() = default;
  PinnedHost(PinnedHost&& other) noexcept;
  PinnedHost& operator=(PinnedHost&& other) noexcept;
  PinnedHost(const PinnedHost&) = delete;
  PinnedHost& operator=(const PinnedHost&) = delete;
  ~PinnedHost();

  void* data() const { return data_; }
  size_t bytes() const { return bytes_; }
  // At least `bytes`, grown by half again where it needs more (so repeated launches settle on one
  // size), never shrunk; growing replaces the memory and its contents.
  Status reserve(const ComputeContext& ctx, size_t bytes);

 private:
  void release();

  cl::CommandQueue queue_;
  cl::Buffer buffer_;
  void* data_ = nullptr;
  size_t bytes_ = 0;
};

// A device buffer kept from launch to launch, grown by half again when a launch needs more (so a
// server's batches settle on one size), never shrunk: no allocation per launch.
class GrowingBuffer {
 public:
  explicit GrowingBuffer(cl_mem_flags flags) : flags_(flags) {}
  // The buffer, at least `bytes` (> 0) long; growing replaces it and its contents.
  Result<cl::Buffer*> reserve(const ComputeContext& ctx, size_t bytes);

 private:
  cl_mem_flags flags_;
  std::optional<cl::Buffer> buffer_;
  size_t bytes_ = 0;
};

// Milliseconds between a completed command's CL_PROFILING_COMMAND_START and _END: how long the
// device ran it, without the host's enqueue or wait. 0 when the queue does not profile.
double event_ms(const cl::Event& event);
// Milliseconds from `first`'s start to `last`'s end (commands of one queue); 0 without profiling.
double event_span_ms(const cl::Event& first, const cl::Event& last);

// Sets arguments 0, 1, 2, ... of `kernel`; the error names the first argument that failed.
template <typename... Args>
Status set_kernel_args(cl::Kernel& kernel, const Args&... args) {
  cl_uint index = 0;
  cl_int code = CL_SUCCESS;
  auto set_one = [&](const auto& arg) {
    if (code == CL_SUCCESS) code = kernel.setArg(index++, arg);
  };
  (set_one(args), ...);
  if (code == CL_SUCCESS) return {};
  return cl_error(code, "clSetKernelArg(arg " + std::to_string(index - 1) + ")", __FILE__,
                  __LINE__);
}

// Enqueues `kernel` over global_size work items (the driver picks the work-group size) without
// waiting for it. global_size must be > 0.
Status enqueue_1d(const ComputeContext& ctx, const cl::Kernel& kernel, size_t global_size);

}  // namespace grotto::kernels
