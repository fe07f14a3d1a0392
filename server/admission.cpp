#include "server/admission.hpp"

#include <algorithm>
#include <cmath>

namespace grotto::server {

using std::chrono::milliseconds;

AdmissionQueue::AdmissionQueue(AdmissionConfig config)
    : config_(config),
      burst_(std::max({config.burst_start, config.admit_per_measurement, size_t{1}})) {}

std::vector<AdmissionAction> AdmissionQueue::take() {
  std::vector<AdmissionAction> out;
  out.swap(actions_);
  return out;
}

std::optional<AdmissionAction> AdmissionQueue::enter(uint64_t session, bool can_queue,
                                                     AdmissionTime now) {
  if (admitted_.contains(session)) return std::nullopt;
  for (const Waiter& w : queue_) {
    if (w.session == session) return std::nullopt;
  }
  forget_old_admissions(now);
  // First come, first served: nobody passes the queue, even once caught up (the queue drains
  // at the next measurement). Past the interval's burst budget a newcomer waits like one that
  // finds the service behind: the budget is what the measurements showed the service absorbs.
  if (room_for_one() && queue_.empty()) {
    admit(session, now);
    return adm::Admit{session};
  }
  if (!can_queue || queue_.size() >= config_.max_queue) {
    adm::Refuse r{session, retry_after(queue_.size() + 1), can_queue};
    emit(r);
    return r;
  }
  queue_.push_back(Waiter{session, now, {}, 0, 0});
  tell(queue_.back(), static_cast<uint32_t>(queue_.size()), now, true);
  return std::get<adm::Queued>(actions_.back());
}

void AdmissionQueue::leave(uint64_t session, AdmissionTime now) {
  if (admitted_.erase(session) > 0) {
    // Its place goes to the head at once, behind or not: the players served stay as many.
    if (!queue_.empty() && (config_.max_players == 0 || admitted_.size() < config_.max_players))
      admit_head(now);
    tell_all(now, false);
    return;
  }
  auto it = std::find_if(queue_.begin(), queue_.end(),
                         [&](const Waiter& w) { return w.session == session; });
  if (it == queue_.end()) return;
  queue_.erase(it);
  tell_all(now, false);
}

void AdmissionQueue::measure(const AdmissionSample& sample, AdmissionTime now) {
  forget_old_admissions(now);
  const bool backlog = config_.max_send_backlog_bytes > 0 &&
                       sample.send_backlog_bytes > config_.max_send_backlog_bytes;
  const bool late = sample.oldest_urgent >= config_.late_after || backlog;
  const bool young = sample.oldest_urgent < config_.caught_up_below && !backlog;
  if (!young) {
    young_since_.reset();
  } else if (!young_since_) {
    young_since_ = now;
  }
  // The budget's own lateness: urgent wants late, or any want (a newcomer's prefetch) waiting
  // as long; its youth: both young.
  const bool slow = late || sample.oldest_want >= config_.late_after;
  const bool quick = young && sample.oldest_want < config_.caught_up_below;
  if (late && !behind_) {
    behind_ = true;
    capacity_ = admitted_.size();
  } else if (behind_ && young_since_ && now - *young_since_ >= config_.window) {
    behind_ = false;
  }
  const size_t floor = std::max<size_t>(config_.admit_per_measurement, 1);
  if (slow && !slow_) {
    // Once a run of slow measurements: those that follow show the same excess, not a new one.
    burst_ = std::max(floor, burst_ / 2);
    used_since_.reset();
  } else if (!behind_ && quick && entered_ >= burst_) {
    // The whole budget came in and the service stayed quick, interval after interval for a
    // window: it absorbs more. One young measurement is not enough: a newcomer's prefetch
    // comes due a second or so after its first rooms, so a burst's cost shows late.
    if (!used_since_) used_since_ = measured_at_.value_or(now);  // the interval's start
    if (now - *used_since_ >= config_.window) {
      burst_ *= 2;
      used_since_ = now;
    }
  } else {
    used_since_.reset();
  }
  if (slow) {
    slow_ = true;
  } else if (quick) {
    slow_ = false;
  }
  if (measured_at_) interval_ = std::chrono::duration_cast<milliseconds>(now - *measured_at_);
  measured_at_ = now;
  entered_ = 0;
  while (!queue_.empty() && room_for_one())
    admit_head(now);
  tell_all(now, false);
}

milliseconds AdmissionQueue::estimate(size_t position) const {
  if (admissions_.empty()) {
    // Nobody admitted from the queue yet: while caught up and under max_players (where only
    // leavers make room) it drains a budget a measurement.
    if (!behind_ && interval_.count() > 0 &&
        (config_.max_players == 0 || admitted_.size() < config_.max_players)) {
      const auto intervals = static_cast<int64_t>((position + burst_ - 1) / burst_);
      return interval_ * intervals;
    }
    return config_.unmeasured_wait * static_cast<int64_t>(position);
  }
  const double per_ms =
      static_cast<double>(admissions_.size()) / static_cast<double>(config_.rate_window.count());
  return milliseconds{static_cast<int64_t>(std::ceil(static_cast<double>(position) / per_ms))};
}

bool AdmissionQueue::room_for_one() const {
  return !behind_ && entered_ < burst_ &&
         (config_.max_players == 0 || admitted_.size() < config_.max_players);
}

void AdmissionQueue::admit(uint64_t session, AdmissionTime) {
  admitted_.insert(session);
  // Every newcomer counts against the budget, one handed a leaver's place too: its first rooms
  // cost what any newcomer's do.
  ++entered_;
  emit(adm::Admit{session});
}

void AdmissionQueue::admit_head(AdmissionTime now) {
  const uint64_t session = queue_.front().session;
  queue_.pop_front();
  admissions_.push_back(now);
  admit(session, now);
}

void AdmissionQueue::tell(Waiter& w, uint32_t position, AdmissionTime now, bool force) {
  const auto wait = estimate(position);
  const auto wait_s = static_cast<uint32_t>(wait.count() / 1000);
  if (!force) {
    if (position == w.told_position && wait_s == w.told_wait_s) return;
    if (now - w.told_at < config_.update_every) return;
  }
  w.told_at = now;
  w.told_position = position;
  w.told_wait_s = wait_s;
  emit(adm::Queued{w.session, position,
                   static_cast<uint32_t>(std::min<int64_t>(wait.count(), UINT32_MAX)),
                   static_cast<uint32_t>(queue_.size())});
}

void AdmissionQueue::tell_all(AdmissionTime now, bool force) {
  uint32_t position = 1;
  for (Waiter& w : queue_)
    tell(w, position++, now, force);
}

uint32_t AdmissionQueue::retry_after(size_t position) const {
  return static_cast<uint32_t>(
      std::clamp(estimate(position), config_.min_retry, config_.max_retry).count());
}

static_assert(static_cast<size_t>(Redirect::kBurst) + 1 == kRedirectCount,
              "kRedirectCount counts every Redirect");

Redirect redirect_newcomer(const Door& door) {
  if (door.stopping) return Redirect::kStopping;
  if (door.players + door.handshakes >= door.max_connections) return Redirect::kMaxConnections;
  if (door.handshakes >= door.max_handshakes) return Redirect::kMaxHandshakes;
  if (!door.admission) return Redirect::kNone;
  if (door.queued > 0) return Redirect::kQueue;
  if (door.max_players > 0 && door.admitted + door.handshakes >= door.max_players)
    return Redirect::kMaxPlayers;
  if (door.behind) return Redirect::kBehind;
  // Upgrades on their way in take the budget's places as they take max_players'.
  if (door.handshakes >= door.burst_left) return Redirect::kBurst;
  return Redirect::kNone;
}

std::string_view redirect_name(Redirect reason) {
  switch (reason) {
    case Redirect::kNone:
      return "none";
    case Redirect::kStopping:
      return "stopping";
    case Redirect::kMaxConnections:
      return "max_connections";
    case Redirect::kMaxHandshakes:
      return "max_handshakes";
    case Redirect::kQueue:
      return "queue";
    case Redirect::kMaxPlayers:
      return "max_players";
    case Redirect::kBehind:
      return "behind";
    case Redirect::kBurst:
      return "burst";
  }
  return "none";
}

void AdmissionQueue::forget_old_admissions(AdmissionTime now) {
  while (!admissions_.empty() && now - admissions_.front() > config_.rate_window)
    admissions_.pop_front();
}

}  // namespace grotto::server
