// Device choice and the ComputeContext's lifetime.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <exception>
#include <utility>
#include <vector>

#include "common/kernels/binary_cache.hpp"
#include "common/kernels/cl_context.hpp"
#include "common/kernels/cl_context_state.hpp"

namespace grotto::kernels {
namespace {

std::string lowercase(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

std::string trim(std::string_view text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = text.find_last_not_of(" \t\r\n");
  return std::string(text.substr(first, last - first + 1));
}

const char* type_name(cl_device_type type) {
  if (type & CL_DEVICE_TYPE_GPU) return "gpu";
  if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  if (type & CL_DEVICE_TYPE_CPU) return "cpu";
  return "other";
}

// Lower is preferred by "auto": a GPU is what the kernels are written for, PoCL on the CPU is
// the portable fallback that still beats the scalar reference on many cores.
int auto_rank(const std::string& type) {
  if (type == "gpu") return 0;
  if (type == "accelerator") return 1;
  if (type == "cpu") return 2;
  return 3;
}

struct Candidate {
  cl::Platform platform;
  cl::Device device;
  DeviceInfo info;
  std::string unusable;  // why the device cannot run our kernels; empty if it can
};

// Reads one device's description; a failed query leaves the field empty rather than failing,
// because the fields only feed logs and the cache key (an empty field just misses the cache).
Candidate describe_device(const cl::Platform& platform, const cl::Device& device) {
  Candidate c{platform, device, {}, {}};
  platform.getInfo(CL_PLATFORM_NAME, &c.info.platform_name);
  platform.getInfo(CL_PLATFORM_VERSION, &c.info.platform_version);
  device.getInfo(CL_DEVICE_NAME, &c.info.device_name);
  device.getInfo(CL_DEVICE_VERSION, &c.info.device_version);
  device.getInfo(CL_DRIVER_VERSION, &c.info.driver_version);
  cl_device_type type = 0;
  device.getInfo(CL_DEVICE_TYPE, &type);
  c.info.device_type = type_name(type);
  cl_uint units = 0;
  device.getInfo(CL_DEVICE_MAX_COMPUTE_UNITS, &units);
  c.info.compute_units = units;
  cl_ulong memory = 0;
  device.getInfo(CL_DEVICE_GLOBAL_MEM_SIZE, &memory);
  c.info.global_mem_bytes = memory;
  cl_bool available = CL_FALSE;
  cl_bool compiler = CL_FALSE;
  device.getInfo(CL_DEVICE_AVAILABLE, &available);
  device.getInfo(CL_DEVICE_COMPILER_AVAILABLE, &compiler);
  // Every Grotto kernel is built from source, so a device without a compiler is of no use.
  if (!available) c.unusable = "not available";
  if (!compiler) c.unusable = "no compiler";
  return c;
}

Result<std::vector<Candidate>> list_devices() {
  std::vector<cl::Platform> platforms;
  const cl_int code = cl::Platform::get(&platforms);
  if (code != CL_SUCCESS || platforms.empty()) {
    return Error{ErrorCode::kUnavailable,
                 "no OpenCL platform found (clGetPlatformIDs: " + std::string(cl_error_name(code)) +
                     "); install an ICD such as pocl-opencl-icd, or set GROTTO_OPENCL_DEVICE=none "
                     "to use the CPU reference path"};
  }
  std::vector<Candidate> candidates;
  for (const cl::Platform& platform : platforms) {
    std::vector<cl::Device> devices;
    // CL_DEVICE_NOT_FOUND here only means this platform has no devices; others may.
    if (platform.getDevices(CL_DEVICE_TYPE_ALL, &devices) != CL_SUCCESS) continue;
    for (const cl::Device& device : devices) {
      candidates.push_back(describe_device(platform, device));
    }
  }
  if (candidates.empty()) {
    return Error{
        ErrorCode::kUnavailable,
        "no OpenCL device found on " + std::to_string(platforms.size()) + " OpenCL platform(s)"};
  }
  return candidates;
}

std::string list_for_message(const std::vector<Candidate>& candidates) {
  std::string out;
  for (const Candidate& c : candidates) {
    if (!out.empty()) out += ", ";
    out += "'" + c.info.device_name + "' (" + c.info.device_type + ", " + c.info.platform_name;
    if (!c.unusable.empty()) out += ", " + c.unusable;
    out += ")";
  }
  return out;
}

Result<Candidate> choose_device(const std::string& request) {
  const std::string wanted = lowercase(request);
  if (wanted == "none") {
    return Error{ErrorCode::kUnavailable,
                 "OpenCL disabled by configuration (device=none); use the CPU reference path"};
  }
  auto listed = list_devices();
  if (!listed.ok()) return listed.error();
  const std::vector<Candidate>& candidates = listed.value();

  const Candidate* best = nullptr;
  if (wanted == "auto") {
    for (const Candidate& c : candidates) {
      if (!c.unusable.empty()) continue;
      // Strictly better only, so ties keep the driver's platform and device order.
      if (best == nullptr || auto_rank(c.info.device_type) < auto_rank(best->info.device_type)) {
        best = &c;
      }
    }
  } else {
    const bool by_type = wanted == "gpu" || wanted == "cpu" || wanted == "accelerator";
    for (const Candidate& c : candidates) {
      const bool match = by_type ? c.info.device_type == wanted
                                 : lowercase(c.info.device_name).find(wanted) != std::string::npos;
      if (match && c.unusable.empty()) {
        best = &c;
        break;
      }
    }
  }
  if (best == nullptr) {
    return Error{ErrorCode::kNotFound, "no usable OpenCL device matches '" + request +
                                           "' (GROTTO_OPENCL_DEVICE or config); found " +
                                           list_for_message(candidates)};
  }
  return *best;
}

// A unique_ptr because State holds a mutex and cannot move.
Result<std::unique_ptr<ComputeContext::State>> open_device(const Candidate& chosen,
                                                           const DeviceConfig& config) {
  auto state_ptr = std::make_unique<ComputeContext::State>();
  ComputeContext::State& state = *state_ptr;
  state.info = chosen.info;
  state.device = chosen.device;
  cl_int code = CL_SUCCESS;
  state.context = cl::Context(chosen.device, nullptr, nullptr, nullptr, &code);
  if (code != CL_SUCCESS) return cl_error(code, "clCreateContext", __FILE__, __LINE__);
  // In order, as before; with profiling where asked and the device lists it (every conformant
  // device does), falling back to a plain queue rather than failing.
  cl_command_queue_properties supported = 0;
  chosen.device.getInfo(CL_DEVICE_QUEUE_ON_HOST_PROPERTIES, &supported);
  state.profiling = config.profiling && (supported & CL_QUEUE_PROFILING_ENABLE) != 0;
  state.queue = cl::CommandQueue(state.context, chosen.device,
                                 state.profiling ? CL_QUEUE_PROFILING_ENABLE : 0, &code);
  if (code != CL_SUCCESS && state.profiling) {
    spdlog::warn("opencl queue profiling refused ({}); using a plain queue", cl_error_name(code));
    state.profiling = false;
    state.queue = cl::CommandQueue(state.context, chosen.device, 0, &code);
  }
  if (code != CL_SUCCESS) {
    return cl_error(code, "clCreateCommandQueueWithProperties", __FILE__, __LINE__);
  }
  if (!config.disable_disk_cache) state.cache_dir = resolve_cache_dir(config.cache_dir);
  return state_ptr;
}

}  // namespace

std::string resolve_device_request(const DeviceConfig& config) {
  std::string request = trim(config.device);
  if (request.empty()) {
    const char* env = std::getenv("GROTTO_OPENCL_DEVICE");
    if (env != nullptr) request = trim(env);
  }
  return request.empty() ? std::string("auto") : request;
}

bool opencl_disabled(const DeviceConfig& config) {
  return lowercase(resolve_device_request(config)) == "none";
}

const char* build_origin_name(BuildOrigin origin) {
  switch (origin) {
    case BuildOrigin::kSource:
      return "source";
    case BuildOrigin::kDiskCache:
      return "disk_cache";
    case BuildOrigin::kMemoryCache:
      return "memory_cache";
  }
  return "source";
}

Result<ComputeContext> ComputeContext::create(const DeviceConfig& config) {
  try {
    const std::string request = resolve_device_request(config);
    if (opencl_disabled(config) && !config.none_reason.empty()) {
      return Error{ErrorCode::kUnavailable, config.none_reason};
    }
    auto chosen = choose_device(request);
    if (!chosen.ok()) return chosen.error();
    auto state = open_device(chosen.value(), config);
    if (!state.ok()) return state.error();
    ComputeContext ctx(std::move(state).value());
    spdlog::info("opencl context request={} {} cache_dir={}", request, ctx.describe(),
                 ctx.cache_dir().empty() ? "off" : ctx.cache_dir().string());
    return ctx;
  } catch (const std::exception& e) {
    // Only allocation failures can land here (the bindings run without exceptions).
    return Error{ErrorCode::kInternal, std::string("ComputeContext::create: ") + e.what()};
  }
}

ComputeContext::ComputeContext(std::unique_ptr<State> state) : state_(std::move(state)) {}
ComputeContext::ComputeContext(ComputeContext&&) noexcept = default;
ComputeContext& ComputeContext::operator=(ComputeContext&&) noexcept = default;
ComputeContext::~ComputeContext() = default;

const DeviceInfo& ComputeContext::info() const {
  assert(state_ != nullptr);
  return state_->info;
}

std::string ComputeContext::describe() const {
  const DeviceInfo& i = info();
  return "platform=\"" + i.platform_name + "\" device=\"" + i.device_name +
         "\" type=" + i.device_type + " driver=\"" + i.driver_version + "\" version=\"" +
         i.device_version + "\" compute_units=" + std::to_string(i.compute_units);
}

bool ComputeContext::profiling() const {
  assert(state_ != nullptr);
  return state_->profiling;
}

const std::filesystem::path& ComputeContext::cache_dir() const {
  assert(state_ != nullptr);
  return state_->cache_dir;
}

BuildStats ComputeContext::stats() const {
  assert(state_ != nullptr);
  std::lock_guard lock(state_->mutex);
  return state_->stats;
}

const cl::Context& ComputeContext::context() const {
  assert(state_ != nullptr);
  return state_->context;
}

const cl::Device& ComputeContext::device() const {
  assert(state_ != nullptr);
  return state_->device;
}

const cl::CommandQueue& ComputeContext::queue() const {
  assert(state_ != nullptr);
  return state_->queue;
}

Status enqueue_1d(const ComputeContext& ctx, const cl::Kernel& kernel, size_t global_size) {
  if (global_size == 0) return invalid_argument("enqueue_1d: zero work items");
  GROTTO_CL_TRY(ctx.queue().enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(global_size),
                                                 cl::NullRange));
  return {};
}

Result<PinnedHost> PinnedHost::create(const ComputeContext& ctx, size_t bytes) {
  if (bytes == 0) return invalid_argument("PinnedHost: zero bytes (no zero-size CL buffers)");
  cl_int code = CL_SUCCESS;
  cl::Buffer buffer(ctx.context(), CL_MEM_ALLOC_HOST_PTR | CL_MEM_READ_WRITE, bytes, nullptr,
                    &code);
  if (code != CL_SUCCESS)
    return cl_error(code, "clCreateBuffer(ALLOC_HOST_PTR)", __FILE__, __LINE__);
  void* data = ctx.queue().enqueueMapBuffer(buffer, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, bytes,
                                            nullptr, nullptr, &code);
  if (code != CL_SUCCESS) return cl_error(code, "clEnqueueMapBuffer", __FILE__, __LINE__);
  PinnedHost host;
  host.queue_ = ctx.queue();
  host.buffer_ = std::move(buffer);
  host.data_ = data;
  host.bytes_ = bytes;
  return host;
}

Status PinnedHost::reserve(const ComputeContext& ctx, size_t bytes) {
  if (bytes_ >= bytes) return {};
  auto grown = create(ctx, std::max(bytes, bytes_ + bytes_ / 2));
  if (!grown) return grown.error();
  *this = std::move(grown).value();
  return {};
}

Result<cl::Buffer*> GrowingBuffer::reserve(const ComputeContext& ctx, size_t bytes) {
  if (!buffer_ || bytes_ < bytes) {
    const size_t grown = std::max(bytes, bytes_ + bytes_ / 2);
    auto buffer = make_buffer<uint8_t>(ctx, flags_, grown);
    if (!buffer) return buffer.error();
    buffer_ = std::move(buffer).value();
    bytes_ = grown;
  }
  return &*buffer_;
}

PinnedHost::PinnedHost(PinnedHost&& other) noexcept
    : queue_(std::move(other.queue_)),
      buffer_(std::move(other.buffer_)),
      data_(std::exchange(other.data_, nullptr)),
      bytes_(std::exchange(other.bytes_, 0)) {}

PinnedHost& PinnedHost::operator=(PinnedHost&& other) noexcept {
  if (this != &other) {
    release();
    queue_ = std::move(other.queue_);
    buffer_ = std::move(other.buffer_);
    data_ = std::exchange(other.data_, nullptr);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

PinnedHost::~PinnedHost() {
  release();
}

void PinnedHost::release() {
  if (data_ == nullptr) return;
  // Nothing to report from a destructor: a failed unmap leaves the driver to free the buffer with
  // its context.
  cl::Event unmapped;
  if (queue_.enqueueUnmapMemObject(buffer_, data_, nullptr, &unmapped) == CL_SUCCESS) {
    unmapped.wait();
  }
  data_ = nullptr;
  bytes_ = 0;
}

double event_ms(const cl::Event& event) {
  return event_span_ms(event, event);
}

double event_span_ms(const cl::Event& first, const cl::Event& last) {
  cl_ulong start = 0, end = 0;
  if (first.getProfilingInfo(CL_PROFILING_COMMAND_START, &start) != CL_SUCCESS ||
      last.getProfilingInfo(CL_PROFILING_COMMAND_END, &end) != CL_SUCCESS || end < start) {
    return 0;
  }
  return 1e-6 * static_cast<double>(end - start);
}

}  // namespace grotto::kernels
