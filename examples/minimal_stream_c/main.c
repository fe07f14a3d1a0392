/* Grotto::stream from C: connect (saying where it stands while a full server holds it in its
 * queue), stand at the server's spawn point until the ground within 8 m exists, then walk away
 * from it portal by portal, printing rooms as they arrive.
 * Usage: minimal_stream_c ws://host:port/ws [seconds] */
#include <grotto/grotto_stream.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

/* What the walk keeps of a room: a poll's pointers are valid only until the next poll. */
typedef struct seen_room {
  uint64_t key;
  char id[32];
  int visited;
  size_t portal_count;
  grotto_portal portals[16]; /* a Grotto room has at most 16 */
} seen_room;
static seen_room seen[4096];
static size_t seen_count;

static seen_room* find(uint64_t key) {
  for (size_t i = 0; i < seen_count; ++i)
    if (seen[i].key == key) return &seen[i];
  return NULL;
}

static double distance(const double a[3], const double b[3]) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

static void sleep_ms(long ms) {
  struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&t, NULL);
}

static const char* ordinal_suffix(uint64_t n) {
  if (n % 100 >= 11 && n % 100 <= 13) return "th";
  switch (n % 10) {
    case 1:
      return "st";
    case 2:
      return "nd";
    case 3:
      return "rd";
    default:
      return "th";
  }
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
  double spawn[3];
  uint64_t here = 0; /* the room the player is in */
  int spawned = 0;
  uint64_t told_position = 0, told_wait_s = 0;
  for (int i = 0; i < 500;) { /* the server's answer: up to 10 s, once admitted */
    spawned = grotto_stream_spawn_point(stream, spawn, &here);
    if (spawned) break;
    /* A server past its capacity holds newcomers in a queue: tell the player where they stand
     * (a game shows it instead of its loading screen) and wait as long as it takes. */
    grotto_stream_stats stats;
    grotto_stream_get_stats(stream, &stats);
    if (stats.state == GROTTO_STATE_QUEUED) {
      const uint64_t wait_s = stats.queue_wait_ms < 1000 ? 1 : (stats.queue_wait_ms + 500) / 1000;
      if (stats.queue_position != told_position || wait_s != told_wait_s) {
        printf("waiting to enter: %llu%s of %llu, about %llu s\n",
               (unsigned long long)stats.queue_position, ordinal_suffix(stats.queue_position),
               (unsigned long long)stats.queue_length, (unsigned long long)wait_s);
        fflush(stdout);
        told_position = stats.queue_position;
        told_wait_s = wait_s;
      }
    } else {
      ++i;
    }
    sleep_ms(20);
  }
  if (!spawned) {
    fprintf(stderr, "minimal_stream_c: no spawn point: %s\n", grotto_stream_last_error(stream));
    grotto_stream_destroy(stream);
    return 1;
  }
  for (int k = 0; k < 3; ++k)
    pose.position[k] = spawn[k];
  grotto_stream_set_pose(stream, &pose);
  int ground = grotto_stream_area_ready(stream, spawn, 8.0, 0, 20000);
  printf("spawn at %.2f %.2f %.2f, ground within 8 m: %s\n", spawn[0], spawn[1], spawn[2],
         ground ? "ready" : "not ready");

  grotto_room rooms[16];
  uint64_t evicted[16];
  const grotto_portal* target = NULL; /* the portal the player walks to */
  const double dt = 0.05, speed = 4.0;
  for (double t = 0; t < seconds; t += dt) {
    size_t n = grotto_stream_poll_rooms(stream, rooms, 16);
    for (size_t i = 0; i < n; ++i) {
      const grotto_room* r = &rooms[i];
      /* How far the walk has brought the stream: from the spawn point to the room's sphere. */
      printf("room %s lod %u: %zu vertices, %zu triangles, %zu portals, %.1f m from the spawn\n",
             r->id, r->lod, r->vertex_count, r->index_count / 3, r->portal_count,
             fmax(0.0, distance(r->centre, spawn) - r->radius));
      if (find(r->key) || seen_count == sizeof seen / sizeof seen[0]) continue;
      seen_room* s = &seen[seen_count++];
      s->key = r->key;
      snprintf(s->id, sizeof s->id, "%s", r->id);
      s->portal_count = r->portal_count < 16 ? r->portal_count : 16;
      for (size_t p = 0; p < s->portal_count; ++p)
        s->portals[p] = r->portals[p];
    }
    grotto_stream_poll_evicted(stream, evicted, 16); /* a renderer frees their buffers */

    seen_room* room = find(here);
    if (!target && room) {
      /* Onwards: the unvisited neighbour farthest from the spawn, else any way out. */
      room->visited = 1;
      for (size_t p = 0; p < room->portal_count; ++p) {
        const grotto_portal* q = &room->portals[p];
        const seen_room* next = find(q->neighbour);
        if (next && next->visited) continue;
        if (!target || distance(q->centre, spawn) > distance(target->centre, spawn)) target = q;
      }
      if (!target && room->portal_count) target = &room->portals[rand() % room->portal_count];
    }
    if (target) { /* a step towards the portal; through it once the next room has arrived */
      const double left = distance(target->centre, pose.position), step = speed * dt;
      for (int k = 0; k < 3; ++k) {
        pose.forward[k] = target->centre[k] - pose.position[k];
        pose.position[k] += left <= step ? pose.forward[k] : pose.forward[k] / left * step;
      }
      pose.speed = speed;
      grotto_stream_set_pose(stream, &pose);
      if (left <= step && find(target->neighbour)) {
        here = target->neighbour;
        printf("entered %s\n", find(here)->id);
        target = NULL;
      }
    }
    sleep_ms(50);
  }
  grotto_stream_stats stats;
  grotto_stream_get_stats(stream, &stats);
  printf("%s: %llu rooms ready, %llu held\n", grotto_stream_state_name(stats.state),
         (unsigned long long)stats.rooms_ready, (unsigned long long)stats.rooms_held);
  grotto_stream_destroy(stream);
  return stats.rooms_ready > 0 ? 0 : 1;
}
