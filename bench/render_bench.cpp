// client/render's benchmark, on whatever GL 4.1 core context the display gives (Mesa
// llvmpipe under xvfb-run on the CI machines): along a path through a fully loaded block of
// sectors, frame times of
//   (a) the tessellated patch mesh against the untessellated detail mesh (Lod::kDetail rooms built
//       in-process, drawn flat, level 1) over the same poses (the thesis: 53 -> 44 fps);
//   (b) portal culling on against off (the thesis expected >= 2x);
//   (c) the LOD heuristics and patch culling: frame time, patches submitted and triangles out of
//       the tessellator (GL_PRIMITIVES_GENERATED).
// Every frame is drawn into an off-screen framebuffer and waited for (glFinish); the
// configurations take turns frame by frame at each pose (so that the machine's load weighs on
// all alike); a pose's time is the median of --repetitions frames, a configuration's the sum of
// its poses' medians. Writes a
// JSON report. Command and results: docs/BENCHMARKS.md ("Rendering").
#include <GLFW/glfw3.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "bench/flags.hpp"
#include "bench/timing.hpp"
#include "client/render/gl.hpp"
#include "client/render/renderer.hpp"
#include "client/render/room_cache.hpp"
#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;
using bench::median;

// A room as the renderer holds it, without the codec (the detail level is larger than a wire
// frame needs to be for this comparison, and both levels should pay the same: nothing).
stream::ReadyRoom ready_room(const mesh::RoomMesh& m, const cave::Room& r) {
  stream::ReadyRoom out;
  out.room = r;
  out.origin = m.origin;
  out.mesh.positions = m.positions;
  out.mesh.normals = m.normals;
  out.mesh.roughness = m.roughness;
  out.mesh.mineral = m.mineral;
  out.mesh.rim_portal = m.rim_portal;
  out.mesh.rim_index = m.rim_index;
  out.mesh.indices = m.indices;
  return out;
}

// A walk through the loaded rooms: from an interior room, to a loaded neighbour not yet visited
// (else back along the way it came), the camera at each room's centre and at each portal it
// passes, looking towards the next point. Deterministic for a given cache.
std::vector<render::Camera> walk(const std::map<cave::RoomId, cave::Room>& rooms, int poses) {
  std::vector<Vec3> points;
  std::set<cave::RoomId> visited;
  std::vector<cave::RoomId> trail;
  for (const auto& [id, room] : rooms) {
    if (id.is_gate()) continue;
    trail.push_back(id);
    break;
  }
  while (!trail.empty() && static_cast<int>(points.size()) <= poses) {
    const cave::Room& here = rooms.at(trail.back());
    if (visited.insert(here.id).second) points.push_back(here.sphere.centre);
    const cave::Portal* next = nullptr;
    for (const cave::Portal& p : here.portals)
      if (rooms.count(p.neighbour) != 0 && visited.count(p.neighbour) == 0) {
        next = &p;
        break;
      }
    if (next == nullptr) {
      trail.pop_back();
      if (!trail.empty()) points.push_back(rooms.at(trail.back()).sphere.centre);
      continue;
    }
    points.push_back(next->centre);
    trail.push_back(next->neighbour);
  }
  std::vector<render::Camera> out;
  for (size_t i = 0; i + 1 < points.size() && static_cast<int>(out.size()) < poses; ++i) {
    const Vec3 d = points[i + 1] - points[i];
    const double horizontal = std::sqrt(d.x * d.x + d.z * d.z);
    if (horizontal + std::abs(d.y) < 1e-6) continue;
    render::Camera c;
    c.position = points[i];
    c.yaw = std::atan2(d.x, -d.z);
    c.pitch = std::atan2(d.y, horizontal);
    out.push_back(c);
  }
  return out;
}

struct Measurement {
  std::string name;
  double total_ms = 0;         // sum over poses of the median frame time
  double median_frame_ms = 0;  // median over poses
  double rooms_drawn = 0;      // mean per frame
  double patches = 0;          // mean per frame
  double triangles = 0;        // mean per frame, out of the tessellator
};

// One configuration of the renderer: what it draws and how.
struct Config {
  std::string name;
  const render::GpuRoomCache* cache;
  render::RenderOptions options;
};

class Bench {
 public:
  Bench(render::Renderer& renderer, render::Framebuffer& framebuffer, int repetitions)
      : renderer_(renderer), framebuffer_(framebuffer), repetitions_(repetitions) {}

  // Every configuration at every pose, interleaved: at each pose one frame of each in turn,
  // --repetitions times, so that a change of the machine's load during the run (these machines
  // are shared) weighs on every configuration alike and their ratios hold. A pose's time is the
  // median of its frames, a configuration's the sum over poses.
  std::vector<Measurement> measure(const std::vector<Config>& configs,
                                   const std::vector<render::Camera>& path) {
    using clock = std::chrono::steady_clock;
    std::vector<Measurement> out(configs.size());
    std::vector<std::vector<double>> pose_ms(configs.size());
    GLuint query = 0;
    glGenQueries(1, &query);
    for (const render::Camera& camera : path) {
      for (size_t c = 0; c < configs.size(); ++c) {
        glBeginQuery(GL_PRIMITIVES_GENERATED, query);
        render::FrameStats stats = draw(configs[c], camera);
        glEndQuery(GL_PRIMITIVES_GENERATED);
        glFinish();  // also warms the caches for this pose
        GLuint triangles = 0;
        glGetQueryObjectuiv(query, GL_QUERY_RESULT, &triangles);
        out[c].rooms_drawn += stats.rooms_drawn;
        out[c].patches += static_cast<double>(stats.patches);
        out[c].triangles += triangles;
      }
      std::vector<std::vector<double>> frames(configs.size());
      for (int r = 0; r < repetitions_; ++r) {
        for (size_t c = 0; c < configs.size(); ++c) {
          const auto start = clock::now();
          draw(configs[c], camera);
          glFinish();
          frames[c].push_back(1000.0 * std::chrono::duration<double>(clock::now() - start).count());
        }
      }
      for (size_t c = 0; c < configs.size(); ++c) {
        pose_ms[c].push_back(median(frames[c]));
        out[c].total_ms += pose_ms[c].back();
      }
    }
    glDeleteQueries(1, &query);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    const double n = std::max<double>(1, static_cast<double>(path.size()));
    for (size_t c = 0; c < configs.size(); ++c) {
      Measurement& m = out[c];
      m.name = configs[c].name;
      m.rooms_drawn /= n;
      m.patches /= n;
      m.triangles /= n;
      m.median_frame_ms = median(pose_ms[c]);
      spdlog::info(
          "config={} total_ms={:.1f} median_frame_ms={:.2f} rooms_drawn={:.1f} "
          "patches={:.0f} triangles={:.0f}",
          m.name, m.total_ms, m.median_frame_ms, m.rooms_drawn, m.patches, m.triangles);
    }
    return out;
  }

 private:
  render::FrameStats draw(const Config& config, const render::Camera& camera) {
    framebuffer_.bind();
    return renderer_.draw(*config.cache, camera, framebuffer_.width(), framebuffer_.height(),
                          config.options);
  }

  render::Renderer& renderer_;
  render::Framebuffer& framebuffer_;
  int repetitions_;
};

nlohmann::json to_json(const Measurement& m) {
  return {{"total_ms", m.total_ms},
          {"median_frame_ms", m.median_frame_ms},
          {"rooms_drawn", m.rooms_drawn},
          {"patches", m.patches},
          {"triangles", m.triangles}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "render_bench: frame times of client/render along a path through a loaded block of "
      "sectors (tessellated patch mesh vs flat detail mesh, portal culling on vs off, LOD "
      "heuristics, patch culling), with a JSON report. Needs a display with GL 4.1 core "
      "(run under xvfb-run)."};
  std::string json_path = "render_bench.json";
  int reps = 5, poses = 20, width = 320, height = 240, sectors = 2;
  float max_tess = 8;
  uint64_t seed = 7;
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--repetitions", reps, "Frames per pose and configuration (the median counts)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--poses", poses, "Poses along the path")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--width", width, "Framebuffer width, pixels")
      ->check(CLI::Range(16, 7680))
      ->capture_default_str();
  app.add_option("--height", height, "Framebuffer height, pixels")
      ->check(CLI::Range(16, 4320))
      ->capture_default_str();
  app.add_option("--sectors", sectors, "Loaded block: sectors (0,0,0) to (n-1,0,n-1)")
      ->check(CLI::Range(1, 4))
      ->capture_default_str();
  app.add_option("--max-tess", max_tess, "MaxTess of the tessellated configurations")
      ->check(CLI::Range(1.0f, 64.0f))
      ->capture_default_str();
  app.add_option("--seed", seed, "World seed")->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;

  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') {
    std::fprintf(stderr, "render_bench: DISPLAY is not set (run under xvfb-run)\n");
    return 1;
  }
  if (glfwInit() != GLFW_TRUE) {
    std::fprintf(stderr, "render_bench: glfwInit failed for DISPLAY=%s\n", display);
    return 1;
  }
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, GLFW_FALSE);
  GLFWwindow* window = glfwCreateWindow(64, 64, "render_bench", nullptr, nullptr);
  if (window == nullptr) {
    std::fprintf(stderr, "render_bench: no OpenGL 4.1 core context on DISPLAY=%s\n", display);
    glfwTerminate();
    return 1;
  }
  glfwMakeContextCurrent(window);
  const std::string context = render::describe_context();
  spdlog::info("context=\"{}\"", context);

  int rc = 0;
  {
    // Both levels of every room of the block, built in-process with the CPU reference.
    const cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
    const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
    std::map<cave::RoomId, cave::Room> rooms;
    render::GpuRoomCache patch_cache, detail_cache;
    size_t patch_triangles = 0, detail_triangles = 0;
    for (const cave::Room& r :
         cave::generate_region(world, {0, 0, 0}, {sectors - 1, 0, sectors - 1}).rooms) {
      auto patch = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
      auto detail = mesh::build_room_mesh(ctx, r, mesh::Lod::kDetail);
      if (!patch.ok() || !detail.ok()) {
        std::fprintf(stderr, "render_bench: building room %s failed\n", r.id.to_string().c_str());
        return 1;
      }
      rooms[r.id] = r;
      patch_cache.upload(ready_room(patch.value(), r));
      detail_cache.upload(ready_room(detail.value(), r));
      patch_triangles += patch.value().triangle_count();
      detail_triangles += detail.value().triangle_count();
    }
    const std::vector<render::Camera> path = walk(rooms, poses);
    spdlog::info("rooms={} poses={} patch_triangles={} detail_triangles={}", rooms.size(),
                 path.size(), patch_triangles, detail_triangles);

    auto renderer = render::Renderer::create();
    auto framebuffer = render::Framebuffer::create(width, height);
    if (!renderer.ok() || !framebuffer.ok()) {
      std::fprintf(stderr, "render_bench: %s\n",
                   (!renderer.ok() ? renderer.error() : framebuffer.error()).message.c_str());
      return 1;
    }
    Bench bench(renderer.value(), framebuffer.value(), reps);

    render::RenderOptions tessellated;
    tessellated.max_tess = max_tess;
    // The thesis's heuristic as the baseline; the client's default (screen) is lod_screen-space.
    tessellated.lod = render::LodHeuristic::kDistance;
    render::RenderOptions flat = tessellated;
    flat.tessellation = false;
    render::RenderOptions no_portals = tessellated;
    no_portals.portal_culling = false;
    render::RenderOptions no_patch_culling = tessellated;
    no_patch_culling.patch_culling = false;
    render::RenderOptions no_culling = no_patch_culling;
    no_culling.portal_culling = false;

    std::vector<Config> configs = {{"patch_tessellated", &patch_cache, tessellated},
                                   {"detail_flat", &detail_cache, flat},
                                   {"patch_flat", &patch_cache, flat},
                                   {"portal_culling_off", &patch_cache, no_portals},
                                   {"patch_culling_off", &patch_cache, no_patch_culling},
                                   {"both_culling_off", &patch_cache, no_culling}};
    for (render::LodHeuristic lod :
         {render::LodHeuristic::kScreenSpace, render::LodHeuristic::kSilhouette}) {
      render::RenderOptions o = tessellated;
      o.lod = lod;
      configs.push_back({std::string("lod_") + render::lod_heuristic_name(lod), &patch_cache, o});
    }
    const std::vector<Measurement> runs = bench.measure(configs, path);
    std::map<std::string, Measurement> by_name;
    for (const Measurement& m : runs)
      by_name[m.name] = m;
    auto ratio = [&](const char* a, const char* b) {
      return by_name[b].total_ms > 0 ? by_name[a].total_ms / by_name[b].total_ms : 0.0;
    };

    nlohmann::json report;
    report["context"] = context;
    report["seed"] = seed;
    report["sectors"] = sectors;
    report["rooms"] = rooms.size();
    report["poses"] = path.size();
    report["repetitions"] = reps;
    report["width"] = width;
    report["height"] = height;
    report["max_tess"] = max_tess;
    report["patch_triangles"] = patch_triangles;
    report["detail_triangles"] = detail_triangles;
    for (const Measurement& m : runs)
      report["configs"][m.name] = to_json(m);
    report["ratios"] = {
        {"tessellated_patch_over_flat_detail", ratio("patch_tessellated", "detail_flat")},
        // The client's default LOD (screen space) against the flat detail mesh: held to
        // at most 1.25.
        {"screen_space_patch_over_flat_detail", ratio("lod_screen-space", "detail_flat")},
        {"portal_culling_speedup", ratio("portal_culling_off", "patch_tessellated")},
        {"portal_culling_speedup_without_patch_culling",
         ratio("both_culling_off", "patch_culling_off")},
        {"patch_culling_speedup", ratio("patch_culling_off", "patch_tessellated")},
        {"both_culling_speedup", ratio("both_culling_off", "patch_tessellated")},
        {"screen_space_over_distance", ratio("lod_screen-space", "patch_tessellated")},
        {"silhouette_over_distance", ratio("lod_silhouette", "patch_tessellated")}};
    std::ofstream out(json_path);
    out << report.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "render_bench: cannot write %s\n", json_path.c_str());
      rc = 1;
    }
    std::printf("%s\n", report["ratios"].dump(2).c_str());
  }
  glfwDestroyWindow(window);
  glfwTerminate();
  return rc;
}
