/* Grotto's streaming client, C interface (the installed library Grotto::stream).
 *
 * The same library as grotto/stream.hpp, for engines written in C or bound from other languages:
 * opaque handles, plain structs, no callbacks. A grotto_stream is one connection to a
 * grotto-server that follows the player's pose, fetches the cave rooms around it and hands them
 * over decoded. docs/INTEGRATION.md walks through embedding it.
 *
 * Threading: every function may be called from any thread. The pointers a poll hands out stay
 * valid until the next grotto_stream_poll_rooms on the same stream (or its destroy), so poll
 * from one thread (the game's frame loop) and copy or upload before polling again. The stream
 * runs one network thread and its decoding threads of its own and never calls back.
 *
 * Ownership: the caller owns what it passes in (strings are copied before the call returns) and
 * every array it asks to be filled; the library owns what its pointers point at.
 *
 * Errors: create returns NULL and writes the reason into the caller's buffer; a running stream
 * never fails a call: grotto_stream_get_stats reports its state and grotto_stream_last_error its
 * last error. Functions given a NULL stream do nothing and return 0.
 *
 * Coordinates: world space in metres, y up, as doubles; vertex positions are floats relative to
 * their room's origin. Room ids are 64-bit keys (proto/PROTOCOL.md "Room ids").
 */
#ifndef GROTTO_STREAM_H
#define GROTTO_STREAM_H

#include <stddef.h>
#include <stdint.h>

#if defined(__GNUC__) || defined(__clang__)
#define GROTTO_C_API __attribute__((visibility("default")))
#else
#define GROTTO_C_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef struct grotto_stream grotto_stream;

/* Configuration. Zero-initialize it and set url: every zero field means its default. */
typedef struct grotto_stream_config {
  const char* url;            /* required: ws://host:port[/path] (path default /ws); no TLS */
  int has_seed;               /* 0: the world the server serves by default; 1: `seed` */
  uint64_t seed;              /* the world wanted, when has_seed */
  const char* token;          /* NULL: none; the deployment's shared secret otherwise */
  const char* name;           /* NULL: "grotto-engine"; shown in the server's logs */
  uint32_t lod;               /* wire lod: 0 the streamed patch mesh, 1 detail (when offered) */
  double horizon_s;           /* 0: 4 s. Rooms reachable within this much walking are fetched */
  double min_horizon_s;       /* 0: adaptive, floor 1.5 s; > 0: adaptive, this floor;
                                 negative: a fixed horizon of horizon_s */
  size_t memory_budget_bytes; /* 0: 256 MiB of decoded rooms held */
  int decode_threads;         /* 0: two; at most 64 */
} grotto_stream_config;

/* The player. Zero forward: no view preference; zero speed: 4 m/s. */
typedef struct grotto_pose {
  double position[3];
  double forward[3]; /* view direction, any length; rooms behind count up to twice as far */
  double speed;      /* m/s, for time-to-reach */
} grotto_pose;

typedef struct grotto_portal {
  uint64_t neighbour;
  double centre[3]; /* world space */
  double normal[3]; /* unit, out of this room into the neighbour */
  double radius;
} grotto_portal;

/* One decoded room. Vertex i lies at origin + positions[3i..3i+2] (add in double). Triangles face
 * into the cave; the rims at portals match the neighbours' exactly. */
typedef struct grotto_room {
  uint64_t key;
  char id[32];      /* text form of key, NUL-terminated, e.g. "0.0.0.r3" */
  uint32_t lod;     /* the wire lod */
  double origin[3]; /* on the world grid */
  double centre[3]; /* the room's sphere */
  double radius;
  size_t vertex_count;
  size_t index_count; /* 3 per triangle; every index < vertex_count */
  size_t portal_count;
  const float* positions;       /* 3 per vertex: metres from origin */
  const float* normals;         /* 3 per vertex: unit, into the cave */
  const float* roughness;       /* 1 per vertex, 0-1 */
  const float* mineral;         /* 1 per vertex, 0-1 */
  const uint32_t* indices;      /* index_count */
  const grotto_portal* portals; /* portal_count, sorted by neighbour */
} grotto_room;

enum {
  GROTTO_STATE_CONNECTING = 0, /* connecting, or waiting for the server's welcome */
  GROTTO_STATE_READY = 1,      /* connected: requesting and receiving rooms */
  GROTTO_STATE_BACKOFF = 2,    /* dropped; reconnecting after a delay (rooms held stay usable) */
  GROTTO_STATE_FAILED = 3,     /* refused for good (version, world, token): see last_error */
  GROTTO_STATE_STOPPED = 4,    /* grotto_stream_stop was called */
  /* Connected and waiting in the server's admission queue: the server is past its capacity and
   * lets newcomers in as players leave or it catches up (proto/PROTOCOL.md "Waiting to enter").
   * A stream always offers to wait (hello.queue), so a full server tells it its place instead of
   * refusing it. No spawn point and no rooms come meanwhile; the stats' queue_* fields say where
   * it stands. Then READY, as after any welcome. */
  GROTTO_STATE_QUEUED = 5
};

typedef struct grotto_stream_stats {
  int state; /* GROTTO_STATE_* */
  uint64_t connects;
  uint64_t reconnects;
  uint64_t rooms_received;
  uint64_t rooms_ready;
  uint64_t rooms_rejected;
  uint64_t rooms_evicted;
  uint64_t bytes_received;
  uint64_t in_flight;    /* now */
  uint64_t rooms_held;   /* now */
  uint64_t memory_bytes; /* now */
  /* The admission queue (GROTTO_STATE_QUEUED), as the server last said: it says again when the
   * place or the estimate changes, at most about once a second. A player waits here instead of
   * being refused, so show it rather than a bare loading screen, e.g. "waiting to enter: 14th,
   * about 20 s" (queue_position, and queue_wait_ms in whole seconds). The three are 0 in every
   * other state. Added after the fields above, which keep their offsets; the struct grew, so a
   * program built against an older header must be rebuilt. */
  uint64_t queue_position; /* 1-based place: 1 enters next */
  uint64_t queue_length;   /* sessions waiting, this one included */
  uint64_t queue_wait_ms;  /* the server's estimate of the wait, from the rate it lets players in */
  uint64_t times_queued;   /* connections that waited in the queue before their welcome */
  double queued_ms;        /* time spent queued since create, the current wait included */
} grotto_stream_stats;

/* Checks the configuration and starts connecting; never blocks on the network. Returns NULL when
 * config or its url is NULL or a value is out of range, and then writes the reason, NUL-terminated
 * and cut to error_size bytes, into `error` (when error is not NULL and error_size > 0). A server
 * that cannot be reached is no error here: the stream keeps trying. */
GROTTO_C_API grotto_stream* grotto_stream_create(const grotto_stream_config* config, char* error,
                                                 size_t error_size);

/* Closes the connection, joins the stream's threads and frees it (within about 3 s). Every
 * pointer it handed out becomes invalid. No other thread may be inside a call on `stream` (a
 * grotto_stream_area_ready waiting in another thread included: grotto_stream_stop first). NULL:
 * nothing. */
GROTTO_C_API void grotto_stream_destroy(grotto_stream* stream);

/* Closes the connection and stops reconnecting (state GROTTO_STATE_STOPPED), within about 3 s; a
 * grotto_stream_area_ready waiting in another thread returns 0 at once. Pointers from the last
 * poll stay valid; polls still hand out rooms decoded before. Idempotent. NULL: nothing. */
GROTTO_C_API void grotto_stream_stop(grotto_stream* stream);

/* The player's pose; call it every frame or on every move. Until a pose is set, the stream asks
 * the server for a spawn point and uses it. */
GROTTO_C_API void grotto_stream_set_pose(grotto_stream* stream, const grotto_pose* pose);

/* 1 and the spawn point's position (and room key, when room is not NULL) once the server sent
 * one; 0 before. */
GROTTO_C_API int grotto_stream_spawn_point(grotto_stream* stream, double position[3],
                                           uint64_t* room);

/* Fills rooms[0..n) with rooms decoded since the last poll, oldest first, and returns n <=
 * capacity; rooms that did not fit wait for the next poll. The arrays each grotto_room points at
 * stay valid until the next call of this function on `stream` or its destroy, whichever comes
 * first: upload or copy them before. Drain it every frame. */
GROTTO_C_API size_t grotto_stream_poll_rooms(grotto_stream* stream, grotto_room* rooms,
                                             size_t capacity);

/* Fills keys[0..n) with rooms evicted since the last poll (free their GPU buffers) and returns
 * n <= capacity; the rest wait for the next poll. */
GROTTO_C_API size_t grotto_stream_poll_evicted(grotto_stream* stream, uint64_t* keys,
                                               size_t capacity);

/* 1 when the room holding `point` and every room within radius_m metres of it along the portal
 * graph are held at a lod <= max_lod, waiting up to timeout_ms for it; 0 at the timeout, and 0 at
 * once when the stream failed or stopped or when max_lod is below the session's lod (the config's
 * lod, capped by the server). While it waits it fetches the area, wherever `point` lies: the
 * stream asks the server which room holds the point and requests the rooms within radius_m of
 * it, ahead of the pose's, and keeps them from eviction until the call returns (an area larger
 * than memory_budget_bytes holds the stream over its budget meanwhile); then they are ordinary
 * rooms again. They arrive through grotto_stream_poll_rooms like any other. timeout_ms 0 only
 * answers and fetches nothing. A point in rock or outside the world is never ready. Any number
 * of threads may wait at once; a game holds its spawn (or a teleport) on it.
 * grotto/stream.hpp's Stream::wait_area_ready says more. */
GROTTO_C_API int grotto_stream_area_ready(grotto_stream* stream, const double point[3],
                                          double radius_m, uint32_t max_lod, uint32_t timeout_ms);

/* Fills *stats with the counters since create and the figures of now. */
GROTTO_C_API void grotto_stream_get_stats(grotto_stream* stream, grotto_stream_stats* stats);

/* The stream's last error, for people ("" when none). The string stays valid until the next call
 * of this function on `stream` or its destroy. */
GROTTO_C_API const char* grotto_stream_last_error(grotto_stream* stream);

/* "connecting", "ready", "backoff", "failed", "stopped", "queued"; "unknown" for other values.
 * Static. */
GROTTO_C_API const char* grotto_stream_state_name(int state);

/* The library logs one key=value line per event through spdlog's default logger (stdout, level
 * info, unless the process configured spdlog otherwise). Sets its level: "trace", "debug",
 * "info", "warn", "error" or "off"; returns 0 (and changes nothing) for anything else or NULL.
 * Process-wide and thread-safe. */
GROTTO_C_API int grotto_set_log_level(const char* level);

#ifdef __cplusplus
}
#endif

#endif /* GROTTO_STREAM_H */
