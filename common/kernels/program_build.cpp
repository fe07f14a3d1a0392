// build_program(): the in-process cache, the disk cache and the source build behind them.
#include <spdlog/spdlog.h>

#include <exception>
#include <vector>

#include "common/kernels/binary_cache.hpp"
#include "common/kernels/cl_context.hpp"
#include "common/kernels/cl_context_state.hpp"

namespace grotto::kernels {
namespace {

// Build logs of broken kernels can run to megabytes of repeated diagnostics; the head holds the
// first error, which is the one that matters.
constexpr size_t kMaxBuildLogBytes = 32 * 1024;

// Length-prefixed so that no (options, source) pair can spell another.
std::string memory_key(std::string_view source, std::string_view options) {
  std::string key = std::to_string(options.size()) + ":";
  key += options;
  key += source;
  return key;
}

std::string build_log(const cl::Program& program, const cl::Device& device) {
  std::string log;
  if (program.getBuildInfo(device, CL_PROGRAM_BUILD_LOG, &log) != CL_SUCCESS) {
    return "(no build log: clGetProgramBuildInfo failed)";
  }
  while (!log.empty() && (log.back() == '\n' || log.back() == '\0')) {
    log.pop_back();
  }
  if (log.size() > kMaxBuildLogBytes) {
    log.resize(kMaxBuildLogBytes);
    log += "\n... (build log truncated)";
  }
  return log.empty() ? "(empty build log)" : log;
}

// Builds a program object that is already created (from source or binary) for the device;
// on failure the error carries the build log.
Status build_for_device(const cl::Program& program, const cl::Device& device,
                        const std::string& options) {
  const cl_int code = program.build(std::vector<cl::Device>{device}, options.c_str());
  if (code == CL_SUCCESS) return {};
  Error error = cl_error(code, "clBuildProgram", __FILE__, __LINE__);
  error.message +=
      " options=\"" + options + "\"\nCL_PROGRAM_BUILD_LOG:\n" + build_log(program, device);
  return error;
}

Result<cl::Program> load_from_disk(const ComputeContext::State& state, uint64_t key,
                                   const std::string& options) {
  auto binary = read_cache_entry(state.cache_dir, key);
  if (!binary.ok()) return binary.error();
  cl_int code = CL_SUCCESS;
  std::vector<cl_int> status;
  cl::Program program(state.context, {state.device}, cl::Program::Binaries{binary.value()}, &status,
                      &code);
  if (code != CL_SUCCESS) return cl_error(code, "clCreateProgramWithBinary", __FILE__, __LINE__);
  // A binary still has to be built (linked for the device) before kernels can be created.
  if (Status built = build_for_device(program, state.device, options); !built.ok()) {
    return built.error();
  }
  return program;
}

Result<cl::Program> build_from_source(const ComputeContext::State& state, std::string_view source,
                                      const std::string& options) {
  cl_int code = CL_SUCCESS;
  cl::Program program(state.context, std::string(source), false, &code);
  if (code != CL_SUCCESS) {
    return cl_error(code, "clCreateProgramWithSource", __FILE__, __LINE__);
  }
  if (Status built = build_for_device(program, state.device, options); !built.ok()) {
    return built.error();
  }
  return program;
}

// Best effort: a failure is a warning, because the program in hand is fine without the cache.
void store_to_disk(const ComputeContext::State& state, uint64_t key, const cl::Program& program) {
  cl_int code = CL_SUCCESS;
  std::vector<std::vector<unsigned char>> binaries = program.getInfo<CL_PROGRAM_BINARIES>(&code);
  if (code != CL_SUCCESS || binaries.size() != 1 || binaries[0].empty()) {
    spdlog::warn("opencl cache_write=skipped key={} reason=\"no program binary ({})\"",
                 cache_file_name(key), cl_error_name(code));
    return;
  }
  if (Status written = write_cache_entry(state.cache_dir, key, binaries[0]); !written.ok()) {
    spdlog::warn("opencl cache_write=failed key={} reason=\"{}\"", cache_file_name(key),
                 written.error().message);
  }
}

Result<Program> build_locked(ComputeContext::State& state, std::string_view source,
                             std::string_view options) {
  const uint64_t key = program_cache_key(source, options, state.info);
  const std::string mem_key = memory_key(source, options);
  if (auto found = state.programs.find(mem_key); found != state.programs.end()) {
    ++state.stats.memory_cache_hits;
    return Program(found->second, BuildOrigin::kMemoryCache, key);
  }
  const std::string options_text(options);
  if (!state.cache_dir.empty()) {
    auto loaded = load_from_disk(state, key, options_text);
    if (loaded.ok()) {
      ++state.stats.disk_cache_hits;
      state.programs.emplace(mem_key, loaded.value());
      spdlog::debug("opencl build origin=disk_cache key={}", cache_file_name(key));
      return Program(std::move(loaded).value(), BuildOrigin::kDiskCache, key);
    }
    // A missing entry is the normal cold start; anything else is worth a line in the log.
    if (loaded.error().code != ErrorCode::kNotFound) {
      spdlog::warn("opencl cache_entry=rejected key={} reason=\"{}\"", cache_file_name(key),
                   loaded.error().message);
    }
  }
  auto built = build_from_source(state, source, options_text);
  if (!built.ok()) {
    ++state.stats.failures;
    return built.error();
  }
  ++state.stats.source_builds;
  if (!state.cache_dir.empty()) store_to_disk(state, key, built.value());
  state.programs.emplace(mem_key, built.value());
  spdlog::debug("opencl build origin=source key={}", cache_file_name(key));
  return Program(std::move(built).value(), BuildOrigin::kSource, key);
}

}  // namespace

Result<Program> build_program(ComputeContext& ctx, std::string_view source,
                              std::string_view options) {
  assert(ctx.state_ != nullptr);
  try {
    std::lock_guard lock(ctx.state_->mutex);
    return build_locked(*ctx.state_, source, options);
  } catch (const std::exception& e) {
    // Only allocation or filesystem failures can land here (the bindings run without exceptions).
    return Error{ErrorCode::kInternal, std::string("build_program: ") + e.what()};
  }
}

Result<cl::Kernel> Program::kernel(const char* name) const {
  cl_int code = CL_SUCCESS;
  cl::Kernel kernel(program_, name, &code);
  if (code != CL_SUCCESS) {
    return cl_error(code, std::string("clCreateKernel(\"") + name + "\")", __FILE__, __LINE__);
  }
  return kernel;
}

}  // namespace grotto::kernels
