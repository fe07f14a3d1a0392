// include/grotto/stream.hpp over client/stream: the installed library's C++ face. It translates
// types and nothing else; the protocol, plan, store and threads are stream::Stream's. Rooms are
// handed over without copying their arrays: a grotto::Room's spans point into the decoded room,
// which the RoomPtr keeps alive (shared_ptr's aliasing constructor).
#include <spdlog/spdlog.h>

#include <array>
#include <chrono>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <grotto/stream.hpp>
#include "client/stream/stream.hpp"
#include "common/cave/room_id.hpp"

namespace grotto {

namespace {

static_assert(sizeof(mesh::core::float3) == 3 * sizeof(float), "positions are read as floats");

Vec3d to_public(Vec3 v) {
  return {v.x, v.y, v.z};
}
Vec3 to_internal(Vec3d v) {
  return {v.x, v.y, v.z};
}

// A public Room and the decoded room its spans point into.
struct HeldRoom {
  Room room;
  std::shared_ptr<const stream::ReadyRoom> source;
};

RoomPtr to_public(std::shared_ptr<const stream::ReadyRoom> ready) {
  if (!ready) return nullptr;
  auto held = std::make_shared<HeldRoom>();
  held->source = std::move(ready);
  const stream::ReadyRoom& r = *held->source;
  Room& out = held->room;
  out.key = r.room.id.packed();
  out.id = r.room.id.to_string();
  out.lod = r.lod;
  out.origin = to_public(r.origin);
  out.centre = to_public(r.room.sphere.centre);
  out.radius = r.room.sphere.radius;
  out.portals.reserve(r.room.portals.size());
  for (const cave::Portal& p : r.room.portals) {
    out.portals.push_back(
        {p.neighbour.packed(), to_public(p.centre), to_public(p.normal), p.radius});
  }
  const codec::DecodedRoom& m = r.mesh;
  out.positions = {reinterpret_cast<const float*>(m.positions.data()), 3 * m.positions.size()};
  out.normals = {reinterpret_cast<const float*>(m.normals.data()), 3 * m.normals.size()};
  out.roughness = m.roughness;
  out.mineral = m.mineral;
  out.indices = m.indices;
  return RoomPtr(held, &held->room);
}

// The public enum mirrors the library's, value for value, so one cast converts and one
// state_name (client/stream/options.hpp) names both; kQueued, after them, is the library's
// kConnecting with a place in the admission queue (stats().queued), which a game shows.
static_assert(
    static_cast<int>(StreamState::kConnecting) ==
        static_cast<int>(stream::StreamState::kConnecting) &&
    static_cast<int>(StreamState::kReady) == static_cast<int>(stream::StreamState::kReady) &&
    static_cast<int>(StreamState::kBackoff) == static_cast<int>(stream::StreamState::kBackoff) &&
    static_cast<int>(StreamState::kFailed) == static_cast<int>(stream::StreamState::kFailed) &&
    static_cast<int>(StreamState::kStopped) == static_cast<int>(stream::StreamState::kStopped));
StreamState to_public(const stream::StreamStats& s) {
  if (s.state == stream::StreamState::kConnecting && s.queued) return StreamState::kQueued;
  return static_cast<StreamState>(s.state);
}

}  // namespace

// The Runtime is declared first so that it outlives the Stream that runs on it.
struct Stream::Impl {
  stream::Runtime runtime;
  std::unique_ptr<stream::Stream> stream;

  explicit Impl(int decode_threads) : runtime(1, decode_threads > 0 ? decode_threads : 2) {}
};

std::unique_ptr<Stream> Stream::start(const StreamConfig& config, std::string* error) {
  stream::StreamOptions o;
  o.url = config.url;
  o.seed = config.seed;
  o.token = config.token;
  o.name = config.name;
  o.lod = config.lod;
  o.plan.horizon_s = config.horizon_s;
  o.min_horizon_s = config.min_horizon_s;
  o.store_bytes = config.memory_budget_bytes;
  // Past its capacity a server then queues the player and says where (kQueued) rather than
  // refusing it: a game can tell the player how long, instead of retrying blindly.
  o.queue = true;
  std::string why;
  if (config.decode_threads < 0 || config.decode_threads > 64) {
    why = "decode_threads must be in [0, 64]";
  } else if (Status valid = stream::validate_options(o); !valid) {
    why = valid.error().message;
  }
  if (!why.empty()) {
    if (error) *error = why;
    return nullptr;
  }
  auto impl = std::make_unique<Impl>(config.decode_threads);
  auto started = stream::Stream::start(o, impl->runtime);
  if (!started) {
    if (error) *error = started.error().message;
    return nullptr;
  }
  impl->stream = std::move(started).value();
  return std::unique_ptr<Stream>(new Stream(std::move(impl)));
}

Stream::Stream(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Stream::~Stream() {
  // The stream::Stream stops and goes before its Runtime (member order in Impl).
  impl_->stream.reset();
}

void Stream::set_pose(const Pose& pose) {
  stream::Pose p;
  p.position = to_internal(pose.position);
  p.forward = to_internal(pose.forward);
  p.speed = pose.speed;
  impl_->stream->set_pose(p);
}

std::optional<SpawnPoint> Stream::spawn_point() const {
  auto s = impl_->stream->spawn_point();
  if (!s) return std::nullopt;
  return SpawnPoint{s->room.packed(), to_public(s->position)};
}

std::vector<RoomPtr> Stream::poll_rooms() {
  std::vector<RoomPtr> out;
  for (auto& r : impl_->stream->take_new_rooms())
    out.push_back(to_public(std::move(r)));
  return out;
}

std::vector<RoomKey> Stream::poll_evicted() {
  std::vector<RoomKey> out;
  for (cave::RoomId id : impl_->stream->take_evicted())
    out.push_back(id.packed());
  return out;
}

RoomPtr Stream::room(RoomKey key) const {
  auto id = cave::RoomId::unpack(key);
  if (!id) return nullptr;
  return to_public(impl_->stream->room(*id));
}

StreamStats Stream::stats() const {
  stream::StreamStats s = impl_->stream->stats();
  StreamStats out;
  out.state = to_public(s);
  out.connects = s.connects;
  out.reconnects = s.reconnects;
  out.rooms_received = s.rooms_received;
  out.rooms_ready = s.rooms_ready;
  out.rooms_rejected = s.rooms_rejected;
  out.rooms_evicted = s.rooms_evicted;
  out.bytes_received = s.bytes_received;
  out.in_flight = s.in_flight;
  out.rooms_held = s.store_rooms;
  out.memory_bytes = s.store_bytes;
  out.horizon_s = s.horizon_s;
  out.seed = s.seed;
  out.last_error = s.last_error;
  if (out.state == StreamState::kQueued) {
    out.queued = StreamStats::QueuePlace{s.queued->position, s.queued->queue, s.queued->wait_ms};
  }
  out.times_queued = s.times_queued;
  out.queued_ms = s.queued_ms;
  return out;
}

bool Stream::area_ready(Vec3d point, double radius_m, uint32_t max_lod) const {
  return impl_->stream->area_status(to_internal(point), radius_m, max_lod).ready;
}

bool Stream::wait_area_ready(Vec3d point, double radius_m, uint32_t max_lod,
                             std::chrono::milliseconds timeout) const {
  return impl_->stream->wait_area_ready(to_internal(point), radius_m, max_lod, timeout);
}

void Stream::stop() {
  impl_->stream->stop();
}

std::string room_name(RoomKey key) {
  auto id = cave::RoomId::unpack(key);
  return id ? id->to_string() : std::string();
}

const char* state_name(StreamState state) {
  if (state == StreamState::kQueued) return "queued";
  return stream::state_name(static_cast<stream::StreamState>(state));
}

bool set_log_level(std::string_view level) {
  static constexpr std::array<std::pair<std::string_view, spdlog::level::level_enum>, 6> kLevels{{
      {"trace", spdlog::level::trace},
      {"debug", spdlog::level::debug},
      {"info", spdlog::level::info},
      {"warn", spdlog::level::warn},
      {"error", spdlog::level::err},
      {"off", spdlog::level::off},
  }};
  for (const auto& [name, value] : kLevels) {
    if (name == level) {
      spdlog::set_level(value);
      return true;
    }
  }
  return false;
}

}  // namespace grotto
