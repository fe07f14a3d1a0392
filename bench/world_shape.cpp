// world_shape: how much space the world has. Builds the patch meshes of every room in a block of
// sectors (CPU path) for some seeds and reports, per seed:
//   - kept radius: per room, the median distance of its vertices from its sphere's centre over the
//     sphere's radius; the median and minimum over the rooms of radius >= --big-radius (8 m);
//   - halls: the largest rooms, their horizontal and vertical extent and their median kept metres;
//   - floor flatness: of the up-facing area of the rooms with a floor (cave::floor_height: the
//     halls), the share within 15 degrees of horizontal (normals face into the cave);
//   - streamed bytes per room (Draco, protocol version 2's layout, normals derived by the client):
//     p50, p99 and the largest, and the largest vertex count;
//   - CPU time per room (prepare + deform + assemble + encode), one thread.
// Writes a JSON report and prints a Markdown table (docs/BENCHMARKS.md, "Space in the world").
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "bench/flags.hpp"
#include "bench/sector_sample.hpp"
#include "bench/timing.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;

struct RoomShape {
  std::string id;
  double radius = 0;
  double kept = 0;       // median vertex distance from the centre / radius
  double kept_m = 0;     // the same in metres
  double near10_m = 0;   // 10th percentile of the vertex distance, metres
  double width_m = 0;    // horizontal extent (the larger of x and z), metres
  double height_m = 0;   // vertical extent, metres
  double up_area = 0;    // area of up-facing triangles, m^2
  double flat_area = 0;  // of it, within 15 degrees of horizontal
  bool floored = false;
  double bytes = 0;
  size_t vertices = 0;
  double ms = 0;
};

RoomShape measure(const mesh::RoomMesh& m, const cave::Room& room) {
  RoomShape s;
  s.id = room.id.to_string();
  s.radius = room.sphere.radius;
  std::vector<double> dist;
  dist.reserve(m.vertex_count());
  Vec3 lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
  for (size_t i = 0; i < m.vertex_count(); ++i) {
    Vec3 p = m.world_position(i);
    dist.push_back(distance(p, room.sphere.centre));
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  }
  s.kept_m = bench::percentile(dist, 0.5);
  s.kept = s.kept_m / s.radius;
  s.near10_m = bench::percentile(dist, 0.1);
  s.width_m = std::max(hi[0] - lo[0], hi[2] - lo[2]);
  s.height_m = hi[1] - lo[1];
  const double cos15 = std::cos(15.0 * 3.14159265358979323846 / 180.0);
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    Vec3 a = m.world_position(m.indices[t]), b = m.world_position(m.indices[t + 1]),
         c = m.world_position(m.indices[t + 2]);
    Vec3 n = cross(b - a, c - a);  // counter-clockwise seen from inside: faces into the cave
    double len = length(n);
    if (len <= 0) continue;
    double area = 0.5 * len;
    double up = n[1] / len;
    if (up > 0) {
      s.up_area += area;
      if (up >= cos15) s.flat_area += area;
    }
  }
  s.vertices = m.vertex_count();
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "world_shape: kept radius, hall sizes, floor flatness and bytes per room of the patch "
      "meshes of a block of sectors; writes a JSON report and prints a Markdown table"};
  std::vector<uint64_t> seeds{3, 7, 95};
  std::vector<int> from{0, 0, 0}, to{1, 0, 1};
  double big_radius = 8.0;
  std::string json_path = "world_shape.json";
  app.add_option("--seed", seeds, "World seeds")->capture_default_str();
  app.add_option("--from", from, "First sector, x y z")->expected(3)->capture_default_str();
  app.add_option("--to", to, "Last sector, x y z")->expected(3)->capture_default_str();
  app.add_option("--big-radius", big_radius, "Rooms at least this big count as big (metres)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  const std::optional<bench::SectorBlock> block = bench::sector_block(from, to);
  if (!block) {
    spdlog::error("--from and --to must be sectors within the range with from <= to");
    return 2;
  }
  const cave::SectorCoord lo = block->lo, hi = block->hi;

  nlohmann::json report;
  report["from"] = from;
  report["to"] = to;
  report["big_radius"] = big_radius;
  report["per_seed"] = nlohmann::json::array();
  std::printf(
      "| seed | rooms | big rooms | kept, median (min) | largest room: r, kept m, 10%% m, width x "
      "height m | halls | halls' up-facing area flat | bytes p50 / p99 / max | vertices max | ms "
      "per room |\n| ---: | ---: | ---: | --- | --- | ---: | ---: | --- | ---: | ---: |\n");
  for (uint64_t seed : seeds) {
    auto world = cave::World::create(seed, cave::LayoutParams{});
    if (!world) {
      spdlog::error("seed {}: {}", seed, world.error().message);
      return 2;
    }
    mesh::MeshContext ctx = mesh::MeshContext::create(*world, mesh::MeshParams{}).value();
    cave::Region region = cave::generate_region(*world, lo, hi);
    std::vector<RoomShape> shapes;
    codec::EncodeOptions options;
    options.normals = false;
    for (const cave::Room& room : region.rooms) {
      auto t0 = std::chrono::steady_clock::now();
      auto m = mesh::build_room_mesh(ctx, room, mesh::Lod::kPatch);
      if (!m) {
        spdlog::error("seed {} room {}: {}", seed, room.id.to_string(), m.error().message);
        return 1;
      }
      auto bytes = codec::encode_room(*m, options);
      if (!bytes) {
        spdlog::error("seed {} room {}: {}", seed, room.id.to_string(), bytes.error().message);
        return 1;
      }
      double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      RoomShape s = measure(*m, room);
      s.floored = cave::floor_height(world->params(), room.sphere).has_value();
      s.bytes = static_cast<double>(bytes->size());
      s.ms = ms;
      shapes.push_back(s);
    }
    std::vector<double> kept, bytes, ms;
    double up = 0, flat = 0;
    int halls = 0;
    size_t max_vertices = 0;
    const RoomShape* largest = nullptr;
    nlohmann::json rooms = nlohmann::json::array();
    for (const RoomShape& s : shapes) {
      bytes.push_back(s.bytes);
      ms.push_back(s.ms);
      max_vertices = std::max(max_vertices, s.vertices);
      if (!largest || s.radius > largest->radius) largest = &s;
      if (s.floored) {
        ++halls;
        up += s.up_area;
        flat += s.flat_area;
      }
      if (s.radius >= big_radius) {
        kept.push_back(s.kept);
        rooms.push_back({{"room", s.id},
                         {"radius", s.radius},
                         {"kept", s.kept},
                         {"kept_m", s.kept_m},
                         {"near10_m", s.near10_m},
                         {"width_m", s.width_m},
                         {"height_m", s.height_m},
                         {"floor", s.floored},
                         {"flat_share", s.up_area > 0 ? s.flat_area / s.up_area : 0},
                         {"bytes", s.bytes},
                         {"vertices", s.vertices}});
      }
    }
    double kept_min = kept.empty() ? 0 : *std::min_element(kept.begin(), kept.end());
    nlohmann::json row = {{"seed", seed},
                          {"rooms", shapes.size()},
                          {"big_rooms", kept.size()},
                          {"kept_median", bench::percentile(kept, 0.5)},
                          {"kept_min", kept_min},
                          {"halls", halls},
                          {"flat_share", up > 0 ? flat / up : 0},
                          {"bytes_p50", bench::percentile(bytes, 0.5)},
                          {"bytes_p99", bench::percentile(bytes, 0.99)},
                          {"bytes_max", bench::percentile(bytes, 1.0)},
                          {"vertices_max", max_vertices},
                          {"ms_per_room_median", bench::percentile(ms, 0.5)},
                          {"ms_per_room_mean",
                           [&] {
                             double sum = 0;
                             for (double x : ms)
                               sum += x;
                             return ms.empty() ? 0 : sum / static_cast<double>(ms.size());
                           }()},
                          {"big", rooms}};
    if (largest) {
      row["largest"] = {{"room", largest->id},         {"radius", largest->radius},
                        {"kept_m", largest->kept_m},   {"near10_m", largest->near10_m},
                        {"width_m", largest->width_m}, {"height_m", largest->height_m}};
      std::printf(
          "| %llu | %zu | %zu | %.2f (%.2f) | %s: %.1f, %.1f, %.1f, %.0f x %.0f | %d | "
          "%.0f%% | %.0f / %.0f / %.0f | %zu | %.2f |\n",
          static_cast<unsigned long long>(seed), shapes.size(), kept.size(),
          bench::percentile(kept, 0.5), kept_min, largest->id.c_str(), largest->radius,
          largest->kept_m, largest->near10_m, largest->width_m, largest->height_m, halls,
          up > 0 ? 100.0 * flat / up : 0.0, bench::percentile(bytes, 0.5),
          bench::percentile(bytes, 0.99), bench::percentile(bytes, 1.0), max_vertices,
          row["ms_per_room_mean"].get<double>());
    }
    report["per_seed"].push_back(row);
  }
  std::ofstream f(json_path);
  f << report.dump(2) << '\n';
  if (!f) {
    spdlog::error("cannot write {}", json_path);
    return 1;
  }
  return 0;
}
