// grotto-server's descriptor limit (server/fd_limit.hpp): the count it needs, the soft
// limit it asks for and its verdict, by tables. tests/server/fd_limit_test.sh runs the program
// under low limits and reads its log line.
#include "server/fd_limit.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace {

using grotto::server::FdDemand;
using grotto::server::fds_needed;
using grotto::server::judge_fd_limit;
using grotto::server::kUnlimitedFds;
using grotto::server::soft_limit_target;

// The fixed part, spelled out so that a change to any term shows here: the shed cap's 64 spare
// sockets, the 4 reserve descriptors, 32 for the process, 24 per worker.
TEST(FdLimit, need_is_every_socket_the_server_accepts_plus_the_rest_of_the_process) {
  struct Row {
    FdDemand demand;
    uint64_t need;
  };
  const Row rows[] = {
      {{1024, 512, 2}, 1024 + 512 + 64 + 4 + 32 + 2 * 24},    // the defaults on 2 cores: 1684
      {{1000, 512, 1}, 1000 + 512 + 64 + 4 + 32 + 24},        // 1636
      {{2000, 512, 14}, 2000 + 512 + 64 + 4 + 32 + 14 * 24},  // a 16-core replica: 2948
      {{1, 1, 1}, 1 + 1 + 64 + 4 + 32 + 24},                  // the least settings allow: 126
      {{100000, 512, 16}, 100000 + 512 + 64 + 4 + 32 + 384},  // 100,996
  };
  for (const Row& r : rows) {
    EXPECT_EQ(fds_needed(r.demand), r.need)
        << r.demand.max_connections << " " << r.demand.max_handshakes << " " << r.demand.contexts;
  }
}

TEST(FdLimit, the_soft_limit_goes_up_to_the_hard_one_and_never_down) {
  struct Row {
    uint64_t soft, hard, need, target;
  };
  const Row rows[] = {
      {1024, 524288, 1684, 524288},           // Debian's defaults: raised to the hard limit
      {64, 4096, 1636, 4096},                 // raised, and enough
      {64, 1024, 1636, 1024},                 // raised, still short (the verdict says so)
      {64, 64, 1636, 64},                     // nothing to raise
      {4096, 4096, 126, 4096},                // already at the hard limit
      {1024, kUnlimitedFds, 1684, 1684},      // unlimited hard: what is needed
      {100000, kUnlimitedFds, 1684, 100000},  // ... never below the soft limit
      {kUnlimitedFds, kUnlimitedFds, 1684, kUnlimitedFds},  // both unlimited: left alone
  };
  for (const Row& r : rows) {
    EXPECT_EQ(soft_limit_target(r.soft, r.hard, r.need), r.target)
        << "soft " << r.soft << " hard " << r.hard << " need " << r.need;
  }
}

TEST(FdLimit, a_limit_below_the_need_is_short_and_says_how_many_players_fit) {
  struct Row {
    uint64_t limit;
    FdDemand demand;
    bool enough;
    uint64_t fit;
  };
  const Row rows[] = {
      {1684, {1024, 512, 2}, true, 1024},   // exactly the need
      {1683, {1024, 512, 2}, false, 1023},  // one short: one player less
      {524288, {1024, 512, 2}, true, 1024},
      {64, {1000, 512, 1}, false, 0},      // not even the handshakes and the fixed part fit
      {1024, {1000, 512, 1}, false, 388},  // 1024 - (512 + 64 + 4 + 32 + 24)
      {kUnlimitedFds, {100000, 512, 16}, true, 100000},
  };
  for (const Row& r : rows) {
    auto v = judge_fd_limit(r.limit, r.demand);
    EXPECT_EQ(v.enough, r.enough) << "limit " << r.limit;
    EXPECT_EQ(v.connections_that_fit, r.fit) << "limit " << r.limit;
    EXPECT_EQ(v.limit, r.limit);
    EXPECT_EQ(v.need, fds_needed(r.demand));
  }
}

// One OpenCL context when the workers share the device (the default); else one a worker, workers
// set to 0 meaning one per hardware thread, as the generator reads them.
TEST(FdLimit, the_demand_counts_the_contexts_the_generator_will_open) {
  grotto::server::ServerConfig c;
  c.max_connections = 2000;
  c.max_handshakes = 100;
  c.generator.workers = 6;
  auto d = grotto::server::fd_demand(c);
  EXPECT_EQ(d.max_connections, 2000u);
  EXPECT_EQ(d.max_handshakes, 100u);
  EXPECT_EQ(d.contexts, 1u);
  c.generator.share_device = false;
  EXPECT_EQ(grotto::server::fd_demand(c).contexts, 6u);
  c.generator.workers = 0;
  EXPECT_GE(grotto::server::fd_demand(c).contexts, 1u);
}

}  // namespace
