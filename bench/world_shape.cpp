// world_shape: how much space the world has. Builds the patch meshes of every room in a block of
// sectors (CPU path) for some seeds and reports, per seed:
//   - kept radius: per room, the median distance of its vertices from its sphere's centre over the
//     sphere's radius; the median and minimum over the rooms of radius >= --big-radius (8 m);
//   - halls: the largest rooms, their horizontal and vertical extent and their median kept metres;
//   - floor flatness: of the up-facing area of the rooms with a floor (cave::floor_height: the
//     halls), the share within 15 degrees of horizontal (normals face into the cave);
//   - streamed bytes per room (Draco, protocol version 2's layout, normals derived by the client):
//     p50, p99 and the largest, and the largest vertex count;
//   - CPU time per room (prepare + deform + assemble + encode), one thread;
//   - what the halls' floors hold: each hall's formations placed as a client places them
//     (formations::place over the payload decoded, normals derived: protocol 2), its fallen blocks
//     (breakdown: how many, how many of 0.5, 1 and 2 m or more across, the largest) and the
//     placement's time;
//   - the speleothems' colours: how many are 0.15 or more from white in a channel of sRGB;
//   - how the halls' stalagmites gather: of the 2 m cells of the hall's plan within 0.7 of its
//     radius of its centre, the share that hold no stalagmite or column root (water drips along
//     few lines: most of a real floor is bare between clusters).
// Writes a JSON report and prints two Markdown tables (docs/BENCHMARKS.md, "Space in the world"
// and "Breakdown in the halls").
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "bench/flags.hpp"
#include "bench/sector_sample.hpp"
#include "bench/timing.hpp"
#include "common/codec/room_codec.hpp"
#include "common/formations/formations.hpp"
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

// A hall's formations as a client places them.
struct HallFloor {
  std::string id;
  double radius = 0;
  int boulders = 0, over_half = 0, over_1 = 0, over_2 = 0, speleothems = 0;
  int stalagmites = 0;  // stalagmites and columns
  int coloured = 0;     // speleothems whose colour (sRGB) is 0.15 or more from white in a channel
  int iron = 0, manganese = 0;  // of them, orange or brown (tint 0.3-0.8), grey (0.8 or more)
  double bare = 0;              // share of the 2 m cells within 0.7 r holding no stalagmite
  double largest = 0;           // metres across
  double place_ms = 0;          // formations::place, one thread
};

// Decodes `payload` as a protocol 2 client does (no normals: derived from the surface and the
// portal discs) and places its formations.
Result<HallFloor> hall_floor(std::span<const uint8_t> payload, const mesh::RoomMesh& m,
                             const cave::Room& room) {
  codec::DecodeLimits limits;
  limits.normals = false;
  limits.portal_count = static_cast<int>(room.portals.size());
  auto decoded = codec::decode_room(payload, limits);
  if (!decoded) return decoded.error();
  std::vector<codec::PortalDisc> discs;
  for (const cave::Portal& p : room.portals)
    discs.push_back({p.centre, p.normal});
  if (Status st = codec::derive_normals(decoded.value(), m.origin, discs); !st) return st.error();
  HallFloor h;
  h.id = room.id.to_string();
  h.radius = room.sphere.radius;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<formations::FormationShape> placed =
      formations::place(formations::surface_of(decoded.value(), m.origin, room.sphere.radius));
  h.place_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  // The 2 m cells of the plan round the sphere's centre (room frame) within 0.7 r.
  constexpr double kCell = 2.0;
  const Vec3 centre = room.sphere.centre - m.origin;
  const int span = static_cast<int>(std::ceil(0.7 * room.sphere.radius / kCell));
  std::set<std::pair<int, int>> inside, held;
  for (int z = -span; z < span; ++z)
    for (int x = -span; x < span; ++x) {
      const double cx = (x + 0.5) * kCell, cz = (z + 0.5) * kCell;
      if (cx * cx + cz * cz <= 0.49 * room.sphere.radius * room.sphere.radius)
        inside.insert({x, z});
    }
  for (const formations::FormationShape& f : placed) {
    if (f.kind == formations::kFormationStalagmite || f.kind == formations::kFormationColumn) {
      ++h.stalagmites;
      held.insert({static_cast<int>(std::floor((f.root.x - centre.x) / kCell)),
                   static_cast<int>(std::floor((f.root.z - centre.z) / kCell))});
    }
    if (f.kind != formations::kFormationBoulder) {
      ++h.speleothems;
      const glm::vec3 c = formations::formation_srgb(f.tint);
      const bool far = c.r <= 0.85f || c.g <= 0.85f || c.b <= 0.85f;
      h.coloured += far;
      h.iron += f.tint >= 0.3f && f.tint < 0.8f;
      h.manganese += f.tint >= 0.8f;
      continue;
    }
    const double across = 2.0 * f.radius;
    ++h.boulders;
    h.over_half += across >= 0.5;
    h.over_1 += across >= 1.0;
    h.over_2 += across >= 2.0;
    h.largest = std::max(h.largest, across);
  }
  size_t bare = 0;
  for (const auto& cell : inside)
    bare += !held.contains(cell);
  h.bare = inside.empty() ? 1.0 : static_cast<double>(bare) / static_cast<double>(inside.size());
  return h;
}

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
      "meshes of a block of sectors, and the fallen blocks on the halls' floors; writes a JSON "
      "report and prints Markdown tables"};
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
  std::vector<std::pair<uint64_t, std::vector<HallFloor>>> all_floors;
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
    std::vector<HallFloor> floors;
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
      if (s.floored) {
        auto floor = hall_floor(*bytes, *m, room);
        if (!floor) {
          spdlog::error("seed {} room {}: {}", seed, room.id.to_string(), floor.error().message);
          return 1;
        }
        floors.push_back(*floor);
      }
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
    nlohmann::json hall_floors = nlohmann::json::array();
    for (const HallFloor& h : floors)
      hall_floors.push_back({{"room", h.id},
                             {"radius", h.radius},
                             {"boulders", h.boulders},
                             {"boulders_over_0_5m", h.over_half},
                             {"boulders_over_1m", h.over_1},
                             {"boulders_over_2m", h.over_2},
                             {"largest_boulder_m", h.largest},
                             {"speleothems", h.speleothems},
                             {"stalagmites", h.stalagmites},
                             {"coloured", h.coloured},
                             {"iron", h.iron},
                             {"manganese", h.manganese},
                             {"bare_cells", h.bare},
                             {"place_ms", h.place_ms}});
    row["hall_floors"] = hall_floors;
    all_floors.emplace_back(seed, std::move(floors));
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
  std::printf(
      "\n| seed | hall | r m | boulders | of 0.5 / 1 / 2 m or more | largest m | speleothems | "
      "stalagmites | 2 m cells bare | coloured | place ms |\n"
      "| ---: | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n");
  for (const auto& [seed, floors] : all_floors)
    for (const HallFloor& h : floors)
      std::printf(
          "| %llu | %s | %.1f | %d | %d / %d / %d | %.2f | %d | %d | %.0f %% | %.0f %% | %.1f |\n",
          static_cast<unsigned long long>(seed), h.id.c_str(), h.radius, h.boulders, h.over_half,
          h.over_1, h.over_2, h.largest, h.speleothems, h.stalagmites, 100 * h.bare,
          h.speleothems > 0 ? 100.0 * h.coloured / h.speleothems : 0.0, h.place_ms);
  std::ofstream f(json_path);
  f << report.dump(2) << '\n';
  if (!f) {
    spdlog::error("cannot write {}", json_path);
    return 1;
  }
  return 0;
}
