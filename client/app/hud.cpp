#include "client/app/hud.hpp"

#include <algorithm>
#include <cstdio>

namespace grotto::app {
namespace {
// "1ST", "2ND", "3RD", "11TH", "22ND".
const char* ordinal_suffix(uint32_t n) {
  if (n % 100 >= 11 && n % 100 <= 13) return "TH";
  switch (n % 10) {
    case 1:
      return "ST";
    case 2:
      return "ND";
    case 3:
      return "RD";
    default:
      return "TH";
  }
}

constexpr size_t kLatencyWindow = 64;

template <typename... Args>
std::string format(const char* pattern, Args... args) {
  char text[200];
  std::snprintf(text, sizeof text, pattern, args...);
  return text;
}

const char* on_off(bool on) {
  return on ? "ON" : "OFF";
}

}  // namespace

void HudMeter::frame(double frame_ms, double now_s, uint64_t bytes_received,
                     const std::vector<stream::RoomSample>& samples) {
  if (frame_ms > 0) frame_ms_ = frame_ms_ == 0 ? frame_ms : frame_ms_ + (frame_ms - frame_ms_) / 30;
  for (const stream::RoomSample& sample : samples) {
    latencies_.push_back(sample.latency_ms);
    if (latencies_.size() > kLatencyWindow) latencies_.pop_front();
  }
  if (window_start_s_ < 0) {
    window_start_s_ = now_s, window_bytes_ = bytes_received;
  } else if (now_s - window_start_s_ >= 1.0) {
    kbytes_per_s_ =
        static_cast<double>(bytes_received - window_bytes_) / 1024.0 / (now_s - window_start_s_);
    window_start_s_ = now_s, window_bytes_ = bytes_received;
  }
}

double HudMeter::latency_ms() const {
  if (latencies_.empty()) return -1;
  std::vector<double> sorted(latencies_.begin(), latencies_.end());
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  return sorted[sorted.size() / 2];
}

std::vector<render::OverlayLine> hud_lines(const HudState& s) {
  std::vector<render::OverlayLine> lines;
  const stream::StreamStats& st = s.stream;
  switch (st.state) {
    case stream::StreamState::kReady:
      break;
    case stream::StreamState::kConnecting:
      if (st.queued) {
        // Past the server's capacity (PROTOCOL.md, "Waiting to enter"): where we stand.
        const int wait_s = std::max(1, static_cast<int>((st.queued->wait_ms + 500) / 1000));
        lines.push_back({format("WAITING TO ENTER: %u%s IN LINE, ABOUT %d S", st.queued->position,
                                ordinal_suffix(st.queued->position), wait_s),
                         render::kOverlayWarning});
        break;
      }
      lines.push_back(
          {st.connects == 0 ? "CONNECTING TO THE SERVER..." : "SERVER LOST: RECONNECTING...",
           render::kOverlayWarning});
      break;
    case stream::StreamState::kBackoff:
      lines.push_back(
          {st.connects == 0 ? "CANNOT REACH THE SERVER: RETRYING" : "SERVER LOST: RECONNECTING",
           render::kOverlayError});
      if (!st.last_error.empty()) lines.push_back({st.last_error, render::kOverlayError});
      break;
    case stream::StreamState::kFailed:
      lines.push_back({"SERVER REFUSED US: " + st.last_error, render::kOverlayError});
      break;
    case stream::StreamState::kStopped:
      lines.push_back({"STREAM STOPPED", render::kOverlayWarning});
      break;
  }
  lines.push_back(
      {format("SEED %s  ROOM %s  AT %.1f, %.1f, %.1f", s.seed.empty() ? "-" : s.seed.c_str(),
              s.room.empty() ? "-" : s.room.c_str(), s.position.x, s.position.y, s.position.z)});
  lines.push_back(
      {format("%.1f MS  %.0f FPS   ROOMS %zu LOADED  %d DRAWN", s.frame_ms,
              s.frame_ms > 0 ? 1000.0 / s.frame_ms : 0.0, s.rooms_on_gpu, s.frame.rooms_drawn)});
  const std::string latency = s.latency_ms < 0 ? std::string("-") : format("%.0f MS", s.latency_ms);
  lines.push_back({format("STREAM %llu IN FLIGHT  LATENCY %s  %.0f KB/S  RECONNECTS %llu",
                          static_cast<unsigned long long>(st.in_flight), latency.c_str(),
                          s.kbytes_per_s, static_cast<unsigned long long>(st.reconnects))});
  const render::RenderOptions& r = s.render;
  const char* surface = !r.tessellation                        ? "FLAT"
                        : r.surface == render::Surface::kPhong ? "PHONG"
                                                               : "PN";
  lines.push_back({format(
      "TESS %s %.0f  RELIEF %s  BLOOM %s  BLUR %s  PORTALS %s  LOD %s  DETAIL %s  AO %s  %s",
      surface, r.max_tess, on_off(r.displacement > 0), on_off(r.bloom), on_off(r.motion_blur),
      on_off(r.portal_culling), render::lod_heuristic_name(r.lod), on_off(r.fine_detail > 0),
      on_off(r.ambient_occlusion), s.mode.c_str())});
  if (s.help) {
    lines.push_back(
        {"MOUSE LOOK  WASD MOVE  SHIFT RUN  SPACE JUMP/UP  C DOWN  G WALK/FLY  N NOCLIP"});
    lines.push_back(
        {"T TESS  P PN/PHONG  X RELIEF  J DETAIL  K AO  B BLOOM  M BLUR  O PORTALS  L LOD"});
    lines.push_back({"F THROW FLARE  Q HEADLAMP  R WIREFRAME  V OVERLAY  H HELP  ESC QUIT"});
  } else {
    lines.push_back({"H: KEYS"});
  }
  return lines;
}

}  // namespace grotto::app
