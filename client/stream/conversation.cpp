#include "client/stream/conversation.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "client/stream/area.hpp"
#include "common/core/bytes.hpp"

namespace grotto::stream {

namespace {

// Samples and evicted ids kept for a caller that does not drain them.
constexpr size_t kMaxUndrained = size_t{1} << 16;

template <class T>
void trim(std::vector<T>& v) {
  if (v.size() > kMaxUndrained) v.erase(v.begin(), v.begin() + (v.size() - kMaxUndrained));
}

double ms_between(SteadyTime from, SteadyTime to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

// The id field of a frame refused before its descriptor could be read (bytes 8-15).
std::optional<cave::RoomId> frame_id(std::span<const uint8_t> bytes) {
  if (bytes.size() < 16) return std::nullopt;
  auto id = cave::RoomId::unpack(le::load(bytes.data() + 8));
  if (!id) return std::nullopt;
  return id.value();
}

}  // namespace

const char* state_name(StreamState state) {
  switch (state) {
    case StreamState::kConnecting:
      return "connecting";
    case StreamState::kReady:
      return "ready";
    case StreamState::kBackoff:
      return "backoff";
    case StreamState::kFailed:
      return "failed";
    case StreamState::kStopped:
      return "stopped";
  }
  return "unknown";
}

bool is_final_error(ErrorCode code) {
  return code == ErrorCode::kUnsupportedVersion || code == ErrorCode::kWorldMismatch ||
         code == ErrorCode::kUnauthorized;
}

Conversation::Conversation(const StreamOptions& options, uint64_t jitter_seed)
    : options_(options), rng_(jitter_seed), store_(options.store_bytes) {}

// ---- connection events ----

void Conversation::connecting() {
  if (stats_.state == StreamState::kFailed || stats_.state == StreamState::kStopped) return;
  stats_.state = StreamState::kConnecting;
}

Actions Conversation::opened(SteadyTime now) {
  Actions out;
  if (stats_.state == StreamState::kFailed || stats_.state == StreamState::kStopped) return out;
  stats_.state = StreamState::kConnecting;
  open_ = true;
  welcomed_ = false;
  opened_at_ = now;
  fatal_.clear();
  proto::Hello hello;
  hello.ref = next_ref_++;
  for (uint32_t v = proto::kProtocolVersion; v >= proto::kMinProtocolVersion; --v) {
    if (options_.protocol_version == 0 || options_.protocol_version == v)
      hello.versions.push_back(v);
  }
  hello.seed = options_.seed;
  hello.params = options_.params;
  hello.name = options_.name;
  if (!options_.token.empty()) hello.token = options_.token;
  hello.queue = options_.queue;
  send(hello, now, out);
  return out;
}

Actions Conversation::text(std::string_view message, SteadyTime now) {
  Actions out;
  if (!open_) return out;
  stats_.bytes_received += message.size();
  auto parsed = proto::parse_server_message(message, limits_);
  if (!parsed) {
    ++stats_.errors["bad_message"];
    note_error("server sent an invalid message: " + parsed.error().message);
    if (!welcomed_) reconnect("before welcome: " + parsed.error().message, false, out);
    return out;
  }
  std::visit([&](const auto& m) { on_message(m, now, out); }, parsed.value());
  return out;
}

Actions Conversation::binary(std::span<const uint8_t> bytes, SteadyTime now) {
  Actions out;
  if (!open_) return out;
  stats_.bytes_received += bytes.size();
  if (!welcomed_) {
    reconnect("a room frame before welcome", false, out);
    return out;
  }
  auto decoded = proto::decode_room_frame(bytes, limits_);
  if (!decoded) {
    // PROTOCOL.md "Binary room frame": drop it, use no part of it, ask again later. The id field,
    // when it names a room in flight, releases that room for the next plan.
    ++stats_.rooms_rejected;
    note_error("refused a room frame: " + decoded.error().message);
    if (auto id = frame_id(bytes); id && in_flight_.erase(*id)) count_failure(*id);
    plan(now, out);
    return out;
  }
  proto::RoomFrame frame = std::move(decoded).value();
  const cave::RoomId id = frame.room.id;
  auto it = in_flight_.find(id);
  if (frame.version != version_) {
    // PROTOCOL.md "Versioning": every frame uses the version welcome chose.
    ++stats_.rooms_rejected;
    note_error("refused a room frame: version " + std::to_string(frame.version) +
               ", the session's is " + std::to_string(version_));
    if (it != in_flight_.end()) {
      in_flight_.erase(it);
      count_failure(id);
    }
    plan(now, out);
    return out;
  }
  // Cancelled while on the wire, or never asked for: not ours to use.
  if (it == in_flight_.end()) return out;
  if (frame.lod != it->second.lod) {
    ++stats_.rooms_rejected;
    note_error("room " + id.to_string() + " came at lod " + std::to_string(frame.lod) +
               ", requested at lod " + std::to_string(it->second.lod));
    in_flight_.erase(it);
    count_failure(id);
    plan(now, out);
    return out;
  }
  RoomSample sample;
  sample.id = id;
  sample.frame_bytes = bytes.size();
  sample.latency_ms = ms_between(it->second.sent, now);
  sample.priority_ms = it->second.priority;
  const SteadyTime due = it->second.sent + std::chrono::milliseconds(it->second.priority);
  if (it->second.priority <= kUrgentPriorityMs) {
    recent_latency_ms_.push_back({now, sample.latency_ms});
    if (recent_latency_ms_.size() > kLatencyWindow) recent_latency_ms_.pop_front();
  }
  recent_any_latency_ms_.push_back({now, sample.latency_ms});
  if (recent_any_latency_ms_.size() > kLatencyWindow) recent_any_latency_ms_.pop_front();
  in_flight_.erase(it);
  if (auto added = graph_.add(frame.room); !added) {
    ++stats_.rooms_rejected;
    note_error("room " + id.to_string() + " disagrees with a neighbour: " + added.error().message);
    count_failure(id);
    plan(now, out);
    return out;
  }
  ++stats_.rooms_received;
  decoding_.insert(id);
  DecodeRoom job;
  job.limits = frame.lod == 0 ? codec::DecodeLimits{} : codec::kDetailLimits;
  job.limits.portal_count = static_cast<int>(frame.room.portals.size());
  job.limits.normals = proto::payload_has_normals(frame.version);
  job.frame = std::move(frame);
  job.sample = sample;
  job.epoch = epoch_;
  job.due = due;
  out.emplace_back(std::in_place_type<DecodeRoom>, std::move(job));
  plan(now, out);  // the new descriptor's portals extend the graph
  return out;
}

Actions Conversation::closed(uint16_t code, std::string_view reason, SteadyTime /*now*/) {
  Actions out;
  if (!open_) return out;
  const std::string text(reason);
  const std::string why = "server closed the connection (" + std::to_string(code) +
                          (text.empty() ? "" : " " + proto::echo(text)) + ")" +
                          (fatal_.empty() ? "" : ": " + fatal_);
  // The reason is the error code that caused the close (PROTOCOL.md "Transport"); one that no
  // reconnect cures stops us even when its error message was lost.
  if (auto named = proto::parse_wire_code(text); named && is_final_error(*named)) {
    fail(why, out);
    return out;
  }
  const bool restart = code == kCloseGoingAway || text == "service_restart";
  reconnect(why, restart, out);
  return out;
}

Actions Conversation::lost(std::string_view why, SteadyTime /*now*/) {
  Actions out;
  if (stats_.state == StreamState::kFailed || stats_.state == StreamState::kStopped) return out;
  reconnect(std::string(why), false, out);
  return out;
}

Actions Conversation::decoded(DecodeRoom job, Result<codec::DecodedRoom> mesh, SteadyTime now) {
  Actions out;
  const cave::RoomId id = job.frame.room.id;
  if (job.epoch == epoch_) decoding_.erase(id);
  if (stats_.state == StreamState::kStopped || stats_.state == StreamState::kFailed) return out;
  // Another world since, or another lod: a room of it must not sit next to this session's.
  if (job.epoch != epoch_ || job.frame.lod != lod_) return out;
  if (!mesh) {
    ++stats_.rooms_rejected;
    note_error("room " + id.to_string() + ": " + mesh.error().message);
    count_failure(id);
    plan(now, out);
    return out;
  }
  auto ready = std::make_shared<ReadyRoom>();
  ready->room = std::move(job.frame.room);
  ready->lod = job.frame.lod;
  ready->origin = job.frame.origin;
  ready->mesh = std::move(mesh).value();
  ready->payload_bytes = job.frame.payload.size();
  ready->decode_ms = job.sample.decode_ms;
  store_.insert(ready);
  fresh_.push_back(ready);
  samples_.push_back(job.sample);
  failures_.erase(id);
  ++stats_.rooms_ready;
  // Neither what the pose's plan wants nor what a caller waits for (the pinned areas).
  std::set<cave::RoomId> merged;
  if (!pinned_.empty()) {
    merged = wanted_;
    merged.insert(pinned_.begin(), pinned_.end());
  }
  auto gone = store_.evict(pose_.position, pinned_.empty() ? wanted_ : merged);
  stats_.rooms_evicted += gone.size();
  // Their descriptors go too, so a long walk keeps the graph as bounded as the store; coming
  // back asks for the rooms again, descriptors included.
  for (auto g : gone)
    graph_.remove(g);
  evicted_.insert(evicted_.end(), gone.begin(), gone.end());
  // A caller that never drains must not make memory grow without bound: rooms it never took
  // and that are gone now are dropped from `fresh` (it holds them alive), and the oldest
  // samples and evicted ids go past kMaxUndrained.
  if (!gone.empty() && !fresh_.empty()) {
    std::set<cave::RoomId> dead(gone.begin(), gone.end());
    std::erase_if(fresh_, [&](const auto& r) { return dead.count(r->room.id) != 0; });
  }
  trim(samples_);
  trim(evicted_);
  return out;
}

Actions Conversation::tick(SteadyTime now) {
  Actions out;
  if (!open_) return out;
  if (!welcomed_ && queued_since_) {
    // Queued, the server talks to us: connect_timeout does not apply, a ping now and then
    // keeps the connection known to be alive.
    stats_.queued_ms += std::chrono::duration<double, std::milli>(now - *queued_since_).count();
    queued_since_ = now;
    if (now - last_send_ > std::chrono::seconds{10}) {
      proto::Ping p;
      p.t = std::chrono::duration<double, std::milli>(now.time_since_epoch()).count();
      send(p, now, out);
    }
    return out;
  }
  if (!welcomed_) {
    if (now - opened_at_ >= options_.connect_timeout) {
      reconnect("no welcome within " + std::to_string(options_.connect_timeout.count()) + " ms",
                false, out);
    }
    return out;
  }
  bool replan = pose_dirty_;
  // Rooms in flight too long: the server lost them, or a frame was refused without an id.
  for (auto it = in_flight_.begin(); it != in_flight_.end();) {
    if (now - it->second.sent > options_.request_timeout) {
      it = in_flight_.erase(it);
      replan = true;
    } else {
      ++it;
    }
  }
  if (expire_pins(now)) replan = true;
  if (hold_until_ != SteadyTime{} && now >= hold_until_) {
    hold_until_ = {};
    replan = true;
  }
  if (replan) plan(now, out);
  const auto ping_every =
      std::chrono::milliseconds(std::clamp<int64_t>(limits_.idle_timeout_ms / 3, 1, 10'000));
  if (now - last_send_ > ping_every) {
    proto::Ping p;
    p.t = std::chrono::duration<double, std::milli>(now.time_since_epoch()).count();
    send(p, now, out);
  }
  return out;
}

void Conversation::set_pose(const Pose& pose) {
  pose_ = pose;
  pose_set_ = true;
  pose_from_spawn_ = false;
  pose_dirty_ = true;
}

void Conversation::stop() {
  if (stats_.state != StreamState::kFailed) stats_.state = StreamState::kStopped;
  open_ = false;
}

uint64_t Conversation::pin_area(const AreaPin& pin) {
  const uint64_t handle = next_pin_++;
  pins_[handle].pin = pin;
  pose_dirty_ = true;  // the next tick plans it
  return handle;
}

void Conversation::unpin_area(uint64_t handle) {
  if (pins_.erase(handle) == 0) return;
  plan_areas({}, nullptr);  // its rooms may be evicted from now on
  pose_dirty_ = true;  // and cancelled at the next tick when the pose's plan has no use for them
}

bool Conversation::expire_pins(SteadyTime now) {
  return std::erase_if(pins_, [&](const auto& p) { return now >= p.second.pin.deadline; }) != 0;
}

// ---- messages ----

void Conversation::on_message(const proto::Queued& q, SteadyTime now, Actions&) {
  if (welcomed_) return note_error("server sent queued after welcome");
  if (!queued_since_) {
    queued_since_ = now;
    ++stats_.times_queued;
  }
  stats_.queued = StreamStats::QueuePlace{q.position, q.wait_ms, q.queue};
}

void Conversation::leave_queue(SteadyTime now) {
  if (!queued_since_) return;
  stats_.queued_ms += std::chrono::duration<double, std::milli>(now - *queued_since_).count();
  queued_since_.reset();
  stats_.queued.reset();
}

void Conversation::on_message(const proto::Welcome& w, SteadyTime now, Actions& out) {
  if (welcomed_) return note_error("server sent a second welcome");
  leave_queue(now);
  if (!proto::speaks_version(w.version)) {
    return fail("server chose protocol version " + std::to_string(w.version) +
                    "; this client speaks " + std::to_string(proto::kMinProtocolVersion) + " to " +
                    std::to_string(proto::kProtocolVersion),
                out);
  }
  version_ = w.version;
  if (options_.seed && w.seed != *options_.seed) {
    return fail("server serves seed " + std::to_string(w.seed) + ", not the requested " +
                    std::to_string(*options_.seed),
                out);
  }
  if (options_.params && w.params != *options_.params) {
    return fail("server uses parameter digest " + proto::digest_text(w.params) +
                    ", not the requested " + proto::digest_text(*options_.params),
                out);
  }
  if (world_ && *world_ != std::pair{w.seed, w.params}) {
    // Another world behind the same address (a redeploy with another seed or parameters): what
    // we hold belongs to the old one. Renderers learn of it through take_evicted().
    spdlog::warn("event=world_changed server={} seed={} action=clear_rooms", w.server, w.seed);
    drop_rooms_held("world changed");
    graph_.clear();
    failures_.clear();
    given_up_.clear();
    current_.reset();
    wanted_.clear();
    pinned_.clear();
    for (auto& [handle, area] : pins_)
      area.located.reset();  // the old world's room
    if (pose_from_spawn_) {  // the old world's spawn point means nothing here
      pose_set_ = false;
      pose_from_spawn_ = false;
      pose_ = {};
    }
    spawn_.reset();
  }
  world_ = std::pair{w.seed, w.params};
  welcomed_ = true;
  limits_ = w.limits;
  const uint32_t lod = std::min(options_.lod, limits_.max_lod);
  if (lod != lod_ && (store_.size() != 0 || !decoding_.empty())) {
    // One lod a session: rooms of two lods do not share rims (PROTOCOL.md "Levels of detail"),
    // so the rooms held at the old lod go and the neighbourhood is asked for again.
    drop_rooms_held("lod changed");
  }
  lod_ = lod;
  out.emplace_back(std::in_place_type<SetReadLimit>,
                   SetReadLimit{std::max(limits_.max_frame_bytes, limits_.max_message_bytes)});
  stats_.limits = limits_;
  stats_.server = w.server;
  stats_.seed = w.seed;
  stats_.state = StreamState::kReady;
  if (stats_.connects++ > 0) ++stats_.reconnects;
  attempts_ = 0;
  if (options_.lod > limits_.max_lod) {
    note_error("server serves lod up to " + std::to_string(limits_.max_lod) + "; asked for " +
               std::to_string(options_.lod) + ", using " + std::to_string(limits_.max_lod));
  }
  if (!pose_set_ && options_.spawn && !spawn_) {
    proto::Spawn s;
    s.ref = next_ref_++;
    send(s, now, out);
  }
  plan(now, out);
}

void Conversation::on_message(const proto::SpawnPoint& s, SteadyTime now, Actions& out) {
  if (!welcomed_) return;
  spawn_ = s;
  if (!pose_set_) {
    pose_.position = s.position;
    pose_.room = s.room;
    pose_set_ = true;
    pose_from_spawn_ = true;
  }
  plan(now, out);
}

void Conversation::on_message(const proto::Located& l, SteadyTime now, Actions& out) {
  if (!welcomed_) return;
  if (auto it = l.ref ? pin_locates_.find(*l.ref) : pin_locates_.end(); it != pin_locates_.end()) {
    // A pinned area's point, not the player's. Null: in rock or beyond the sector range, and so
    // it stays on this connection (the world is deterministic).
    if (auto pin = pins_.find(it->second); pin != pins_.end()) pin->second.located = l.room;
    pin_locates_.erase(it);
  } else if (l.room) {
    current_ = l.room;
  }
  plan(now, out);
}

void Conversation::on_message(const proto::ErrorMessage& e, SteadyTime now, Actions& out) {
  const char* code = proto::wire_code_name(e.code);
  // service_restart is a graceful drain (PROTOCOL.md), a notice rather than an error: the close
  // follows and we reconnect at once. What it names is asked for again on the next connection,
  // so it is no failure of a room.
  const bool restart = e.code == ErrorCode::kServiceRestart;
  if (restart) {
    ++stats_.restart_notices;
    spdlog::debug("event=stream_restart_notice detail=\"{}\"", e.message);
  } else {
    ++stats_.errors[code];
    note_error(std::string("server error ") + code + ": " + e.message);
  }
  if (e.room) {
    in_flight_.erase(*e.room);
    if (e.code == ErrorCode::kNotFound) {
      give_up(*e.room);
    } else if (!restart) {
      count_failure(*e.room);
    }
  } else if (e.ref) {
    // A request refused whole put nothing in flight (PROTOCOL.md "Rooms in flight").
    if (auto it = pending_.find(*e.ref); it != pending_.end()) {
      for (auto id : it->second) {
        auto f = in_flight_.find(id);
        if (f != in_flight_.end() && f->second.ref == *e.ref) in_flight_.erase(f);
      }
      pending_.erase(it);
    }
  }
  if (e.code == ErrorCode::kOverloaded || e.code == ErrorCode::kLimitExceeded) {
    hold_until_ = now + backoff_delay(1);
  }
  // Refused at the door with a time to come back: the reconnect waits at least that long, so a
  // crowd refused together does not return together before the server can take it.
  if (e.fatal && e.retry_after_ms) retry_after_ = std::chrono::milliseconds{*e.retry_after_ms};
  // Every error before welcome is fatal, whatever its flag says (PROTOCOL.md "Session").
  const bool fatal = e.fatal || !welcomed_;
  if (fatal) fatal_ = std::string(code) + ": " + e.message;
  if (fatal && is_final_error(e.code)) return fail(fatal_, out);
  // Other fatal errors: the server closes next, and closed() reconnects. A room refused alone is
  // asked for again at once (max_room_failures bounds the retries; a hold bounds overload).
  if (!fatal && e.room) plan(now, out);
}

// ---- planning ----

// Rooms must arrive before the player reaches them: the horizon covers the time a room takes to
// come (the p90 of recent latencies, doubled for its spread) and a second for decoding, a turn and
// a sprint's start. Only the urgent class counts (rooms requested with a priority within
// kUrgentPriorityMs): those are what the player walks into next, and the server takes them before
// everyone's far prefetch, so their latency is how long the next room takes. Far rooms' latency
// is the server's backlog of prefetch; widening the horizon on it would ask for more of what
// makes the backlog (a crowd arriving at once drove every horizon to the maximum, and the backlog
// to 10-14 s). Urgent rooms still in flight count with the time they have waited so far, so a
// server that slows down widens the horizon before its late rooms arrive. A stream starts at the
// floor: its first rooms are the nearest, and their latency says what the server can do.
double Conversation::horizon_s(SteadyTime now) const {
  const double max = options_.plan.horizon_s;
  if (options_.min_horizon_s <= 0) return max;
  double floor = std::min(options_.min_horizon_s, max);
  std::vector<double> waits;
  for (const auto& [at, ms] : recent_latency_ms_)
    if (now - at <= kLatencyWindowTime) waits.push_back(ms);
  // The link's round trip: no room comes sooner than the quickest of the last ones
  // (urgent or not) did, a round trip and a frame's time on the link; on a far or thin link
  // (300 ms, 512 kbit/s) that is most of what a room takes, and a plan that changes (a turn, a
  // sprint) costs it again before the first new room can come. The floor keeps six of them
  // ahead, once enough rooms have come to know it (on loopback, a few milliseconds: the floor
  // stays as it is).
  double quickest = -1;
  size_t samples = 0;
  for (const auto& [at, ms] : recent_any_latency_ms_) {
    if (now - at > kLatencyWindowTime) continue;
    quickest = samples++ == 0 ? ms : std::min(quickest, ms);
  }
  if (samples >= kRoundTripSamples) {
    floor = std::min(max, std::max(floor, 1.0 + 6.0 * quickest / 1000.0));
  }
  for (const auto& [id, room] : in_flight_)
    if (room.priority <= kUrgentPriorityMs) waits.push_back(ms_between(room.sent, now));
  if (waits.empty()) return floor;
  std::sort(waits.begin(), waits.end());
  const double p90 = waits[std::min(waits.size() - 1, waits.size() * 9 / 10)];
  return std::clamp(1.0 + 2.0 * p90 / 1000.0, floor, max);
}

void Conversation::send(proto::ClientMessage message, SteadyTime now, Actions& out) {
  last_send_ = now;
  out.emplace_back(std::in_place_type<SendMessage>, SendMessage{std::move(message)});
}

void Conversation::plan(SteadyTime now, Actions& out) {
  if (!open_ || !welcomed_) return;
  pose_dirty_ = false;
  expire_pins(now);
  std::optional<cave::RoomId> start = pose_.room;
  if (!start) start = graph_.room_at(pose_.position);
  if (!start) start = current_;
  if (!start && spawn_) start = spawn_->room;
  if (!start && pose_set_ &&
      (last_locate_ == SteadyTime{} || now - last_locate_ > std::chrono::seconds(1))) {
    last_locate_ = now;
    proto::Locate l;
    l.ref = next_ref_++;
    l.point = pose_.position;
    send(l, now, out);
  }
  const std::vector<PlannedRoom> areas = plan_areas(now, &out);
  // The pose's plan, when the pose has a room: what it keeps in flight and what it wants.
  std::vector<PlannedRoom> keep;
  const double horizon = start ? horizon_s(now) : 0;
  const uint32_t batch = batch_size();
  if (start) {
    current_ = start;
    horizon_s_ = horizon;
    PlanOptions wide = options_.plan;
    wide.horizon_s = horizon * options_.cancel_factor;
    keep = graph_.plan(*start, pose_, wide);
    std::set<cave::RoomId> keep_ids;
    wanted_.clear();
    for (const auto& p : keep) {
      keep_ids.insert(p.id);
      if (p.seconds <= horizon) wanted_.insert(p.id);
    }
    std::vector<cave::RoomId> cancels;
    for (auto it = in_flight_.begin(); it != in_flight_.end();) {
      if (keep_ids.count(it->first) || pinned_.count(it->first)) {
        ++it;
        continue;
      }
      cancels.push_back(it->first);
      it = in_flight_.erase(it);
    }
    for (size_t i = 0; i < cancels.size(); i += batch) {
      proto::Cancel c;
      c.ref = next_ref_++;
      c.rooms.assign(cancels.begin() + i,
                     cancels.begin() + std::min(cancels.size(), size_t{i + batch}));
      stats_.cancels_sent += c.rooms.size();
      send(std::move(c), now, out);
    }
  }
  if (now < hold_until_) return;
  const size_t cap = std::min(options_.max_in_flight, limits_.max_rooms_in_flight);
  std::vector<proto::RoomWant> wants;
  std::set<cave::RoomId> asked;
  // Whether `id` is worth asking for now (false also when it was just added to wants).
  auto missing = [&](cave::RoomId id) {
    return !store_.contains(id) && !in_flight_.count(id) && !decoding_.count(id) &&
           !given_up_.count(id) && !asked.count(id);
  };
  // A caller waits for the pinned areas: their rooms first, priority 0 (the soonest).
  for (const auto& p : areas) {
    if (in_flight_.size() + wants.size() >= cap) break;
    if (!missing(p.id)) continue;
    asked.insert(p.id);
    wants.push_back({p.id, lod_, 0});
  }
  for (const auto& p : keep) {
    if (in_flight_.size() + wants.size() >= cap) break;
    if (p.seconds > horizon) break;
    if (!missing(p.id)) continue;
    const double ms = std::min(p.seconds * 1000.0, 4294967295.0);
    asked.insert(p.id);
    wants.push_back({p.id, lod_, static_cast<uint32_t>(ms)});
  }
  for (size_t i = 0; i < wants.size(); i += batch) {
    proto::Request r;
    r.ref = next_ref_++;
    r.rooms.assign(wants.begin() + i, wants.begin() + std::min(wants.size(), size_t{i + batch}));
    auto& ids = pending_[*r.ref];
    for (const auto& w : r.rooms) {
      in_flight_[w.id] = {now, w.lod, w.priority, *r.ref};
      ids.push_back(w.id);
    }
    stats_.requests_sent += r.rooms.size();
    send(std::move(r), now, out);
  }
  // Refs are answered only by a refusal, which comes before later replies: keep a bounded tail.
  while (pending_.size() > 256)
    pending_.erase(pending_.begin());
}

std::vector<PlannedRoom> Conversation::plan_areas(SteadyTime now, Actions* out) {
  pinned_.clear();
  std::vector<PlannedRoom> rooms;
  for (auto& [handle, area] : pins_) {
    // Rooms come at the session's lod only (one lod a session): nothing fetched could make an
    // area asked for below it ready.
    if (area.pin.max_lod < lod_) continue;
    std::optional<cave::RoomId> start = graph_.room_at(area.pin.point);
    if (!start) start = area.located;
    if (!start) {
      const Vec3 p = area.pin.point;
      const bool valid = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
                         std::abs(p.x) <= proto::kMaxCoordinate &&
                         std::abs(p.y) <= proto::kMaxCoordinate &&
                         std::abs(p.z) <= proto::kMaxCoordinate;
      if (out && valid && !area.asked) {
        area.asked = true;
        proto::Locate l;
        l.ref = next_ref_++;
        l.point = p;
        pin_locates_[*l.ref] = handle;
        send(l, now, *out);
      }
      continue;
    }
    for (const PlannedRoom& room : area_rooms(graph_, *start, area.pin.point, area.pin.radius_m))
      if (pinned_.insert(room.id).second) rooms.push_back(room);
  }
  // Nearest first across areas (each area's own list already is).
  std::stable_sort(rooms.begin(), rooms.end(), [](const PlannedRoom& a, const PlannedRoom& b) {
    return a.seconds < b.seconds;
  });
  return rooms;
}

// Rooms per request or cancel: the server's limit, and what fits in max_message_bytes (an entry
// is at most ~72 bytes of JSON: a 30-character id, lod, a 10-digit priority).
uint32_t Conversation::batch_size() const {
  const uint32_t by_bytes =
      limits_.max_message_bytes > 256 ? (limits_.max_message_bytes - 128) / 80 : 1;
  return std::max(1u, std::min(limits_.max_rooms_per_request, by_bytes));
}

void Conversation::count_failure(cave::RoomId id) {
  if (++failures_[id] >= options_.max_room_failures) give_up(id);
}

void Conversation::give_up(cave::RoomId id) {
  if (given_up_.insert(id).second) ++stats_.rooms_given_up;
}

void Conversation::note_error(const std::string& message) {
  stats_.last_error = message;
  spdlog::debug("event=stream_error detail=\"{}\"", message);
}

void Conversation::drop_rooms_held(const char* why) {
  spdlog::info("event=stream_rooms_dropped rooms={} reason=\"{}\"", store_.size(), why);
  for (auto id : store_.ids())
    evicted_.push_back(id);
  trim(evicted_);
  stats_.rooms_evicted += store_.size();
  store_.clear();
  fresh_.clear();
  decoding_.clear();
  ++epoch_;
}

// ---- losing the connection ----

std::chrono::milliseconds Conversation::backoff_delay(int attempt) {
  double base =
      static_cast<double>(options_.backoff_initial.count()) * std::pow(2.0, std::min(attempt, 30));
  base = std::min(base, static_cast<double>(options_.backoff_max.count()));
  std::uniform_real_distribution<double> jitter(0.5, 1.0);  // "equal jitter"
  return std::chrono::milliseconds(static_cast<int64_t>(base * jitter(rng_)));
}

std::chrono::milliseconds Conversation::restart_delay() {
  std::uniform_real_distribution<double> spread(
      static_cast<double>(options_.backoff_initial.count()) / 2,
      static_cast<double>(options_.restart_spread.count()));
  return std::chrono::milliseconds(static_cast<int64_t>(spread(rng_)));
}

void Conversation::end_connection() {
  if (open_ || stats_.state == StreamState::kConnecting) ++stats_.drops;
  if (queued_since_) leave_queue(*queued_since_);  // no clock here: ticks kept queued_ms
  open_ = false;
  welcomed_ = false;
  in_flight_.clear();
  pending_.clear();
  hold_until_ = {};
  pin_locates_.clear();
  for (auto& [handle, area] : pins_)
    area.asked = false;  // locate again on the next connection
}

void Conversation::reconnect(const std::string& why, bool restart, Actions& out) {
  if (stats_.state == StreamState::kFailed || stats_.state == StreamState::kStopped) return;
  end_connection();
  note_error(why);
  stats_.state = StreamState::kBackoff;
  const auto delay = std::max(restart ? restart_delay() : backoff_delay(attempts_++),
                              std::exchange(retry_after_, std::chrono::milliseconds{0}));
  out.emplace_back(std::in_place_type<Reconnect>, Reconnect{delay, why});
}

void Conversation::fail(const std::string& why, Actions& out) {
  end_connection();
  stats_.state = StreamState::kFailed;
  stats_.last_error = why;
  out.emplace_back(std::in_place_type<Fail>, Fail{why});
}

// ---- reads ----

StreamStats Conversation::stats() const {
  StreamStats s = stats_;
  s.in_flight = in_flight_.size();
  s.store_bytes = store_.bytes();
  s.store_rooms = store_.size();
  s.horizon_s = horizon_s_ > 0 ? horizon_s_ : options_.plan.horizon_s;
  return s;
}

std::vector<std::shared_ptr<const ReadyRoom>> Conversation::take_new_rooms() {
  return std::exchange(fresh_, {});
}
std::vector<cave::RoomId> Conversation::take_evicted() {
  return std::exchange(evicted_, {});
}
std::vector<RoomSample> Conversation::take_samples() {
  return std::exchange(samples_, {});
}

Result<codec::DecodedRoom> decode_payload(const DecodeRoom& job) {
  auto mesh = codec::decode_room(job.frame.payload, job.limits);
  if (!mesh || job.limits.normals) return mesh;
  std::vector<codec::PortalDisc> discs;
  discs.reserve(job.frame.room.portals.size());
  for (const cave::Portal& p : job.frame.room.portals)
    discs.push_back({p.centre, p.normal});
  if (Status s = codec::derive_normals(mesh.value(), job.frame.origin, discs); !s) return s.error();
  return mesh;
}

}  // namespace grotto::stream
