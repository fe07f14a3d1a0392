// grotto-client: the player's program (issue 7). A GLFW window over client/render, fed by a
// client/stream Stream connected to --server or to a server started in-process; first-person fly
// controls; a headless --screenshot mode for tests and docs.
#include <GLFW/glfw3.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "client/render/gl.hpp"
#include "client/render/renderer.hpp"
#include "client/render/room_cache.hpp"
#include "client/stream/stream.hpp"
#include "server/server.hpp"
#include "tools/png.hpp"

namespace {

using namespace std::chrono_literals;
using grotto::Vec3;
namespace render = grotto::render;
namespace client = grotto::client;

constexpr double kPi = 3.14159265358979323846;

struct Options {
  std::string server_url;  // empty: an in-process server
  std::optional<uint64_t> seed;
  std::string device = "auto";
  int width = 1280;
  int height = 720;
  float tess_max = 8;
  bool no_tess = false;
  bool wireframe = false;
  std::string surface = "pn";
  std::string screenshot;
  int frames = 30;
  std::string pose;
  double wait_s = 60;
  double speed = 4;
  std::string log_level = "warn";
};

struct Pose5 {
  Vec3 position;
  double yaw = 0, pitch = 0;  // degrees
};

std::optional<Pose5> parse_pose(const std::string& text) {
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
  Pose5 p{{v[0], v[1], v[2]}, 0, 0};
  if (v.size() == 5) p.yaw = v[3], p.pitch = v[4];
  return p;
}

// Prints the plain sentence issue 7 asks for instead of a raw GLFW error.
int no_display(const std::string& why) {
  std::fprintf(stderr,
               "grotto-client: no display (%s); run it under a desktop session or `xvfb-run -a "
               "grotto-client ...`, or use grotto-load for headless streaming\n",
               why.c_str());
  return 1;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "grotto-client: %s\n", message.c_str());
  return 1;
}

// The room whose sphere holds p most deeply, among the rooms on the GPU.
std::optional<grotto::cave::RoomId> room_at(const render::GpuRoomCache& cache, Vec3 p) {
  std::optional<grotto::cave::RoomId> best;
  double best_depth = 0;
  for (const auto& [id, room] : cache.rooms()) {
    Vec3 d = p - room.room.sphere.centre;
    double depth = room.room.sphere.radius - std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (depth > best_depth) best = id, best_depth = depth;
  }
  return best;
}

// Rooms around the camera are ready: its room and every neighbour through its portals are on the
// GPU, and nothing is in flight.
bool surroundings_ready(const render::GpuRoomCache& cache, const client::Stream& stream, Vec3 p) {
  auto id = room_at(cache, p);
  if (!id) return false;
  for (const auto& portal : cache.rooms().at(*id).room.portals)
    if (!cache.contains(portal.neighbour)) return false;
  return stream.stats().in_flight == 0;
}

struct Input {
  double last_x = 0, last_y = 0;
  bool have_mouse = false;
  render::Camera* camera = nullptr;
};

void on_cursor(GLFWwindow* window, double x, double y) {
  auto* in = static_cast<Input*>(glfwGetWindowUserPointer(window));
  if (in->have_mouse) {
    constexpr double kRadiansPerPixel = 0.0025;
    in->camera->yaw += (x - in->last_x) * kRadiansPerPixel;
    in->camera->pitch = std::clamp(in->camera->pitch - (y - in->last_y) * kRadiansPerPixel,
                                   -89 * kPi / 180, 89 * kPi / 180);
  }
  in->last_x = x, in->last_y = y, in->have_mouse = true;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "grotto-client: explore Grotto's endless cave. Streams rooms from --server (or from a "
      "server started in-process) and renders them with hardware tessellation (OpenGL 4.1). "
      "Mouse: look; W/A/S/D: move; Space/C: up/down; Shift: run; T: tessellation on/off; P: PN "
      "triangles/Phong; F: wireframe; Esc: quit."};
  app.add_option("--server", o.server_url,
                 "Server URL ws://host:port[/ws]; without it a server runs in-process");
  app.add_option("--seed", o.seed,
                 "World seed (unsigned 64-bit): the in-process server's world, or the world "
                 "asked of --server (default: the server's)");
  app.add_option("--device", o.device,
                 "In-process server's OpenCL device: auto, gpu, accelerator, cpu, none (CPU "
                 "reference)")
      ->capture_default_str();
  app.add_option("--width", o.width, "Window or screenshot width in pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  app.add_option("--height", o.height, "Window or screenshot height in pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  app.add_option("--tess-max", o.tess_max,
                 "MaxTess: the tessellation level of the nearest edges (1-64)")
      ->capture_default_str()
      ->check(CLI::Range(1.0f, 64.0f));
  app.add_flag("--no-tess", o.no_tess,
               "Draw the patch mesh flat: no tessellation, no displacement");
  app.add_flag("--wireframe", o.wireframe, "Draw edges only");
  app.add_option("--surface", o.surface, "Tessellated surface: pn (PN triangles) or phong")
      ->capture_default_str()
      ->check(CLI::IsMember({"pn", "phong"}));
  app.add_option("--screenshot", o.screenshot,
                 "Headless: render --frames frames, write this PNG and exit");
  app.add_option("--frames", o.frames, "Frames rendered before the screenshot")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--pose", o.pose,
                 "Start pose x,y,z[,yaw,pitch] (metres, degrees; yaw 0 looks along -z, positive "
                 "turns to +x); default: the server's spawn point");
  app.add_option("--wait", o.wait_s,
                 "Screenshot: seconds to wait at most for the rooms around the pose")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--speed", o.speed, "Walking speed in m/s (Shift runs at 4x)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 1000.0));
  app.add_option("--log-level", o.log_level, "Log level on stderr (trace ... off)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::from_str(o.log_level));

  std::optional<Pose5> start_pose;
  if (!o.pose.empty()) {
    start_pose = parse_pose(o.pose);
    if (!start_pose)
      return fail("--pose: expected x,y,z or x,y,z,yaw,pitch (got '" + o.pose + "')");
  }

  // The display first: without one nothing else is worth starting.
  const char* display = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  if ((display == nullptr || *display == '\0') && (wayland == nullptr || *wayland == '\0'))
    return no_display("DISPLAY is not set");
  glfwSetErrorCallback([](int, const char* text) { spdlog::debug("event=glfw_error {}", text); });
  if (glfwInit() != GLFW_TRUE)
    return no_display(std::string("cannot open DISPLAY=") + (display ? display : ""));
  struct GlfwGuard {
    ~GlfwGuard() { glfwTerminate(); }
  } glfw_guard;

  const bool headless = !o.screenshot.empty();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, headless ? GLFW_FALSE : GLFW_TRUE);
  GLFWwindow* window = glfwCreateWindow(headless ? 64 : o.width, headless ? 64 : o.height,
                                        "grotto-client", nullptr, nullptr);
  if (window == nullptr)
    return fail("this display gives no OpenGL 4.1 core context (the renderer needs tessellation)");
  glfwMakeContextCurrent(window);
  glfwSwapInterval(headless ? 0 : 1);
  spdlog::info("event=gl_context {}", render::describe_context());

  auto renderer_or = render::Renderer::create();
  if (!renderer_or) return fail(renderer_or.error().message);
  // GL objects: released below while the context still exists.
  auto renderer_owner = std::make_unique<render::Renderer>(std::move(renderer_or).value());
  auto cache_owner = std::make_unique<render::GpuRoomCache>();
  render::Renderer& renderer = *renderer_owner;
  render::GpuRoomCache& cache = *cache_owner;

  // The in-process server when no --server was given.
  std::unique_ptr<grotto::server::Server> server;
  std::string url = o.server_url;
  if (url.empty()) {
    grotto::server::ServerConfig config;
    config.port = 0;
    config.bind = "127.0.0.1";
    if (o.seed) config.seed = *o.seed;
    config.generator.builder.device.device = o.device;
    config.drain_timeout = 2000ms;
    config.log_level = o.log_level;
    auto started = grotto::server::Server::start(config);
    if (!started) return fail("in-process server: " + started.error().message);
    server = std::move(started).value();
    url = "ws://127.0.0.1:" + std::to_string(server->port()) + "/ws";
  }
  client::Runtime runtime(1, 0);
  client::StreamOptions so;
  so.url = url;
  so.seed = o.seed;
  so.name = "grotto-client";
  so.spawn = !start_pose.has_value();
  auto stream_or = client::Stream::start(so, runtime);
  if (!stream_or) return fail(stream_or.error().message);
  std::unique_ptr<client::Stream> stream = std::move(stream_or).value();

  render::Camera camera;
  bool placed = false;
  if (start_pose) {
    camera.position = start_pose->position;
    camera.yaw = start_pose->yaw * kPi / 180;
    camera.pitch = start_pose->pitch * kPi / 180;
    placed = true;
  }

  render::RenderOptions ro;
  ro.tessellation = !o.no_tess;
  ro.max_tess = o.tess_max;
  ro.wireframe = o.wireframe;
  ro.surface = o.surface == "phong" ? render::Surface::kPhong : render::Surface::kPnTriangles;

  // At the spawn point the camera looks through the spawn room's widest portal, into the cave
  // rather than at the nearest wall, once the room's descriptor has arrived.
  std::optional<grotto::cave::RoomId> aim_room;
  auto pump = [&](double speed) {
    for (auto& room : stream->take_new_rooms())
      cache.upload(*room);
    for (auto id : stream->take_evicted())
      cache.evict(id);
    if (aim_room) {
      if (auto room = stream->descriptor(*aim_room)) {
        aim_room.reset();
        const grotto::cave::Portal* widest = nullptr;
        for (const auto& portal : room->portals)
          if (widest == nullptr || portal.radius > widest->radius) widest = &portal;
        if (widest != nullptr) {
          Vec3 d = widest->centre - camera.position;
          double horizontal = std::sqrt(d.x * d.x + d.z * d.z);
          camera.yaw = std::atan2(d.x, -d.z);
          camera.pitch = std::clamp(std::atan2(d.y, horizontal), -kPi / 4, kPi / 4);
        }
      }
    }
    if (!placed) {
      if (auto spawn = stream->spawn_point()) {
        camera.position = spawn->position;
        placed = true;
        aim_room = spawn->room;
        spdlog::info("event=spawn room={} x={} y={} z={}", spawn->room.to_string(),
                     spawn->position.x, spawn->position.y, spawn->position.z);
      }
    }
    if (placed) {
      client::Pose pose;
      pose.position = camera.position;
      pose.forward = render::camera_forward(camera);
      pose.speed = speed;
      stream->set_pose(pose);
    }
  };

  int status = 0;
  if (headless) {
    auto fb_or = render::Framebuffer::create(o.width, o.height);
    if (!fb_or) return fail(fb_or.error().message);
    render::Framebuffer fb = std::move(fb_or).value();
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(o.wait_s);
    while (!(placed && surroundings_ready(cache, *stream, camera.position))) {
      if (std::chrono::steady_clock::now() > deadline) {
        // A pose in solid rock is located in no room, so nothing streams in.
        spdlog::warn(
            "event=screenshot_wait_timeout rooms={} placed={} hint=\"is the pose inside the "
            "cave?\"",
            cache.size(), placed);
        break;
      }
      pump(o.speed);
      std::this_thread::sleep_for(20ms);
    }
    for (int i = 0; i < o.frames; ++i) {
      pump(o.speed);
      fb.bind();
      renderer.draw(cache, camera, o.width, o.height, ro);
    }
    glFinish();
    std::vector<unsigned char> rgb = fb.read_rgb();
    if (auto s = grotto::tools::write_png(o.screenshot, rgb, o.width, o.height); !s)
      status = fail(s.error().message);
    else
      std::printf("grotto-client: wrote %s (%dx%d, %zu rooms loaded)\n", o.screenshot.c_str(),
                  o.width, o.height, cache.size());
  } else {
    Input input;
    input.camera = &camera;
    glfwSetWindowUserPointer(window, &input);
    glfwSetInputMode(window, GLFW_CURSOR, GLFW_CURSOR_DISABLED);
    glfwSetCursorPosCallback(window, on_cursor);
    auto last = std::chrono::steady_clock::now();
    double title_timer = 0;
    bool t_down = false, p_down = false, f_down = false;
    auto pressed = [&](int key, bool& was) {
      bool now = glfwGetKey(window, key) == GLFW_PRESS;
      bool edge = now && !was;
      was = now;
      return edge;
    };
    while (!glfwWindowShouldClose(window)) {
      glfwPollEvents();
      auto now = std::chrono::steady_clock::now();
      double dt = std::min(std::chrono::duration<double>(now - last).count(), 0.1);
      last = now;
      if (glfwGetKey(window, GLFW_KEY_ESCAPE) == GLFW_PRESS) glfwSetWindowShouldClose(window, 1);
      if (pressed(GLFW_KEY_T, t_down)) ro.tessellation = !ro.tessellation;
      if (pressed(GLFW_KEY_F, f_down)) ro.wireframe = !ro.wireframe;
      if (pressed(GLFW_KEY_P, p_down))
        ro.surface = ro.surface == render::Surface::kPhong ? render::Surface::kPnTriangles
                                                           : render::Surface::kPhong;
      const bool run = glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                       glfwGetKey(window, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS;
      const double speed = o.speed * (run ? 4 : 1);
      Vec3 forward = render::camera_forward(camera);
      Vec3 right{std::cos(camera.yaw), 0, std::sin(camera.yaw)};
      Vec3 move{};
      auto key = [&](int k) { return glfwGetKey(window, k) == GLFW_PRESS; };
      if (key(GLFW_KEY_W)) move = move + forward;
      if (key(GLFW_KEY_S)) move = move - forward;
      if (key(GLFW_KEY_D)) move = move + right;
      if (key(GLFW_KEY_A)) move = move - right;
      if (key(GLFW_KEY_SPACE)) move = move + Vec3{0, 1, 0};
      if (key(GLFW_KEY_C)) move = move - Vec3{0, 1, 0};
      double length = std::sqrt(move.x * move.x + move.y * move.y + move.z * move.z);
      if (length > 0 && placed) camera.position = camera.position + move * (speed * dt / length);
      pump(length > 0 ? speed : o.speed);

      int w = 0, h = 0;
      glfwGetFramebufferSize(window, &w, &h);
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
      glViewport(0, 0, w, h);
      render::FrameStats fs = renderer.draw(cache, camera, w, h, ro);
      glfwSwapBuffers(window);

      title_timer += dt;
      if (title_timer > 0.5) {
        title_timer = 0;
        auto st = stream->stats();
        char title[256];
        std::snprintf(
            title, sizeof title,
            "grotto-client  %.1f ms  rooms %zu drawn %d in flight %llu  %s%s  %s", dt * 1000,
            cache.size(), fs.rooms_drawn, static_cast<unsigned long long>(st.in_flight),
            ro.tessellation ? (ro.surface == render::Surface::kPhong ? "phong" : "pn") : "flat",
            ro.wireframe ? " wire" : "", client::state_name(st.state));
        glfwSetWindowTitle(window, title);
      }
    }
  }

  stream->stop();
  stream.reset();
  cache_owner.reset();
  renderer_owner.reset();
  glfwDestroyWindow(window);
  if (server) server->stop(2000ms);
  return status;
}
