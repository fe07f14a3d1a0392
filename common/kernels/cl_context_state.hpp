// The inside of a ComputeContext, shared by cl_context.cpp and program_build.cpp; not part of the
// public face (include common/kernels/cl_context.hpp instead).
#pragma once

#include <map>
#include <mutex>
#include <string>

#include "common/kernels/cl_context.hpp"

namespace grotto::kernels {

struct ComputeContext::State {
  DeviceInfo info;
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
  bool profiling = false;           // the queue was created with CL_QUEUE_PROFILING_ENABLE
  std::filesystem::path cache_dir;  // empty: disk cache off

  // Guards programs and stats, and is held for a whole build so that two threads asking for the
  // same program compile it once.
  mutable std::mutex mutex;
  // Keyed by the exact (options, source) text rather than a hash, so a collision cannot hand out
  // the wrong program.
  std::map<std::string, cl::Program> programs;
  BuildStats stats;
};

}  // namespace grotto::kernels
