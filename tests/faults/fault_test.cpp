// The fault suite: each test starts a real server (in-process, or the grotto-server
// program where the fault needs a process of its own: a low file limit, a broken cache, its log),
// produces one fault, and while the fault lasts and after it ends checks the one thing that must
// hold: /healthz answers 200 and a real player gets rooms (expect_still_serving, in
// tests/server/server_harness.hpp). docs/OPERATING.md's "Faults and what Grotto does" names the
// test of each fault. Every wait is bounded and every loop ends on its own.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "common/core/bytes.hpp"
#include "common/kernels/binary_cache.hpp"
#include "tests/server/server_harness.hpp"

namespace {

using namespace grotto::server_test;

// `count` TCP connections to the server that never send a byte; their descriptors.
std::vector<int> connect_raw(uint16_t port, int count) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::vector<int> fds;
  for (int i = 0; i < count; ++i) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    EXPECT_GE(fd, 0);
    if (fd < 0) break;
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    fds.push_back(fd);
  }
  return fds;
}

void close_all(std::vector<int>& fds) {
  for (int fd : fds)
    close(fd);
  fds.clear();
}

size_t count_of(const std::string& text, const std::string& needle) {
  size_t n = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1))
    ++n;
  return n;
}

// Polls /readyz until it answers 200 (the server accepts normally again), at most 10 s.
bool ready_again(uint16_t port) {
  auto deadline = Clock::now() + 10s;
  while (Clock::now() < deadline) {
    if (http_get(port, "/readyz", 0, 0, 2s).status == 200) return true;
    std::this_thread::sleep_for(100ms);
  }
  return false;
}

// ---- 1. out of file descriptors ----

// grotto-server with 64 descriptors and 150 raw connections that never send a byte: the ones it
// accepted hold its descriptors, the rest wait in the backlog.
struct FdStarved {
  Process process;
  uint16_t port = 0;
};

FdStarved start_with_64_fds(std::vector<std::string> extra = {}) {
  std::vector<std::string> args{"--port",       "0", "--opencl-device",   "none", "--workers", "1",
                                "--io-threads", "1", "--http-timeout-ms", "60000"};
  args.insert(args.end(), extra.begin(), extra.end());
  FdStarved s;
  s.process = spawn(args, 64);
  auto text = read_until(s.process.out, "/ws)", 30s);
  s.port = listening_port(text);
  EXPECT_NE(s.port, 0) << text;
  return s;
}

// Out of descriptors, the acceptor pauses instead of spinning, logs a line a second at most,
// counts the failures, and serves again once descriptors free up.
TEST(FdExhaustion, accepting_pauses_without_spinning_and_recovers) {
  auto [p, port] = start_with_64_fds();
  ASSERT_NE(port, 0);
  Client player(port);
  ASSERT_FALSE(player.connect());
  player.hello("player");
  auto squatters = connect_raw(port, 150);
  std::this_thread::sleep_for(500ms);
  double before = cpu_seconds(p.pid);
  auto log = read_until(p.out, "\x01", 2000ms);
  double used = cpu_seconds(p.pid) - before;
  EXPECT_LT(used, 0.5) << "the acceptor spins: " << used << " CPU s in 2 s";
  size_t lines = count_of(log, "accept_failed");
  EXPECT_GE(lines, 1u) << log;
  EXPECT_LE(lines, 4u) << log;
  // While it lasts: /healthz from the fd reserve, and the player already in gets rooms.
  expect_still_serving(port, &player);
  close_all(squatters);
  // Descriptors free again: it accepts, and counted what happened.
  EXPECT_TRUE(ready_again(port));
  auto failures = metric(http_get(port, "/metrics").body, "grotto_accept_failures_total");
  ASSERT_TRUE(failures);
  EXPECT_GT(*failures, 0);
  expect_still_serving(port, &player);
  expect_still_serving(port);
  player.close_tcp();  // else the stop waits its drain for a client that does not read
  stop_process(p);
}

// The fd reserve: with every descriptor held by squatters (for a minute: nothing frees one),
// /healthz, /readyz and /metrics still answer, one connection at a time on a reserve descriptor;
// anything else, a WebSocket upgrade included, is told why it is refused. Without the reserve the
// probes wait in the backlog until the squatters go.
TEST(FdExhaustion, health_and_metrics_answer_from_the_fd_reserve) {
  auto [p, port] = start_with_64_fds({"--handshake-timeout-ms", "60000"});
  ASSERT_NE(port, 0);
  Client player(port);
  ASSERT_FALSE(player.connect());
  player.hello("player");
  auto squatters = connect_raw(port, 150);
  auto log = read_until(p.out, "event=accept_failed", 10s);
  ASSERT_NE(log.find("event=accept_failed"), std::string::npos) << "never out of descriptors";

  auto health = http_get(port, "/healthz", 0, 0, 5s);
  EXPECT_EQ(health.status, 200);
  EXPECT_NE(health.body.find("out of file descriptors"), std::string::npos) << health.body;
  EXPECT_EQ(health.connection, "close");
  auto ready = http_get(port, "/readyz", 0, 0, 5s);
  EXPECT_EQ(ready.status, 503) << "out of descriptors, the replica takes no new players";
  EXPECT_NE(ready.body.find("not ready: out of file descriptors"), std::string::npos) << ready.body;
  auto scrape = http_get(port, "/metrics", 0, 0, 5s);
  ASSERT_EQ(scrape.status, 200);
  EXPECT_GT(metric(scrape.body, "grotto_accept_failures_total").value_or(0), 0);
  EXPECT_GE(metric(scrape.body, "grotto_fd_reserve_connections_total").value_or(0), 3)
      << "healthz, readyz and this scrape";
  EXPECT_GE(metric(scrape.body, "grotto_fd_reserve_held").value_or(0), 1);
  EXPECT_EQ(http_get(port, "/version", 0, 0, 5s).status, 503);
  Client late(port);
  EXPECT_TRUE(late.connect()) << "an upgrade is refused while out of descriptors";
  EXPECT_EQ(late.response().result_int(), 503);
  EXPECT_NE(late.response().body().find("only GET /healthz, /readyz and /metrics"),
            std::string::npos)
      << late.response().body();
  expect_still_serving(port, &player);

  close_all(squatters);
  EXPECT_TRUE(ready_again(port));
  auto after = http_get(port, "/metrics").body;
  EXPECT_EQ(metric(after, "grotto_fd_reserve_held"), 4) << "every reserve descriptor came back";
  // One I/O thread and no OpenCL: nothing but the acceptor opens descriptors, so every reserve
  // descriptor was opened again at the first try.
  EXPECT_EQ(metric(after, "grotto_fd_reserve_refill_failures_total"), 0);
  expect_still_serving(port, &player);
  expect_still_serving(port);
  player.close_tcp();  // else the stop waits its drain for a client that does not read
  stop_process(p);
}

// ---- 2. the cache volume full, truncated caches ----

// The cache volume full: PoCL's compiler would abort the process; the probe child dies instead
// and the server serves from the CPU, saying why in /metrics and /readyz.
TEST(CacheFaults, a_full_cache_volume_falls_back_to_the_cpu_and_keeps_serving) {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("grotto-full-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  if (std::system(
          ("mount -t tmpfs -o size=256k tmpfs '" + dir.string() + "' 2>/dev/null").c_str()) != 0) {
    std::filesystem::remove(dir);
    GTEST_SKIP() << "cannot mount a small tmpfs here (needs root)";
  }
  auto [p, port, text] = start_with_cache(dir.string());
  ASSERT_NE(port, 0) << text;
  auto metrics = http_get(port, "/metrics").body;
  auto ready = http_get(port, "/readyz");
  expect_still_serving(port);  // with the volume still full
  stop_process(p);
  EXPECT_EQ(std::system(("umount '" + dir.string() + "'").c_str()), 0);
  std::filesystem::remove(dir);
  if (metrics.find("path=\"opencl") != std::string::npos) {
    GTEST_SKIP() << "OpenCL built within 256 KiB here: nothing to fall back from";
  }
  EXPECT_NE(
      metrics.find("grotto_compute_path_info{path=\"cpu: CPU fallback: the OpenCL probe failed"),
      std::string::npos)
      << metrics;
  EXPECT_EQ(ready.status, 200);
  EXPECT_NE(ready.body.find("compute: cpu: CPU fallback"), std::string::npos) << ready.body;
  EXPECT_NE(text.find("event=compute_path_fallback"), std::string::npos) << text;
}

// Truncated files in PoCL's cache (a crash mid-write, a full disk): the server still starts and
// serves, on OpenCL after discarding PoCL's cache: Grotto's own, or one POCL_CACHE_DIR names (as
// the deployments do) that holds nothing else.
class TruncatedPoclCache : public ::testing::TestWithParam<bool> {};
INSTANTIATE_TEST_SUITE_P(CacheFaults, TruncatedPoclCache, ::testing::Values(false, true),
                         [](const auto& param_info) {
                           return std::string(param_info.param ? "pocl_cache_dir_set" : "owned");
                         });

TEST_P(TruncatedPoclCache, does_not_stop_the_start) {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("grotto-trunc-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  const std::string pocl_dir = GetParam() ? (dir / "pocl").string() : std::string();
  {
    auto [p, port, text] = start_with_cache(dir.string(), pocl_dir);  // fills the caches
    ASSERT_NE(port, 0) << text;
    stop_process(p);
  }
  size_t truncated = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir / "pocl")) {
    if (!e.is_regular_file() || e.file_size() < 2) continue;
    std::filesystem::resize_file(e.path(), e.file_size() / 2);
    ++truncated;
  }
  if (truncated == 0) {
    std::filesystem::remove_all(dir);
    GTEST_SKIP() << "no OpenCL device here: PoCL left no cache";
  }
  auto [p, port, text] = start_with_cache(dir.string(), pocl_dir);
  ASSERT_NE(port, 0) << "the server did not start after " << truncated << " files were cut\n"
                     << text;
  EXPECT_EQ(http_get(port, "/readyz").status, 200);
  // PoCL aborts on the cut program: the probe dies, the cache Grotto owns is discarded, and the
  // second probe (and the server) build afresh.
  EXPECT_NE(text.find("event=opencl_probe_failed attempt=1"), std::string::npos) << text;
  EXPECT_NE(text.find("event=pocl_cache_discarded"), std::string::npos) << text;
  expect_still_serving(port);
  stop_process(p);
  // After: the cache it rebuilt starts the next server without a failed probe.
  auto [again, again_port, again_text] = start_with_cache(dir.string(), pocl_dir);
  ASSERT_NE(again_port, 0) << again_text;
  EXPECT_EQ(again_text.find("event=opencl_probe_failed"), std::string::npos) << again_text;
  expect_still_serving(again_port);
  stop_process(again);
  std::filesystem::remove_all(dir);
}

// A Grotto program binary cut *before* it was checksummed passes the entry's checks and would
// crash the driver: the probe dies on it, the binaries are discarded, and OpenCL comes back.
TEST(CacheFaults, a_checksummed_but_cut_program_binary_does_not_stop_the_start) {
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("grotto-cutbin-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  {
    auto [p, port, text] = start_with_cache(dir.string());
    ASSERT_NE(port, 0) << text;
    stop_process(p);
  }
  size_t cut = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".clbin") continue;
    std::ifstream in(e.path(), std::ios::binary);
    std::vector<unsigned char> file((std::istreambuf_iterator<char>(in)),
                                    std::istreambuf_iterator<char>());
    in.close();
    ASSERT_GT(file.size(), grotto::kernels::kCacheHeaderSize);
    const uint64_t key = grotto::le::load(file.data() + 8);
    std::vector<unsigned char> half(file.begin() + grotto::kernels::kCacheHeaderSize,
                                    file.begin() + grotto::kernels::kCacheHeaderSize +
                                        (file.size() - grotto::kernels::kCacheHeaderSize) / 2);
    auto entry = grotto::kernels::encode_cache_entry(key, half);
    ASSERT_TRUE(grotto::kernels::decode_cache_entry(key, entry).ok()) << "passes its checks";
    std::ofstream(e.path(), std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(entry.data()),
               static_cast<std::streamsize>(entry.size()));
    ++cut;
  }
  if (cut == 0) {
    std::filesystem::remove_all(dir);
    GTEST_SKIP() << "no OpenCL device here: no program binary to cut";
  }
  auto [p, port, text] = start_with_cache(dir.string());
  ASSERT_NE(port, 0) << text;
  EXPECT_EQ(http_get(port, "/readyz").status, 200);
  EXPECT_NE(text.find("event=program_cache_discarded"), std::string::npos) << text;
  auto metrics = http_get(port, "/metrics").body;
  EXPECT_NE(metrics.find("grotto_compute_path_info{path=\"opencl"), std::string::npos) << metrics;
  expect_still_serving(port);
  stop_process(p);
  std::filesystem::remove_all(dir);
}

// ---- 3. a driver that fails later ----

// PoCL 5.0 passed a probe that built the kernel once, then aborted the server when its workers
// ran side by side. The probe child drives the server's whole life cycle: two cycles of one
// builder per worker (here 2: an OpenCL context and the deformation program each) opened, batches
// of 1, 2, 8 and 32 rooms of seed 7 at both levels of detail built on all at once, all released;
// its report says what ran (2 cycles x 2 builders x 2 lods x 43 rooms = 344).
TEST(OpenclProbe, runs_the_servers_whole_life_cycle_twice) {
  // The workers on one shared device (the default: one context a cycle) or on a context each.
  for (const char* queue : {"shared", "per-worker"}) {
    SCOPED_TRACE(queue);
    std::filesystem::path dir =
        std::filesystem::temp_directory_path() / ("grotto-probe-" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    auto [p, port, text] = start_with_cache(dir.string(), {}, {"--opencl-queue", queue});
    ASSERT_NE(port, 0) << text;
    auto metrics = http_get(port, "/metrics").body;
    stop_process(p);
    std::filesystem::remove_all(dir);
    if (metrics.find("grotto_compute_path_info{path=\"opencl") == std::string::npos) {
      GTEST_SKIP() << "no OpenCL device here: the probe has no cycle to run";
    }
    const std::string contexts = std::string(queue) == "shared" ? "2" : "4";
    EXPECT_NE(text.find("event=opencl_probe_passed attempt=1 cycles=2 builders=2 contexts=" +
                        contexts + " batches=32 rooms=344 released=4"),
              std::string::npos)
        << text;
    EXPECT_EQ(text.find("event=opencl_probe_failed"), std::string::npos) << text;
  }
}

// A driver that dies at a step of the second cycle (GROTTO_OPENCL_PROBE_FAULT aborts the child
// there, as PoCL's assertion did): a failed probe that names the step, both attempts, and the
// server serves on the CPU, saying why.
class LaterDriverFault : public ::testing::TestWithParam<const char*> {};
INSTANTIATE_TEST_SUITE_P(OpenclProbe, LaterDriverFault, ::testing::Values("2:1:run", "2:2:release"),
                         [](const auto& param_info) {
                           std::string name = param_info.param;
                           for (char& c : name)
                             if (c == ':') c = '_';
                           return "cycle_" + name;
                         });

TEST_P(LaterDriverFault, is_a_failed_probe_that_names_the_step) {
  const std::string fault = GetParam();
  const int builder = fault[2] - '0';
  const std::string step = fault.substr(4);
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("grotto-probe-fault-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  setenv("GROTTO_OPENCL_PROBE_FAULT", fault.c_str(), 1);
  auto [p, port, text] = start_with_cache(dir.string());
  unsetenv("GROTTO_OPENCL_PROBE_FAULT");
  ASSERT_NE(port, 0) << text;
  auto metrics = http_get(port, "/metrics").body;
  expect_still_serving(port);
  stop_process(p);
  std::filesystem::remove_all(dir);
  if (text.find("event=opencl_probe_failed") == std::string::npos &&
      metrics.find("grotto_compute_path_info{path=\"opencl") == std::string::npos) {
    GTEST_SKIP() << "no OpenCL device here: the probe stops before its cycles";
  }
  // The runs of a cycle overlap, so a run's failure names them all; the driver's (here the
  // fault's) own line says more.
  const std::string where = step == "run"
                                ? "cycle 2/2, builders 1-2 at once, run"
                                : "cycle 2/2, builder " + std::to_string(builder) + "/2, " + step;
  const std::string detail = "the OpenCL probe failed at " + where + " (killed by signal " +
                             std::to_string(SIGABRT) + "): GROTTO_OPENCL_PROBE_FAULT=" + fault +
                             ": aborting at cycle 2/2, builder " + std::to_string(builder) +
                             "/2, " + step;
  EXPECT_NE(text.find("event=opencl_probe_failed attempt=1 detail=\"" + detail), std::string::npos)
      << text;
  EXPECT_NE(text.find("event=opencl_probe_failed attempt=2 detail=\"" + detail), std::string::npos)
      << text;
  EXPECT_EQ(text.find("event=opencl_probe_passed"), std::string::npos) << text;
  EXPECT_NE(text.find("event=compute_path_fallback"), std::string::npos) << text;
  EXPECT_NE(metrics.find("grotto_compute_path_info{path=\"cpu: CPU fallback: " + detail),
            std::string::npos)
      << metrics;
}

// ---- 4. a log flood ----

// A client sending bad messages in a loop gets each answered, costs the log ten lines and a count,
// and slows nobody else.
TEST(LogFlood, bad_messages_in_a_loop_log_a_few_lines_and_a_count) {
  auto p = spawn({"--port", "0", "--opencl-device", "none", "--workers", "1", "--io-threads", "1"});
  auto text = read_until(p.out, "/ws)", 30s);
  uint16_t port = listening_port(text);
  ASSERT_NE(port, 0) << text;
  Client player(port);
  ASSERT_FALSE(player.connect());
  player.hello("player");
  Client flooder(port);
  ASSERT_FALSE(flooder.connect());
  flooder.hello("flooder");
  for (int i = 0; i < 500; ++i)
    ASSERT_FALSE(flooder.send("{not json"));
  expect_still_serving(port, &player);
  for (int i = 0; i < 500; ++i)
    ASSERT_FALSE(flooder.send("[1, 2"));
  for (int i = 0; i < 1000; ++i) {
    auto e = flooder.next_error();
    ASSERT_TRUE(e) << "error " << i;
    ASSERT_FALSE(e->fatal) << e->message;
  }
  EXPECT_TRUE(flooder.alive());
  flooder.close_tcp();
  auto log = read_until(p.out, "event=errors_not_logged", 10s);
  EXPECT_EQ(count_of(log, "event=error_sent"), 10u) << log;
  EXPECT_NE(log.find("count=990"), std::string::npos) << log;
  expect_still_serving(port, &player);
  expect_still_serving(port);
  player.close_tcp();  // else the stop waits its drain for a client that does not read
  stop_process(p);
}

// ---- 5. squatters ----

// Sockets that upgrade and never say hello wait in their own pool: they cannot take players'
// places, a full pool refuses more at the door, and each leaves after handshake_timeout_ms.
TEST(Squatters, upgrades_without_hello_do_not_take_players_places) {
  auto c = test_config();
  c.max_connections = 2;
  c.max_handshakes = 2;
  c.limits.handshake_timeout_ms = 400;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client player(server->port());
  ASSERT_FALSE(player.connect());
  player.hello("player");
  Client squat1(server->port()), squat2(server->port()), squat3(server->port());
  // The server admits a socket just after its upgrade's answer: wait until each squatter holds
  // its place, or under load the second could be admitted before the first and the first,
  // finding the pool full, be the one refused.
  const auto admitted = [&](size_t sessions) {
    const auto deadline = Clock::now() + 10s;
    while (server->sessions() < sessions && Clock::now() < deadline)
      std::this_thread::sleep_for(5ms);
    return server->sessions();
  };
  ASSERT_FALSE(squat1.connect());
  ASSERT_EQ(admitted(2), 2u);
  ASSERT_FALSE(squat2.connect());
  ASSERT_EQ(admitted(3), 3u);
  // The handshake pool is full: the next one is refused at once.
  ASSERT_FALSE(squat3.connect());
  auto e = squat3.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kOverloaded);
  EXPECT_EQ(squat3.wait_close().code, 1008);
  expect_still_serving(server->port(), &player);
  // The squatters are closed with timeout; then the other player place is free.
  EXPECT_EQ(std::string(squat1.wait_close().reason.c_str()), "timeout");
  EXPECT_EQ(std::string(squat2.wait_close().reason.c_str()), "timeout");
  Client second(server->port());
  ASSERT_FALSE(second.connect());
  second.hello("second");
  expect_still_serving(server->port(), &second);
  expect_still_serving(server->port(), &player);
  // With both player places taken, one more is refused at the door; a squatter meanwhile still
  // gets a handshake place without costing a player anything.
  Client extra(server->port());
  ASSERT_FALSE(extra.connect());
  e = extra.next_error();
  ASSERT_TRUE(e);
  EXPECT_EQ(e->code, ErrorCode::kOverloaded);
  EXPECT_TRUE(player.alive());
}

// Every accepted socket counts, upgraded or not: raw TCP connections beyond max_connections +
// max_handshakes + 64 are closed at once, and those that never send a request go after
// handshake_timeout_ms; then players and probes get in again. While the flood is over the cap a
// new probe is shed like any socket (that is the cap's point), so only the player already in is
// checked during it.
TEST(Squatters, raw_sockets_are_counted_shed_and_timed_out) {
  auto c = test_config();
  c.max_connections = 2;
  c.max_handshakes = 2;
  c.admission.max_queue = 0;  // no places kept for waiting players: the cap is 2 + 2 + 64
  c.limits.handshake_timeout_ms = 300;
  auto server = start(c);
  ASSERT_TRUE(server);
  Client player(server->port());
  ASSERT_FALSE(player.connect());
  player.hello("player");
  auto raw = connect_raw(server->port(), 100);
  expect_player_gets_rooms(player);
  // The server closes every one of them: 33 at once (the player's socket and 67 of them fill
  // 2 + 2 + 64), the rest after 300 ms.
  auto deadline = Clock::now() + 5s;
  size_t closed = 0;
  for (int fd : raw) {
    pollfd pfd{fd, POLLIN, 0};
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    char byte;
    if (poll(&pfd, 1, static_cast<int>(std::max<int64_t>(left.count(), 0))) == 1 &&
        recv(fd, &byte, 1, 0) <= 0)
      ++closed;
  }
  EXPECT_EQ(closed, raw.size());
  close_all(raw);
  EXPECT_GE(server->metrics().sockets_shed.value(), 32u);
  expect_still_serving(server->port(), &player);
  expect_still_serving(server->port());
}

// ---- a slow reader ----

TEST(SlowReader, a_client_that_does_not_read_is_dropped_and_others_carry_on) {
  auto c = test_config();
  c.send_queue_bytes = 4096;
  c.limits.max_rooms_per_request = 256;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(1024);
  Client other(server->port());
  ASSERT_FALSE(other.connect());
  other.hello("other");
  Client slow(server->port());
  slow.set_receive_buffer(4096);  // so the server's writes back up soon
  ASSERT_FALSE(slow.connect());
  slow.hello("slow");
  for (size_t i = 0; i < 1024; i += 256)
    ASSERT_FALSE(slow.send(request_of(rooms, i, 256, i)));
  // ... and never reads. The server notices once its queue for this client passes 4 KiB.
  expect_still_serving(server->port(), &other);
  auto deadline = Clock::now() + kWait;
  while (server->metrics().slow_clients_dropped.value() == 0 && Clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(server->metrics().slow_clients_dropped.value(), 1u);
  deadline = Clock::now() + kWait;
  while (server->sessions() > 1 && Clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  EXPECT_EQ(server->sessions(), 1u);  // its session and memory are gone
  expect_still_serving(server->port(), &other);
  expect_still_serving(server->port());
}

// The close arrives: a client with a small receive buffer asks for the same 4 cached
// rooms 377 times (1,508 frames: its queue passes the bound at once, and the server's socket
// buffer fills with frames it cannot send), says nothing for 3 s, then reads. It gets the frames
// that were on their way and then the close frame, 1008 slow_client: the server lingered, reading
// and dropping, instead of cutting the socket after 1 s with a TCP reset that threw away what it
// had sent and left the client one frame and ECONNRESET.
TEST(SlowReader, a_slow_reader_that_reads_again_gets_close_1008_slow_client) {
  auto c = test_config();
  c.send_queue_bytes = 256 << 10;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(4);
  Client warm(server->port());
  ASSERT_FALSE(warm.connect());
  warm.hello("warm");
  ASSERT_FALSE(warm.send(request_of(rooms, 0, 4, 1)));
  for (int i = 0; i < 4; ++i) {
    auto [ec, in] = warm.read();
    ASSERT_FALSE(ec);
    ASSERT_FALSE(in.text) << in.data;
  }
  Client slow(server->port());
  slow.set_receive_buffer(4096);
  ASSERT_FALSE(slow.connect());
  slow.hello("slow");
  for (int i = 0; i < 377; ++i)
    ASSERT_FALSE(slow.send(request_of(rooms, 0, 4, static_cast<size_t>(i))));
  std::this_thread::sleep_for(3s);
  EXPECT_EQ(server->metrics().slow_clients_dropped.value(), 1u);
  size_t frames = 0;
  websocket::close_reason reason;
  for (;;) {
    auto [ec, in] = slow.read();
    if (ec) {
      reason = slow.ws().reason();
      EXPECT_EQ(ec, websocket::error::closed) << ec.message() << " after " << frames << " frames";
      break;
    }
    ++frames;
  }
  EXPECT_EQ(reason.code, 1008) << "after " << frames << " frames";
  EXPECT_EQ(std::string(reason.reason.c_str()), "slow_client");
  expect_still_serving(server->port(), &warm);
}

// ---- 6. request floods ----

// One client with 1,000 rooms queued saturates the only worker: probes still answer (they touch
// nothing the generator holds) and another player's rooms come in their turn.
TEST(RequestFlood, healthz_answers_while_generation_is_saturated) {
  auto c = test_config();
  c.generator.workers = 1;
  c.generator.max_batch_rooms = 1;
  auto server = start(c);
  ASSERT_TRUE(server);
  auto rooms = many_rooms(1000);
  Client player(server->port());
  ASSERT_FALSE(player.connect());
  player.hello("player");
  Client greedy(server->port());
  ASSERT_FALSE(greedy.connect());
  greedy.hello("greedy");
  for (size_t i = 0; i < 1000; i += 250)
    ASSERT_FALSE(greedy.send(request_of(rooms, i, 250, i)));
  auto deadline = Clock::now() + kWait;
  while (server->generator().queue_depth() < 100 && Clock::now() < deadline) {
    std::this_thread::sleep_for(5ms);
  }
  ASSERT_GE(server->generator().queue_depth(), 100u);
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(http_get(server->port(), "/healthz").status, 200);
  EXPECT_EQ(http_get(server->port(), "/readyz").status, 200);
  expect_still_serving(server->port(), &player);
  EXPECT_GT(server->generator().queue_depth(), 0u);  // still saturated after the probes
  greedy.close_tcp();
  expect_still_serving(server->port(), &player);
  expect_still_serving(server->port());
}

// A client requesting and cancelling in a loop (reconnecting whenever it is closed) runs into its
// request rate; another player keeps getting rooms meanwhile and after.
TEST(RequestFlood, a_request_churner_does_not_stop_another_player_getting_rooms) {
  auto c = test_config();
  c.limits.request_rate = 500;  // rooms a second, requests and cancels together
  c.limits.request_burst = 1000;
  auto server = start(c);
  ASSERT_TRUE(server);
  const uint16_t port = server->port();
  auto rooms = sector_rooms(c.seed, {1, 0, 0});
  ASSERT_GE(rooms.size(), 16u);
  grotto::proto::Cancel cancel;
  for (size_t i = 0; i < 16; ++i)
    cancel.rooms.push_back(rooms[i].id);
  Client player(port);
  ASSERT_FALSE(player.connect());
  player.hello("player");

  std::atomic<bool> stop{false};
  std::atomic<int> pairs{0}, refused{0}, closed{0};
  std::thread churner([&] {
    // Bounded: at most 200 connections of at most 100 rounds each, and it stops when told.
    for (int connection = 0; connection < 200 && !stop; ++connection) {
      Client ch(port);
      if (ch.connect()) return;
      ch.hello("churner");
      bool open = true;
      for (int round = 0; round < 100 && open && !stop; ++round) {
        for (int i = 0; i < 20 && open; ++i) {
          open = !ch.send(request_of(rooms, 0, 16, i)) && !ch.send(cancel);
          ++pairs;
        }
        // Read up to a pong, counting refusals; a fatal error or a close ends this connection.
        grotto::proto::Ping ping;
        ping.ref = 7;
        if (open && ch.send(ping)) open = false;
        while (open) {
          auto in = ch.next_text(5s);
          if (!in) {
            open = false;
          } else if (auto* e = in->as<grotto::proto::ErrorMessage>()) {
            if (e->code == ErrorCode::kLimitExceeded) ++refused;
            if (e->fatal) open = false;
          } else if (in->as<grotto::proto::Pong>()) {
            break;
          }
        }
        ch.frames.clear();
      }
      if (!open) ++closed;
    }
  });
  struct Join {
    std::atomic<bool>& stop;
    std::thread& thread;
    ~Join() {
      stop = true;
      thread.join();
    }
  } join{stop, churner};

  auto deadline = Clock::now() + kWait;
  while (refused == 0 && Clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  ASSERT_GT(refused.load(), 0) << "the churner never ran into its rate (" << pairs << " pairs)";
  // While it churns.
  for (int i = 0; i < 3; ++i)
    expect_still_serving(port, &player);
  EXPECT_GT(server->metrics().errors(ErrorCode::kLimitExceeded), 0u);
  stop = true;
  // After.
  expect_still_serving(port, &player);
  expect_still_serving(port);
}

}  // namespace
