// include/grotto/grotto_stream.h over the public C++ Stream (grotto/stream.hpp). What C needs
// on top: zero-means-default configuration, rooms handed out through caller-owned arrays, and the
// queues that hold rooms and evictions a poll had no room for. The rooms of the last poll are
// kept here (lent_), so their pointers stay valid until the next poll.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grotto/grotto_stream.h>
#include <grotto/stream.hpp>

struct grotto_stream {
  std::unique_ptr<grotto::Stream> stream;
  std::mutex mu;                        // guards everything below
  std::deque<grotto::RoomPtr> waiting;  // polled from the Stream, not yet handed out
  std::vector<grotto::RoomPtr> lent;    // handed out by the last poll
  std::vector<std::vector<grotto_portal>> lent_portals;
  std::deque<uint64_t> evicted;
  std::string last_error;
};

namespace {

static_assert(static_cast<int>(grotto::StreamState::kConnecting) == GROTTO_STATE_CONNECTING &&
                  static_cast<int>(grotto::StreamState::kReady) == GROTTO_STATE_READY &&
                  static_cast<int>(grotto::StreamState::kBackoff) == GROTTO_STATE_BACKOFF &&
                  static_cast<int>(grotto::StreamState::kFailed) == GROTTO_STATE_FAILED &&
                  static_cast<int>(grotto::StreamState::kStopped) == GROTTO_STATE_STOPPED &&
                  static_cast<int>(grotto::StreamState::kQueued) == GROTTO_STATE_QUEUED,
              "the C states are the C++ ones");
// The last state: grotto_stream_state_name names every value up to it.
constexpr int kLastState = GROTTO_STATE_QUEUED;

void copy3(const grotto::Vec3d& v, double out[3]) {
  out[0] = v.x;
  out[1] = v.y;
  out[2] = v.z;
}

grotto::Vec3d vec(const double v[3]) {
  return {v[0], v[1], v[2]};
}

void write_error(const std::string& why, char* error, size_t error_size) {
  if (!error || error_size == 0) return;
  const size_t n = std::min(why.size(), error_size - 1);
  std::memcpy(error, why.data(), n);
  error[n] = '\0';
}

}  // namespace

extern "C" {

grotto_stream* grotto_stream_create(const grotto_stream_config* config, char* error,
                                    size_t error_size) {
  // Nothing may unwind into C: an allocation failure becomes NULL and a message too.
  try {
    if (!config || !config->url) {
      write_error(config ? "config.url is NULL" : "config is NULL", error, error_size);
      return nullptr;
    }
    grotto::StreamConfig c;
    c.url = config->url;
    if (config->has_seed) c.seed = config->seed;
    if (config->token) c.token = config->token;
    if (config->name) c.name = config->name;
    c.lod = config->lod;
    if (config->horizon_s != 0) c.horizon_s = config->horizon_s;
    // Zero means the default (adaptive, grotto::StreamConfig's floor); negative, fixed.
    if (config->min_horizon_s < 0) {
      c.min_horizon_s = 0;
    } else if (config->min_horizon_s != 0) {
      c.min_horizon_s = config->min_horizon_s;
    }
    if (config->memory_budget_bytes != 0) c.memory_budget_bytes = config->memory_budget_bytes;
    c.decode_threads = config->decode_threads;
    std::string why;
    auto stream = grotto::Stream::start(c, &why);
    if (!stream) {
      write_error(why, error, error_size);
      return nullptr;
    }
    auto* handle = new grotto_stream;
    handle->stream = std::move(stream);
    return handle;
  } catch (const std::exception& e) {
    write_error(e.what(), error, error_size);
    return nullptr;
  }
}

void grotto_stream_destroy(grotto_stream* stream) {
  delete stream;
}

void grotto_stream_stop(grotto_stream* stream) {
  if (stream) stream->stream->stop();
}

void grotto_stream_set_pose(grotto_stream* stream, const grotto_pose* pose) {
  if (!stream || !pose) return;
  grotto::Pose p;
  p.position = vec(pose->position);
  p.forward = vec(pose->forward);
  if (pose->speed != 0) p.speed = pose->speed;
  stream->stream->set_pose(p);
}

int grotto_stream_spawn_point(grotto_stream* stream, double position[3], uint64_t* room) {
  if (!stream) return 0;
  auto spawn = stream->stream->spawn_point();
  if (!spawn) return 0;
  if (position) copy3(spawn->position, position);
  if (room) *room = spawn->room;
  return 1;
}

size_t grotto_stream_poll_rooms(grotto_stream* stream, grotto_room* rooms, size_t capacity) {
  if (!stream) return 0;
  std::lock_guard lock(stream->mu);
  for (auto& r : stream->stream->poll_rooms())
    stream->waiting.push_back(std::move(r));
  // The last poll's rooms are released only now: their pointers were valid until this call.
  stream->lent.clear();
  stream->lent_portals.clear();
  const size_t n = rooms ? std::min(capacity, stream->waiting.size()) : 0;
  for (size_t i = 0; i < n; ++i) {
    grotto::RoomPtr r = std::move(stream->waiting.front());
    stream->waiting.pop_front();
    grotto_room& out = rooms[i];
    std::memset(&out, 0, sizeof out);
    out.key = r->key;
    std::snprintf(out.id, sizeof out.id, "%s", r->id.c_str());
    out.lod = r->lod;
    copy3(r->origin, out.origin);
    copy3(r->centre, out.centre);
    out.radius = r->radius;
    out.vertex_count = r->vertex_count();
    out.index_count = r->indices.size();
    out.portal_count = r->portals.size();
    out.positions = r->positions.data();
    out.normals = r->normals.data();
    out.roughness = r->roughness.data();
    out.mineral = r->mineral.data();
    out.indices = r->indices.data();
    auto& portals = stream->lent_portals.emplace_back();
    for (const grotto::Portal& p : r->portals) {
      grotto_portal& q = portals.emplace_back();
      q.neighbour = p.neighbour;
      copy3(p.centre, q.centre);
      copy3(p.normal, q.normal);
      q.radius = p.radius;
    }
    out.portals = portals.data();
    stream->lent.push_back(std::move(r));
  }
  return n;
}

size_t grotto_stream_poll_evicted(grotto_stream* stream, uint64_t* keys, size_t capacity) {
  if (!stream) return 0;
  std::lock_guard lock(stream->mu);
  for (uint64_t key : stream->stream->poll_evicted())
    stream->evicted.push_back(key);
  const size_t n = keys ? std::min(capacity, stream->evicted.size()) : 0;
  for (size_t i = 0; i < n; ++i) {
    keys[i] = stream->evicted.front();
    stream->evicted.pop_front();
  }
  return n;
}

int grotto_stream_area_ready(grotto_stream* stream, const double point[3], double radius_m,
                             uint32_t max_lod, uint32_t timeout_ms) {
  if (!stream || !point) return 0;
  return stream->stream->wait_area_ready(vec(point), radius_m, max_lod,
                                         std::chrono::milliseconds(timeout_ms))
             ? 1
             : 0;
}

void grotto_stream_get_stats(grotto_stream* stream, grotto_stream_stats* stats) {
  if (!stream || !stats) return;
  grotto::StreamStats s = stream->stream->stats();
  std::memset(stats, 0, sizeof *stats);
  stats->state = static_cast<int>(s.state);
  stats->connects = s.connects;
  stats->reconnects = s.reconnects;
  stats->rooms_received = s.rooms_received;
  stats->rooms_ready = s.rooms_ready;
  stats->rooms_rejected = s.rooms_rejected;
  stats->rooms_evicted = s.rooms_evicted;
  stats->bytes_received = s.bytes_received;
  stats->in_flight = s.in_flight;
  stats->rooms_held = s.rooms_held;
  stats->memory_bytes = s.memory_bytes;
  if (s.queued) {
    stats->queue_position = s.queued->position;
    stats->queue_length = s.queued->length;
    stats->queue_wait_ms = s.queued->wait_ms;
  }
  stats->times_queued = s.times_queued;
  stats->queued_ms = s.queued_ms;
}

const char* grotto_stream_last_error(grotto_stream* stream) {
  if (!stream) return "";
  std::string error = stream->stream->stats().last_error;
  std::lock_guard lock(stream->mu);
  stream->last_error = std::move(error);
  return stream->last_error.c_str();
}

const char* grotto_stream_state_name(int state) {
  if (state < GROTTO_STATE_CONNECTING || state > kLastState) return "unknown";
  return grotto::state_name(static_cast<grotto::StreamState>(state));
}

int grotto_set_log_level(const char* level) {
  return level && grotto::set_log_level(level) ? 1 : 0;
}

}  // extern "C"
