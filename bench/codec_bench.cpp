// The room codec against its budget and a peer, in one run: bytes per streamed patch room and
// encode/decode time per room at several Draco settings, against the raw float32 detail room
// (positions + normals + indices, what a client would otherwise need) and against meshoptimizer's
// vertex/index codec on the same quantized data. One thread; per room the median over
// repetitions, then the median, mean and (decode) maximum over rooms, and the bits per vertex of
// positions and connectivity alone (codec::encode_geometry_only). Writes a JSON report and prints
// a Markdown table; --profile-loops only encodes and decodes, for a profiler. Command and results:
// docs/BENCHMARKS.md ("Room codec"); bench/codec_levers.cpp compares Draco's levers one by one.
// --grid-step-log2 measures another world grid for the encoder (coarser_grid.hpp).
#include <draco/compression/decode.h>
#include <meshoptimizer.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "bench/coarser_grid.hpp"
#include "bench/flags.hpp"
#include "bench/timing.hpp"
#include "common/codec/room_codec.hpp"
#include "common/core/grid.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;
using bench::median;
using bench::median_ms;

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v)
    s += x;
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}

double max_of(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
}

// Per room: bytes, bytes of positions and connectivity alone (Draco rows), encode ms, decode ms.
struct Row {
  std::string name;
  std::vector<double> bytes, geometry_bytes, encode_ms, decode_ms;
};

// The meshoptimizer peer's vertex, quantized like the Draco payload (positions on the same grid,
// as 16-bit grid units from the room's lowest corner; 8-bit normals; 8-bit channels; the rim
// attribute as two uint16), 16 bytes as meshopt's codec wants (a multiple of 4).
struct PeerVertex {
  uint16_t p[3];
  int8_t n[3];
  uint8_t pad;
  uint8_t c[2];
  uint16_t rim[2];
};
static_assert(sizeof(PeerVertex) == 16);

struct PeerEncoded {
  std::vector<unsigned char> vertices, indices;
  size_t vertex_count = 0, index_count = 0;
};

PeerEncoded peer_encode(const mesh::RoomMesh& m, double step) {
  float lo[3] = {1e30f, 1e30f, 1e30f};
  for (const auto& p : m.positions) {
    lo[0] = std::min(lo[0], p.x);
    lo[1] = std::min(lo[1], p.y);
    lo[2] = std::min(lo[2], p.z);
  }
  auto q16 = [step](float v, float origin) {
    return static_cast<uint16_t>(std::lround((v - origin) / step));
  };
  auto s8 = [](float v) { return static_cast<int8_t>(std::lround(v * 127.0f)); };
  auto u8 = [](float v) { return static_cast<uint8_t>(std::lround(v * 255.0f)); };
  std::vector<PeerVertex> verts(m.vertex_count());
  for (size_t v = 0; v < verts.size(); ++v) {
    const auto p = m.positions[v], n = m.normals[v];
    verts[v] = {{q16(p.x, lo[0]), q16(p.y, lo[1]), q16(p.z, lo[2])},
                {s8(n.x), s8(n.y), s8(n.z)},
                0,
                {u8(m.roughness[v]), u8(m.mineral[v])},
                {static_cast<uint16_t>(m.rim_portal[v] + 1), m.rim_index[v]}};
  }
  std::vector<unsigned int> indices(m.indices.size());
  meshopt_optimizeVertexCache(indices.data(), m.indices.data(), indices.size(), verts.size());
  std::vector<PeerVertex> fetched(verts.size());
  const size_t vc = meshopt_optimizeVertexFetch(fetched.data(), indices.data(), indices.size(),
                                                verts.data(), verts.size(), sizeof(PeerVertex));
  PeerEncoded out;
  out.vertex_count = vc;
  out.index_count = indices.size();
  out.vertices.resize(meshopt_encodeVertexBufferBound(vc, sizeof(PeerVertex)));
  out.vertices.resize(meshopt_encodeVertexBuffer(out.vertices.data(), out.vertices.size(),
                                                 fetched.data(), vc, sizeof(PeerVertex)));
  out.indices.resize(meshopt_encodeIndexBufferBound(indices.size(), vc));
  out.indices.resize(meshopt_encodeIndexBuffer(out.indices.data(), out.indices.size(),
                                               indices.data(), indices.size()));
  return out;
}

size_t raw_bytes(const mesh::RoomMesh& m) {
  return m.vertex_count() * (3 + 3) * sizeof(float) + m.indices.size() * sizeof(uint32_t);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "codec_bench: bytes and encode/decode time per streamed patch room at several Draco "
      "settings, against the raw float32 detail room and meshoptimizer, with a JSON report"};
  std::string json_path = "codec_bench.json";
  int reps = 5, room_count = 100;
  uint64_t seed = 7;  // every binary's default world
  int profile_loops = 0;
  int grid_step_log2 = grid::kStepLog2;
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--repetitions", reps, "Runs per room and setting (the median is kept)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--rooms", room_count, "Rooms measured")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--seed", seed, "World seed")->capture_default_str();
  app.add_option("--profile-loops", profile_loops,
                 "Only encode, decode and derive the normals of every room this many times as "
                 "the default protocol (version 2) does, for a profiler (perf record, "
                 "callgrind), and report nothing")
      ->check(CLI::Range(0, 100000));
  app.add_option(
         "--grid-step-log2", grid_step_log2,
         "Quantize positions on the world grid of step 2^-N m (EncodeOptions::grid_step_log2); "
         "below the mesh's grid, origins and rims are snapped to it first")
      ->check(CLI::Range(0, grid::kStepLog2))
      ->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  std::vector<mesh::RoomMesh> patch, detail;
  std::vector<std::vector<codec::PortalDisc>> discs;  // patch[i]'s portals, for version 2 decoding
  for (const cave::Room& r : region.rooms) {
    if (static_cast<int>(patch.size()) == room_count) break;
    auto p = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
    auto d = mesh::build_room_mesh(ctx, r, mesh::Lod::kDetail);
    if (!p || !d) continue;
    patch.push_back(bench::on_coarser_grid(p.value(), grid_step_log2));
    detail.push_back(std::move(d).value());
    discs.emplace_back();
    for (const cave::Portal& portal : r.portals)
      discs.back().push_back({portal.centre, portal.normal});
  }
  spdlog::info("codec_bench rooms={} reps={} grid_step_log2={}", patch.size(), reps,
               grid_step_log2);
  codec::EncodeOptions defaults;
  defaults.grid_step_log2 = grid_step_log2;
  if (profile_loops > 0) {
    // What a server and a client do with the default protocol (version 2): no normal attribute,
    // the client derives them.
    codec::EncodeOptions served = defaults;
    served.normals = false;
    codec::DecodeLimits limits;
    limits.normals = false;
    size_t total = 0;
    for (int i = 0; i < profile_loops; ++i) {
      for (size_t r = 0; r < patch.size(); ++r) {
        std::vector<uint8_t> bytes = codec::encode_room(patch[r], served).value();
        codec::DecodedRoom room = codec::decode_room(bytes, limits).value();
        if (!codec::derive_normals(room, patch[r].origin, discs[r])) return 1;
        total += room.vertex_count();
      }
    }
    spdlog::info("codec_bench profile loops={} vertices={}", profile_loops, total);
    return 0;
  }

  std::vector<double> raw_detail, raw_patch, patch_vertices;
  for (size_t i = 0; i < patch.size(); ++i) {
    raw_detail.push_back(static_cast<double>(raw_bytes(detail[i])));
    raw_patch.push_back(static_cast<double>(raw_bytes(patch[i])));
    patch_vertices.push_back(static_cast<double>(patch[i].vertex_count()));
  }

  std::vector<Row> rows;
  auto measure_draco = [&](const std::string& name, codec::EncodeOptions opt) {
    Row row{name, {}, {}, {}, {}};
    codec::DecodeLimits limits;
    limits.normals = opt.normals;
    for (size_t i = 0; i < patch.size(); ++i) {
      const mesh::RoomMesh& m = patch[i];
      std::vector<uint8_t> bytes;
      row.encode_ms.push_back(median_ms(reps, [&] { bytes = codec::encode_room(m, opt).value(); }));
      row.bytes.push_back(static_cast<double>(bytes.size()));
      row.geometry_bytes.push_back(
          static_cast<double>(codec::encode_geometry_only(codec::view_of(m), opt).value().size()));
      // Version 2's decode includes deriving the normals, as a client does.
      row.decode_ms.push_back(median_ms(reps, [&] {
        auto d = codec::decode_room(bytes, limits);
        if (!d) std::abort();
        if (!opt.normals && !codec::derive_normals(d.value(), m.origin, discs[i]).ok())
          std::abort();
      }));
    }
    rows.push_back(std::move(row));
  };
  auto label = [](const codec::EncodeOptions& o) {
    return "draco speed " + std::to_string(o.speed) + ", normals " + std::to_string(o.normal_bits) +
           ", channels " + std::to_string(o.channel_bits);
  };
  // Speed (edgebreaker traversal and prediction schemes) at the default quantization.
  for (int speed : {0, 3, 5, 7, 9}) {
    codec::EncodeOptions opt = defaults;
    opt.speed = speed;
    measure_draco(label(opt), opt);
  }
  // Quantization of normals and channels at the default speed.
  for (auto [normal_bits, channel_bits] :
       {std::pair{10, 8}, {8, 8}, {8, 7}, {8, 6}, {8, 5}, {7, 6}, {7, 5}}) {
    codec::EncodeOptions opt = defaults;
    opt.normal_bits = normal_bits;
    opt.channel_bits = channel_bits;
    measure_draco(label(opt), opt);
  }
  measure_draco(label(defaults) + " (protocol 1)", defaults);
  codec::EncodeOptions v2 = defaults;
  v2.normals = false;
  measure_draco("draco speed 3, no normals (derived on decode), channels 6 (protocol 2)", v2);
  // Protocol 2 at the faster speeds (no valence coding): what a hall's encode would save.
  for (int speed : {5, 7}) {
    codec::EncodeOptions faster = v2;
    faster.speed = speed;
    measure_draco("draco speed " + std::to_string(speed) + ", protocol 2", faster);
  }

  // Protocol 2's normals alone: derive_normals on a decoded room.
  {
    Row row{"codec::derive_normals alone (protocol 2's decode includes it)", {}, {}, {}, {}};
    codec::DecodeLimits limits;
    limits.normals = false;
    for (size_t i = 0; i < patch.size(); ++i) {
      std::vector<uint8_t> bytes = codec::encode_room(patch[i], v2).value();
      codec::DecodedRoom d = codec::decode_room(bytes, limits).value();
      row.bytes.push_back(static_cast<double>(bytes.size()));
      row.decode_ms.push_back(median_ms(reps, [&] {
        if (!codec::derive_normals(d, patch[i].origin, discs[i]).ok()) std::abort();
      }));
    }
    rows.push_back(std::move(row));
  }

  // Draco's decoder alone (no validation, no copy into DecodedRoom), default settings.
  {
    Row row{"draco::Decoder alone, default settings", {}, {}, {}, {}};
    for (const mesh::RoomMesh& m : patch) {
      std::vector<uint8_t> bytes = codec::encode_room(m, defaults).value();
      row.bytes.push_back(static_cast<double>(bytes.size()));
      row.decode_ms.push_back(median_ms(reps, [&] {
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size());
        draco::Decoder decoder;
        if (!decoder.DecodeMeshFromBuffer(&buffer).ok()) std::abort();
      }));
    }
    rows.push_back(std::move(row));
  }

  // The peer: meshoptimizer's vertex and index codecs after its vertex cache and fetch passes.
  {
    Row row{
        "meshoptimizer vertex+index codec (16-bit grid positions, 8-bit normals)", {}, {}, {}, {}};
    for (const mesh::RoomMesh& m : patch) {
      PeerEncoded enc;
      row.encode_ms.push_back(
          median_ms(reps, [&] { enc = peer_encode(m, 1.0 / (1 << grid_step_log2)); }));
      row.bytes.push_back(static_cast<double>(enc.vertices.size() + enc.indices.size()));
      std::vector<PeerVertex> verts(enc.vertex_count);
      std::vector<unsigned int> indices(enc.index_count);
      row.decode_ms.push_back(median_ms(reps, [&] {
        if (meshopt_decodeVertexBuffer(verts.data(), enc.vertex_count, sizeof(PeerVertex),
                                       enc.vertices.data(), enc.vertices.size()) != 0 ||
            meshopt_decodeIndexBuffer(indices.data(), enc.index_count, sizeof(unsigned int),
                                      enc.indices.data(), enc.indices.size()) != 0) {
          std::abort();
        }
      }));
    }
    rows.push_back(std::move(row));
  }

  nlohmann::json report;
  report["rooms"] = patch.size();
  report["repetitions"] = reps;
  report["seed"] = seed;
  report["grid_step_log2"] = grid_step_log2;
  report["patch_vertices_per_room_median"] = median(patch_vertices);
  report["raw_detail_bytes_per_room_median"] = median(raw_detail);
  report["raw_detail_bytes_per_room_mean"] = mean(raw_detail);
  report["raw_patch_bytes_per_room_median"] = median(raw_patch);
  nlohmann::json settings = nlohmann::json::array();
  std::printf(
      "rooms %zu, patch vertices/room (median) %.0f, raw float32 detail room %.0f B, "
      "raw float32 patch room %.0f B\n\n",
      patch.size(), median(patch_vertices), median(raw_detail), median(raw_patch));
  std::printf(
      "| setting | bytes/room (median) | bytes/room (mean) | raw detail / bytes | positions + "
      "connectivity bits/vertex | encode ms/room (median / mean) | decode ms/room (median / mean "
      "/ max) |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n");
  for (const Row& r : rows) {
    std::vector<double> ratio, geometry_bits;
    double geometry_total = 0, vertex_total = 0;
    for (size_t i = 0; i < r.bytes.size(); ++i)
      ratio.push_back(raw_detail[i] / r.bytes[i]);
    for (size_t i = 0; i < r.geometry_bytes.size(); ++i) {
      geometry_bits.push_back(8.0 * r.geometry_bytes[i] / patch_vertices[i]);
      geometry_total += 8.0 * r.geometry_bytes[i];
      vertex_total += patch_vertices[i];
    }
    nlohmann::json s = {{"name", r.name},
                        {"bytes_median", median(r.bytes)},
                        {"bytes_mean", mean(r.bytes)},
                        {"raw_detail_ratio_median", median(ratio)},
                        {"raw_detail_ratio_of_means", mean(raw_detail) / mean(r.bytes)},
                        {"decode_ms_median", median(r.decode_ms)},
                        {"decode_ms_mean", mean(r.decode_ms)},
                        {"decode_ms_max", max_of(r.decode_ms)}};
    if (!r.encode_ms.empty()) {
      s["encode_ms_median"] = median(r.encode_ms);
      s["encode_ms_mean"] = mean(r.encode_ms);
      s["encode_ms_max"] = max_of(r.encode_ms);
    }
    char encode[48] = "–", bits[48] = "–";
    if (!r.encode_ms.empty()) {
      std::snprintf(encode, sizeof encode, "%.3f / %.3f", median(r.encode_ms), mean(r.encode_ms));
    }
    if (!r.geometry_bytes.empty()) {
      // Per room (median), and over all rooms' bits and vertices.
      s["geometry_bytes_median"] = median(r.geometry_bytes);
      s["geometry_bits_per_vertex_median"] = median(geometry_bits);
      s["geometry_bits_per_vertex_overall"] = geometry_total / vertex_total;
      std::snprintf(bits, sizeof bits, "%.1f (%.0f B)", median(geometry_bits),
                    median(r.geometry_bytes));
    }
    settings.push_back(s);
    std::printf("| %s | %.0f | %.0f | %.1f | %s | %s | %.3f / %.3f / %.3f |\n", r.name.c_str(),
                median(r.bytes), mean(r.bytes), median(ratio), bits, encode, median(r.decode_ms),
                mean(r.decode_ms), max_of(r.decode_ms));
  }
  report["settings"] = settings;
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
