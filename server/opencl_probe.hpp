// grotto-server's OpenCL probe: before the server opens its devices, a child process (this same
// program, same settings) builds the deformation kernel once. PoCL's compiler aborts the whole
// process when its cache volume is full ("LLVM ERROR: IO failure on output stream") and can
// crash on truncated files in its own cache; a child that dies says so without taking the server
// down, and the server then runs on the CPU reference path and says why (compute path, /metrics,
// the log). A child that succeeds leaves PoCL's cache warm, so the server's own build is quick.
#pragma once

#include <optional>
#include <string>

#include "server/config.hpp"

namespace grotto::server {

// Set in the child's environment; main() runs probe_child() when it sees it.
inline constexpr const char* kProbeEnv = "GROTTO_OPENCL_PROBE";

// In the child: opens the device and builds the kernel as the server would. Exit status: 0 on
// OpenCL, 3 when the builder fell back to the CPU by itself (no device: nothing to protect).
int probe_child(const ServerConfig& config);

// In the parent, before Server::start: unless the device is "none", gives PoCL a cache directory
// Grotto owns (<cache dir>/pocl) when POCL_CACHE_DIR is not set, runs the child (argv as given),
// and on a failure empties PoCL's cache (Grotto's own, or the operator's when it holds nothing
// else) and Grotto's program binaries, and tries once more.
// Returns why OpenCL must not be used (the child's last stderr line), or nothing when it may.
std::optional<std::string> probe_opencl(const ServerConfig& config, int argc, char** argv);

}  // namespace grotto::server
