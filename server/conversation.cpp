#include "server/conversation.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "proto/token.hpp"
#include "server/metrics.hpp"

namespace grotto::server {
namespace {

uint64_t steady_now_ms() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::steady_clock::now().time_since_epoch())
                                   .count());
}

uint64_t system_unix_ms() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

}  // namespace

CloseCode close_code_for(ErrorCode code) {
  switch (code) {
    case ErrorCode::kServiceRestart:
      return CloseCode::kGoingAway;
    case ErrorCode::kTooLarge:
      return CloseCode::kTooBig;
    default:
      return CloseCode::kPolicy;
  }
}

Conversation::Conversation(ConversationConfig config, WorldPort& worlds, Metrics* metrics)
    : config_(std::move(config)), worlds_(worlds), metrics_(metrics) {
  if (!config_.unix_ms) config_.unix_ms = system_unix_ms;
  if (!config_.steady_ms) config_.steady_ms = steady_now_ms;
}

std::vector<Action> Conversation::take() {
  std::vector<Action> out;
  out.swap(actions_);
  return out;
}

// ---- events ----

void Conversation::admit(Admission admission) {
  if (state_ != State::kNew) return;
  switch (admission) {
    case Admission::kAdmitted:
      state_ = State::kAwaitingHello;
      emit(act::Timer{std::chrono::milliseconds{config_.limits.handshake_timeout_ms}});
      return;
    case Admission::kStopping:
      fail(Error{ErrorCode::kServiceRestart, "the server is shutting down"}, std::nullopt);
      return;
    case Admission::kFull:
      fail(Error{ErrorCode::kOverloaded, "too many connections (max_connections " +
                                             std::to_string(config_.max_connections) +
                                             "); retry later"},
           std::nullopt);
      return;
    case Admission::kHandshakesFull:
      fail(Error{ErrorCode::kOverloaded, "too many connections waiting for hello (max_handshakes " +
                                             std::to_string(config_.max_handshakes) +
                                             "); retry later"},
           std::nullopt);
      return;
  }
}

// PROTOCOL.md, "Which error a message gets": size, JSON, type, then order (hello first and only
// once), then fields, then what the message asks; every error before welcome is fatal.
void Conversation::text(std::string_view message) {
  if (state_ == State::kNew || state_ == State::kClosed) return;
  if (metrics_) metrics_->messages_total.add();
  if (message.size() > config_.limits.max_message_bytes) return oversized();
  if (state_ == State::kOpen) {
    emit(act::Timer{std::chrono::milliseconds{config_.limits.idle_timeout_ms}});
  }
  // A queued client has said its hello: only ping, which keeps it company while it waits.
  const bool welcomed = state_ == State::kOpen || state_ == State::kQueued;
  proto::Ref ref;
  std::string type;
  auto parsed = proto::parse_client_message(message, config_.limits, &ref, &type);
  if (state_ == State::kQueued && !type.empty() && type != "ping" && type != "hello") {
    return fail(Error{ErrorCode::kOutOfOrder, "'" + type + "' while queued (only ping)"}, ref);
  }
  if (!type.empty() && (type == "hello") == welcomed) {
    // The order check comes before any field error.
    return fail(
        Error{ErrorCode::kOutOfOrder, welcomed ? "a second hello" : "'" + type + "' before hello"},
        ref);
  }
  if (!parsed) {
    Error e{parsed.error().code, parsed.error().message};
    if (!welcomed) return fail(e, ref);
    return send_error(proto::error_reply(e, ref));
  }
  std::visit([&](const auto& m) { on(m); }, parsed.value());
}

void Conversation::binary() {
  if (state_ == State::kNew || state_ == State::kClosed) return;
  if (metrics_) metrics_->messages_total.add();
  fail(Error{ErrorCode::kBadFrame, "clients must not send binary frames"}, std::nullopt);
}

void Conversation::oversized() {
  if (state_ == State::kNew || state_ == State::kClosed) return;
  fail(
      Error{ErrorCode::kTooLarge, "message over max_message_bytes (" +
                                      std::to_string(config_.limits.max_message_bytes) + " bytes)"},
      std::nullopt);
}

void Conversation::deadline() {
  if (state_ == State::kAwaitingHello) {
    fail(Error{ErrorCode::kTimeout, "no hello within handshake_timeout_ms (" +
                                        std::to_string(config_.limits.handshake_timeout_ms) +
                                        " ms)"},
         std::nullopt);
  } else if (state_ == State::kOpen) {
    fail(Error{ErrorCode::kTimeout, "no message within idle_timeout_ms (" +
                                        std::to_string(config_.limits.idle_timeout_ms) + " ms)"},
         std::nullopt);
  }
}

void Conversation::delivery(Delivery d) {
  if (state_ != State::kOpen) return;
  auto it = in_flight_.find(d.key.id.packed());
  if (it == in_flight_.end()) return;       // cancelled meanwhile: not sent
  if (it->second.lod != d.key.lod) return;  // a lod the client replaced since
  if (d.error) {
    proto::Ref ref = it->second.ref;
    in_flight_.erase(it);
    if (d.error->code == ErrorCode::kServiceRestart) {
      return fail(*d.error, std::nullopt);
    }
    auto e = proto::error_reply(*d.error, ref, d.key.id);
    e.fatal = false;  // a room's failure refuses that room only
    return send_error(std::move(e));
  }
  if (config_.limits.max_kbps == 0) {
    const uint64_t due = it->second.due_ms;
    in_flight_.erase(it);
    ++rooms_sent_;
    if (metrics_) metrics_->rooms_served.add();
    return emit(act::SendRoom{std::move(d.room), due});
  }
  // Asked again while waiting, it may be delivered twice: it waits once.
  if (!it->second.ready) ++waiting_;
  it->second.ready = std::move(d.room);
  send_ready();
}

void Conversation::pace() {
  if (state_ != State::kOpen) return;
  send_ready();
}

void Conversation::send_ready() {
  const double bytes_per_ms = config_.limits.max_kbps / 8.0;  // kbit/s = 1000/8 B/s
  const uint64_t now = config_.steady_ms();
  bytes_tokens_ =
      std::min(bytes_per_ms * 1000,
               bytes_tokens_ + static_cast<double>(now - bytes_tokens_at_) * bytes_per_ms);
  bytes_tokens_at_ = now;
  while (waiting_ > 0 && bytes_tokens_ >= 0) {
    // The most urgent; ties by room id, so the order does not depend on the map's.
    auto next = in_flight_.end();
    for (auto it = in_flight_.begin(); it != in_flight_.end(); ++it) {
      if (!it->second.ready) continue;
      if (next == in_flight_.end() || it->second.priority < next->second.priority ||
          (it->second.priority == next->second.priority && it->first < next->first)) {
        next = it;
      }
    }
    RoomPtr room = std::move(next->second.ready);
    const uint64_t due = next->second.due_ms;
    in_flight_.erase(next);
    --waiting_;
    bytes_tokens_ -= static_cast<double>(room->frame.size());
    ++rooms_sent_;
    if (metrics_) metrics_->rooms_served.add();
    emit(act::SendRoom{std::move(room), due});
  }
  if (waiting_ > 0) {
    if (metrics_) metrics_->bandwidth_waits.add();
    const auto ms = static_cast<int64_t>(std::ceil(-bytes_tokens_ / bytes_per_ms));
    emit(act::Pace{std::chrono::milliseconds{std::max<int64_t>(ms, 1)}});
  }
}

void Conversation::sent(uint64_t bytes) {
  bytes_sent_ += bytes;
}

void Conversation::shutdown() {
  if (state_ == State::kClosed) return;
  fail(Error{ErrorCode::kServiceRestart, "the server is shutting down"}, std::nullopt);
}

void Conversation::slow_client(size_t queued_bytes) {
  if (state_ == State::kClosed) return;
  spdlog::warn("event=slow_client_dropped session={} peer={} queued_bytes={}", config_.session,
               config_.peer, queued_bytes);
  if (metrics_) metrics_->slow_clients_dropped.add();
  release();
  close(CloseCode::kPolicy, "slow_client");
}

void Conversation::admitted() {
  if (state_ != State::kQueued) return;
  open_world();
}

void Conversation::queue_update(uint32_t position, uint32_t wait_ms, uint32_t queue) {
  if (state_ != State::kQueued) return;
  send(proto::Queued{hello_ref_, position, std::min(wait_ms, proto::kMaxWaitMs), queue});
}

void Conversation::transport_closed() {
  release();
  log_unlogged();
  state_ = State::kClosed;
}

// ---- messages ----

void Conversation::on(const proto::Hello& m) {
  // The token comes first: a client without it learns nothing about this server's worlds.
  if (!config_.token.empty() && (!m.token || !proto::token_equals(config_.token, *m.token))) {
    return fail(Error{ErrorCode::kUnauthorized, m.token ? "wrong token" : "missing token"}, m.ref);
  }
  uint32_t chosen = 0;  // the highest version both speak
  for (uint32_t v : m.versions) {
    if (proto::speaks_version(v)) chosen = std::max(chosen, v);
  }
  if (chosen == 0) {
    std::vector<uint32_t> ours;
    for (uint32_t v = proto::kMinProtocolVersion; v <= proto::kProtocolVersion; ++v)
      ours.push_back(v);
    return fail(
        Error{ErrorCode::kUnsupportedVersion, "no protocol version in common; this server speaks " +
                                                  std::to_string(proto::kMinProtocolVersion) +
                                                  " to " + std::to_string(proto::kProtocolVersion)},
        m.ref, std::move(ours));
  }
  if (m.params && *m.params != config_.params_digest) {
    return fail(Error{ErrorCode::kWorldMismatch,
                      "this server's parameter digest differs from the one asked for"},
                m.ref);
  }
  hello_ref_ = m.ref;
  hello_seed_ = m.seed.value_or(worlds_.own_seed());
  hello_version_ = chosen;
  hello_name_ = m.name;
  // Past capacity (server/admission.hpp): wait in the queue if the client understands it, else
  // a refusal saying when to come back; never silence.
  const Entry entry = worlds_.enter(m.queue);
  if (entry.kind == Entry::Kind::kRefused) {
    if (metrics_) metrics_->sessions_refused.add();
    return fail(Error{ErrorCode::kOverloaded,
                      entry.queue_full ? "the server is full and so is its queue; retry later"
                                       : "the server is full (send hello.queue to wait in its "
                                         "queue); retry later"},
                m.ref, {}, entry.retry_after_ms);
  }
  if (entry.kind == Entry::Kind::kQueued) {
    state_ = State::kQueued;
    spdlog::info("event=queued session={} position={} wait_ms={}", config_.session, entry.position,
                 entry.wait_ms);
    return queue_update(entry.position, entry.wait_ms, entry.queue);
  }
  open_world();
}

void Conversation::open_world() {
  // The world: the one named, opened now if need be (--max-worlds), else the server's own.
  const uint64_t seed = hello_seed_;
  const uint32_t chosen = hello_version_;
  auto client = worlds_.open(seed, chosen);
  if (!client) return fail(client.error(), hello_ref_);
  client_ = *client;
  state_ = State::kOpen;
  tokens_ = config_.limits.request_burst;
  tokens_at_ = config_.steady_ms();
  bytes_tokens_ = config_.limits.max_kbps / 8.0 * 1000;
  bytes_tokens_at_ = tokens_at_;
  proto::Welcome w;
  w.ref = hello_ref_;
  w.version = chosen;
  w.server = config_.server_name;
  w.seed = seed;
  w.params = config_.params_digest;
  w.limits = config_.limits;
  send(w);
  spdlog::info("event=hello session={} name=\"{}\" version={} seed={}", config_.session,
               proto::echo(hello_name_), chosen, seed);
  emit(act::Timer{std::chrono::milliseconds{config_.limits.idle_timeout_ms}});
}

void Conversation::on(const proto::Locate& m) {
  proto::Located r;
  r.ref = m.ref;
  r.point = m.point;
  r.room = worlds_.locate(client_, m.point);
  send(r);
}

void Conversation::on(const proto::Spawn& m) {
  cave::Spawn spawn = worlds_.spawn(client_);
  proto::SpawnPoint r;
  r.ref = m.ref;
  r.room = spawn.room;
  r.position = spawn.position;
  send(r);
}

// The token bucket: `rooms` tokens (at least one) for a request or cancel, refilled at
// request_rate a second up to request_burst. A cancel is never refused (the client's ledger must
// stay the server's) but takes its tokens, down to one burst below zero.
bool Conversation::take_tokens(size_t rooms) {
  const proto::Limits& l = config_.limits;
  if (l.request_rate == 0) return true;
  const uint64_t now = config_.steady_ms();
  tokens_ = std::min<double>(
      l.request_burst, tokens_ + static_cast<double>(now - tokens_at_) * l.request_rate / 1000);
  tokens_at_ = now;
  const double cost = static_cast<double>(std::max<size_t>(rooms, 1));
  if (tokens_ < cost) return false;
  tokens_ -= cost;
  return true;
}

void Conversation::on(const proto::Request& m) {
  if (!take_tokens(m.rooms.size())) {
    const proto::Limits& l = config_.limits;
    if (++refused_in_a_row_ > kMaxRefusedInARow) {
      return fail(Error{ErrorCode::kLimitExceeded,
                        "over " + std::to_string(kMaxRefusedInARow) +
                            " requests in a row refused for the request rate (request_rate " +
                            std::to_string(l.request_rate) + " rooms/s)"},
                  m.ref);
    }
    return send_error(proto::error_reply(
        Error{ErrorCode::kLimitExceeded,
              "request rate over request_rate (" + std::to_string(l.request_rate) +
                  " rooms/s, request_burst " + std::to_string(l.request_burst) +
                  "); nothing in it was queued, slow down"},
        m.ref));
  }
  refused_in_a_row_ = 0;
  size_t added = 0;
  for (const auto& w : m.rooms) {
    if (!in_flight_.contains(w.id.packed())) ++added;
  }
  const size_t limit = config_.limits.max_rooms_in_flight;
  if (in_flight_.size() + added > limit) {
    return send_error(proto::error_reply(
        Error{ErrorCode::kLimitExceeded,
              "request would take rooms in flight to " + std::to_string(in_flight_.size() + added) +
                  " (max_rooms_in_flight " + std::to_string(limit) + "); nothing in it was queued"},
        m.ref));
  }
  std::vector<cave::RoomId> relod;
  const uint64_t now = config_.steady_ms();
  for (const auto& w : m.rooms) {
    auto [it, inserted] =
        in_flight_.try_emplace(w.id.packed(), InFlight{w.lod, w.priority, m.ref, 0, nullptr});
    it->second.due_ms = now + w.priority;
    // Re-requested: the generator replaces its priority; a new lod replaces the old one, so the
    // old lod's want goes (and a room of the old lod waiting for bandwidth). An error about the
    // room names the latest request.
    it->second.ref = m.ref;
    it->second.priority = w.priority;
    if (!inserted && it->second.lod != w.lod) {
      it->second.lod = w.lod;
      if (it->second.ready) {
        it->second.ready.reset();
        --waiting_;
      }
      relod.push_back(w.id);
    }
  }
  if (!relod.empty()) emit(act::Drop{client_, std::move(relod)});
  if (metrics_) metrics_->rooms_requested.add(m.rooms.size());
  // Cache hits are delivered as soon as they are asked for: sorted first so they go out by
  // priority too (stable: ties keep the order requested).
  std::vector<Want> wants;
  wants.reserve(m.rooms.size());
  for (const proto::RoomWant& w : m.rooms)
    wants.push_back({w.id, w.lod, w.priority});
  std::stable_sort(wants.begin(), wants.end(),
                   [](const auto& a, const auto& b) { return a.priority < b.priority; });
  emit(act::Want{client_, std::move(wants)});
}

void Conversation::on(const proto::Cancel& m) {
  if (!take_tokens(m.rooms.size())) {
    tokens_ = std::max<double>(tokens_ - static_cast<double>(m.rooms.size()),
                               -static_cast<double>(config_.limits.request_burst));
  }
  std::vector<cave::RoomId> ids;
  for (const auto& id : m.rooms) {
    auto it = in_flight_.find(id.packed());
    if (it == in_flight_.end()) continue;
    // A room waiting for bandwidth is built: nothing to cancel in the generator.
    if (it->second.ready) {
      --waiting_;
    } else {
      ids.push_back(id);
    }
    in_flight_.erase(it);
  }
  if (!ids.empty()) emit(act::Drop{client_, std::move(ids)});
}

void Conversation::on(const proto::Ping& m) {
  proto::Pong p;
  p.ref = m.ref;
  p.t = m.t;
  p.time_ms = config_.unix_ms();
  send(p);
}

void Conversation::on(const proto::StatsQuery& m) {
  proto::Stats s;
  s.ref = m.ref;
  s.in_flight = in_flight_.size();
  s.rooms_sent = rooms_sent_;
  s.bytes_sent = bytes_sent_;
  s.errors = errors_sent_;
  send(s);
}

// ---- replies ----

void Conversation::send(const proto::ServerMessage& m) {
  emit(act::SendText{proto::serialize(m)});
}

void Conversation::send_error(proto::ErrorMessage e) {
  ++errors_sent_;
  if (metrics_) metrics_->count_error(e.code);
  // A client sending garbage in a loop must not flood the log: the first few non-fatal errors
  // of a connection are logged, the rest counted and summed up when it closes. Fatal ones end
  // the connection, so each is logged.
  if (e.fatal || errors_logged_ < kErrorsLogged) {
    if (!e.fatal) ++errors_logged_;
    spdlog::info("event=error_sent session={} code={} fatal={} detail=\"{}\"", config_.session,
                 proto::wire_code_name(e.code), e.fatal, proto::echo(e.message));
  } else {
    ++errors_unlogged_;
  }
  send(proto::ServerMessage{std::move(e)});
}

void Conversation::log_unlogged() {
  if (errors_unlogged_ == 0) return;
  spdlog::info("event=errors_not_logged session={} count={} (only the first {} are)",
               config_.session, errors_unlogged_, kErrorsLogged);
  errors_unlogged_ = 0;
}

void Conversation::fail(const Error& error, proto::Ref ref, std::vector<uint32_t> versions,
                        std::optional<uint32_t> retry_after_ms) {
  if (state_ == State::kClosed) return;
  release();
  auto e = proto::error_reply(error, ref);
  e.fatal = true;
  e.versions = std::move(versions);
  e.retry_after_ms = retry_after_ms;
  send_error(std::move(e));
  close(close_code_for(error.code), proto::wire_code_name(error.code),
        error.code != ErrorCode::kTimeout);
}

void Conversation::close(CloseCode code, std::string reason, bool await_reply) {
  log_unlogged();
  spdlog::info("event=closing session={} code={} reason={}", config_.session,
               static_cast<int>(code), reason);
  emit(act::Close{code, std::move(reason), await_reply});
  state_ = State::kClosed;
}

void Conversation::release() {
  // Nothing this client asked for is wanted any more.
  in_flight_.clear();
  waiting_ = 0;
  if (client_ != 0) {
    emit(act::Release{client_});
    client_ = 0;
  }
}

}  // namespace grotto::server
