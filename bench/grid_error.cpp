// What quantizing patch rooms on a world grid does to their geometry, for each grid asked
// (--grids, default 1/64 m and 1/32 m): every room of one sector, encoded with protocol version 2
// (no normals) on that grid (the mesh's own grid unchanged; coarser_grid.hpp snaps origins and
// rims first), decoded, and its normals derived as a client does (codec::derive_normals).
// Reports, over every vertex and over the first --rooms rooms (codec_bench's set):
// - the angle between the derived normals and the server's (mesh stage, unquantized positions),
// - how far vertices moved (per axis and in length),
// - triangles that quantization made zero-area or turned over (face normal against the
//   unquantized triangle's), and those it turned by more than 30 degrees,
// - vertices that fell onto another vertex of their room,
// - how far rim vertices lie from their portal's plane (grotto-load --verify allows grid::kStep),
// - rims: decoded positions and derived normals of both rooms of every portal, bit for bit.
// The decoded rooms are compared with the mesh vertex for vertex by quantizing the mesh the way
// Draco's explicit quantization does (floor((v - origin) / step + 0.5) in float32); the tool
// checks that this reproduces the decoded positions exactly. Writes a JSON report and prints a
// Markdown table. Usage: grid_error [--grids 6,5] (the codec's side: codec_bench --grid-step-log2).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "bench/coarser_grid.hpp"
#include "bench/flags.hpp"
#include "common/codec/room_codec.hpp"
#include "common/core/grid.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;
using mesh::core::float3;

constexpr double kDegrees = 180.0 / 3.14159265358979323846;

Vec3 vec(float3 p) {
  return {p.x, p.y, p.z};
}

// Quantiles of a sample (sorted in place).
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// One grid's figures over a set of rooms.
struct Stats {
  std::vector<double> angle, rim_angle, interior_angle;  // degrees
  double max_axis_mm = 0, max_length_mm = 0;
  double rim_plane_mm = 0;   // the farthest rim vertex from its portal's plane
  size_t rim_off_plane = 0;  // rim vertices further than client/stream/verify's tolerance (1 step)
  size_t vertices = 0, triangles = 0, zero_area = 0, flipped = 0, turned_30 = 0;
  size_t coincident = 0;  // vertices on the same point as an earlier vertex of their room
  size_t bytes = 0;

  void add(const Stats& o) {
    angle.insert(angle.end(), o.angle.begin(), o.angle.end());
    rim_angle.insert(rim_angle.end(), o.rim_angle.begin(), o.rim_angle.end());
    interior_angle.insert(interior_angle.end(), o.interior_angle.begin(), o.interior_angle.end());
    max_axis_mm = std::max(max_axis_mm, o.max_axis_mm);
    max_length_mm = std::max(max_length_mm, o.max_length_mm);
    rim_plane_mm = std::max(rim_plane_mm, o.rim_plane_mm);
    rim_off_plane += o.rim_off_plane;
    vertices += o.vertices;
    triangles += o.triangles;
    zero_area += o.zero_area;
    flipped += o.flipped;
    turned_30 += o.turned_30;
    coincident += o.coincident;
    bytes += o.bytes;
  }
};

// The positions Draco's explicit quantization gives `m` (encode_room's origin and range: a grid
// multiple below the lowest offset, step exactly 2^-step_log2), in m's vertex order.
std::vector<float3> quantized_like_draco(const mesh::RoomMesh& m, int step_log2) {
  const double step = 1.0 / static_cast<double>(1 << step_log2);
  double lo[3] = {codec::kMaxOffset, codec::kMaxOffset, codec::kMaxOffset};
  for (const float3& p : m.positions) {
    lo[0] = std::min(lo[0], static_cast<double>(p.x));
    lo[1] = std::min(lo[1], static_cast<double>(p.y));
    lo[2] = std::min(lo[2], static_cast<double>(p.z));
  }
  float origin[3], inverse = static_cast<float>(1 << step_log2), delta = static_cast<float>(step);
  for (int c = 0; c < 3; ++c)
    origin[c] = static_cast<float>(std::floor(lo[c] / step) * step);
  // draco/core/quantization_utils.h (QuantizeFloat, Dequantizer) in float32, as Draco does.
  auto q = [&](float v, int c) {
    const auto i = static_cast<int32_t>(std::floor((v - origin[c]) * inverse + 0.5f));
    return static_cast<float>(i) * delta + origin[c];
  };
  std::vector<float3> out(m.vertex_count());
  for (size_t v = 0; v < out.size(); ++v)
    out[v] = {q(m.positions[v].x, 0), q(m.positions[v].y, 1), q(m.positions[v].z, 2)};
  return out;
}

bool same_multiset(std::vector<float3> a, std::vector<float3> b) {
  auto less = [](const float3& x, const float3& y) {
    return std::tie(x.x, x.y, x.z) < std::tie(y.x, y.y, y.z);
  };
  std::sort(a.begin(), a.end(), less);
  std::sort(b.begin(), b.end(), less);
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float3)) == 0;
}

// Twice the triangle's area along its normal (the orientation the mesh's winding gives).
Vec3 face(Vec3 a, Vec3 b, Vec3 c) {
  return cross(b - a, c - a);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "grid_error: what quantizing patch rooms on a world grid does to their geometry (derived "
      "normals against the server's, displacement, degenerate and flipped triangles, rims), with "
      "a JSON report"};
  std::string json_path = "grid_error.json";
  uint64_t seed = 7;  // every binary's default world
  int room_count = 100;
  std::vector<int> grids = {grid::kStepLog2, grid::kStepLog2 - 1};
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--seed", seed, "World seed (sector 0,0,0)")->capture_default_str();
  app.add_option("--rooms", room_count, "Also report the first N rooms alone (codec_bench's set)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--grids", grids, "Grid steps as log2 of 1/step, at most the mesh's grid")
      ->delimiter(',')
      ->check(CLI::Range(0, grid::kStepLog2))
      ->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  std::vector<mesh::RoomMesh> meshes;
  std::vector<const cave::Room*> rooms;
  for (const cave::Room& r : region.rooms) {
    auto m = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
    if (!m) continue;
    meshes.push_back(std::move(m).value());
    rooms.push_back(&r);
  }
  spdlog::info("grid_error seed={} rooms={}", seed, meshes.size());

  nlohmann::json report;
  report["seed"] = seed;
  report["rooms"] = meshes.size();
  report["first_rooms"] = room_count;
  std::printf(
      "| grid | rooms | payload B | derived vs server normals, deg: median / p99 / max (rim "
      "p99, interior p99) | max move per axis / length, mm | zero-area / flipped / turned > 30 "
      "deg triangles | coincident vertices | rims | origins / rim vertices snapped | rim off "
      "plane: max mm, over 1/64 m |\n"
      "| --- | --- | ---: | --- | --- | --- | ---: | --- | --- | --- |\n");
  for (int step_log2 : grids) {
    codec::EncodeOptions options;
    options.grid_step_log2 = step_log2;
    options.normals = false;
    codec::DecodeLimits limits;
    limits.normals = false;
    Stats first, all;
    size_t moved_origins = 0, moved_rims = 0, rim_vertices = 0, mismatched_rooms = 0;
    size_t refused_unsnapped =
        0;  // rooms encode_room refuses on this grid as the mesh stage made them
    std::map<cave::RoomId, std::pair<codec::DecodedRoom, Vec3>> decoded;
    for (size_t i = 0; i < meshes.size(); ++i) {
      const mesh::RoomMesh& m = meshes[i];
      const mesh::RoomMesh g = bench::on_coarser_grid(m, step_log2);
      moved_origins += g.origin == m.origin ? 0 : 1;
      refused_unsnapped += codec::encode_room(m, options).ok() ? 0 : 1;
      std::vector<codec::PortalDisc> discs;
      for (const cave::Portal& p : rooms[i]->portals)
        discs.push_back({p.centre, p.normal});
      Stats s;
      auto bytes = codec::encode_room(g, options);
      if (!bytes) {
        spdlog::error("event=encode_failed room={} error=\"{}\"", m.id.to_string(),
                      bytes.error().message);
        return 1;
      }
      s.bytes = bytes->size();
      codec::DecodedRoom d = codec::decode_room(bytes.value(), limits).value();
      if (!codec::derive_normals(d, g.origin, discs).ok()) return 1;
      // The same room quantized here, in the mesh's vertex order; its normals as a client derives.
      codec::DecodedRoom q;
      q.positions = quantized_like_draco(g, step_log2);
      if (!same_multiset(q.positions, d.positions)) ++mismatched_rooms;
      q.roughness = m.roughness;
      q.mineral = m.mineral;
      q.rim_portal = m.rim_portal;
      q.rim_index = m.rim_index;
      q.indices = m.indices;
      if (!codec::derive_normals(q, g.origin, discs).ok()) return 1;
      decoded.emplace(m.id, std::pair{std::move(d), g.origin});

      std::map<std::tuple<float, float, float>, int> seen;
      for (size_t v = 0; v < m.vertex_count(); ++v) {
        const bool rim = m.rim_portal[v] >= 0;
        rim_vertices += rim ? 1 : 0;
        moved_rims += rim && !(g.world_position(v) == m.world_position(v)) ? 1 : 0;
        const Vec3 a = vec(q.normals[v]), b = vec(m.normals[v]);
        const double angle = std::acos(std::clamp(dot(a, b), -1.0, 1.0)) * kDegrees;
        s.angle.push_back(angle);
        (rim ? s.rim_angle : s.interior_angle).push_back(angle);
        const Vec3 moved = (g.origin + vec(q.positions[v])) - m.world_position(v);
        s.max_axis_mm = std::max({s.max_axis_mm, 1e3 * std::fabs(moved.x), 1e3 * std::fabs(moved.y),
                                  1e3 * std::fabs(moved.z)});
        s.max_length_mm = std::max(s.max_length_mm, 1e3 * length(moved));
        if (rim) {
          const cave::Portal& portal = rooms[i]->portals[m.rim_portal[v]];
          const double off =
              std::fabs(dot(g.origin + vec(q.positions[v]) - portal.centre, portal.normal));
          s.rim_plane_mm = std::max(s.rim_plane_mm, 1e3 * off);
          if (off > grid::kStep) ++s.rim_off_plane;
        }
        const float3 p = q.positions[v];
        if (!seen.emplace(std::tuple{p.x, p.y, p.z}, 0).second) ++s.coincident;
      }
      s.vertices = m.vertex_count();
      s.triangles = m.triangle_count();
      for (size_t t = 0; t < m.indices.size(); t += 3) {
        const uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
        const Vec3 before = face(vec(m.positions[a]), vec(m.positions[b]), vec(m.positions[c]));
        // Grid values: the differences and the cross product are exact in binary64.
        const Vec3 after = face(vec(q.positions[a]), vec(q.positions[b]), vec(q.positions[c]));
        if (after.x == 0 && after.y == 0 && after.z == 0) {
          ++s.zero_area;
          continue;
        }
        const double cosine = dot(before, after) / (length(before) * length(after));
        if (cosine < 0) ++s.flipped;
        if (cosine < std::cos(30.0 / kDegrees)) ++s.turned_30;
      }
      if (static_cast<int>(i) < room_count) first.add(s);
      all.add(s);
    }
    // Rims: both rooms of every portal within the sector, decoded alone, bit for bit.
    size_t portals = 0, differing_portals = 0;
    for (size_t i = 0; i < rooms.size(); ++i) {
      const cave::Room& a = *rooms[i];
      for (size_t sa = 0; sa < a.portals.size(); ++sa) {
        const cave::RoomId b_id = a.portals[sa].neighbour;
        if (!(a.id < b_id) || !decoded.count(b_id)) continue;
        const cave::Room* b = region.find(b_id);
        int sb = -1;
        for (size_t k = 0; k < b->portals.size(); ++k)
          if (b->portals[k].neighbour == a.id) sb = static_cast<int>(k);
        auto rim_of = [&](cave::RoomId id, int slot) {
          const auto& [d, origin] = decoded.at(id);
          std::map<uint16_t, std::pair<Vec3, float3>> rim;
          for (size_t v = 0; v < d.vertex_count(); ++v)
            if (d.rim_portal[v] == slot)
              rim[d.rim_index[v]] = {origin + vec(d.positions[v]), d.normals[v]};
          return rim;
        };
        const auto ra = rim_of(a.id, static_cast<int>(sa)), rb = rim_of(b_id, sb);
        bool same = ra.size() == rb.size() && !ra.empty();
        for (const auto& [k, va] : ra) {
          auto it = rb.find(k);
          same = same && it != rb.end() &&
                 std::memcmp(&va.first, &it->second.first, sizeof(Vec3)) == 0 &&
                 std::memcmp(&va.second, &it->second.second, sizeof(float3)) == 0;
        }
        ++portals;
        differing_portals += same ? 0 : 1;
      }
    }
    spdlog::info("grid_error grid_step_log2={} rooms_refused_unsnapped={}", step_log2,
                 refused_unsnapped);
    if (mismatched_rooms > 0) {
      spdlog::warn("event=quantization_not_reproduced grid_step_log2={} rooms={}", step_log2,
                   mismatched_rooms);
    }
    const std::string name = "1/" + std::to_string(1 << step_log2) + " m";
    nlohmann::json grid_report = {{"grid_step_log2", step_log2},
                                  {"rooms_refused_unsnapped", refused_unsnapped},
                                  {"origins_snapped", moved_origins},
                                  {"rim_vertices", rim_vertices},
                                  {"rim_vertices_moved", moved_rims},
                                  {"rooms_not_reproduced", mismatched_rooms},
                                  {"portals", portals},
                                  {"portals_differing", differing_portals}};
    for (auto [label, st] : {std::pair<const char*, Stats*>{"sector", &all}, {"first", &first}}) {
      const double rooms_in =
          label == std::string("sector")
              ? static_cast<double>(meshes.size())
              : static_cast<double>(std::min<size_t>(room_count, meshes.size()));
      nlohmann::json j = {{"rooms", rooms_in},
                          {"vertices", st->vertices},
                          {"triangles", st->triangles},
                          {"payload_bytes", st->bytes},
                          {"angle_median_deg", quantile(st->angle, 0.5)},
                          {"angle_p99_deg", quantile(st->angle, 0.99)},
                          {"angle_max_deg", quantile(st->angle, 1.0)},
                          {"rim_angle_p99_deg", quantile(st->rim_angle, 0.99)},
                          {"rim_angle_max_deg", quantile(st->rim_angle, 1.0)},
                          {"interior_angle_median_deg", quantile(st->interior_angle, 0.5)},
                          {"interior_angle_p99_deg", quantile(st->interior_angle, 0.99)},
                          {"interior_angle_max_deg", quantile(st->interior_angle, 1.0)},
                          {"max_move_per_axis_mm", st->max_axis_mm},
                          {"max_move_mm", st->max_length_mm},
                          {"rim_plane_max_mm", st->rim_plane_mm},
                          {"rim_vertices_off_plane_over_kstep", st->rim_off_plane},
                          {"zero_area_triangles", st->zero_area},
                          {"flipped_triangles", st->flipped},
                          {"turned_over_30_deg_triangles", st->turned_30},
                          {"coincident_vertices", st->coincident}};
      grid_report[label] = j;
      std::printf(
          "| %s | %s (%.0f) | %zu | %.2f / %.2f / %.2f (%.2f, %.2f) | %.1f / %.1f | %zu / %zu / "
          "%zu "
          "of %zu | %zu | %zu portals, %zu differ | %zu / %zu of %zu | %.1f, %zu |\n",
          name.c_str(), label, rooms_in, st->bytes, j["angle_median_deg"].get<double>(),
          j["angle_p99_deg"].get<double>(), j["angle_max_deg"].get<double>(),
          j["rim_angle_p99_deg"].get<double>(), j["interior_angle_p99_deg"].get<double>(),
          st->max_axis_mm, st->max_length_mm, st->zero_area, st->flipped, st->turned_30,
          st->triangles, st->coincident, portals, differing_portals, moved_origins, moved_rims,
          rim_vertices, st->rim_plane_mm, st->rim_off_plane);
    }
    report["grids"].push_back(grid_report);
  }
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
