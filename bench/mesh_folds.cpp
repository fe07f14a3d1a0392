// mesh_folds: counts folded triangles in the room meshes of many sectors (mesh_sweep's draw of
// sectors, the CPU path) and says where they are and which stage made them.
//
// A triangle is folded when its face normal points against the sum of its corners' normals (the
// area-weighted vertex normals the mesh carries) or when it meets a neighbour across an interior
// edge at more than --fold-degrees (150); fold_edges counts those edges. For each folded triangle:
// whether it is a stitch triangle (a corner on a canonical rim) or a donor triangle, its distance
// to the nearest portal disc and plane, its world centroid (for grotto-client --pose), and the
// room's largest portal radius over its sphere radius and, with two portals, how they face
// each other (-dot of the normals); rooms of two portals are also counted by that facing, all
// and folded. With --stages, each room with a fold is deformed again without the surface and
// big-room noise (spline blend and roundness only), and again without roundness, and the same
// donor triangles are judged in those surfaces: a fold already in the noiseless surface comes
// from the spline blend, one that needs the noise from a displacement larger than the local
// spacing. It also gives the noise displacement's spread over the triangle against its edge, and
// how far the undeformed donor corners lie from a portal's axis line (the centre along the
// normal), where grotto_rim_direction turns fastest. Writes a JSON report and prints one line per
// seed and lod (docs/BENCHMARKS.md, "Folded triangles").
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <unordered_map>

#include "bench/flags.hpp"
#include "bench/sector_sample.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;
using mesh::core::float3;

constexpr double kDegrees = 180.0 / 3.14159265358979323846;

Vec3 vec(float3 p) {
  return {p.x, p.y, p.z};
}

// Distance from p (room frame) to a portal's disc, and its height above the plane (room side +).
std::pair<double, double> portal_distance(const mesh::core::GrottoPortal& g, Vec3 p) {
  Vec3 c{g.cx, g.cy, g.cz}, n{g.nx, g.ny, g.nz};
  Vec3 rel = p - c;
  double h = -dot(rel, n);
  Vec3 in_plane = rel + n * h;
  double beyond = std::max(0.0, length(in_plane) - g.radius);
  return {std::sqrt(h * h + beyond * beyond), h};
}

struct FoldedTriangle {
  bool stitch = false;                // a corner on a canonical rim
  double portal_distance = 0;         // to the nearest portal disc, metres
  double plane_height = 0;            // to the nearest portal plane (room side positive), metres
  double worst_dihedral = 0;          // the largest angle to a neighbour's normal, degrees
  double area = 0;                    // m^2
  std::array<uint32_t, 3> corners{};  // mesh vertex indices
  Vec3 centre;                        // the centroid in world coordinates
  // --stages, donor triangles only: the donor triangle and whether it is folded in the full
  // deformation, without noise, and without noise or roundness; the largest noise displacement
  // of a corner, the largest difference between two corners' and the longest edge without noise.
  int donor_triangle = -1;
  std::array<uint32_t, 3> donor_corners{};
  bool donor_folded = false, folded_without_noise = false,
       folded_without_noise_or_roundness = false;
  double noise = 0, noise_spread = 0, smooth_edge = 0;
  // The donor sphere's points of its corners: the smallest distance to a portal's axis line
  // (where grotto_rim_direction turns fastest), metres, and that portal's index.
  double axis_offset = 0;
  int axis_portal = -1;
};

struct RoomFolds {
  std::string room;
  std::string lod;
  size_t triangles = 0;
  size_t fold_edges = 0;
  std::vector<FoldedTriangle> folded;
  double room_radius = 0, largest_portal_ratio = 0;
  double facing = 0;  // two portals: -dot of their normals (1: straight across, -1: side by side)
  int portals = 0;
  int donor_folded = -1;  // --stages: folded triangles of the deformed donor (kept ones)
};

// Folds in a finished mesh.
void find_folds(const mesh::RoomMesh& m, const mesh::DeformInput& in, double fold_degrees,
                RoomFolds& out) {
  const size_t nt = m.triangle_count();
  out.triangles = nt;
  std::vector<Vec3> face(nt);
  std::vector<double> worst(nt, 0.0);
  for (size_t t = 0; t < nt; ++t) {
    Vec3 a = vec(m.positions[m.indices[3 * t]]);
    face[t] = cross(vec(m.positions[m.indices[3 * t + 1]]) - a,
                    vec(m.positions[m.indices[3 * t + 2]]) - a);
  }
  std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> edges;
  edges.reserve(2 * nt);
  for (size_t t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      uint64_t a = m.indices[3 * t + k], b = m.indices[3 * t + (k + 1) % 3];
      uint64_t key = std::min(a, b) << 32 | std::max(a, b);
      auto [it, fresh] = edges.try_emplace(key, static_cast<uint32_t>(t), UINT32_MAX);
      if (!fresh) it->second.second = static_cast<uint32_t>(t);
    }
  }
  for (const auto& [key, tt] : edges) {
    if (tt.second == UINT32_MAX) continue;
    double la = length(face[tt.first]), lb = length(face[tt.second]);
    if (la == 0 || lb == 0) continue;
    double c = std::clamp(dot(face[tt.first], face[tt.second]) / (la * lb), -1.0, 1.0);
    double angle = std::acos(c) * kDegrees;
    worst[tt.first] = std::max(worst[tt.first], angle);
    worst[tt.second] = std::max(worst[tt.second], angle);
    if (angle > fold_degrees) ++out.fold_edges;
  }
  for (size_t t = 0; t < nt; ++t) {
    Vec3 vn{0, 0, 0};
    bool stitch = false;
    Vec3 centroid{0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      uint32_t v = m.indices[3 * t + k];
      vn = vn + vec(m.normals[v]);
      stitch = stitch || m.rim_portal[v] >= 0;
      centroid = centroid + vec(m.positions[v]) * (1.0 / 3.0);
    }
    if (!(dot(face[t], vn) < 0) && !(worst[t] > fold_degrees)) continue;
    FoldedTriangle f;
    f.stitch = stitch;
    f.worst_dihedral = worst[t];
    f.area = 0.5 * length(face[t]);
    f.portal_distance = 1e300;
    f.plane_height = 1e300;
    for (const auto& g : in.portals) {
      auto [d, h] = portal_distance(g, centroid);
      f.portal_distance = std::min(f.portal_distance, d);
      f.plane_height = std::min(f.plane_height, h);
    }
    for (int k = 0; k < 3; ++k)
      f.corners[k] = m.indices[3 * t + k];
    f.centre = m.origin + centroid;
    out.folded.push_back(f);
  }
}

// The same test on the deformed donor sphere, before any cut or stitch, for the triangles marked in
// `kept`: folded[t] when t's normal points against the sum of its corners' area-weighted normals
// (over kept triangles) or meets a kept neighbour at more than fold_degrees.
std::vector<char> donor_folds(const mesh::DonorSphere& d, std::span<const float3> pos,
                              const std::vector<char>& kept, double fold_degrees) {
  const size_t nt = d.indices.size() / 3;
  std::vector<Vec3> face(nt), vn(d.directions.size(), Vec3{0, 0, 0});
  for (size_t t = 0; t < nt; ++t) {
    uint32_t a = d.indices[3 * t], b = d.indices[3 * t + 1], c = d.indices[3 * t + 2];
    face[t] = cross(vec(pos[b]) - vec(pos[a]), vec(pos[c]) - vec(pos[a]));
    if (!kept[t]) continue;
    for (uint32_t v : {a, b, c})
      vn[v] = vn[v] + face[t];
  }
  std::vector<char> out(nt, 0);
  for (size_t t = 0; t < nt; ++t) {
    if (!kept[t]) continue;
    Vec3 s = vn[d.indices[3 * t]] + vn[d.indices[3 * t + 1]] + vn[d.indices[3 * t + 2]];
    bool fold = dot(face[t], s) < 0;
    for (int k = 0; k < 3 && !fold; ++k) {
      uint32_t u = d.neighbours[3 * t + k];
      double la = length(face[t]), lb = length(face[u]);
      if (!kept[u] || la == 0 || lb == 0) continue;
      double angle = std::acos(std::clamp(dot(face[t], face[u]) / (la * lb), -1.0, 1.0));
      fold = angle * kDegrees > fold_degrees;
    }
    out[t] = fold;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mesh_folds: count folded triangles in the room meshes of many sectors (CPU path), where "
      "they lie and which deformation stage folds them; writes a JSON report"};
  std::vector<uint64_t> seeds{7, 42};
  int sample = 20, spread = 1000, threads = 1;
  uint64_t sample_seed = 1;
  double fold_degrees = 150;
  bool stages = false;
  std::vector<std::string> lod_names{"patch", "detail"};
  std::string json_path = "mesh_folds.json";
  app.add_option("--seed", seeds, "World seeds")->capture_default_str();
  app.add_option("--sectors", sample, "Sectors drawn at random per seed (as mesh_sweep)")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--spread", spread, "Sectors are drawn from [-spread, spread] on each axis")
      ->check(CLI::Range(0, static_cast<int>(cave::kSectorCoordLimit)))
      ->capture_default_str();
  app.add_option("--sample-seed", sample_seed, "Seed of the random draw of sectors")
      ->capture_default_str();
  app.add_option("--lod", lod_names, "Levels of detail")
      ->check(CLI::IsMember(std::vector<std::string>{"detail", "patch"}))
      ->capture_default_str();
  app.add_option("--fold-degrees", fold_degrees, "Dihedral angle that counts as a fold")
      ->check(CLI::Range(90.0, 180.0))
      ->capture_default_str();
  app.add_flag("--stages", stages, "Deform rooms with folds again without noise / roundness");
  app.add_option("--threads", threads, "Worker threads")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  nlohmann::json report;
  report["fold_degrees"] = fold_degrees;
  report["per_seed"] = nlohmann::json::array();
  for (uint64_t seed : seeds) {
    auto world = cave::World::create(seed, cave::LayoutParams{});
    if (!world) {
      spdlog::error("seed {}: {}", seed, world.error().message);
      return 2;
    }
    mesh::MeshParams params;
    mesh::MeshContext ctx = mesh::MeshContext::create(*world, params).value();
    // Without the surface and big-room octaves: the spline blend and roundness only.
    mesh::MeshParams smooth_params = params;
    smooth_params.octave_amplitude.fill(0.0);
    smooth_params.big_amplitude = 0;
    mesh::MeshContext smooth = mesh::MeshContext::create(*world, smooth_params).value();
    mesh::MeshParams flat_params = smooth_params;
    flat_params.roundness = 0;
    flat_params.passage_roundness = 0;
    mesh::MeshContext flat = mesh::MeshContext::create(*world, flat_params).value();

    // mesh_sweep's draw: the same sample seed gives the same sectors.
    const std::vector<cave::SectorCoord> sectors =
        bench::sample_sectors(seed, sample_seed, sample, spread);
    std::vector<cave::Room> rooms = bench::rooms_of(*world, sectors);
    for (const std::string& lod_name : lod_names) {
      const mesh::Lod lod = lod_name == "patch" ? mesh::Lod::kPatch : mesh::Lod::kDetail;
      std::vector<RoomFolds> out(rooms.size());
      std::atomic<size_t> next{0}, failed{0};
      auto work = [&] {
        for (size_t i; (i = next.fetch_add(1)) < out.size();) {
          const cave::Room& r = rooms[i];
          RoomFolds& f = out[i];
          f.room = r.id.to_string();
          f.lod = lod_name;
          mesh::DeformInput in = mesh::prepare_room(ctx, r, lod);
          const size_t nv = in.donor->directions.size();
          std::vector<float3> pos(nv);
          std::vector<float> clearance(nv);
          mesh::deform_cpu(ctx, in, pos, clearance);
          mesh::AssembleStats assembled;
          auto m = mesh::assemble_room(ctx, in, pos, clearance, &assembled);
          // Rooms whose holes touch (a pinch both loops keep): the fixtures of
          // tests/mesh/portal_holes_test.cpp come from these lines.
          if (assembled.pinches_kept > 0) {
            spdlog::info("event=pinch_kept seed={} lod={} room={} pinches={}", seed, lod_name,
                         r.id.to_string(), assembled.pinches_kept);
          }
          if (!m) {
            ++failed;
            spdlog::error("event=room_failed seed={} lod={} room={} error=\"{}\"", seed, lod_name,
                          r.id.to_string(), m.error().message);
            continue;
          }
          f.room_radius = r.sphere.radius;
          f.portals = static_cast<int>(r.portals.size());
          if (r.portals.size() == 2) f.facing = -dot(r.portals[0].normal, r.portals[1].normal);
          for (const cave::Portal& p : r.portals)
            f.largest_portal_ratio = std::max(f.largest_portal_ratio, p.radius / r.sphere.radius);
          find_folds(*m, in, fold_degrees, f);
          if (!stages || f.folded.empty()) continue;
          const double band = ctx.shape(lod).remove_band;
          const mesh::DonorSphere& d = *in.donor;
          const size_t nt = d.indices.size() / 3;
          std::vector<char> kept(nt);
          std::map<std::array<uint32_t, 3>, uint32_t> by_corners;
          for (size_t t = 0; t < nt; ++t) {
            std::array<uint32_t, 3> c{d.indices[3 * t], d.indices[3 * t + 1], d.indices[3 * t + 2]};
            kept[t] = clearance[c[0]] >= band && clearance[c[1]] >= band && clearance[c[2]] >= band;
            std::sort(c.begin(), c.end());
            by_corners[c] = static_cast<uint32_t>(t);
          }
          // Mesh vertices are donor positions bit for bit (rim vertices aside).
          std::map<std::array<float, 3>, uint32_t> donor_of;
          for (size_t v = 0; v < nv; ++v)
            donor_of[{pos[v].x, pos[v].y, pos[v].z}] = static_cast<uint32_t>(v);
          auto surface = [&](const mesh::MeshContext& c) {
            mesh::DeformInput in2 = mesh::prepare_room(c, r, lod);
            std::vector<float3> p2(nv);
            std::vector<float> c2(nv);
            mesh::deform_cpu(c, in2, p2, c2);
            return p2;
          };
          std::vector<float3> p_smooth = surface(smooth), p_flat = surface(flat);
          std::vector<char> fold_full = donor_folds(d, pos, kept, fold_degrees);
          std::vector<char> fold_smooth = donor_folds(d, p_smooth, kept, fold_degrees);
          std::vector<char> fold_flat = donor_folds(d, p_flat, kept, fold_degrees);
          f.donor_folded = static_cast<int>(std::count(fold_full.begin(), fold_full.end(), 1));
          for (FoldedTriangle& t : f.folded) {
            if (t.stitch) continue;
            std::array<uint32_t, 3> c;
            for (int k = 0; k < 3; ++k) {
              const float3 q = m->positions[t.corners[k]];
              c[k] = donor_of.at({q.x, q.y, q.z});
            }
            t.donor_corners = c;
            std::sort(c.begin(), c.end());
            auto it = by_corners.find(c);
            if (it == by_corners.end()) continue;
            const uint32_t dt = it->second;
            t.donor_triangle = static_cast<int>(dt);
            t.donor_folded = fold_full[dt];
            t.folded_without_noise = fold_smooth[dt];
            t.folded_without_noise_or_roundness = fold_flat[dt];
            double edge = 0, spread_noise = 0, noise = 0;
            Vec3 disp[3];
            for (int k = 0; k < 3; ++k) {
              uint32_t v = d.indices[3 * dt + k], w = d.indices[3 * dt + (k + 1) % 3];
              disp[k] = vec(pos[v]) - vec(p_smooth[v]);
              noise = std::max(noise, length(disp[k]));
              edge = std::max(edge, length(vec(p_smooth[v]) - vec(p_smooth[w])));
            }
            for (int k = 0; k < 3; ++k)
              spread_noise = std::max(spread_noise, length(disp[k] - disp[(k + 1) % 3]));
            t.axis_offset = 1e300;
            const Vec3 o{in.record.ox, in.record.oy, in.record.oz};
            for (int k = 0; k < 3; ++k) {
              const Vec3 sp = o + vec(d.directions[d.indices[3 * dt + k]]) * in.record.radius;
              for (size_t pi = 0; pi < in.portals.size(); ++pi) {
                const auto& g = in.portals[pi];
                const Vec3 n{g.nx, g.ny, g.nz};
                const Vec3 rel = sp - Vec3{g.cx, g.cy, g.cz};
                const double off = length(rel - n * dot(rel, n));
                if (off < t.axis_offset) t.axis_offset = off, t.axis_portal = static_cast<int>(pi);
              }
            }
            t.noise = noise;
            t.smooth_edge = edge;
            t.noise_spread = spread_noise;
          }
        }
      };
      std::vector<std::thread> pool;
      for (int t = 1; t < threads; ++t)
        pool.emplace_back(work);
      work();
      for (auto& t : pool)
        t.join();

      // Rooms of two portals by how they face each other, all and with folds.
      std::array<size_t, 8> facing_all{}, facing_folded{};
      for (const RoomFolds& f : out) {
        if (f.portals != 2) continue;
        auto b = static_cast<size_t>(std::clamp((f.facing + 1) * 4, 0.0, 7.0));
        ++facing_all[b];
        facing_folded[b] += f.folded.empty() ? 0 : 1;
      }
      size_t triangles = 0, folded = 0, folded_rooms = 0, fold_edges = 0, stitch = 0;
      nlohmann::json list = nlohmann::json::array();
      for (const RoomFolds& f : out) {
        triangles += f.triangles;
        fold_edges += f.fold_edges;
        if (f.folded.empty()) continue;
        ++folded_rooms;
        folded += f.folded.size();
        nlohmann::json tris = nlohmann::json::array();
        for (const FoldedTriangle& t : f.folded) {
          stitch += t.stitch ? 1 : 0;
          tris.push_back(
              {{"stitch", t.stitch},
               {"portal_distance", t.portal_distance},
               {"plane_height", t.plane_height},
               {"worst_dihedral", t.worst_dihedral},
               {"area", t.area},
               {"corners", t.corners},
               {"centre", {t.centre.x, t.centre.y, t.centre.z}},
               {"donor_triangle", t.donor_triangle},
               {"donor_corners", t.donor_corners},
               {"donor_folded", t.donor_folded},
               {"folded_without_noise", t.folded_without_noise},
               {"folded_without_noise_or_roundness", t.folded_without_noise_or_roundness},
               {"noise", t.noise},
               {"noise_spread", t.noise_spread},
               {"smooth_edge", t.smooth_edge},
               {"axis_offset", t.axis_offset},
               {"axis_portal", t.axis_portal}});
        }
        list.push_back({{"room", f.room},
                        {"lod", f.lod},
                        {"triangles", f.triangles},
                        {"fold_edges", f.fold_edges},
                        {"room_radius", f.room_radius},
                        {"portals", f.portals},
                        {"largest_portal_ratio", f.largest_portal_ratio},
                        {"facing", f.facing},
                        {"donor_folded", f.donor_folded},
                        {"folded", tris}});
      }
      spdlog::info(
          "event=folds seed={} lod={} sectors={} rooms={} failed={} triangles={} "
          "rooms_folded={} triangles_folded={} stitch={} fold_edges={}",
          seed, lod_name, sectors.size(), rooms.size(), failed.load(), triangles, folded_rooms,
          folded, stitch, fold_edges);
      report["per_seed"].push_back({{"seed", seed},
                                    {"lod", lod_name},
                                    {"sectors", sectors.size()},
                                    {"rooms", rooms.size()},
                                    {"failed", failed.load()},
                                    {"triangles", triangles},
                                    {"rooms_folded", folded_rooms},
                                    {"triangles_folded", folded},
                                    {"stitch_triangles_folded", stitch},
                                    {"fold_edges", fold_edges},
                                    {"two_portal_rooms_by_facing_eighths", facing_all},
                                    {"folded_two_portal_rooms_by_facing_eighths", facing_folded},
                                    {"rooms_with_folds", list}});
    }
  }
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
