// Runs grotto-layout (GROTTO_LAYOUT_BIN) as a user does: a real process, its exit code and output.
#pragma once

#include <sys/wait.h>
#include <cstdio>
#include <string>

namespace grotto::testing {

struct ProcessResult {
  int exit_code;
  std::string output;  // stdout and stderr together
};

// `command` through the shell; stdout and stderr together.
inline ProcessResult run_shell(const std::string& command) {
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  ProcessResult r{-1, {}};
  if (p == nullptr) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0)
    r.output.append(buf, n);
  int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// grotto-layout with `args` (shell words), on the OpenCL device `device` ("auto", "none": CPU).
inline ProcessResult run_layout(const std::string& args, const char* device = "auto") {
  return run_shell(std::string("GROTTO_OPENCL_DEVICE=") + device + " '" + GROTTO_LAYOUT_BIN + "' " +
                   args);
}

}  // namespace grotto::testing
