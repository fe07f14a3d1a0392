// grotto-layout: look at what the layout parameters do. Generates a block of sectors, prints its
// rooms and portals as JSON and writes an SVG picture (top and side views).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <thread>

#include "common/cave/layout.hpp"
#include "common/cave/svg.hpp"
#include "common/kernels/room_builder.hpp"
#include "common/relief/relief_bake.hpp"
#include "proto/layout_json.hpp"
#include "tools/glb.hpp"
#include "tools/preview.hpp"

namespace {

using grotto::Result;
using grotto::cave::SectorCoord;

constexpr long kMaxSectors = 512;

Result<SectorCoord> parse_sector(const std::string& flag, const std::string& text) {
  SectorCoord s;
  const char* p = text.data();
  const char* end = text.data() + text.size();
  for (int a = 0; a < 3; ++a) {
    auto [next, ec] = std::from_chars(p, end, s[a]);
    bool last = a == 2;
    if (ec != std::errc() || (last ? next != end : (next == end || *next != ','))) {
      return grotto::invalid_argument(flag + " must be three integers like 0,-1,2 (got '" + text +
                                      "')");
    }
    p = next + 1;
  }
  if (!grotto::cave::in_range(s)) {
    return grotto::invalid_argument(flag + " is outside the sector range +/-" +
                                    std::to_string(grotto::cave::kSectorCoordLimit));
  }
  return s;
}

bool write_file(const std::string& path, const std::string& text) {
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fputc('\n', stdout);
    return true;
  }
  std::ofstream f(path, std::ios::binary);
  f << text;
  f.close();
  if (!f) {
    spdlog::error("cannot write {}", path);
    return false;
  }
  return true;
}

// The region's room meshes, built on OpenCL or the CPU reference. A room that cannot be built is
// logged and left out of `built`; `errors` says why, one entry per region room (empty: built).
struct RegionMeshes {
  std::vector<grotto::mesh::RoomMesh> built;  // in region order
  std::vector<std::string> errors;            // parallel to region.rooms
  size_t failed = 0;
  size_t first_failed = 0;  // index into region.rooms, when failed > 0
};

RegionMeshes build_meshes(const grotto::cave::World& world, const grotto::cave::Region& region,
                          grotto::mesh::Lod lod, int threads) {
  RegionMeshes out;
  out.errors.resize(region.rooms.size());
  auto note_failure = [&](size_t i, std::string why) {
    if (out.failed++ == 0) out.first_failed = i;
    out.errors[i] = std::move(why);
  };
  auto ctx = grotto::mesh::MeshContext::create(world, grotto::mesh::MeshParams{});
  if (!ctx) {
    spdlog::error("{}", ctx.error().message);
    for (size_t i = 0; i < region.rooms.size(); ++i)
      note_failure(i, ctx.error().message);
    return out;
  }
  auto builder = grotto::kernels::RoomBuilder::create(*ctx, {{}, threads});
  auto meshes = builder.build(region.rooms, lod);
  for (size_t i = 0; i < meshes.size(); ++i) {
    if (!meshes[i]) {
      spdlog::warn("event=room_mesh_failed room={} error=\"{}\"", region.rooms[i].id.to_string(),
                   meshes[i].error().message);
      note_failure(i, meshes[i].error().message);
      continue;
    }
    out.built.push_back(std::move(meshes[i]).value());
  }
  spdlog::info("event=meshes_built rooms={} lod={} compute_path=\"{}\"", out.built.size(),
               grotto::mesh::lod_name(lod), builder.path());
  return out;
}

// The relief baked into every built mesh (common/relief/relief_bake.hpp).
void bake_meshes(const grotto::cave::Region& region, RegionMeshes& meshes) {
  size_t next = 0, moved = 0;
  double largest = 0;
  for (size_t i = 0; i < region.rooms.size(); ++i) {
    if (!meshes.errors[i].empty()) continue;
    grotto::relief::BakeStats s = grotto::relief::bake_relief(meshes.built[next++]);
    moved += s.moved;
    largest = std::max(largest, s.largest);
  }
  spdlog::info("event=relief_baked meshes={} vertices={} largest_m={:.2f}", next, moved, largest);
}

// glTF 2.0 binary: every room of the region a node, with its mesh where it could be built.
grotto::Status write_glb(const std::string& path, const grotto::cave::World& world,
                         const grotto::cave::Region& region, grotto::mesh::Lod lod,
                         const RegionMeshes& meshes) {
  const double size = world.params().sector_size;
  grotto::tools::GlbSource source;
  source.generator = std::string("grotto-layout ") + GROTTO_VERSION;
  source.seed = world.seed();
  source.world = &world;
  source.sector_size = size;
  source.lo = region.lo;
  source.hi = region.hi;
  source.lod = lod;
  // The block's first corner, as --obj uses: translations stay within the block's few hundred
  // metres, where float32 holds the 1/64 m grid exactly (when the sector size is on that grid,
  // as the default 96 m is).
  source.anchor = {region.lo.x * size, region.lo.y * size, region.lo.z * size};
  std::vector<grotto::tools::GlbRoom> rooms(region.rooms.size());
  size_t next = 0;
  for (size_t i = 0; i < region.rooms.size(); ++i) {
    rooms[i].room = &region.rooms[i];
    rooms[i].lights = grotto::cave::room_lights(world.seed(), world.params(), region.rooms[i]);
    if (meshes.errors[i].empty()) {
      rooms[i].mesh = &meshes.built[next++];
    } else {
      rooms[i].mesh_error = meshes.errors[i];
    }
  }
  auto bytes = grotto::tools::region_glb(source, rooms);
  if (!bytes) return bytes.error();
  if (auto s = grotto::tools::write_file_replacing(path, *bytes); !s) return s;
  spdlog::info("event=glb_written path={} rooms={} meshes={} bytes={}", path, rooms.size(),
               meshes.built.size(), bytes->size());
  return {};
}

// Wavefront OBJ: one object per room, positions in metres relative to the block's first corner
// (written in a comment) so readers that use float keep precision.
bool write_obj(const std::string& path, const grotto::cave::World& world,
               const grotto::cave::Region& region,
               const std::vector<grotto::mesh::RoomMesh>& meshes) {
  grotto::Vec3 base{region.lo.x * world.params().sector_size,
                    region.lo.y * world.params().sector_size,
                    region.lo.z * world.params().sector_size};
  std::ofstream f(path, std::ios::binary);
  f << "# Grotto cave, seed " << world.seed() << ", sectors " << grotto::cave::to_string(region.lo)
    << " to " << grotto::cave::to_string(region.hi) << "\n# positions are world coordinates minus ("
    << base.x << ", " << base.y << ", " << base.z
    << "); y is up; triangles face the inside of the cave\n";
  size_t next = 1;
  char line[160];
  for (const grotto::mesh::RoomMesh& m : meshes) {
    f << "o room_" << m.id.to_string() << "\n";
    for (size_t v = 0; v < m.vertex_count(); ++v) {
      grotto::Vec3 p = m.world_position(v) - base;
      std::snprintf(line, sizeof line, "v %.4f %.4f %.4f\nvn %.4f %.4f %.4f\n", p.x, p.y, p.z,
                    m.normals[v].x, m.normals[v].y, m.normals[v].z);
      f << line;
    }
    for (size_t t = 0; t < m.indices.size(); t += 3) {
      size_t a = next + m.indices[t], b = next + m.indices[t + 1], c = next + m.indices[t + 2];
      f << "f " << a << "//" << a << " " << b << "//" << b << " " << c << "//" << c << "\n";
    }
    next += m.vertex_count();
  }
  f.close();
  if (!f) {
    spdlog::error("cannot write {}", path);
    return false;
  }
  spdlog::info("event=obj_written path={} rooms={} vertices={}", path, meshes.size(), next - 1);
  return true;
}

// One line on stderr; exit code 2 for input the command line got wrong, 1 for what went wrong
// after.
int fail(const std::string& message, int code = 2) {
  std::fprintf(stderr, "grotto-layout: %s\n", message.c_str());
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "grotto-layout: generate a block of sectors of an unbounded Grotto cave, print its rooms "
      "and portals as JSON and draw it as SVG (top and side views, coloured by region).\n"
      "Example: grotto-layout --seed 7 --sectors 2 --svg cave.svg --json cave.json"};
  std::string seed_text = std::to_string(grotto::cave::kDefaultSeed);
  std::string from_text = "0,0,0", to_text;
  int sectors = 2;
  std::string svg_path, json_path, obj_path, glb_path, png_path, room_text, character;
  std::string lod_text = "patch";
  bool bake = false;
  grotto::cave::LayoutParams params;
  std::optional<double> tunnel_chance, big_probability;
  std::optional<int> room_count, loops;
  std::vector<double> bias;
  app.add_option("--seed", seed_text, "World seed, an unsigned 64-bit integer")
      ->capture_default_str();
  app.add_option("--from", from_text, "First sector of the block, as x,y,z")->capture_default_str();
  app.add_option("--to", to_text, "Last sector of the block, as x,y,z (default: from + sectors-1)");
  app.add_option("--sectors", sectors, "Edge of the block in sectors when --to is not given")
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  app.add_option("--svg", svg_path, "Write the SVG picture to this file");
  app.add_option("--json", json_path, "Write the region as JSON to this file ('-' for stdout)");
  app.add_option("--obj", obj_path,
                 "Write the rooms' meshes as Wavefront OBJ (opens in Blender and most 3D tools)");
  app.add_option(
      "--glb", glb_path,
      "Write the rooms as glTF 2.0 binary: a node per room (portals in its extras, the "
      "world's lights as child nodes with KHR_lights_punctual point lights), "
      "meshes Draco-compressed as streamed (protocol 1, with normals), with plain fallback data "
      "(docs/INTEGRATION.md, 'Exporting to glTF')");
  app.add_option("--png", png_path,
                 "Render the rooms' meshes to a PNG picture (software, no GPU or display needed)");
  app.add_option("--lod", lod_text,
                 "Level of detail of --obj, --glb and --png: patch (streamed) or detail")
      ->check(CLI::IsMember({"patch", "detail"}))
      ->capture_default_str();
  app.add_flag(
      "--bake-relief", bake,
      "Move the meshes of --obj, --glb and --png by the relief the client draws (the rock, "
      "stalactites and stalagmites of shaders/relief.glsl; rims stay put): use with "
      "--lod detail for an engine that does not tessellate");
  app.add_option("--room", room_text, "Print one room as JSON instead, e.g. 0.0.0.r3 or 0.0.0.x1");
  app.add_option("--character", character,
                 "Use one character everywhere instead of the region mix: maze, shafts or caverns")
      ->check(CLI::IsMember({"maze", "shafts", "caverns"}));
  app.add_option("--sector-size", params.sector_size, "Sector edge in metres")
      ->capture_default_str();
  app.add_option("--region-scale", params.region_scale,
                 "Regions change over about this many "
                 "sectors")
      ->capture_default_str();
  app.add_option("--tunnel-chance", tunnel_chance,
                 "Chance to grow from the most recent room, for every character (thesis 3.1.2)");
  app.add_option("--big-probability", big_probability, "Chance of a big room, for every character");
  app.add_option("--room-count", room_count, "Rooms grown per sector, for every character");
  app.add_option("--loops", loops,
                 "Extra passages per sector between rooms near in space but far apart in the "
                 "graph, for every character");
  app.add_option("--bias", bias, "Displacement bias x,y,z for every character, e.g. 1,0.1,1")
      ->delimiter(',')
      ->expected(3);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;  // --help: 0; a bad flag: 2, as in every Grotto binary
  }
  // stdout carries JSON; logs go to stderr.
  spdlog::set_default_logger(spdlog::stderr_color_mt("grotto-layout"));

  if (!character.empty()) {
    for (const auto& c : grotto::cave::LayoutParams::default_characters()) {
      if (c.name == character) {
        double size = params.sector_size, scale = params.region_scale;
        params = grotto::cave::LayoutParams::uniform(c);
        params.sector_size = size;
        params.region_scale = scale;
      }
    }
  }
  for (auto& c : params.characters) {
    if (tunnel_chance) c.tunnel_chance = *tunnel_chance;
    if (big_probability) c.big_probability = *big_probability;
    if (room_count) c.room_count = *room_count;
    if (loops) c.loops = *loops;
    if (!bias.empty()) c.bias = {bias[0], bias[1], bias[2]};
  }
  uint64_t seed = 0;
  auto [seed_end, seed_ec] =
      std::from_chars(seed_text.data(), seed_text.data() + seed_text.size(), seed);
  if (seed_ec != std::errc() || seed_end != seed_text.data() + seed_text.size()) {
    return fail("--seed must be an unsigned 64-bit integer (got '" + seed_text + "')");
  }
  auto world = grotto::cave::World::create(seed, params);
  if (!world) return fail(world.error().message);

  if (!room_text.empty()) {
    auto id = grotto::cave::RoomId::parse(room_text);
    if (!id) return fail(id.error().message);
    auto r = grotto::cave::room(*world, *id);
    if (!r) return fail(r.error().message);
    std::printf("%s\n", grotto::proto::room_json(*world, *r, 2).c_str());
    return 0;
  }

  auto lo = parse_sector("--from", from_text);
  if (!lo) return fail(lo.error().message);
  SectorCoord hi{lo->x + sectors - 1, lo->y + sectors - 1, lo->z + sectors - 1};
  if (!to_text.empty()) {
    auto parsed = parse_sector("--to", to_text);
    if (!parsed) return fail(parsed.error().message);
    hi = *parsed;
  }
  long count = 1;
  for (int a = 0; a < 3; ++a) {
    if (hi[a] < (*lo)[a]) return fail("--to must not be below --from on any axis");
    count *= hi[a] - (*lo)[a] + 1;
  }
  if (!grotto::cave::in_range(hi)) {
    return fail("the block's last sector " + grotto::cave::to_string(hi) +
                " is outside the sector range +/-" +
                std::to_string(grotto::cave::kSectorCoordLimit));
  }
  if (count > kMaxSectors) {
    return fail("the block has " + std::to_string(count) + " sectors; at most " +
                std::to_string(kMaxSectors) + " at once");
  }

  // Every hardware thread: the sectors are independent and the region the same bytes either way.
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  grotto::cave::Region region = grotto::cave::generate_region(*world, *lo, hi, threads);
  size_t portals = 0;
  for (const auto& r : region.rooms)
    portals += r.portals.size();
  spdlog::info("event=region seed={} from={} to={} sectors={} rooms={} portals={}", seed,
               grotto::cave::to_string(*lo), grotto::cave::to_string(hi), count,
               region.rooms.size(), portals / 2);
  if (!svg_path.empty()) {
    if (!write_file(svg_path, grotto::cave::region_svg(*world, region))) return 1;
    spdlog::info("event=svg_written path={}", svg_path);
  }
  if (!json_path.empty()) {
    if (!write_file(json_path, grotto::proto::region_json(*world, region, 1))) return 1;
    if (json_path != "-") spdlog::info("event=json_written path={}", json_path);
  }
  if (!obj_path.empty() || !png_path.empty() || !glb_path.empty()) {
    auto lod = lod_text == "detail" ? grotto::mesh::Lod::kDetail : grotto::mesh::Lod::kPatch;
    RegionMeshes meshes = build_meshes(*world, region, lod, threads);
    if (bake) bake_meshes(region, meshes);
    if (!obj_path.empty() && !write_obj(obj_path, *world, region, meshes.built)) return 1;
    if (!glb_path.empty()) {
      if (auto s = write_glb(glb_path, *world, region, lod, meshes); !s) {
        return fail(s.error().message, 1);
      }
    }
    if (!png_path.empty()) {
      grotto::tools::PreviewOptions preview;
      auto image = grotto::tools::render_preview(meshes.built, preview);
      if (auto s = grotto::png::write_png(png_path, image, preview.width, preview.height); !s) {
        return fail(s.error().message);
      }
      spdlog::info("event=png_written path={}", png_path);
    }
    if (meshes.failed > 0) {
      // Mesh errors usually name their room already.
      const std::string id = region.rooms[meshes.first_failed].id.to_string();
      const std::string& why = meshes.errors[meshes.first_failed];
      return fail(std::to_string(meshes.failed) + " of " + std::to_string(region.rooms.size()) +
                      " rooms could not be meshed (first: " +
                      (why.find(id) == std::string::npos ? id + ": " + why : why) +
                      "); the files hold the others" +
                      (glb_path.empty() ? "" : ", the glb their nodes without a mesh"),
                  1);
    }
  }
  if (svg_path.empty() && json_path.empty() && obj_path.empty() && glb_path.empty() &&
      png_path.empty()) {
    std::printf("%s\n", grotto::proto::region_json(*world, region, 1).c_str());
  }
  return 0;
}
