// The generation service in-process (server/generator.hpp), no sockets: rooms/s built and
// encoded at the patch lod with the chosen workers, per-room build and encode time from the
// service's own histograms, batches, and what the sector-layout cache saves (cave::room
// regenerates a sector per call). Writes a JSON report; docs/BENCHMARKS.md keeps the numbers.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench/flags.hpp"
#include "common/cave/layout.hpp"
#include "proto/messages.hpp"
#include "server/generator.hpp"
#include "server/metrics.hpp"
#include "server/sector_cache.hpp"

namespace {

using namespace grotto;
using clock_type = std::chrono::steady_clock;

double seconds_since(clock_type::time_point t) {
  return std::chrono::duration<double>(clock_type::now() - t).count();
}

// The first n interior rooms of sectors (0,0,0), (1,0,0), ...: the clustered wants of a player.
std::vector<cave::RoomId> rooms_along_x(const cave::World& world, size_t n) {
  std::vector<cave::RoomId> out;
  for (int x = 0; out.size() < n; ++x) {
    for (const cave::Room& r : cave::generate_sector(world, {x, 0, 0}).rooms) {
      if (out.size() < n) out.push_back(r.id);
    }
  }
  return out;
}

struct PipelineRun {
  std::string path;
  int workers = 0;
  double seconds = 0;
  size_t rooms = 0;
  size_t failed = 0;
  uint64_t batches = 0;
  double build_ms_per_room = 0;
  double encode_ms_per_room = 0;
  double frame_bytes_mean = 0;
  size_t device_launches = 0;  // the shared device's, and the batches they carried
  size_t device_batches = 0;
};

// One client wants every room at once (cache off, so each is built), lod 0 (patch).
PipelineRun run_pipeline(const cave::World& world, const std::vector<cave::RoomId>& ids,
                         server::GeneratorConfig config, uint32_t version) {
  config.cache_bytes = 0;
  server::Metrics metrics;
  auto gen = server::Generator::create(world, mesh::MeshParams{}, config, metrics);
  if (!gen) {
    spdlog::error("event=generator_create_failed error=\"{}\"", gen.error().message);
    std::exit(1);
  }
  std::mutex m;
  std::condition_variable cv;
  size_t got = 0, failed = 0, bytes = 0;
  server::ClientId c = *(*gen)->add_client(
      world.seed(),
      [&](server::Delivery d) {
        std::lock_guard lock(m);
        ++got;
        if (d.room) {
          bytes += d.room->frame.size();
        } else {
          ++failed;
        }
        cv.notify_all();
      },
      version);
  std::vector<server::Want> wants;
  for (size_t i = 0; i < ids.size(); ++i)
    wants.push_back({ids[i], 0, static_cast<uint32_t>(i)});
  auto start = clock_type::now();
  (*gen)->request(c, wants);
  {
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return got == ids.size(); });
  }
  PipelineRun run;
  run.seconds = seconds_since(start);
  run.path = (*gen)->compute_path();
  run.workers = config.workers;
  run.rooms = ids.size();
  run.failed = failed;
  run.batches = metrics.batches.value();
  run.device_launches = (*gen)->device_launches().launches;
  run.device_batches = (*gen)->device_launches().batches;
  size_t built = metrics.build_seconds.count();
  run.build_ms_per_room = built ? 1000.0 * metrics.build_seconds.sum() / built : 0;
  run.encode_ms_per_room =
      built ? 1000.0 * metrics.encode_seconds.sum() / metrics.encode_seconds.count() : 0;
  run.frame_bytes_mean = built ? static_cast<double>(bytes) / static_cast<double>(built) : 0;
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "server_bench: the generation service in-process (no sockets): rooms/s built and encoded "
      "at the patch lod, per-room build and encode time, and the sector-layout cache's effect"};
  std::string json_path = "server_bench.json";
  size_t rooms = 200;
  int workers = 0;
  size_t batch = 32;
  int repetitions = 3;
  std::vector<std::string> devices = {"", "none"};
  std::vector<std::string> queues = {"shared"};
  uint32_t version = proto::kProtocolVersion;
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--rooms", rooms, "Rooms per run")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--workers", workers, "Build threads (0: one per hardware thread)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--batch", batch, "max_batch_rooms")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--repetitions", repetitions, "Runs per setting; the median rate is reported")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--devices", devices,
                 "OpenCL device choices to run (\"\": $GROTTO_OPENCL_DEVICE or auto; none: CPU)");
  app.add_option("--queues", queues,
                 "How the workers use an OpenCL device: shared (one context and queue, batches "
                 "merged into launches: the server's default), per-worker (a context each); each "
                 "one named is run")
      ->check(CLI::IsMember({"shared", "per-worker"}))
      ->capture_default_str();
  app.add_option("--protocol", version,
                 "Protocol version the rooms are framed for (1: payloads with normals, 2: without)")
      ->check(CLI::Range(1, 2))
      ->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;
  spdlog::set_level(spdlog::level::warn);

  cave::World world = cave::World::create(7, cave::LayoutParams{}).value();
  std::vector<cave::RoomId> ids = rooms_along_x(world, rooms);

  // Layout: cave::room regenerates the room's sector (both, for a gate) on every call; the
  // service's sector cache generates each sector once.
  auto t = clock_type::now();
  for (cave::RoomId id : ids) {
    if (!cave::room(world, id)) return 1;
  }
  double uncached_ms = 1000.0 * seconds_since(t) / ids.size();
  server::SectorCache sectors(world, 4096);
  t = clock_type::now();
  for (cave::RoomId id : ids) {
    if (!sectors.room(id)) return 1;
  }
  double cold_ms = 1000.0 * seconds_since(t) / ids.size();
  t = clock_type::now();
  for (cave::RoomId id : ids) {
    if (!sectors.room(id)) return 1;
  }
  double warm_ms = 1000.0 * seconds_since(t) / ids.size();

  nlohmann::json report;
  report["rooms"] = rooms;
  report["repetitions"] = repetitions;
  report["protocol"] = version;
  report["hardware_threads"] = std::thread::hardware_concurrency();
  report["layout"] = {{"cave_room_ms_per_room", uncached_ms},
                      {"sector_cache_cold_ms_per_room", cold_ms},
                      {"sector_cache_warm_ms_per_room", warm_ms},
                      {"sectors", sectors.misses()}};
  spdlog::set_level(spdlog::level::info);
  spdlog::info(
      "layout: cave::room {:.3f} ms/room, sector cache cold {:.3f}, warm {:.4f} ({} sectors)",
      uncached_ms, cold_ms, warm_ms, sectors.misses());

  nlohmann::json runs = nlohmann::json::array();
  for (const std::string& device : devices) {
    for (const std::string& queue : queues) {
      for (size_t sector_cache : {size_t{4096}, size_t{0}}) {
        // The CPU reference has no device to share: one run.
        if (device == "none" && queue != queues.front()) continue;
        server::GeneratorConfig config;
        config.share_device = queue == "shared";
        config.workers = workers;
        config.max_batch_rooms = batch;
        config.sector_cache_entries = sector_cache;
        config.builder.device.device = device;
        spdlog::set_level(spdlog::level::warn);
        // The run with the median time (the machine may be shared; medians resist that).
        std::vector<PipelineRun> reps;
        for (int i = 0; i < repetitions; ++i)
          reps.push_back(run_pipeline(world, ids, config, version));
        std::sort(reps.begin(), reps.end(),
                  [](const PipelineRun& a, const PipelineRun& b) { return a.seconds < b.seconds; });
        PipelineRun r = reps[reps.size() / 2];
        spdlog::set_level(spdlog::level::info);
        double rate = static_cast<double>(r.rooms) / r.seconds;
        spdlog::info(
            "pipeline: device=\"{}\" queue={} sector_cache={} {:.1f} rooms/s ({} rooms, {:.2f} s, "
            "{} batches in {} device launches, build {:.2f} ms/room, encode {:.2f} ms/room, {:.0f} "
            "B/frame, {} failed) path=\"{}\"",
            device, queue, sector_cache, rate, r.rooms, r.seconds, r.batches, r.device_launches,
            r.build_ms_per_room, r.encode_ms_per_room, r.frame_bytes_mean, r.failed, r.path);
        runs.push_back({{"device", device},
                        {"queue", queue},
                        {"device_launches", r.device_launches},
                        {"device_batches", r.device_batches},
                        {"path", r.path},
                        {"workers", workers},
                        {"sector_cache_entries", sector_cache},
                        {"max_batch_rooms", batch},
                        {"seconds", r.seconds},
                        {"rooms_per_second", rate},
                        {"batches", r.batches},
                        {"build_ms_per_room", r.build_ms_per_room},
                        {"encode_ms_per_room", r.encode_ms_per_room},
                        {"frame_bytes_mean", r.frame_bytes_mean},
                        {"failed", r.failed}});
      }
    }
  }
  report["pipeline"] = runs;
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
