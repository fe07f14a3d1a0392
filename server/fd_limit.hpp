// grotto-server's file-descriptor limit: at start the soft RLIMIT_NOFILE is raised to
// the hard limit, and a limit below what the settings need is one warning line with the numbers,
// instead of players refused later with EMFILE at accept. The arithmetic is pure (tested by a
// table in tests/server/fd_limit_test.cpp); raise_fd_limit() is the one place that touches the
// process. Only the grotto-server program calls it: an embedded server leaves its host's limits
// alone.
#pragma once

#include <cstdint>
#include <string>

#include "server/config.hpp"

namespace grotto::server {

// RLIM_INFINITY in these plain numbers.
inline constexpr uint64_t kUnlimitedFds = UINT64_MAX;

// Descriptors outside the per-socket count; server/server.cpp takes both from here (its socket cap
// is max_connections + max_handshakes + kSpareSockets; its fd reserve holds kFdReserve on
// /dev/null).
inline constexpr uint64_t kSpareSockets = 64;  // plain HTTP (probes, scrapes), upgrades under way
inline constexpr uint64_t kFdReserve = 4;
// stdin/stdout/stderr (the log: spdlog writes to stderr, no log files), the listening socket,
// Asio's epoll, eventfd and timerfd, PoCL's and Grotto's cache files while a program is built or
// loaded, dlopen and /proc reads: 3 + 1 + 3 + a margin. Measured idle: 13 descriptors in all with
// PoCL 3.1 on the CPU (the reserve included), 20 besides the workers' with NVIDIA's driver.
inline constexpr uint64_t kProcessFds = 32;
// Per OpenCL context the server opens: one, the device its workers share (--opencl-queue shared,
// the default), or one a worker (per-worker; server/generator.cpp). PoCL 3.1 on the CPU keeps no
// descriptor open per context; NVIDIA's OpenCL (driver 580.159.04, H200) keeps 18 per context (16
// on /dev/nvidia*, 2 eventfds): 38 descriptors with one context, 272 with 14.
inline constexpr uint64_t kFdsPerContext = 24;

// What the settings need and what the process has; all plain numbers.
struct FdDemand {
  uint64_t max_connections = 0;
  uint64_t max_handshakes = 0;
  uint64_t contexts = 0;  // OpenCL contexts: 1 shared, or the workers (resolved: never 0)
};

// Descriptors the server may hold at once:
//   max_connections + max_handshakes + kSpareSockets      (every accepted socket, the shed cap)
//   + kFdReserve + kProcessFds + kFdsPerContext * contexts (everything that is not a client)
uint64_t fds_needed(const FdDemand& demand);

// The soft limit to set, given the current soft and hard limits: the hard limit (never lower than
// the soft one). With an unlimited hard limit (Linux refuses an infinite RLIMIT_NOFILE, capping
// it at fs.nr_open), the larger of the soft limit and `need`.
uint64_t soft_limit_target(uint64_t soft, uint64_t hard, uint64_t need);

struct FdVerdict {
  uint64_t need = 0;
  uint64_t limit = 0;  // the soft limit in force
  bool enough = false;
  // With the limit short: how many players fit with max_handshakes and the fixed part served
  // (0 when not even those fit).
  uint64_t connections_that_fit = 0;
};
FdVerdict judge_fd_limit(uint64_t limit, const FdDemand& demand);

// The demand of `config`: one context for the shared device, else the workers resolved as the
// generator resolves them (0: one per hardware thread).
FdDemand fd_demand(const ServerConfig& config);

// What raise_fd_limit did, for its log line and the tests.
struct FdLimitReport {
  uint64_t soft_before = 0;
  uint64_t hard = 0;
  uint64_t soft = 0;  // in force afterwards
  std::string error;  // why the soft limit could not be read or raised; empty when fine
  FdVerdict verdict;
};

// Reads RLIMIT_NOFILE, raises the soft limit to soft_limit_target(), and logs one line:
// event=fd_limit (info) when the limit in force is enough, event=fd_limit_low (warn) with the
// numbers and connections_that_fit when it is not or cannot be read; either carries error="..."
// when raising failed. Call once, before threads start.
FdLimitReport raise_fd_limit(const ServerConfig& config);

}  // namespace grotto::server
