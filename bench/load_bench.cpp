// load_bench: what players get from a server, measured with grotto-load's
// engine (client/load) over real loopback WebSockets, in one run:
//   1. throughput: rooms/s delivered to N players (burst mode, spread over distinct sectors, so
//      every room is built once) against the same rooms through the generation service driven
//      in-process, alone and with every room decoded as a player would (the whole pipeline
//      without the network), each phase on a fresh server (empty caches), alternating, median
//      of --repetitions;
//   2. latency: request -> room percentiles and time to first room for walking players at each
//      count of --matrix;
//   3. stalls: N players walking at --stall-speed m/s, for each horizon of --horizons.
// Writes a JSON report (--json FILE) with every figure of every run.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "bench/flags.hpp"
#include "bench/inprocess.hpp"
#include "bench/timing.hpp"
#include "client/load/load.hpp"
#include "client/stream/portal_graph.hpp"
#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "proto/room_frame.hpp"

namespace {

using grotto::bench::Clock;
using grotto::bench::in_process;
using grotto::bench::PhaseResult;
using grotto::load::LoadOptions;
using grotto::load::LoadReport;
using grotto::load::Mode;
using grotto::server::Server;
using grotto::server::ServerConfig;

// The rooms that burst players with --spread want: for player i, everything within the radius of
// interior room 0 of sector (3i, 0, 0), planned over the layout itself with no view preference.
// (The players' Streams look along their walker's initial direction, so their sets can differ at
// the rim of the radius; the report gives both counts.)
std::vector<grotto::cave::RoomId> burst_rooms(uint64_t seed, int players, double radius_m) {
  auto world = grotto::cave::World::create(seed, {});
  std::set<grotto::cave::RoomId> ids;
  for (int i = 0; i < players; ++i) {
    grotto::stream::PortalGraph graph;
    std::vector<grotto::cave::Room> rooms;
    for (int x = 3 * i - 1; x <= 3 * i + 1; ++x) {
      for (int y = -1; y <= 1; ++y) {
        for (int z = -1; z <= 1; ++z) {
          auto sector = grotto::cave::generate_sector(*world, {x, y, z});
          rooms.insert(rooms.end(), sector.rooms.begin(), sector.rooms.end());
        }
      }
    }
    for (const auto& r : rooms)
      (void)graph.add(r);
    for (const auto& r : rooms)
      (void)graph.add(r);  // rooms refused before their neighbours
    auto start = grotto::cave::RoomId::interior({3 * i, 0, 0}, 0);
    if (!graph.find(start)) continue;  // grotto-load refuses such a start
    grotto::stream::Pose pose;
    pose.room = start;
    pose.position = graph.find(start)->sphere.centre;
    pose.forward = {};
    pose.speed = 1.0;
    grotto::stream::PlanOptions plan;
    plan.horizon_s = radius_m;
    for (const auto& p : graph.plan(start, pose, plan))
      ids.insert(p.id);
  }
  return {ids.begin(), ids.end()};
}

// The pipeline a player needs, in-process: the generation service as in_process() does, and every
// frame decoded (room frame, then the Draco payload) on `decoders` threads as a Stream would,
// with no network in between. Done when the last room is decoded.
PhaseResult in_process_decoded(const ServerConfig& config,
                               const std::vector<grotto::cave::RoomId>& ids, int decoders) {
  auto server = Server::start(config);
  if (!server) {
    spdlog::error("{}", server.error().message);
    std::exit(1);
  }
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<grotto::server::RoomPtr> queue;
  size_t delivered = 0, decoded = 0, failed = 0;
  uint64_t bytes = 0;
  bool done = false;
  std::vector<std::thread> threads;
  for (int i = 0; i < decoders; ++i) {
    threads.emplace_back([&] {
      for (;;) {
        grotto::server::RoomPtr room;
        {
          std::unique_lock lock(mutex);
          cv.wait(lock, [&] { return done || !queue.empty(); });
          if (queue.empty()) return;
          room = std::move(queue.front());
          queue.pop_front();
        }
        auto frame = grotto::proto::decode_room_frame(room->frame, config.limits);
        bool ok = frame.ok();
        if (ok) {
          grotto::codec::DecodeLimits limits;
          limits.portal_count = static_cast<int>(frame->room.portals.size());
          ok = grotto::codec::decode_room(frame->payload, limits).ok();
        }
        std::lock_guard lock(mutex);
        ++decoded;
        failed += ok ? 0 : 1;
        cv.notify_all();
      }
    });
  }
  auto& gen = (*server)->generator();
  auto client = gen.add_client([&](grotto::server::Delivery d) {
    std::lock_guard lock(mutex);
    ++delivered;
    if (d.room) {
      bytes += d.room->frame.size();
      queue.push_back(d.room);
    } else {
      ++decoded;  // nothing to decode
    }
    cv.notify_all();
  });
  auto t0 = Clock::now();
  std::vector<grotto::server::Want> wants;
  for (auto id : ids)
    wants.push_back({id, 0, 0});
  gen.request(client, wants);
  {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return decoded == ids.size(); });
    done = true;
    cv.notify_all();
  }
  PhaseResult r;
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.rooms = ids.size();
  r.bytes = bytes;
  for (auto& t : threads)
    t.join();
  if (failed) spdlog::warn("in-process decode: {} rooms failed", failed);
  gen.remove_client(client);
  grotto::bench::fill_histograms(**server, r);
  (*server)->stop(std::chrono::milliseconds{2000});
  return r;
}

LoadReport run(const LoadOptions& options) {
  auto report = grotto::load::run_load(options);
  if (!report) {
    spdlog::error("{}", report.error().message);
    std::exit(1);
  }
  return std::move(report).value();
}

nlohmann::json distribution(const grotto::load::Distribution& d) {
  return {{"count", d.count}, {"mean", d.mean}, {"p50", d.p50},
          {"p90", d.p90},     {"p99", d.p99},   {"max", d.max}};
}

nlohmann::json summary(const LoadReport& r) {
  return {{"players", r.players},
          {"mode", r.mode},
          {"speed", r.speed},
          {"horizon_s", r.horizon_s},
          {"elapsed_s", r.elapsed_s},
          {"rooms_ready", r.rooms_ready},
          {"rooms_per_s", r.rooms_per_s},
          {"mb_per_s", r.mb_per_s},
          {"latency_ms", distribution(r.latency_ms)},
          {"first_room_ms", distribution(r.first_room_ms)},
          {"decode_ms", distribution(r.decode_ms)},
          {"stalls", r.stalls},
          {"stall_total_s", r.stall_total_s},
          {"stall_ms", distribution(r.stall_ms)},
          {"cancels", r.cancels},
          {"errors", r.errors_total},
          {"reconnects", r.reconnects},
          {"burst_s", r.burst_s}};
}

std::vector<double> parse_list(const std::string& text) {
  std::vector<double> out;
  size_t pos = 0;
  while (pos < text.size()) {
    size_t comma = text.find(',', pos);
    out.push_back(std::stod(text.substr(pos, comma - pos)));
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "load_bench: what players get over loopback (grotto-load's engine) vs the "
      "in-process pipeline, latency by player count, stalls by horizon"};
  int players = 32;
  double radius = 40;
  int repetitions = 3;
  int workers = 0;
  std::string device;
  std::string matrix = "1,8,32,128";
  double walk_seconds = 15;
  double walk_speed = 4;
  double stall_speed = 10;
  std::string horizons = "2,4,6";
  std::string json_path;
  app.add_option("--players", players, "Players in the throughput and stall runs")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_option("--radius", radius, "Burst radius (m) around each player")->capture_default_str();
  app.add_option("--repetitions", repetitions, "Throughput runs of each phase (median reported)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--workers", workers, "Server generation threads (0: one per hardware thread)")
      ->capture_default_str();
  app.add_option("--opencl-device", device, "auto, gpu, cpu, none or a name substring");
  app.add_option("--matrix", matrix, "Player counts for the latency runs (empty: skip)")
      ->capture_default_str();
  app.add_option("--walk-seconds", walk_seconds, "Duration of each walking run")
      ->capture_default_str();
  app.add_option("--walk-speed", walk_speed, "Walking speed (m/s) of the latency runs")
      ->capture_default_str();
  app.add_option("--stall-speed", stall_speed, "Walking speed (m/s) of the stall runs")
      ->capture_default_str();
  app.add_option("--horizons", horizons, "Prefetch horizons (s) of the stall runs (empty: skip)")
      ->capture_default_str();
  app.add_option("--json", json_path, "Write the report here");
  if (auto rc = grotto::bench::parse_flags(app, argc, argv)) return *rc;
  spdlog::set_level(spdlog::level::warn);

  ServerConfig config;
  config.port = 0;
  config.io_threads = 1;
  config.generator.workers = workers;
  config.generator.builder.device.device = device;
  config.log_level = "warn";

  // 1. Throughput: the same rooms through the pipeline in-process, and to players over loopback.
  auto ids = burst_rooms(config.seed, players, radius);
  (void)in_process(config, std::vector<grotto::cave::RoomId>(
                               ids.begin(), ids.begin() + std::min<size_t>(ids.size(), 32)));
  std::vector<PhaseResult> locals, decodeds;
  std::vector<LoadReport> bursts;
  // Process CPU seconds per room delivered, server and players together: what a room costs, which
  // other load on the machine does not inflate (unlike rates).
  std::vector<double> local_cpu, decoded_cpu, burst_cpu;
  const int decoders = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (int r = 0; r < repetitions; ++r) {
    double cpu0 = grotto::bench::process_cpu_seconds();
    locals.push_back(in_process(config, ids));
    local_cpu.push_back((grotto::bench::process_cpu_seconds() - cpu0) * 1000.0 /
                        static_cast<double>(ids.size()));
    cpu0 = grotto::bench::process_cpu_seconds();
    decodeds.push_back(in_process_decoded(config, ids, decoders));
    decoded_cpu.push_back((grotto::bench::process_cpu_seconds() - cpu0) * 1000.0 /
                          static_cast<double>(ids.size()));
    cpu0 = grotto::bench::process_cpu_seconds();
    auto server = Server::start(config);
    if (!server) {
      spdlog::error("{}", server.error().message);
      return 1;
    }
    LoadOptions o;
    o.url = "ws://127.0.0.1:" + std::to_string((*server)->port()) + "/ws";
    o.mode = Mode::kBurst;
    o.players = players;
    o.radius_m = radius;
    o.speed = 1.0;
    o.seed = config.seed;
    o.spread = true;
    bursts.push_back(run(o));
    (*server)->stop(std::chrono::milliseconds{2000});
    burst_cpu.push_back((grotto::bench::process_cpu_seconds() - cpu0) * 1000.0 /
                        static_cast<double>(std::max<uint64_t>(bursts.back().rooms_ready, 1)));
  }
  auto by_time = [](const PhaseResult& a, const PhaseResult& b) { return a.seconds < b.seconds; };
  std::sort(locals.begin(), locals.end(), by_time);
  std::sort(decodeds.begin(), decodeds.end(), by_time);
  // A burst's rate: the rooms its players got over the time until every radius was ready.
  auto burst_rate = [](const LoadReport& r) {
    return r.burst_s > 0 ? static_cast<double>(r.rooms_ready) / r.burst_s : 0.0;
  };
  std::sort(bursts.begin(), bursts.end(),
            [&](const auto& a, const auto& b) { return burst_rate(a) < burst_rate(b); });
  const PhaseResult& local = locals[locals.size() / 2];
  const PhaseResult& decoded = decodeds[decodeds.size() / 2];
  const double decoded_rate = static_cast<double>(decoded.rooms) / decoded.seconds;
  const LoadReport& burst = bursts[bursts.size() / 2];
  const double local_rate = static_cast<double>(local.rooms) / local.seconds;
  nlohmann::json throughput = {
      {"players", players},
      {"radius_m", radius},
      {"in_process", grotto::bench::to_json(local)},
      {"over_loopback", summary(burst)},
      {"over_loopback_rooms_per_s", burst_rate(burst)},
      {"in_process_decoded", grotto::bench::to_json(decoded)},
      {"delivered_over_in_process", burst_rate(burst) / local_rate},
      {"delivered_over_in_process_decoded", burst_rate(burst) / decoded_rate},
      {"in_process_decoded_cpu_ms_per_room", grotto::bench::median(decoded_cpu)},
      {"in_process_cpu_ms_per_room", grotto::bench::median(local_cpu)},
      {"over_loopback_cpu_ms_per_room", grotto::bench::median(burst_cpu)}};
  std::fprintf(stderr,
               "throughput: %d players, %.0f rooms/s delivered; in-process %.0f (%.2f), with "
               "decode %.0f (%.2f); CPU ms/room %.2f vs %.2f, with decode %.2f\n",
               players, burst_rate(burst), local_rate, burst_rate(burst) / local_rate, decoded_rate,
               burst_rate(burst) / decoded_rate, grotto::bench::median(burst_cpu),
               grotto::bench::median(local_cpu), grotto::bench::median(decoded_cpu));

  // 2. Latency by player count, walking; 3. stalls by horizon.
  auto walk = [&](int n, double speed, double horizon, bool spread) {
    LoadOptions o;
    o.spread = spread;
    o.players = n;
    o.duration_s = walk_seconds;
    o.speed = speed;
    o.horizon_s = horizon;
    o.device = device;
    o.server_workers = workers;
    return run(o);
  };
  nlohmann::json latency = nlohmann::json::array();
  // Everyone at the server's spawn point (shared rooms: cache hits and single flight), then
  // spread over distinct sectors (every room built for one player).
  for (bool spread : {false, true}) {
    for (double n : parse_list(matrix)) {
      auto r = walk(static_cast<int>(n), walk_speed, 4.0, spread);
      auto s = summary(r);
      s["spread"] = spread;
      latency.push_back(s);
      std::fprintf(stderr,
                   "latency (%s): %3d players: p50 %.1f p90 %.1f p99 %.1f max %.1f ms, first %.1f "
                   "ms, stalls %llu\n",
                   spread ? "spread" : "spawn", r.players, r.latency_ms.p50, r.latency_ms.p90,
                   r.latency_ms.p99, r.latency_ms.max, r.first_room_ms.p50,
                   static_cast<unsigned long long>(r.stalls));
    }
  }
  nlohmann::json stalls = nlohmann::json::array();
  for (bool spread : {false, true}) {
    for (double h : parse_list(horizons)) {
      auto r = walk(players, stall_speed, h, spread);
      auto s = summary(r);
      s["spread"] = spread;
      stalls.push_back(s);
      std::fprintf(stderr, "stalls (%s): %d players at %.0f m/s, horizon %.1f s: %llu (%.2f s)\n",
                   spread ? "spread" : "spawn", r.players, stall_speed, h,
                   static_cast<unsigned long long>(r.stalls), r.stall_total_s);
    }
  }

  nlohmann::json report = {{"hardware_threads", std::thread::hardware_concurrency()},
                           {"workers", workers},
                           {"device", device},
                           {"repetitions", repetitions},
                           {"throughput", throughput},
                           {"latency", latency},
                           {"stalls", stalls}};
  std::string text = report.dump(2);
  std::printf("%s\n", text.c_str());
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  return 0;
}
