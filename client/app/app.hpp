// grotto-client's running parts once the GL context, the renderer and the stream exist (main.cpp
// makes them): rooms flow from the stream into the GPU cache and the collision world, the player
// or the scripted path moves the camera, and one of three loops runs: the window, a headless
// --screenshot, or a headless --bench. Only the window's loop needs a window: headless runs draw
// into a framebuffer object of their own, in any current context (GLFW's or EGL's).
#pragma once

#include <chrono>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "client/app/hud.hpp"
#include "client/app/options.hpp"
#include "client/play/collision.hpp"
#include "client/play/flare.hpp"
#include "client/play/flythrough.hpp"
#include "client/play/player.hpp"
#include "client/render/overlay.hpp"
#include "client/render/renderer.hpp"
#include "client/render/room_cache.hpp"
#include "client/stream/stream.hpp"
#include "common/cave/room_id.hpp"

struct GLFWwindow;

namespace grotto::app {

struct Session {
  Session(const Options& options, render::Renderer& renderer, render::Overlay& overlay,
          render::GpuRoomCache& cache, stream::Stream& stream);

  const Options& options;
  render::Renderer& renderer;
  render::Overlay& overlay;
  render::GpuRoomCache& cache;
  stream::Stream& stream;
  play::CollisionWorld world;
  play::Player player;
  render::Camera camera;
  render::RenderOptions render_options;
  bool placed = false;                     // the camera has a start pose
  std::optional<cave::RoomId> start_room;  // the spawn room, when the server gave one
  std::optional<cave::RoomId> aim_room;    // look through its widest portal once known
  std::optional<cave::RoomId> pose_room;   // --pose room:<id>: placed inside once it arrives
  std::optional<play::Flythrough> path;    // --flythrough / --bench: planned once complete
  std::optional<Vec3> start;               // where the camera was placed first
  std::optional<Vec3> stream_focus;        // told to the stream instead of the camera
  bool show_overlay = false;
  bool show_keys = false;  // the overlay's key list
  bool following = false;  // the camera is on the scripted path
  // The world's lights of the rooms on the GPU (cave::room_lights), and the flares thrown.
  std::map<cave::RoomId, std::vector<render::Light>> world_lights;
  // The formations of arrived rooms, placed on worker threads (formations::place: a hall's takes
  // milliseconds, two frames of a 120 Hz display), a few at a time; then handed to the cache and
  // the collision world. Rooms wait in `to_place` for a thread; `retired`: placements of rooms
  // evicted meanwhile, dropped once they end.
  std::deque<std::shared_ptr<const stream::ReadyRoom>> to_place;
  std::map<cave::RoomId, std::future<std::vector<formations::FormationShape>>> placing;
  std::vector<std::future<std::vector<formations::FormationShape>>> retired;
  std::vector<play::Flare> flares;
  double flare_carry = 0;  // seconds not yet stepped (advance_flares)
  HudMeter meter;
  std::chrono::steady_clock::time_point began = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_frame = began;
};

// Drains the stream (new rooms into the GPU cache and the collision world, evictions out of
// both), takes the spawn point, and tells the stream the camera's pose at `speed` m/s.
void pump(Session& s, double speed);

// The lights of the scene the renderer picks a frame's from (render::frame_lights): the world's
// lights of the loaded rooms and the burning flares.
std::vector<render::Light> scene_lights(const Session& s);
// Throws a flare from the camera along its view.
void throw_flare(Session& s);

// Draws one frame into the bound framebuffer: the cave, then the overlay when shown.
render::FrameStats draw_frame(Session& s, int width, int height);

// The window (its context current) until it is closed or Esc.
int run_window(Session& s, GLFWwindow* window);
// --bench when given, else --screenshot: offscreen frames, then the statistics or the PNG.
int run_headless(Session& s);

}  // namespace grotto::app
