#include "server/fd_limit.hpp"

#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace grotto::server {
namespace {

uint64_t from_rlim(rlim_t v) {
  return v == RLIM_INFINITY ? kUnlimitedFds : static_cast<uint64_t>(v);
}

rlim_t to_rlim(uint64_t v) {
  return v == kUnlimitedFds ? RLIM_INFINITY : static_cast<rlim_t>(v);
}

std::string fds_text(uint64_t v) {
  return v == kUnlimitedFds ? "unlimited" : std::to_string(v);
}

}  // namespace

uint64_t fds_needed(const FdDemand& demand) {
  return demand.max_connections + demand.max_handshakes + kSpareSockets + kFdReserve + kProcessFds +
         kFdsPerContext * demand.contexts;
}

uint64_t soft_limit_target(uint64_t soft, uint64_t hard, uint64_t need) {
  if (hard == kUnlimitedFds) return std::max(soft, need);
  return std::max(soft, hard);
}

FdVerdict judge_fd_limit(uint64_t limit, const FdDemand& demand) {
  FdVerdict v;
  v.need = fds_needed(demand);
  v.limit = limit;
  v.enough = limit >= v.need;
  const uint64_t others = v.need - demand.max_connections;  // everything but the players
  v.connections_that_fit =
      v.enough ? demand.max_connections : (limit > others ? limit - others : 0);
  return v;
}

FdDemand fd_demand(const ServerConfig& config) {
  FdDemand d;
  d.max_connections = static_cast<uint64_t>(std::max(config.max_connections, 0));
  d.max_handshakes = static_cast<uint64_t>(std::max(config.max_handshakes, 0));
  d.contexts = config.generator.share_device ? 1 : resolved_workers(config.generator);
  return d;
}

FdLimitReport raise_fd_limit(const ServerConfig& config) {
  FdLimitReport r;
  const FdDemand demand = fd_demand(config);
  rlimit lim{};
  if (getrlimit(RLIMIT_NOFILE, &lim) != 0) {
    r.error = std::string("getrlimit: ") + std::strerror(errno);
    spdlog::warn("event=fd_limit_low error=\"{}\" need={} max_connections={} max_handshakes={}",
                 r.error, fds_needed(demand), demand.max_connections, demand.max_handshakes);
    return r;
  }
  r.soft_before = from_rlim(lim.rlim_cur);
  r.hard = from_rlim(lim.rlim_max);
  r.soft = r.soft_before;
  const uint64_t target = soft_limit_target(r.soft_before, r.hard, fds_needed(demand));
  if (target != r.soft_before) {
    rlimit raised{to_rlim(target), lim.rlim_max};
    if (setrlimit(RLIMIT_NOFILE, &raised) == 0) {
      r.soft = target;
    } else {
      r.error = "setrlimit to " + fds_text(target) + ": " + std::strerror(errno);
    }
  }
  r.verdict = judge_fd_limit(r.soft, demand);
  const FdVerdict& v = r.verdict;
  const std::string error = r.error.empty() ? std::string() : " error=\"" + r.error + "\"";
  if (v.enough) {
    spdlog::info(
        "event=fd_limit soft={} soft_before={} hard={} need={} max_connections={} "
        "max_handshakes={} contexts={}{}",
        fds_text(r.soft), fds_text(r.soft_before), fds_text(r.hard), v.need, demand.max_connections,
        demand.max_handshakes, demand.contexts, error);
  } else {
    // One line an operator can act on: the numbers, and how many players fit meanwhile.
    spdlog::warn(
        "event=fd_limit_low soft={} soft_before={} hard={} need={} max_connections={} "
        "max_handshakes={} contexts={} connections_that_fit={}{}",
        fds_text(r.soft), fds_text(r.soft_before), fds_text(r.hard), v.need, demand.max_connections,
        demand.max_handshakes, demand.contexts, v.connections_that_fit, error);
  }
  return r;
}

}  // namespace grotto::server
