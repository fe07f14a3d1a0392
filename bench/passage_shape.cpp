// passage_shape: how the rock shaped the passages. Builds the patch meshes of every room in a block
// of sectors (CPU path) for some seeds and reports, per seed:
//   - level passages (rooms with two portals whose axis lies within 45 degrees of level): the
//     height over the width of their middle cross-section (the mesh cut by the plane halfway
//     between the portals, square to the axis; height along the plumb line in that plane): the
//     median, the share at least 1.6 (tall: canyons, fissures) and at most 0.625 (wide: lenses);
//   - portal rims (each canonical loop once): their major over their minor axis (extents along
//     the loop's principal axes): the median and the share at least 1.5;
//   - the sections the geology chose, by kind.
// Writes a JSON report and prints a Markdown table (docs/BENCHMARKS.md, "Passages").
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "bench/flags.hpp"
#include "bench/sector_sample.hpp"
#include "bench/timing.hpp"
#include "common/cave/geology.hpp"
#include "common/mesh/rim.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;

double share(const std::vector<double>& v, bool (*keep)(double)) {
  if (v.empty()) return 0;
  return static_cast<double>(std::count_if(v.begin(), v.end(), keep)) /
         static_cast<double>(v.size());
}

// The height over the width of a passage's mesh where the plane through `mid` square to `axis`
// cuts it, counting only the cut within `reach` of `mid` (the passage's own section, not a wall
// of the room that bends back across the plane). 0 when the plane misses the mesh.
double mid_section_ratio(const mesh::RoomMesh& m, Vec3 mid, Vec3 axis, double reach) {
  const Vec3 plumb = normalize(Vec3{0, 1, 0} - axis * axis.y);
  const Vec3 across = cross(axis, plumb);
  double lo_h = 1e30, hi_h = -1e30, lo_w = 1e30, hi_w = -1e30;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const Vec3 a = m.world_position(m.indices[t + e]);
      const Vec3 b = m.world_position(m.indices[t + (e + 1) % 3]);
      const double da = dot(a - mid, axis), db = dot(b - mid, axis);
      if ((da < 0) == (db < 0)) continue;
      const Vec3 p = a + (b - a) * (da / (da - db)) - mid;
      if (length(p) > reach) continue;
      lo_h = std::min(lo_h, dot(p, plumb));
      hi_h = std::max(hi_h, dot(p, plumb));
      lo_w = std::min(lo_w, dot(p, across));
      hi_w = std::max(hi_w, dot(p, across));
    }
  }
  if (hi_w <= lo_w || hi_h <= lo_h) return 0;
  return (hi_h - lo_h) / (hi_w - lo_w);
}

// A rim loop's extent along its principal axes in its plane: major over minor.
double rim_axes_ratio(const mesh::RimLoop& loop) {
  double mx = 0, my = 0;
  std::vector<std::pair<double, double>> pts;
  for (Vec3 p : loop.positions) {
    Vec3 d = p - loop.centre;
    pts.push_back({dot(d, loop.e1), dot(d, loop.e2)});
    mx += pts.back().first;
    my += pts.back().second;
  }
  mx /= static_cast<double>(pts.size());
  my /= static_cast<double>(pts.size());
  double sxx = 0, syy = 0, sxy = 0;
  for (auto [x, y] : pts) {
    sxx += (x - mx) * (x - mx);
    syy += (y - my) * (y - my);
    sxy += (x - mx) * (y - my);
  }
  // The principal direction of the 2x2 covariance: angle 0.5 atan2(2 sxy, sxx - syy).
  const double angle = 0.5 * std::atan2(2 * sxy, sxx - syy);
  const double cx = std::cos(angle), cy = std::sin(angle);
  double lo_a = 1e30, hi_a = -1e30, lo_b = 1e30, hi_b = -1e30;
  for (auto [x, y] : pts) {
    const double a = x * cx + y * cy, b = -x * cy + y * cx;
    lo_a = std::min(lo_a, a), hi_a = std::max(hi_a, a);
    lo_b = std::min(lo_b, b), hi_b = std::max(hi_b, b);
  }
  const double wa = hi_a - lo_a, wb = hi_b - lo_b;
  return std::max(wa, wb) / std::max(1e-9, std::min(wa, wb));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "passage_shape: the middle sections of level passages, the portal rims' axes and the "
      "kinds of section the geology chose, for the patch meshes of a block of sectors; writes a "
      "JSON report and prints a Markdown table"};
  std::vector<uint64_t> seeds{7, 95, 42};
  std::vector<int> from{0, 0, 0}, to{1, 0, 1};
  std::string json_path = "passage_shape.json";
  app.add_option("--seed", seeds, "World seeds")->capture_default_str();
  app.add_option("--from", from, "First sector, x y z")->expected(3)->capture_default_str();
  app.add_option("--to", to, "Last sector, x y z")->expected(3)->capture_default_str();
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
  report["per_seed"] = nlohmann::json::array();
  std::printf(
      "| seed | level passages | mid section h/w median | >= 1.6 | <= 0.625 | rims | rim axes "
      "median | >= 1.5 | sections: tube, lens, canyon, keyhole, fissure |\n"
      "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n");
  for (uint64_t seed : seeds) {
    auto world = cave::World::create(seed, cave::LayoutParams{});
    if (!world) {
      spdlog::error("seed {}: {}", seed, world.error().message);
      return 2;
    }
    mesh::MeshContext ctx = mesh::MeshContext::create(*world, mesh::MeshParams{}).value();
    cave::Region region = cave::generate_region(*world, lo, hi);
    std::vector<double> mids, rims;
    std::map<std::string, int> kinds;
    std::map<std::string, std::vector<double>> by_kind;
    for (const cave::Room& room : region.rooms) {
      for (const cave::Portal& p : room.portals) {
        if (region.find(p.neighbour) && p.neighbour < room.id) continue;  // each portal once
        const mesh::RimLoop loop = mesh::canonical_rim(ctx, room, p, mesh::Lod::kPatch);
        rims.push_back(rim_axes_ratio(loop));
        ++kinds[cave::section_kind_name(
            cave::passage_section(*world, p.centre, loop.normal, p.radius).kind)];
      }
      if (room.portals.size() != 2) continue;
      const Vec3 a = room.portals[0].centre, b = room.portals[1].centre;
      const Vec3 axis = normalize(b - a);
      if (std::abs(axis.y) > std::sqrt(0.5)) continue;  // steeper than 45 degrees
      auto m = mesh::build_room_mesh(ctx, room, mesh::Lod::kPatch);
      if (!m) {
        spdlog::error("seed {} room {}: {}", seed, room.id.to_string(), m.error().message);
        return 1;
      }
      const double ratio = mid_section_ratio(*m, (a + b) * 0.5, axis, room.sphere.radius);
      if (ratio <= 0) continue;
      mids.push_back(ratio);
      // The passage's kind when both its ends have the same one ("mixed" otherwise).
      const auto kind_at = [&](const cave::Portal& p) {
        return cave::section_kind_name(
            cave::passage_section(*world, p.centre, p.normal, p.radius).kind);
      };
      const std::string ka = kind_at(room.portals[0]), kb = kind_at(room.portals[1]);
      by_kind[ka == kb ? ka : "mixed"].push_back(ratio);
    }
    const auto tall = [](double r) { return r >= 1.6; };
    const auto wide = [](double r) { return r <= 0.625; };
    const auto long_rim = [](double r) { return r >= 1.5; };
    nlohmann::json row = {{"seed", seed},
                          {"level_passages", mids.size()},
                          {"mid_ratio_median", bench::percentile(mids, 0.5)},
                          {"mid_tall_share", share(mids, tall)},
                          {"mid_wide_share", share(mids, wide)},
                          {"rims", rims.size()},
                          {"rim_axes_median", bench::percentile(rims, 0.5)},
                          {"rim_long_share", share(rims, long_rim)},
                          {"sections", kinds}};
    for (const auto& [kind, ratios] : by_kind) {
      row["mid_by_kind"][kind] = {{"passages", ratios.size()},
                                  {"mid_ratio_median", bench::percentile(ratios, 0.5)},
                                  {"mid_tall_share", share(ratios, tall)},
                                  {"mid_wide_share", share(ratios, wide)}};
    }
    report["per_seed"].push_back(row);
    std::printf(
        "| %llu | %zu | %.2f | %.0f %% | %.0f %% | %zu | %.2f | %.0f %% | %d, %d, %d, %d, %d |\n",
        static_cast<unsigned long long>(seed), mids.size(), bench::percentile(mids, 0.5),
        100 * share(mids, tall), 100 * share(mids, wide), rims.size(), bench::percentile(rims, 0.5),
        100 * share(rims, long_rim), kinds["tube"], kinds["lens"], kinds["canyon"],
        kinds["keyhole"], kinds["fissure"]);
  }
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
