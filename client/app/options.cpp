#include "client/app/options.hpp"

#include "common/cave/room_id.hpp"
#include "proto/token.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <vector>

namespace grotto::app {
namespace {

std::optional<Pose5> parse_pose(const std::string& text) {
  if (text.rfind("room:", 0) == 0) {
    auto id = cave::RoomId::parse(std::string_view(text).substr(5));
    if (!id) return {};
    Pose5 p;
    p.room = id.value();
    return p;
  }
  std::vector<double> v;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    double d = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(d)) return {};
    v.push_back(d);
  }
  if (v.size() != 3 && v.size() != 5) return {};
  Pose5 p;
  p.position = {v[0], v[1], v[2]};
  if (v.size() == 5) p.yaw = v[3], p.pitch = v[4];
  return p;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "grotto-client: %s\n", message.c_str());
  return 2;
}

std::string number(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

}  // namespace

std::optional<int> parse_options(int argc, char** argv, Options& o) {
  CLI::App app{
      "grotto-client: explore Grotto's endless cave. Streams rooms from --server (or from a "
      "server started in-process) and renders them with hardware tessellation (OpenGL 4.1). "
      "You walk with gravity and collide with the cave's walls.\n"
      "Mouse: look; W/A/S/D: move; Shift: run; Space: jump (walk) or rise (fly); C: descend "
      "(fly); G: walk/fly; N: noclip (debugging: through walls); T: tessellation on/off; P: PN "
      "triangles/Phong; X: relief (displacement); J: fine detail; K: ambient occlusion; B: bloom; "
      "M: motion blur; O: portal culling; L: LOD heuristic; R: wireframe; F: throw a flare (it "
      "bounces, burns 30 s; 4 at most); Q: "
      "headlamp on/off; H: the overlay's key list; V: overlay on/off; Esc: quit.\n"
      "Light in the dark: halls hold glow-worm colonies, glowing mineral seams and crystal "
      "clusters (the world's lights, the same for every player of a seed); most passages are "
      "dark but for the headlamp and your flares."};
  app.add_option("--server", o.server_url,
                 "Server URL ws://host:port[/ws]; without it a server runs in-process");
  app.add_option("--seed", o.seed,
                 "World seed (unsigned 64-bit): the in-process server's world, or the world "
                 "asked of --server (default: the server's)");
  app.add_option("--protocol", o.protocol_version,
                 "Protocol version offered in hello: 0 every version (the server picks the "
                 "highest), 1 or 2 that one alone (version 2's rooms come without normals, the "
                 "client derives them)")
      ->check(CLI::Range(0, 2))
      ->capture_default_str();
  app.add_option("--device", o.device,
                 "In-process server's OpenCL device: auto, gpu, accelerator, cpu, none (CPU "
                 "reference)")
      ->capture_default_str();
  app.add_option("--width", o.width, "Window, screenshot or bench width in pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  app.add_option("--height", o.height, "Window, screenshot or bench height in pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  app.add_option("--tess-max", o.tess_max,
                 "MaxTess: the tessellation level of the nearest edges (1-64)")
      ->capture_default_str()
      ->check(CLI::Range(1.0f, 64.0f));
  app.add_option("--tess-pixels", o.tess_pixels,
                 "With --lod screen: the pixels a tessellated segment spans on screen (fewer: "
                 "finer relief far away, more vertices)")
      ->capture_default_str()
      ->check(CLI::Range(1.0f, 64.0f));
  app.add_flag("--no-tess", o.no_tess,
               "Draw the patch mesh flat: no tessellation, no displacement");
  app.add_flag("--wireframe", o.wireframe, "Draw edges only");
  app.add_option("--surface", o.surface, "Tessellated surface: pn (PN triangles) or phong")
      ->capture_default_str()
      ->check(CLI::IsMember({"pn", "phong"}));
  app.add_option(
      "--screenshot", o.screenshot,
      "Headless: render --frames frames, write this PNG (and with --json its report) and "
      "exit");
  app.add_option("--frames", o.frames, "Frames rendered before the screenshot")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--pose", o.pose_text,
                 "Start pose x,y,z[,yaw,pitch] (metres, degrees; yaw 0 looks along -z, positive "
                 "turns to +x), or room:<id> (e.g. room:0.0.0.r3) to start inside that room "
                 "looking through its widest portal; default: the server's spawn point");
  app.add_option("--wait", o.wait_s,
                 "Screenshot and bench: seconds to wait at most for the rooms they need")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--speed", o.speed, "Walking and flying speed in m/s (Shift runs at 2.5x)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 1000.0));
  app.add_option("--mode", o.mode_text,
                 "Start in walk mode (gravity, jumps) or fly mode (no gravity); G toggles")
      ->capture_default_str();
  app.add_option("--flythrough", o.flythrough_s,
                 "Follow the scripted path from the start pose through " +
                     std::to_string(kPathHops) + " portals (widest unvisited first) at " +
                     number(kPathSpeed) +
                     " m/s, there and back, starting this many seconds along it; a movement "
                     "key takes over. With --screenshot: the pose at that time");
  app.add_option("--bench", o.bench_s,
                 "Headless: render the scripted path (--flythrough's) for this many seconds at "
                 "--width x --height once its rooms are loaded, print frame-time statistics "
                 "(frames, mean, median, p95, p99, max ms, fps) and exit");
  app.add_flag("--hold", o.hold,
               "With --bench: hold the start pose (--pose) instead of following the path: the "
               "frame cost of one view (a hall, a ceiling close up)");
  app.add_option("--net", o.net_text,
                 "Play over a simulated network: rtt=150ms,jitter=20ms,kbps=2000,stall=0.5s/30s "
                 "(each part optional: round trip, jitter without reordering, the downlink's cap "
                 "in kbit/s, a stall of the link and its period), as grotto-load --net")
      ->type_name("PROFILE");
  app.add_option("--token-file", o.token_file,
                 "File whose first line (trimmed) is the deployment's shared-secret token, sent in "
                 "hello; without it $GROTTO_TOKEN is used; with neither no token is sent")
      ->type_name("FILE");
  app.add_flag("--overlay,!--no-overlay", o.overlay,
               "Status overlay (frame time, rooms, latency, bandwidth, toggles, connection): on "
               "in the window, off in --screenshot unless asked for");
  app.add_option("--lod", o.lod_text,
                 "Tessellation level heuristic: distance (the thesis's), screen (edge length in "
                 "pixels) or silhouette (finer on silhouette edges); L cycles")
      ->capture_default_str();
  app.add_flag("--no-portal-culling", o.no_portal_culling,
               "Draw every loaded room in the view frustum instead of the rooms seen through "
               "portals (O toggles)");
  app.add_flag("--no-displacement", o.no_displacement,
               "Tessellate without the rock's relief (no displacement; X toggles)");
  app.add_flag("--no-formations", o.no_formations,
               "Draw no stalactites, stalagmites, columns, draperies or fallen blocks (the "
               "formations' instances)");
  app.add_flag("--no-fine-detail", o.no_fine_detail,
               "No fine detail on the rock (the grain, pits and joints below 5 cm that the "
               "shading adds, faded with distance; J toggles)");
  app.add_flag("--no-ao", o.no_ao,
               "No ambient occlusion (the relief's crevices and the roots of formations "
               "darken; K toggles)");
  app.add_flag("--no-bloom", o.no_bloom, "No glow around the mineral veins (B toggles)");
  app.add_flag("--no-motion-blur", o.no_motion_blur,
               "No blur along the camera's motion (M toggles)");
  app.add_flag("--no-headlamp", o.no_headlamp,
               "Start with the headlamp off: only the world's lights and flares light the cave (Q "
               "toggles)");
  app.add_flag("--no-world-lights", o.no_world_lights,
               "Leave out the world's lights (glow-worms, mineral seams, crystals): for "
               "comparisons");
  app.add_option("--flares", o.flares,
                 "Screenshot: throw this many flares from the camera before the picture (one "
                 "every half second, fanned 12 degrees apart, along the view), then let them fall "
                 "and settle for 4 s of simulated time")
      ->capture_default_str()
      ->check(CLI::Range(0, 4));
  app.add_option("--exposure", o.exposure,
                 "Brightness before tone mapping (1 is the default exposure)")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 20.0));
  app.add_option("--json", o.json,
                 "With --bench: also write the statistics to this JSON file. With --screenshot: "
                 "write what the picture shows beside it: depth_m (p10, median, p90 of the view "
                 "depth in metres along the view axis, over the pixels that show rock: the far "
                 "plane, the background, fog caps over portals and rock wholly in fog do not "
                 "count), covered (the share of pixels that show rock), lit_depth_m (the same "
                 "over the rock that is lit), clipped (the share of pixels with a channel at "
                 "250 of 255 or more: light burnt white), lights (each light "
                 "source lighting the frame: kind (headlamp, glow_worms, mineral_seam, crystals, "
                 "flare) and position), the pose, "
                 "seed, mode and size");
  app.add_option("--gl", o.gl,
                 "How --screenshot and --bench get OpenGL: glfw (a hidden window: needs an X or "
                 "Wayland display), egl (no window system: a GPU's driver, or Mesa's llvmpipe), or "
                 "auto (glfw where DISPLAY or WAYLAND_DISPLAY is set, else egl). The window always "
                 "uses glfw")
      ->capture_default_str();
  app.add_option("--log-level", o.log_level, "Log level on stderr (trace ... off)")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help prints and exits 0; every bad flag exits 2, as in every Grotto binary.
    return app.exit(e) == 0 ? 0 : 2;
  }

  if (!o.pose_text.empty()) {
    o.pose = parse_pose(o.pose_text);
    if (!o.pose)
      return fail(
          "--pose: expected x,y,z, x,y,z,yaw,pitch or room:<room id> such as room:0.0.0.r3 "
          "(got '" +
          o.pose_text + "')");
  }
  if (o.mode_text == "walk") {
    o.mode = play::Mode::kWalk;
  } else if (o.mode_text == "fly") {
    o.mode = play::Mode::kFly;
  } else {
    return fail("--mode must be walk or fly (got '" + o.mode_text + "')");
  }
  auto token = proto::resolve_token(o.token_file, std::getenv(proto::kTokenEnvVariable));
  if (!token) return fail(token.error().message);
  o.token = std::move(token).value();
  auto net = stream::parse_net_profile(o.net_text);
  if (!net) return fail(net.error().message);
  o.net = *net;
  if (o.lod_text == "distance") {
    o.lod = render::LodHeuristic::kDistance;
  } else if (o.lod_text == "screen") {
    o.lod = render::LodHeuristic::kScreenSpace;
  } else if (o.lod_text == "silhouette") {
    o.lod = render::LodHeuristic::kSilhouette;
  } else {
    return fail("--lod must be distance, screen or silhouette (got '" + o.lod_text + "')");
  }
  if (o.flythrough_s && !(std::isfinite(*o.flythrough_s) && *o.flythrough_s >= 0))
    return fail("--flythrough must be a time along the path of 0 seconds or more (got " +
                number(*o.flythrough_s) + ")");
  if (o.bench_s && !(std::isfinite(*o.bench_s) && *o.bench_s > 0 && *o.bench_s <= 3600))
    return fail("--bench must be a number of seconds in (0, 3600] (got " + number(*o.bench_s) +
                ")");
  if (o.hold && !(o.bench_s && o.pose_text.size()))
    return fail("--hold is for --bench with --pose (it holds that pose)");
  if (o.bench_s && !o.screenshot.empty())
    return fail("--bench and --screenshot are separate runs: give one of them");
  if (o.gl != "auto" && o.gl != "glfw" && o.gl != "egl")
    return fail("--gl must be auto, glfw or egl (got '" + o.gl + "')");
  if (o.gl == "egl" && o.screenshot.empty() && !o.bench_s)
    return fail("--gl egl is for --screenshot and --bench (the window needs a display: glfw)");
  if (o.flares > 0 && o.screenshot.empty())
    return fail("--flares is for --screenshot (in the window, F throws a flare)");
  if (!o.json.empty() && !o.bench_s && o.screenshot.empty())
    return fail("--json needs --bench or --screenshot (it holds their report)");
  return std::nullopt;
}

}  // namespace grotto::app
