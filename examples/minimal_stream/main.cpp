// The smallest game loop over Grotto::stream: connect (saying where it stands while a full server
// holds it in its queue), hold the player until the ground around the spawn point exists, then
// walk from portal centre to portal centre, printing rooms as they arrive.
// Usage: minimal_stream ws://host:port/ws [seconds]
#include <grotto/stream.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <utility>

using namespace std::chrono_literals;

namespace {

const char* ordinal_suffix(uint32_t n) {
  if (n % 100 >= 11 && n % 100 <= 13) return "th";
  return n % 10 == 1 ? "st" : n % 10 == 2 ? "nd" : n % 10 == 3 ? "rd" : "th";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: minimal_stream ws://host:port/ws [seconds]\n");
    return 2;
  }
  const double seconds = argc > 2 ? std::atof(argv[2]) : 10.0;
  grotto::set_log_level("warn");  // the library's event lines: only trouble
  grotto::StreamConfig config;
  config.url = argv[1];
  std::string error;
  auto stream = grotto::Stream::start(config, &error);
  if (!stream) {
    std::fprintf(stderr, "minimal_stream: %s\n", error.c_str());
    return 1;
  }

  // No pose yet: the stream asks the server where to start.
  std::optional<grotto::SpawnPoint> spawn;
  std::pair<uint32_t, uint32_t> told{0, 0};  // the place and the wait (s) last printed
  for (int i = 0; i < 500;) {                // the server's answer: up to 10 s, once admitted
    if ((spawn = stream->spawn_point())) break;
    // A server past its capacity holds newcomers in a queue: tell the player where they stand
    // (a game shows it instead of its loading screen) and wait as long as it takes.
    const grotto::StreamStats s = stream->stats();
    if (s.queued) {
      const std::pair<uint32_t, uint32_t> now{s.queued->position,
                                              std::max(1u, (s.queued->wait_ms + 500) / 1000)};
      if (now != told) {
        std::printf("waiting to enter: %u%s of %u, about %u s\n", now.first,
                    ordinal_suffix(now.first), s.queued->length, now.second);
        std::fflush(stdout);
        told = now;
      }
    } else {
      ++i;
    }
    std::this_thread::sleep_for(20ms);
  }
  if (!spawn) {
    std::fprintf(stderr, "minimal_stream: no spawn point (%s: %s)\n",
                 grotto::state_name(stream->stats().state), stream->stats().last_error.c_str());
    return 1;
  }
  grotto::Pose pose;
  pose.position = spawn->position;
  stream->set_pose(pose);
  const bool ground = stream->wait_area_ready(spawn->position, 8.0, 0, 20s);
  std::printf("spawn %s, ground within 8 m: %s\n", grotto::room_name(spawn->room).c_str(),
              ground ? "ready" : "not ready");

  // Walk: towards a portal of the current room, into its neighbour once that has arrived.
  grotto::RoomKey room = spawn->room;
  std::set<grotto::RoomKey> visited{room};
  std::optional<grotto::Portal> target;
  const double dt = 0.05;
  for (double t = 0; t < seconds; t += dt) {
    for (const grotto::RoomPtr& r : stream->poll_rooms()) {
      std::printf("room %s lod %u: %zu vertices, %zu triangles, %zu portals\n", r->id.c_str(),
                  r->lod, r->vertex_count(), r->triangle_count(), r->portals.size());
    }
    stream->poll_evicted();  // a renderer would free these rooms' buffers
    if (!target) {
      if (auto here = stream->room(room); here && !here->portals.empty()) {
        target = here->portals.front();
        for (const grotto::Portal& p : here->portals) {
          if (!visited.count(p.neighbour)) {
            target = p;
            break;
          }
        }
      }
    } else {
      const grotto::Vec3d d{target->centre.x - pose.position.x, target->centre.y - pose.position.y,
                            target->centre.z - pose.position.z};
      const double left = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
      const double step = pose.speed * dt;
      if (left <= step) {
        pose.position = target->centre;
        if (stream->room(target->neighbour)) {  // else: wait at the portal (a stall)
          room = target->neighbour;
          visited.insert(room);
          std::printf("entered %s\n", grotto::room_name(room).c_str());
          target.reset();
        }
      } else {
        pose.position = {pose.position.x + d.x / left * step, pose.position.y + d.y / left * step,
                         pose.position.z + d.z / left * step};
        pose.forward = d;
      }
      stream->set_pose(pose);
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(dt));
  }
  const grotto::StreamStats s = stream->stats();
  std::printf("%s: %llu rooms ready, %llu held (%.1f MB), %llu bytes received\n",
              grotto::state_name(s.state), static_cast<unsigned long long>(s.rooms_ready),
              static_cast<unsigned long long>(s.rooms_held), s.memory_bytes / 1e6,
              static_cast<unsigned long long>(s.bytes_received));
  return s.rooms_ready > 0 ? 0 : 1;
}
