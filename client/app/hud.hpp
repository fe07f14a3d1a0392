// grotto-client's overlay text: what the player (or the developer next to them) needs at a
// glance: frame time, rooms, the stream's latency and bandwidth, the render toggles and their
// keys, and the connection state, in plain words when the server is gone.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "client/render/overlay.hpp"
#include "client/render/renderer.hpp"
#include "client/stream/stream.hpp"
#include "common/core/vec3.hpp"

namespace grotto::app {

// Running figures the overlay shows, fed once per frame.
class HudMeter {
 public:
  // A frame of `frame_ms` (0: unknown, e.g. the first), and the stream's counters and new samples
  // at `now` (seconds).
  void frame(double frame_ms, double now_s, uint64_t bytes_received,
             const std::vector<stream::RoomSample>& samples);
  double frame_ms() const { return frame_ms_; }  // exponential average over ~30 frames
  double latency_ms() const;                     // median of the last 64 rooms; -1 before any
  double kbytes_per_s() const { return kbytes_per_s_; }  // over the last whole second

 private:
  double frame_ms_ = 0;
  std::deque<double> latencies_;
  double window_start_s_ = -1;
  uint64_t window_bytes_ = 0;
  double kbytes_per_s_ = 0;
};

struct HudState {
  double frame_ms = 0;
  double latency_ms = -1;  // < 0: no room received yet
  double kbytes_per_s = 0;
  size_t rooms_on_gpu = 0;
  render::FrameStats frame;
  stream::StreamStats stream;
  render::RenderOptions render;
  std::string mode;   // "walk", "fly" or "noclip"
  Vec3 position;      // the camera, world metres
  std::string room;   // the room the camera is in ("" when none is loaded there)
  std::string seed;   // the world's seed ("" before the server has said)
  bool help = false;  // the key list
};

// The lines, top to bottom. The connection line comes first, in warning or error colours, when
// the stream is not ready. The overlay wraps lines wider than the window.
std::vector<render::OverlayLine> hud_lines(const HudState& state);

}  // namespace grotto::app
