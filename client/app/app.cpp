#include "client/app/app.hpp"

#include <GLFW/glfw3.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "client/app/bench_report.hpp"
#include "client/app/camera_aim.hpp"
#include "client/app/screenshot_report.hpp"
#include "common/cave/lights.hpp"
#include "common/png/png.hpp"

namespace grotto::app {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr double kPi = 3.14159265358979323846;
// m/s told to the stream while waiting: 64-128 m of horizon (the fixed 4 s, halved behind the
// camera), so that every room whose portal lies within the fog's end (64 m) is asked for, behind
// the camera too (at 20 m/s a hall's portal 47 m behind was waited for and never asked for).
constexpr double kPlanSpeed = 32;

int fail(const std::string& message) {
  std::fprintf(stderr, "grotto-client: %s\n", message.c_str());
  return 1;
}

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// A world light as the renderer takes it: colour x intensity, its range, its glowing patch.
render::Light to_light(const cave::WorldLight& w, const cave::Room& room) {
  render::Light l;
  l.kind = cave::light_kind_name(w.kind);
  l.position = w.position;
  l.colour = glm::vec3(static_cast<float>(w.colour.x), static_cast<float>(w.colour.y),
                       static_cast<float>(w.colour.z)) *
             static_cast<float>(w.intensity);
  l.range = static_cast<float>(w.range);
  l.size = static_cast<float>(w.size);
  l.source_radius = static_cast<float>(cave::light_source_radius(w));
  l.glow = static_cast<int>(w.kind);  // shaders/lights.glsl's GLOW_* follow cave::LightKind
  l.bound_centre = room.sphere.centre;
  l.bound_radius = static_cast<float>(cave::light_bound_radius(room));
  l.room = room.id;
  return l;
}

// A burning flare: a warm magnesium-red light bright enough to show a hall's far wall (20 m and
// more away), with a flicker that is a function of its age alone (pictures repeat).
render::Light flare_light(const play::Flare& f, const play::CollisionWorld& world) {
  const double flicker = 0.9 + 0.1 * std::sin(f.age * 23.0) * std::sin(f.age * 7.3 + 1.0);
  const float power = static_cast<float>(160.0 * play::flare_brightness(f) * flicker);
  render::Light l;
  l.kind = "flare";
  l.position = f.position;
  l.colour = glm::vec3(1.0f, 0.5f, 0.22f) * power;
  l.range = 48;
  l.size = 0.3f;
  l.glow = 3;
  if (const cave::Room* room = world.room_at(f.position)) {
    l.bound_centre = room->sphere.centre;
    l.bound_radius = static_cast<float>(cave::light_bound_radius(*room));
    l.room = room->id;
  }
  return l;
}

// The room whose space holds p by the cave's rule, among the rooms on the GPU.
std::optional<cave::RoomId> room_at(const render::GpuRoomCache& cache, Vec3 p) {
  const cave::Room* room = cave::room_at(
      cache.rooms(), p, [](const auto& entry) -> const cave::Room& { return entry.second.room; });
  return room ? std::optional<cave::RoomId>(room->id) : std::nullopt;
}

// The neighbours of p's room that a picture from p can show: through a portal nearer than the
// fog's end (a hall's far portals lie beyond it, and beyond the stream's horizon).
std::vector<cave::RoomId> visible_neighbours(const Session& s, cave::RoomId id, Vec3 p) {
  std::vector<cave::RoomId> out;
  for (const auto& portal : s.cache.rooms().at(id).room.portals)
    if (length(portal.centre - p) - portal.radius < s.render_options.fog_end)
      out.push_back(portal.neighbour);
  return out;
}

// Every arrived room's formations are placed (place_formations).
bool formations_placed(const Session& s) {
  return s.to_place.empty() && s.placing.empty();
}

// Rooms around p are ready: its room and every neighbour it can show are on the GPU with their
// formations, and nothing is in flight.
bool surroundings_ready(const Session& s, Vec3 p) {
  auto id = room_at(s.cache, p);
  if (!id) return false;
  for (cave::RoomId n : visible_neighbours(s, *id, p))
    if (!s.cache.contains(n)) return false;
  return s.stream.stats().in_flight == 0 && formations_placed(s);
}

// Pumps the stream until `ready` holds or the deadline passes (false, with a warning).
template <typename Ready>
bool wait_until(Session& s, Clock::time_point deadline, const char* what, Ready&& ready) {
  while (!ready()) {
    if (s.stream.state() == stream::StreamState::kFailed) return false;  // refused for good
    if (Clock::now() > deadline) {
      // A pose in solid rock is located in no room, so nothing streams in.
      const auto id = room_at(s.cache, s.camera.position);
      std::string missing;
      if (id)
        for (cave::RoomId n : visible_neighbours(s, *id, s.camera.position))
          if (!s.cache.contains(n)) missing += " " + n.to_string();
      spdlog::warn(
          "event={}_timeout rooms={} placed={} camera_room={} missing=\"{}\" in_flight={} "
          "hint=\"is the pose inside the cave?\"",
          what, s.cache.size(), s.placed, id ? id->to_string() : "none", missing,
          s.stream.stats().in_flight);
      return false;
    }
    pump(s, kPlanSpeed);
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

// One attempt at the scripted path from the start pose; while a descriptor it needs is missing
// the stream is pointed at the path's end so that the room streams in. True once planned.
bool try_plan_path(Session& s) {
  if (s.path) return true;
  if (!s.start) return false;
  std::optional<cave::RoomId> room = s.start_room;
  if (!room) room = room_at(s.cache, *s.start);
  if (!room) return false;
  auto lookup = [&](cave::RoomId id) { return s.stream.descriptor(id); };
  play::Flythrough path = play::Flythrough::plan(*s.start, *room, lookup, kPathHops);
  if (path.waiting_for()) {
    s.stream_focus = path.waypoints().back();
    return false;
  }
  spdlog::info("event=path rooms={} length_m={:.1f}", path.rooms().size(), path.length());
  s.path = std::move(path);
  s.stream_focus.reset();
  return true;
}

// The camera at `seconds` along the scripted path.
void follow_path(Session& s, double seconds) {
  app::follow_path(s.camera, s.aim_room, *s.path, seconds);
}

}  // namespace

Session::Session(const Options& o, render::Renderer& r, render::Overlay& ov,
                 render::GpuRoomCache& c, stream::Stream& st)
    : options(o), renderer(r), overlay(ov), cache(c), stream(st), player(Vec3{}) {
  play::PlayerParams params;
  params.speed = o.speed;
  player = play::Player(Vec3{}, params);
  player.set_mode(o.mode);
  if (o.pose && o.pose->room) {
    pose_room = o.pose->room;
  } else if (o.pose) {
    camera.position = o.pose->position;
    camera.yaw = o.pose->yaw * kPi / 180;
    camera.pitch = o.pose->pitch * kPi / 180;
    placed = true;
    start = camera.position;
    player.place(camera.position);
  }
  render_options.tessellation = !o.no_tess;
  render_options.max_tess = o.tess_max;
  render_options.target_pixels = o.tess_pixels;
  render_options.wireframe = o.wireframe;
  render_options.surface =
      o.surface == "phong" ? render::Surface::kPhong : render::Surface::kPnTriangles;
  render_options.lod = o.lod;
  render_options.portal_culling = !o.no_portal_culling;
  if (o.no_displacement) render_options.displacement = 0;
  render_options.bloom = !o.no_bloom;
  render_options.motion_blur = !o.no_motion_blur;
  render_options.exposure = static_cast<float>(o.exposure);
  render_options.headlamp = !o.no_headlamp;
  render_options.ambient_occlusion = !o.no_ao;
  render_options.formations = !o.no_formations;
  // Benchmarks and screenshot reports time each pass on the GPU (passes_ms).
  render_options.gpu_timing = o.bench_s.has_value() || !o.json.empty();
  if (o.no_fine_detail) render_options.fine_detail = 0;
  show_overlay = o.overlay.value_or(o.screenshot.empty() && !o.bench_s);
}

// Hands finished placements to the cache and the collision world and starts the next ones, at
// most one a hardware thread at once.
void place_formations(Session& s) {
  for (auto it = s.placing.begin(); it != s.placing.end();) {
    if (it->second.wait_for(std::chrono::seconds(0)) != std::future_status::ready) {
      ++it;
      continue;
    }
    std::vector<formations::FormationShape> placed = it->second.get();
    s.world.set_formations(it->first, placed);
    s.cache.set_formations(it->first, std::move(placed));
    it = s.placing.erase(it);
  }
  std::erase_if(s.retired, [](const auto& f) {
    return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
  });
  const size_t threads = std::max(1u, std::thread::hardware_concurrency());
  while (!s.to_place.empty() && s.placing.size() + s.retired.size() < threads) {
    std::shared_ptr<const stream::ReadyRoom> room = std::move(s.to_place.front());
    s.to_place.pop_front();
    if (!s.cache.contains(room->room.id)) continue;  // evicted before its turn
    if (auto old = s.placing.find(room->room.id); old != s.placing.end()) {
      s.retired.push_back(std::move(old->second));
      s.placing.erase(old);
    }
    s.placing[room->room.id] = std::async(std::launch::async, [room] {
      return formations::place(
          formations::surface_of(room->mesh, room->origin, room->room.sphere.radius));
    });
  }
}

void pump(Session& s, double speed) {
  for (auto& room : s.stream.take_new_rooms()) {
    // The rock now, its formations when a worker has placed them (place_formations).
    s.cache.upload(*room, {});
    s.world.add(*room, {});
    s.to_place.push_back(room);
    // The world's lights: a function of the seed and the room (the default layout parameters'
    // floors, as the client assumes them elsewhere).
    if (const auto seed = s.stream.stats().seed; seed && !s.options.no_world_lights) {
      std::vector<render::Light> lights;
      for (const cave::WorldLight& w : cave::room_lights(*seed, cave::LayoutParams{}, room->room))
        lights.push_back(to_light(w, room->room));
      s.world_lights[room->room.id] = std::move(lights);
    }
  }
  for (auto id : s.stream.take_evicted()) {
    s.cache.evict(id);
    s.world.evict(id);
    s.world_lights.erase(id);
    if (auto it = s.placing.find(id); it != s.placing.end()) {
      s.retired.push_back(std::move(it->second));
      s.placing.erase(it);
    }
  }
  place_formations(s);
  aim_when_known(s.camera, s.aim_room, [&](cave::RoomId id) { return s.stream.descriptor(id); });
  if (!s.placed && s.pose_room) {
    // --pose room:<id>: the stream plans from that room until its descriptor is here, then the
    // camera starts inside it, looking through its widest portal.
    if (auto room = s.stream.descriptor(*s.pose_room)) {
      s.camera.position = cave::interior_point(*room);
      s.placed = true;
      s.start = s.camera.position;
      s.start_room = room->id;
      s.aim_room = room->id;
      s.player.place(s.camera.position);
      spdlog::info("event=pose_room room={} x={} y={} z={}", room->id.to_string(),
                   s.camera.position.x, s.camera.position.y, s.camera.position.z);
    } else {
      stream::Pose pose;
      pose.room = s.pose_room;
      s.stream.set_pose(pose);
    }
  } else if (!s.placed) {
    if (auto spawn = s.stream.spawn_point()) {
      s.camera.position = spawn->position;
      s.placed = true;
      s.start = spawn->position;
      s.start_room = spawn->room;
      s.aim_room = spawn->room;
      s.player.place(spawn->position);
      spdlog::info("event=spawn room={} x={} y={} z={}", spawn->room.to_string(), spawn->position.x,
                   spawn->position.y, spawn->position.z);
    }
  }
  if (s.placed) {
    stream::Pose pose;
    pose.position = s.stream_focus.value_or(s.camera.position);
    pose.forward = render::camera_forward(s.camera);
    pose.speed = speed;
    s.stream.set_pose(pose);
  }
}

std::vector<render::Light> scene_lights(const Session& s) {
  std::vector<render::Light> out;
  for (const auto& [id, lights] : s.world_lights)
    out.insert(out.end(), lights.begin(), lights.end());
  for (const play::Flare& f : s.flares)
    out.push_back(flare_light(f, s.world));
  return out;
}

void throw_flare(Session& s) {
  play::add_flare(s.flares, play::throw_flare(s.camera.position, render::camera_forward(s.camera)));
}

render::FrameStats draw_frame(Session& s, int width, int height) {
  const auto began = Clock::now();
  const std::vector<render::Light> lights = scene_lights(s);
  render::FrameStats stats =
      s.renderer.draw(s.cache, s.camera, width, height, s.render_options, lights);
  const stream::StreamStats st = s.stream.stats();
  // The first frame's time would include the wait for rooms: unknown.
  const double frame_ms = s.last_frame == s.began ? 0 : 1000 * seconds_since(s.last_frame);
  s.meter.frame(frame_ms, seconds_since(s.began), st.bytes_received, s.stream.take_samples());
  s.last_frame = began;
  if (s.show_overlay) {
    HudState hud;
    hud.frame_ms = s.meter.frame_ms();
    hud.latency_ms = s.meter.latency_ms();
    hud.kbytes_per_s = s.meter.kbytes_per_s();
    hud.rooms_on_gpu = s.cache.size();
    hud.frame = stats;
    hud.stream = st;
    hud.render = s.render_options;
    hud.mode = s.following         ? "PATH"
               : s.player.noclip() ? "NOCLIP"
                                   : play::mode_name(s.player.mode());
    hud.help = s.show_keys;
    hud.position = s.camera.position;
    if (auto room = room_at(s.cache, s.camera.position)) hud.room = room->to_string();
    if (st.seed) hud.seed = std::to_string(*st.seed);
    s.overlay.draw(hud_lines(hud), width, height);
  }
  return stats;
}

namespace {

// --screenshot and --bench: frames of --width x --height into an offscreen framebuffer, rooms
// waited for until --wait seconds from now.
// Why the stream cannot deliver, when it has stopped for good (the server refused the world,
// the version or the token); empty while it may still.
std::string stream_refusal(const Session& s) {
  if (s.stream.state() != stream::StreamState::kFailed) return {};
  return "the server refused the stream: " + s.stream.stats().last_error;
}

// The share of pixels whose brightest channel passes `test`.
template <class Test>
double pixel_share(const std::vector<unsigned char>& rgb, Test test) {
  size_t n = 0;
  for (size_t i = 0; i + 2 < rgb.size(); i += 3)
    if (test(std::max({rgb[i], rgb[i + 1], rgb[i + 2]}))) ++n;
  return rgb.empty() ? 0 : static_cast<double>(n) / static_cast<double>(rgb.size() / 3);
}

// The share of pixels brighter than the dark beyond the lamp: a picture of the cave has many.
double lit_fraction(const std::vector<unsigned char>& rgb) {
  return pixel_share(rgb, [](unsigned char c) { return c > 12; });
}

// The share of pixels with a channel at 250 of 255 or more: light burnt to white (or to a pure
// hue), the rock's grain lost under it.
double clipped_fraction(const std::vector<unsigned char>& rgb) {
  return pixel_share(rgb, [](unsigned char c) { return c >= 250; });
}

std::string position_text(Vec3 p) {
  char text[96];
  std::snprintf(text, sizeof text, "(%.2f, %.2f, %.2f)", p.x, p.y, p.z);
  return text;
}

std::string seconds_text(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", s);
  return text;
}

std::string gl_string(GLenum name) {
  const auto* text = reinterpret_cast<const char*>(glGetString(name));
  return std::string(text != nullptr ? text : "unknown");
}

// Renders --frames frames of the current pose into fb and returns their pixels and the last
// frame's statistics.
std::vector<unsigned char> render_frames(Session& s, render::Framebuffer& fb,
                                         render::FrameStats& stats) {
  const Options& o = s.options;
  for (int i = 0; i < o.frames; ++i) {
    pump(s, o.speed);
    fb.bind();
    stats = draw_frame(s, o.width, o.height);
  }
  glFinish();
  return fb.read_rgb();
}

// Why the screenshot cannot show the cave (empty when it can): the stream refused, rooms missing,
// the camera in rock.
std::string screenshot_wait(Session& s, Clock::time_point deadline) {
  const Options& o = s.options;
  const std::string wait = "within --wait " + seconds_text(o.wait_s) + " s";
  if (o.flythrough_s) {
    if (!wait_until(s, deadline, "path_wait", [&] { return try_plan_path(s); })) {
      if (auto why = stream_refusal(s); !why.empty()) return why;
      return "the rooms of the scripted path did not arrive " + wait;
    }
    follow_path(s, *o.flythrough_s);
  }
  if (wait_until(s, deadline, "screenshot_wait",
                 [&] { return s.placed && surroundings_ready(s, s.camera.position); }))
    return {};
  if (auto why = stream_refusal(s); !why.empty()) return why;
  if (const stream::StreamStats st = s.stream.stats(); st.connects == 0)
    return "no connection to the server " + wait +
           (st.last_error.empty() ? std::string() : " (" + st.last_error + ")");
  if (!s.placed)
    return "no start pose " + wait +
           (s.pose_room ? " (room " + s.pose_room->to_string() + " did not arrive)"
                        : std::string(" (no spawn point from the server)"));
  if (s.cache.size() > 0 && !room_at(s.cache, s.camera.position))
    return "the camera is in solid rock: no room of the cave holds " +
           position_text(s.camera.position) +
           " (start in a room with --pose room:<id>, or leave --pose out for the spawn point)";
  return "the rooms around the camera did not arrive " + wait;
}

int screenshot(Session& s, render::Framebuffer& fb, Clock::time_point deadline) {
  const Options& o = s.options;
  std::string why = screenshot_wait(s, deadline);
  if (why.empty() && o.flares > 0) {
    // --flares: thrown one every half second, fanned 12 degrees apart, then 4 s to settle, in the
    // player's fixed steps (the same throws land in the same places).
    const render::Camera eye = s.camera;
    for (int i = 0; i < o.flares; ++i) {
      render::Camera aim = eye;
      aim.yaw += (i - (o.flares - 1) / 2.0) * 12.0 * kPi / 180;
      play::add_flare(s.flares, play::throw_flare(aim.position, render::camera_forward(aim)));
      const int eighths =
          i + 1 < o.flares ? 4 : 32;  // advance_flares takes a quarter second at most
      for (int k = 0; k < eighths; ++k)
        play::advance_flares(s.flares, 0.125, s.flare_carry, s.world);
    }
    for (const play::Flare& f : s.flares)
      spdlog::info("event=flare x={:.2f} y={:.2f} z={:.2f} resting={} bounces={}", f.position.x,
                   f.position.y, f.position.z, f.resting, f.bounces);
  }
  render::FrameStats stats;
  std::vector<unsigned char> rgb = render_frames(s, fb, stats);
  // A picture that shows nothing is a failure, not a black PNG.
  if (why.empty() && stats.rooms_drawn == 0)
    why = "no room of the cave is in view from " + position_text(s.camera.position);
  if (const double lit = lit_fraction(rgb); why.empty() && lit < 0.02)
    why = "the picture is dark (" + seconds_text(100 * lit) +
          " % of pixels lit): the camera faces rock at arm's length or sees nothing";
  // The view depth of the last frame, while its framebuffers are as it left them.
  std::vector<float> view_depth = s.renderer.read_view_depth();
  const DepthSummary depth = summarize_depth(view_depth);
  // How far the light reaches: the same over the pixels that are also lit (lit_fraction's test).
  for (size_t i = 0; i < view_depth.size() && 3 * i + 2 < rgb.size(); ++i)
    if (std::max({rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]}) <= 12)
      view_depth[i] = std::numeric_limits<float>::infinity();
  const DepthSummary lit_depth = summarize_depth(view_depth);
  if (why.empty() && depth.counted == 0)
    why = "no pixel shows rock nearer than the fog's end from " + position_text(s.camera.position);
  if (!why.empty()) {
    // With the overlay asked for, the picture shows what went wrong: write it, still failing.
    if (s.show_overlay) {
      if (auto w = png::write_png(o.screenshot, rgb, o.width, o.height); !w)
        return fail(w.error().message);
      return fail("--screenshot: " + why + " (wrote the overlay's picture of it to " +
                  o.screenshot + ")");
    }
    return fail("--screenshot: " + why + "; no picture written");
  }
  if (auto w = png::write_png(o.screenshot, rgb, o.width, o.height); !w)
    return fail(w.error().message);
  std::printf("grotto-client: wrote %s (%dx%d, %zu rooms loaded)\n", o.screenshot.c_str(), o.width,
              o.height, s.cache.size());
  if (!o.json.empty()) {
    ScreenshotReport report;
    report.picture = o.screenshot;
    report.seed = s.stream.stats().seed;
    report.width = o.width;
    report.height = o.height;
    report.position = s.camera.position;
    report.yaw_deg = s.camera.yaw * 180 / kPi;
    report.pitch_deg = s.camera.pitch * 180 / kPi;
    report.mode = play::mode_name(s.player.mode());
    report.depth = depth;
    report.lit_depth = lit_depth;
    report.clipped = clipped_fraction(rgb);
    report.lights = render::frame_lights(s.camera, s.render_options, scene_lights(s));
    report.rooms_loaded = s.cache.size();
    report.rooms_drawn = stats.rooms_drawn;
    report.relief = s.render_options.tessellation && s.render_options.displacement > 0;
    report.gl_renderer = gl_string(GL_RENDERER);
    report.formations = stats.formations;
    report.passes = stats.passes;
    std::ofstream out(o.json);
    out << screenshot_json(report);
    out.close();
    if (!out) return fail("--json: cannot write " + o.json);
  }
  return 0;
}

int bench(Session& s, render::Framebuffer& fb, Clock::time_point deadline) {
  const Options& o = s.options;
  if (o.hold) {
    // The start pose held: its surroundings loaded, as --screenshot waits for them.
    if (!wait_until(s, deadline, "bench_wait",
                    [&] { return s.placed && surroundings_ready(s, s.camera.position); }))
      return fail("--bench --hold: the rooms round the pose did not arrive within --wait " +
                  std::to_string(o.wait_s) + " s");
  } else {
    if (!wait_until(s, deadline, "path_wait", [&] { return try_plan_path(s); }))
      return fail("--bench: the scripted path's rooms did not arrive within --wait " +
                  std::to_string(o.wait_s) + " s");
    // Every room of the path on the GPU and the surroundings of its start, as --screenshot waits.
    follow_path(s, 0);
    wait_until(s, deadline, "bench_wait", [&] {
      for (cave::RoomId id : s.path->rooms())
        if (!s.cache.contains(id)) return false;
      return surroundings_ready(s, s.camera.position);
    });
  }

  std::vector<double> frame_ms;
  double patches = 0, formations = 0;
  std::array<std::vector<double>, 4> passes;  // FrameStats::Passes in its order
  const auto begin = Clock::now();
  std::fprintf(stderr, "grotto-client: bench: %zu rooms loaded; measuring %g s of frames\n",
               s.cache.size(), *o.bench_s);
  int reported = 0;
  while (seconds_since(begin) < *o.bench_s) {
    // Progress every 5 s on stderr (stdout carries the result line).
    if (const int now = static_cast<int>(seconds_since(begin) / 5); now > reported) {
      reported = now;
      std::fprintf(stderr, "grotto-client: bench: %.0f / %g s, %zu frames\n", seconds_since(begin),
                   *o.bench_s, frame_ms.size());
    }
    const auto frame_start = Clock::now();
    if (!o.hold) follow_path(s, seconds_since(begin));
    pump(s, o.hold ? 0.0 : kPathSpeed);
    fb.bind();
    const render::FrameStats stats = draw_frame(s, o.width, o.height);
    patches += static_cast<double>(stats.patches);
    formations += stats.formations;
    if (stats.passes.timed) {
      passes[0].push_back(stats.passes.rock);
      passes[1].push_back(stats.passes.formations);
      passes[2].push_back(stats.passes.caps);
      passes[3].push_back(stats.passes.post);
    }
    glFinish();  // the frame's GPU work belongs to its time (llvmpipe renders here)
    frame_ms.push_back(1000 * seconds_since(frame_start));
  }
  BenchReport report;
  summarize(frame_ms, seconds_since(begin), report);
  report.width = o.width;
  report.height = o.height;
  report.tess_max = o.tess_max;
  report.tessellation = s.render_options.tessellation;
  report.surface = o.surface;
  report.rooms_loaded = s.cache.size();
  report.relief = s.render_options.tessellation && s.render_options.displacement > 0;
  report.bloom = s.render_options.bloom;
  report.motion_blur = s.render_options.motion_blur;
  report.gl_renderer = gl_string(GL_RENDERER);
  report.gl_version = gl_string(GL_VERSION);
  report.patches_mean = frame_ms.empty() ? 0 : patches / static_cast<double>(frame_ms.size());
  report.formations_mean = frame_ms.empty() ? 0 : formations / static_cast<double>(frame_ms.size());
  static constexpr const char* kPassNames[4] = {"rock", "formations", "caps", "post"};
  for (size_t k = 0; k < passes.size(); ++k) {
    std::vector<double>& v = passes[k];
    if (v.empty()) continue;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    report.passes_ms.emplace_back(kPassNames[k], v[v.size() / 2]);
  }
  report.path_length_m = o.hold ? 0.0 : s.path->length();
  report.path_rooms = o.hold ? 0 : s.path->rooms().size();
  std::printf("%s\n", bench_line(report).c_str());
  if (!o.json.empty()) {
    std::ofstream out(o.json);
    out << bench_json(report);
    out.close();
    if (!out) return fail("--json: cannot write " + o.json);
  }
  return 0;
}

}  // namespace

int run_headless(Session& s) {
  const Options& o = s.options;
  auto fb = render::Framebuffer::create(o.width, o.height);
  if (!fb) return fail(fb.error().message);
  const Clock::time_point deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                        std::chrono::duration<double>(o.wait_s));
  return o.bench_s ? bench(s, fb.value(), deadline) : screenshot(s, fb.value(), deadline);
}

int run_window(Session& s, GLFWwindow* window) {
  struct Mouse {
    double last_x = 0, last_y = 0;
    bool seen = false;
    render::Camera* camera = nullptr;
  } mouse;
  mouse.camera = &s.camera;
  glfwSetWindowUserPointer(window, &mouse);
  glfwSetInputMode(window, GLFW_CURSOR, GLFW_CURSOR_DISABLED);
  glfwSetCursorPosCallback(window, [](GLFWwindow* w, double x, double y) {
    auto* m = static_cast<Mouse*>(glfwGetWindowUserPointer(w));
    if (m->seen) {
      constexpr double kRadiansPerPixel = 0.0025;
      m->camera->yaw += (x - m->last_x) * kRadiansPerPixel;
      m->camera->pitch = std::clamp(m->camera->pitch - (y - m->last_y) * kRadiansPerPixel,
                                    -89 * kPi / 180, 89 * kPi / 180);
    }
    m->last_x = x, m->last_y = y, m->seen = true;
  });

  render::RenderOptions& ro = s.render_options;
  bool& following = s.following;
  following = s.options.flythrough_s.has_value();
  const auto began = Clock::now();
  std::optional<Clock::time_point> path_began;
  auto last = Clock::now();
  double title_timer = 0;
  bool t_down = false, p_down = false, f_down = false, g_down = false, n_down = false;
  bool r_down = false, q_down = false;
  bool x_down = false, o_down = false, l_down = false, h_down = false, v_down = false;
  bool b_down = false, m_down = false, k_down = false, j_down = false;
  auto key = [&](int k) { return glfwGetKey(window, k) == GLFW_PRESS; };
  auto pressed = [&](int k, bool& was) {
    const bool now = key(k);
    const bool edge = now && !was;
    was = now;
    return edge;
  };
  while (!glfwWindowShouldClose(window)) {
    glfwPollEvents();
    const auto now = Clock::now();
    const double dt = std::min(std::chrono::duration<double>(now - last).count(), 0.1);
    last = now;
    if (key(GLFW_KEY_ESCAPE)) glfwSetWindowShouldClose(window, 1);
    if (pressed(GLFW_KEY_T, t_down)) ro.tessellation = !ro.tessellation;
    if (pressed(GLFW_KEY_R, r_down)) ro.wireframe = !ro.wireframe;
    if (pressed(GLFW_KEY_F, f_down) && s.placed) throw_flare(s);
    if (pressed(GLFW_KEY_Q, q_down)) ro.headlamp = !ro.headlamp;
    if (pressed(GLFW_KEY_P, p_down))
      ro.surface = ro.surface == render::Surface::kPhong ? render::Surface::kPnTriangles
                                                         : render::Surface::kPhong;
    if (pressed(GLFW_KEY_G, g_down))
      s.player.set_mode(s.player.mode() == play::Mode::kWalk ? play::Mode::kFly
                                                             : play::Mode::kWalk);
    if (pressed(GLFW_KEY_N, n_down)) s.player.set_noclip(!s.player.noclip());
    if (pressed(GLFW_KEY_X, x_down))
      ro.displacement = ro.displacement > 0 ? 0.0f : render::RenderOptions{}.displacement;
    if (pressed(GLFW_KEY_O, o_down)) ro.portal_culling = !ro.portal_culling;
    if (pressed(GLFW_KEY_B, b_down)) ro.bloom = !ro.bloom;
    if (pressed(GLFW_KEY_M, m_down)) ro.motion_blur = !ro.motion_blur;
    if (pressed(GLFW_KEY_K, k_down)) ro.ambient_occlusion = !ro.ambient_occlusion;
    if (pressed(GLFW_KEY_J, j_down))
      ro.fine_detail = ro.fine_detail > 0 ? 0.0f : render::RenderOptions{}.fine_detail;
    if (pressed(GLFW_KEY_L, l_down))
      ro.lod = static_cast<render::LodHeuristic>((static_cast<int>(ro.lod) + 1) % 3);
    if (pressed(GLFW_KEY_H, h_down)) s.show_keys = !s.show_keys;
    if (pressed(GLFW_KEY_V, v_down)) s.show_overlay = !s.show_overlay;

    const Vec3 forward = render::camera_forward(s.camera);
    const Vec3 right{std::cos(s.camera.yaw), 0, std::sin(s.camera.yaw)};
    play::PlayerInput input;
    if (key(GLFW_KEY_W)) input.move = input.move + forward;
    if (key(GLFW_KEY_S)) input.move = input.move - forward;
    if (key(GLFW_KEY_D)) input.move = input.move + right;
    if (key(GLFW_KEY_A)) input.move = input.move - right;
    input.up = key(GLFW_KEY_SPACE);
    input.down = key(GLFW_KEY_C);
    input.run = key(GLFW_KEY_LEFT_SHIFT) || key(GLFW_KEY_RIGHT_SHIFT);
    const bool moving = length(input.move) > 0 || input.up || input.down;

    if (following && moving && s.path) {
      following = false;  // a movement key takes over where the path was
      s.player.place(s.camera.position);
    }
    if (following) {
      if (try_plan_path(s)) {
        if (!path_began) path_began = now;
        follow_path(s, *s.options.flythrough_s + seconds_since(*path_began));
      }
    } else if (s.placed && (s.player.noclip() || s.world.room_at(s.player.eye()) != nullptr)) {
      // The player waits where it is until its room has streamed in (nothing to stand on yet).
      s.player.advance(dt, input, s.world);
      s.camera.position = s.player.eye();
    }
    play::advance_flares(s.flares, dt, s.flare_carry, s.world);
    const double speed = s.options.speed * (input.run ? s.player.params().run_factor : 1);
    pump(s, moving ? speed : s.options.speed);

    int w = 0, h = 0;
    glfwGetFramebufferSize(window, &w, &h);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, w, h);
    const render::FrameStats fs = draw_frame(s, w, h);
    glfwSwapBuffers(window);

    title_timer += dt;
    if (title_timer > 0.5) {
      title_timer = 0;
      const stream::StreamStats st = s.stream.stats();
      char title[256];
      std::snprintf(
          title, sizeof title,
          "grotto-client  %.1f ms  rooms %zu drawn %d in flight %llu  %s%s  %s%s  %s  %.0f s",
          dt * 1000, s.cache.size(), fs.rooms_drawn, static_cast<unsigned long long>(st.in_flight),
          ro.tessellation ? (ro.surface == render::Surface::kPhong ? "phong" : "pn") : "flat",
          ro.wireframe ? " wire" : "", following ? "path" : play::mode_name(s.player.mode()),
          s.player.noclip() ? " noclip" : "", stream::state_name(st.state), seconds_since(began));
      glfwSetWindowTitle(window, title);
    }
  }
  return 0;
}

}  // namespace grotto::app
