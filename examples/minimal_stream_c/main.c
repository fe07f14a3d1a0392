/* Grotto::stream from C: connect, stand at the server's spawn point, hold until the ground within
 * 8 m exists, then print rooms as they arrive for a few seconds.
 * Usage: minimal_stream_c ws://host:port/ws [seconds] */
#include <grotto/grotto_stream.h>

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static void sleep_ms(long ms) {
  struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

int main(int argc, char** argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: minimal_stream_c ws://host:port/ws [seconds]\n");
    return 2;
  }
  const double seconds = argc > 2 ? atof(argv[2]) : 10.0;
  grotto_set_log_level("warn"); /* the library's event lines: only trouble */
  grotto_stream_config config = {0};
  config.url = argv[1];
  char error[256];
  grotto_stream* stream = grotto_stream_create(&config, error, sizeof error);
  if (!stream) {
    fprintf(stderr, "minimal_stream_c: %s\n", error);
    return 1;
  }

  grotto_pose pose = {{0}};
  uint64_t spawn_room = 0;
  int spawned = 0;
  for (int i = 0; i < 500 && !spawned; ++i) { /* the server's answer: up to 10 s */
    spawned = grotto_stream_spawn_point(stream, pose.position, &spawn_room);
    if (!spawned) sleep_ms(20);
  }
  if (!spawned) {
    fprintf(stderr, "minimal_stream_c: no spawn point: %s\n", grotto_stream_last_error(stream));
    grotto_stream_destroy(stream);
    return 1;
  }
  grotto_stream_set_pose(stream, &pose);
  int ground = grotto_stream_area_ready(stream, pose.position, 8.0, 0, 20000);
  printf("spawn at %.2f %.2f %.2f, ground within 8 m: %s\n", pose.position[0], pose.position[1],
         pose.position[2], ground ? "ready" : "not ready");

  grotto_room rooms[16];
  uint64_t evicted[16];
  for (double t = 0; t < seconds; t += 0.05) {
    size_t n = grotto_stream_poll_rooms(stream, rooms, 16);
    for (size_t i = 0; i < n; ++i) {
      /* The first vertex in world space: the room's origin plus a float offset, added in double. */
      const grotto_room* r = &rooms[i];
      printf(
          "room %s lod %u: %zu vertices, %zu triangles, %zu portals, first vertex %.2f %.2f "
          "%.2f\n",
          r->id, r->lod, r->vertex_count, r->index_count / 3, r->portal_count,
          r->origin[0] + r->positions[0], r->origin[1] + r->positions[1],
          r->origin[2] + r->positions[2]);
    }
    grotto_stream_poll_evicted(stream, evicted, 16);
    sleep_ms(50);
  }
  grotto_stream_stats stats;
  grotto_stream_get_stats(stream, &stats);
  printf("%s: %llu rooms ready, %llu held\n", grotto_stream_state_name(stats.state),
         (unsigned long long)stats.rooms_ready, (unsigned long long)stats.rooms_held);
  grotto_stream_destroy(stream);
  return stats.rooms_ready > 0 ? 0 : 1;
}
