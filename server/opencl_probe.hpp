// grotto-server's OpenCL probe: before the server opens its devices, a child process (this same
// program, same settings) drives OpenCL through the life cycle the server gives it: one room
// builder per worker (each an OpenCL context with the deformation program, at least two) opened,
// batches of several sizes built on all of them at once, all released, and all of it twice.
// PoCL's compiler aborts the whole process when its cache volume is full ("LLVM ERROR: IO failure
// on output stream") and can crash on truncated files in its own cache; PoCL 5.0 passed a probe
// that only built the kernel and aborted the server once its workers ran side by side.
// A child that dies says so, and at which step, without taking the server down, and the
// server then runs on the CPU reference path and says why (compute path, /metrics, the log). A
// child that succeeds leaves PoCL's cache warm, so the server's own build is quick. There is no
// timeout: a child that hangs holds the start.
#pragma once

#include <optional>
#include <string>

#include "server/config.hpp"

namespace grotto::server {

// Set in the child's environment; main() runs probe_child() when it sees it.
inline constexpr const char* kProbeEnv = "GROTTO_OPENCL_PROBE";

// For the fault tests only: "<cycle>:<builder>:<step>" (step open, run or release; e.g.
// 2:2:release) makes the child abort when it reaches that step, as a driver that fails later does.
// A value that is not of that form fails the probe, saying so. Unset in production.
inline constexpr const char* kProbeFaultEnv = "GROTTO_OPENCL_PROBE_FAULT";

// In the child: opens the device as the server would and drives the whole cycle, writing to
// stderr (whatever the log level) "opencl_probe: step <where>" before each step ("cycle 1/2,
// builder 3/8, open", "cycle 1/2, builders 1-8 at once, run", "cycle 2/2, builder 8/8, release")
// and "opencl_probe: passed cycles=2 builders=N contexts=.. batches=.. rooms=.. released=.." at
// the end. Exit status: 0 when every step passed on OpenCL, 3 when the first builder fell back to
// the CPU by itself (no device: nothing to protect), 2 for settings it cannot use, 4 when a step
// failed without killing it (a builder without a device after the first had one, a room that
// failed, a launch redone on the CPU): "opencl_probe: error <why>".
int probe_child(const ServerConfig& config);

// In the parent, before Server::start: unless the device is "none", gives PoCL a cache directory
// Grotto owns (<cache dir>/pocl) when POCL_CACHE_DIR is not set, runs the child (argv as given),
// and on a failure empties PoCL's cache (Grotto's own, or the operator's when it holds nothing
// else) and Grotto's program binaries, and tries once more.
// Logs event=opencl_probe_passed with the child's "passed" fields when it passed on OpenCL.
// Returns why OpenCL must not be used ("the OpenCL probe failed at <the step it had begun>
// (<exit status or signal>): <its error, else its last other stderr line>"), or nothing when it
// may.
std::optional<std::string> probe_opencl(const ServerConfig& config, int argc, char** argv);

}  // namespace grotto::server
