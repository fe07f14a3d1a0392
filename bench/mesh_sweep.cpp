// mesh_sweep: builds every room of many sectors on the CPU path (prepare, deform_cpu, assemble)
// and counts the rooms that cannot be meshed, with their errors. Sectors are drawn at random over
// a cube of the sector range (plus any named with --sector), so rare layouts come up. A digest per
// room (--hashes) shows which rooms a mesher change touched. Writes a JSON report; the fast
// subset is tests/mesh/room_mesh_test.cpp's rooms_of_sampled_sectors_all_build.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench/flags.hpp"
#include "bench/sector_sample.hpp"
#include "bench/timing.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;

template <class T>
uint64_t add_bytes(uint64_t h, const std::vector<T>& v) {
  return fnv1a64(reinterpret_cast<const unsigned char*>(v.data()), v.size() * sizeof(T), h);
}

// FNV-1a over every byte of a mesh (mesh_bench's digest, one room at a time).
uint64_t mesh_hash(const mesh::RoomMesh& m) {
  uint64_t h = 0xcbf29ce484222325ull;
  h = add_bytes(h, m.positions);
  h = add_bytes(h, m.normals);
  h = add_bytes(h, m.roughness);
  h = add_bytes(h, m.mineral);
  h = add_bytes(h, m.rim_portal);
  h = add_bytes(h, m.rim_index);
  return add_bytes(h, m.indices);
}

bool parse_sector(const std::string& text, cave::SectorCoord& s) {
  const char* p = text.data();
  const char* end = text.data() + text.size();
  for (int a = 0; a < 3; ++a) {
    auto [next, ec] = std::from_chars(p, end, s[a]);
    if (ec != std::errc() || (a == 2 ? next != end : (next == end || *next != ','))) return false;
    p = next + 1;
  }
  return cave::in_range(s);
}

struct Outcome {
  std::string room;
  std::string lod;
  bool ok = false;
  std::string error;
  uint64_t hash = 0;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mesh_sweep: mesh every room of many sectors on the CPU path and count the rooms that "
      "cannot be meshed; writes a JSON report"};
  std::vector<uint64_t> seeds{7, 42};
  int sample = 100, spread = 1000, threads = 1;
  uint64_t sample_seed = 1;
  std::vector<std::string> named{"676,1,-2"};
  std::vector<std::string> lod_names{"patch", "detail"};
  std::string json_path = "mesh_sweep.json", hashes_path;
  app.add_option("--seed", seeds, "World seeds")->capture_default_str();
  app.add_option("--sectors", sample, "Sectors drawn at random per seed")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--spread", spread, "Sectors are drawn from [-spread, spread] on each axis")
      ->check(CLI::Range(0, static_cast<int>(cave::kSectorCoordLimit)))
      ->capture_default_str();
  app.add_option("--sample-seed", sample_seed, "Seed of the random draw of sectors")
      ->capture_default_str();
  app.add_option("--sector", named, "Sectors built as well, as x,y,z")->capture_default_str();
  app.add_option("--lod", lod_names, "Levels of detail")
      ->check(CLI::IsMember(std::vector<std::string>{"detail", "patch"}))
      ->capture_default_str();
  app.add_option("--threads", threads, "Worker threads")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--hashes", hashes_path,
                 "Write one line per room and lod: id, lod, FNV-1a of the mesh or the error");
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  std::vector<cave::SectorCoord> extra;
  for (const std::string& text : named) {
    cave::SectorCoord s;
    if (!parse_sector(text, s)) {
      spdlog::error("--sector must be three integers like 0,-1,2 within the range (got '{}')",
                    text);
      return 2;
    }
    extra.push_back(s);
  }

  nlohmann::json report;
  report["per_seed"] = nlohmann::json::array();
  std::vector<Outcome> all;
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = bench::process_cpu_seconds();
  for (uint64_t seed : seeds) {
    auto world = cave::World::create(seed, cave::LayoutParams{});
    if (!world) {
      spdlog::error("seed {}: {}", seed, world.error().message);
      return 2;
    }
    mesh::MeshContext ctx = mesh::MeshContext::create(*world, mesh::MeshParams{}).value();
    std::vector<cave::SectorCoord> sectors = extra;
    for (cave::SectorCoord s : bench::sample_sectors(seed, sample_seed, sample, spread))
      sectors.push_back(s);
    std::vector<cave::Room> rooms = bench::rooms_of(*world, sectors);
    std::vector<mesh::Lod> lods;
    for (const std::string& name : lod_names)
      lods.push_back(name == "patch" ? mesh::Lod::kPatch : mesh::Lod::kDetail);

    std::vector<Outcome> out(rooms.size() * lods.size());
    std::atomic<size_t> next{0};
    auto work = [&] {
      for (size_t i; (i = next.fetch_add(1)) < out.size();) {
        const cave::Room& r = rooms[i / lods.size()];
        mesh::Lod lod = lods[i % lods.size()];
        Outcome& o = out[i];
        o.room = r.id.to_string();
        o.lod = mesh::lod_name(lod);
        auto m = mesh::build_room_mesh(ctx, r, lod);
        o.ok = m.ok();
        if (m.ok()) {
          o.hash = mesh_hash(*m);
        } else {
          o.error = m.error().message;
        }
      }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t)
      pool.emplace_back(work);
    work();
    for (auto& t : pool)
      t.join();

    nlohmann::json failures = nlohmann::json::array();
    size_t failed = 0;
    for (const Outcome& o : out) {
      if (o.ok) continue;
      ++failed;
      failures.push_back({{"room", o.room}, {"lod", o.lod}, {"error", o.error}});
    }
    spdlog::info("event=sweep seed={} sectors={} rooms={} meshes={} failures={}", seed,
                 sectors.size(), rooms.size(), out.size(), failed);
    report["per_seed"].push_back({{"seed", seed},
                                  {"sectors", sectors.size()},
                                  {"rooms", rooms.size()},
                                  {"meshes", out.size()},
                                  {"failures", failed},
                                  {"failed", failures}});
    for (Outcome& o : out) {
      o.room = std::to_string(seed) + ":" + o.room;
      all.push_back(std::move(o));
    }
  }
  uint64_t digest = 0xcbf29ce484222325ull;
  for (const Outcome& o : all) {
    digest = fnv1a64(reinterpret_cast<const unsigned char*>(&o.hash), sizeof o.hash, digest);
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(digest));
  const std::string digest_hex = hex;
  report["mesh_digest"] = digest_hex;
  report["lods"] = lod_names;
  report["threads"] = threads;
  report["wall_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report["cpu_s"] = bench::process_cpu_seconds() - cpu_start;
  std::ofstream(json_path) << report.dump(2) << "\n";
  if (!hashes_path.empty()) {
    std::ofstream f(hashes_path);
    for (const Outcome& o : all) {
      std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(o.hash));
      f << o.room << ' ' << o.lod << ' ' << (o.ok ? std::string(hex) : "error: " + o.error) << '\n';
    }
  }
  spdlog::info("event=sweep_done meshes={} digest={} wall_s={:.1f} json={}", all.size(), digest_hex,
               report["wall_s"].get<double>(), json_path);
  return 0;
}
