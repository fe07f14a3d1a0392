// The generation service driven in-process, with no sockets: the pipeline rate that the network
// benchmarks (serve_bench, load_bench) compare what they deliver with, in the same run.
#pragma once
#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/cave/room_id.hpp"
#include "proto/messages.hpp"
#include "server/server.hpp"

namespace grotto::bench {

using Clock = std::chrono::steady_clock;
using grotto::server::Server;
using grotto::server::ServerConfig;

struct PhaseResult {
  double seconds = 0;
  size_t rooms = 0;
  uint64_t bytes = 0;
  double build_ms_per_room = 0;
  double encode_ms_per_room = 0;
  std::string compute_path;
};

inline void fill_histograms(Server& server, PhaseResult& r) {
  auto& m = server.metrics();
  if (m.build_seconds.count() > 0) {
    r.build_ms_per_room =
        1000.0 * m.build_seconds.sum() / static_cast<double>(m.build_seconds.count());
  }
  if (m.encode_seconds.count() > 0) {
    r.encode_ms_per_room =
        1000.0 * m.encode_seconds.sum() / static_cast<double>(m.encode_seconds.count());
  }
  r.compute_path = server.generator().compute_path();
}

// The generation service alone: one in-process client asks for every room.
inline PhaseResult in_process(const ServerConfig& config,
                              const std::vector<grotto::cave::RoomId>& ids) {
  auto server = Server::start(config);
  if (!server) {
    spdlog::error("{}", server.error().message);
    std::exit(1);
  }
  std::mutex mutex;
  std::condition_variable cv;
  size_t done = 0;
  uint64_t bytes = 0;
  auto& gen = (*server)->generator();
  auto client = gen.add_client([&](grotto::server::Delivery d) {
    std::lock_guard lock(mutex);
    ++done;
    if (d.room) bytes += d.room->frame.size();
    cv.notify_all();
  });
  auto t0 = Clock::now();
  std::vector<grotto::server::Want> wants;
  for (auto id : ids)
    wants.push_back({id, 0, 0});
  gen.request(client, wants);
  {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return done == ids.size(); });
  }
  PhaseResult r;
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.rooms = ids.size();
  r.bytes = bytes;
  gen.remove_client(client);
  fill_histograms(**server, r);
  (*server)->stop(std::chrono::milliseconds{2000});
  return r;
}

// A phase as JSON: seconds, rooms, rooms/s, bytes, MB/s, per-room build and encode times.
inline nlohmann::json to_json(const PhaseResult& r) {
  return {{"seconds", r.seconds},
          {"rooms", r.rooms},
          {"rooms_per_second", static_cast<double>(r.rooms) / r.seconds},
          {"bytes", r.bytes},
          {"megabytes_per_second", static_cast<double>(r.bytes) / r.seconds / 1e6},
          {"build_ms_per_room", r.build_ms_per_room},
          {"encode_ms_per_room", r.encode_ms_per_room},
          {"compute_path", r.compute_path}};
}

}  // namespace grotto::bench
