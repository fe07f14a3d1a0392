// serve_bench: rooms per second through the whole server over loopback WebSocket, against the
// same generation service driven in-process, in one run. Each phase starts
// a fresh grotto::server::Server (empty caches) and asks for the same distinct rooms; the ratio
// says what the network half costs. Build and encode time per room come from the server's own
// histograms. Writes a JSON report (--json FILE).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench/flags.hpp"
#include "bench/inprocess.hpp"
#include "common/cave/layout.hpp"
#include "proto/messages.hpp"
#include "server/server.hpp"

namespace {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;
using grotto::bench::fill_histograms;
using grotto::bench::in_process;
using grotto::bench::PhaseResult;
using grotto::bench::to_json;
using grotto::server::Server;
using grotto::server::ServerConfig;

std::vector<grotto::cave::RoomId> distinct_rooms(uint64_t seed, size_t count) {
  auto world = grotto::cave::World::create(seed, {});
  std::vector<grotto::cave::RoomId> out;
  for (int x = 0; out.size() < count; ++x) {
    for (int z = 0; z < 8 && out.size() < count; ++z) {
      for (const auto& r : grotto::cave::generate_sector(*world, {x, 0, z}).rooms) {
        if (out.size() < count) out.push_back(r.id);
      }
    }
  }
  return out;
}

// The whole server: `clients` WebSocket clients on loopback share the rooms between them.
PhaseResult wire_pass(Server& server, const std::vector<grotto::cave::RoomId>& ids, int clients) {
  uint16_t port = server.port();
  std::atomic<uint64_t> bytes{0};
  std::atomic<size_t> rooms{0};
  std::vector<std::thread> threads;
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  Clock::time_point t0;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      net::io_context ioc;
      websocket::stream<tcp::socket> ws(ioc);
      ws.next_layer().connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
      ws.handshake("127.0.0.1", "/ws");
      ws.text(true);
      grotto::proto::Hello h;
      h.versions = {1};
      h.name = "serve_bench";
      ws.write(net::buffer(grotto::proto::serialize(grotto::proto::ClientMessage{h})));
      beast::flat_buffer buffer;
      ws.read(buffer);  // welcome
      buffer.consume(buffer.size());
      std::vector<grotto::proto::Request> requests;
      size_t mine = 0;
      for (size_t i = static_cast<size_t>(c); i < ids.size(); i += static_cast<size_t>(clients)) {
        if (requests.empty() || requests.back().rooms.size() == 256) requests.emplace_back();
        requests.back().rooms.push_back({ids[i], 0, static_cast<uint32_t>(i)});
        ++mine;
      }
      ++ready;
      while (!go.load())
        std::this_thread::yield();
      for (const auto& r : requests) {
        ws.write(net::buffer(grotto::proto::serialize(grotto::proto::ClientMessage{r})));
      }
      for (size_t got = 0; got < mine;) {
        ws.read(buffer);
        if (!ws.got_text()) {
          ++got;
          bytes += buffer.size();
        }
        buffer.consume(buffer.size());
      }
      rooms += mine;
      beast::error_code ignored;
      ws.close(websocket::close_code::normal, ignored);
    });
  }
  while (ready.load() < clients)
    std::this_thread::yield();
  t0 = Clock::now();
  go = true;
  for (auto& t : threads)
    t.join();
  PhaseResult r;
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.rooms = rooms.load();
  r.bytes = bytes.load();
  fill_histograms(server, r);
  return r;
}

// A fresh server: the rooms built on demand (cold), then the same rooms again, every one a cache
// hit, which measures the network half alone.
std::pair<PhaseResult, PhaseResult> over_wire(const ServerConfig& config,
                                              const std::vector<grotto::cave::RoomId>& ids,
                                              int clients) {
  auto server = Server::start(config);
  if (!server) {
    spdlog::error("{}", server.error().message);
    std::exit(1);
  }
  auto cold = wire_pass(**server, ids, clients);
  uint64_t built = (*server)->metrics().rooms_built.value();
  auto cached = wire_pass(**server, ids, clients);
  if ((*server)->metrics().rooms_built.value() != built) spdlog::warn("cached pass built rooms");
  cached.build_ms_per_room = 0;   // nothing built or encoded in this pass (the histograms are
  cached.encode_ms_per_room = 0;  // the cold pass's)
  (*server)->stop(std::chrono::milliseconds{2000});
  return {cold, cached};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"serve_bench: rooms/s over loopback WebSocket vs the in-process generation service"};
  size_t rooms = 400;
  int clients = 4;
  int workers = 0;
  int io_threads = 2;
  std::string device;
  std::string json_path;
  app.add_option("--rooms", rooms, "Distinct rooms per phase")->capture_default_str();
  app.add_option("--clients", clients, "WebSocket clients in the wire phase")
      ->capture_default_str();
  app.add_option("--workers", workers, "Generator workers (0: one per hardware thread)")
      ->capture_default_str();
  app.add_option("--io-threads", io_threads, "Server I/O threads")->capture_default_str();
  int repetitions = 3;
  app.add_option("--repetitions", repetitions, "Runs of each phase (median reported)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--opencl-device", device, "auto, gpu, cpu, none or a name substring");
  app.add_option("--json", json_path, "Write the report here");
  if (auto rc = grotto::bench::parse_flags(app, argc, argv)) return *rc;
  spdlog::set_level(spdlog::level::warn);

  ServerConfig config;
  config.port = 0;
  config.io_threads = io_threads;
  config.generator.workers = workers;
  config.generator.builder.device.device = device;
  config.limits.max_rooms_in_flight = static_cast<uint32_t>(std::max<size_t>(rooms, 1024));
  auto ids = distinct_rooms(config.seed, rooms);

  // A discarded warm-up (process-wide caches, OpenCL program cache), then alternating phases;
  // each phase reported is the median by rooms/s.
  (void)in_process(config, std::vector<grotto::cave::RoomId>(
                               ids.begin(), ids.begin() + std::min<size_t>(ids.size(), 32)));
  std::vector<PhaseResult> locals, wires, cached;
  for (int r = 0; r < repetitions; ++r) {
    locals.push_back(in_process(config, ids));
    auto [cold, hot] = over_wire(config, ids, clients);
    wires.push_back(cold);
    cached.push_back(hot);
  }
  auto median = [](std::vector<PhaseResult> v) {
    std::sort(v.begin(), v.end(),
              [](const auto& a, const auto& b) { return a.seconds < b.seconds; });
    return v[v.size() / 2];
  };
  auto local = median(locals);
  auto wire = median(wires);
  auto hot = median(cached);
  nlohmann::json report = {
      {"rooms", rooms},
      {"clients", clients},
      {"workers", workers},
      {"io_threads", io_threads},
      {"repetitions", repetitions},
      {"hardware_threads", std::thread::hardware_concurrency()},
      {"in_process", to_json(local)},
      {"over_loopback", to_json(wire)},
      {"over_loopback_cached", to_json(hot)},
      {"wire_over_in_process", (static_cast<double>(wire.rooms) / wire.seconds) /
                                   (static_cast<double>(local.rooms) / local.seconds)}};
  std::string text = report.dump(2);
  std::printf("%s\n", text.c_str());
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  return 0;
}
