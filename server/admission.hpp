// Who enters the server past its capacity, as a plain state machine in the manner of the other
// sans-I/O cores (server/conversation.hpp, server/schedule.hpp): the server feeds it events with
// the time passed in (a session asks to enter after a valid hello, a session leaves, a periodic
// measurement of how well the admitted players are served) and carries out the actions it
// returns (admit this session, tell this queued session its place, refuse this one).
//
// The rule: a newcomer enters while the admitted players are served in time (the oldest urgent
// want still waiting is young), and waits in a first-come queue while they are not. Admitted
// players are never sent away for newcomers: past capacity each player keeps the service it had,
// and newcomers wait where they can see their place instead of all stalling together.
//
// A crowd can arrive faster than a measurement can show its cost: 300 players who connect
// together all say hello before the next measurement. So newcomers also enter only within a
// burst budget, a number per measurement interval (at once or from the queue), learned the way
// TCP's congestion window is:
//  - it starts at burst_start (16);
//  - it doubles after a window (1 s) in which every interval's budget was used up and every
//    measurement was quick: the oldest urgent want and the oldest want of any kind, prefetch
//    included, both under caught_up_below (a newcomer's prefetch waits behind everyone's urgent
//    rooms, so a crowd's cost shows there first, a second before its walkers reach them);
//  - it halves when a measurement is slow (either of the two at late_after or older), once for
//    a run of slow ones, never below admit_per_measurement;
//  - otherwise it stays: a budget not used up is no evidence, so a trickle under it never waits,
//    and a quiet spell does not let the next crowd in at once.
// Past the budget a newcomer queues as it would behind; the queue goes first at the next
// measurement. Only late urgent wants make the service behind (nobody enters); slow prefetch
// only shrinks the budget.
//
// No threads, no clocks, no sockets: tests drive it with tables of events and actions.
// Not thread-safe: the server calls it under its sessions lock.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string_view>
#include <variant>
#include <vector>

namespace grotto::server {

using AdmissionTime = std::chrono::steady_clock::time_point;

struct AdmissionConfig {
  // Sessions waiting at most; a newcomer past it is refused (overloaded with retry_after_ms).
  size_t max_queue = 1000;
  // Players admitted at most, however well they are served (0: no fixed bound; the measurements
  // alone decide). For a replica whose capacity was measured ahead (docs/BENCHMARKS.md).
  size_t max_players = 0;
  // Behind: a measurement's oldest urgent want older than this. Caught up again: every
  // measurement within `window` younger than `caught_up_below` (hysteresis, so one quick sample
  // in a slow stretch does not let a crowd in).
  std::chrono::milliseconds late_after{250};
  std::chrono::milliseconds caught_up_below{100};
  std::chrono::milliseconds window{1000};
  // Also behind while the bytes queued to send to players exceed this (0: not looked at): the
  // links, not the workers, can be what is full.
  uint64_t max_send_backlog_bytes = 0;
  // The burst budget: newcomers let in per measurement interval (at once or from the queue),
  // starting at burst_start, doubled after a window of quick measurements whose intervals used
  // it up, halved after a slow one, never below admit_per_measurement (the slowest the queue
  // drains once caught up). burst_start covers a steady arrival of 64 players a second
  // on the default 250 ms measurements without anybody queuing.
  size_t admit_per_measurement = 2;
  size_t burst_start = 16;
  // The admission rate behind the estimated wait is measured over this much time; with none
  // measured yet each place ahead counts `unmeasured_wait`.
  std::chrono::milliseconds rate_window{10'000};
  std::chrono::milliseconds unmeasured_wait{2'000};
  // A queued session hears of a new place or estimate at most this often.
  std::chrono::milliseconds update_every{1'000};
  // The retry_after_ms of a refusal stays within these.
  std::chrono::milliseconds min_retry{1'000};
  std::chrono::milliseconds max_retry{60'000};
};

// One periodic measurement of how the admitted players are served.
struct AdmissionSample {
  std::chrono::milliseconds oldest_urgent{0};  // age of the oldest urgent want still waiting
  // The same over every want, prefetch included (the burst budget's second signal: newcomers'
  // prefetch waits behind the urgent rooms, so their cost shows here first).
  std::chrono::milliseconds oldest_want{0};
  double rooms_per_s = 0;           // rooms built and sent a second (reported only)
  uint64_t send_backlog_bytes = 0;  // bytes queued to send, all players
};

namespace adm {
struct Admit {  // the session enters now: open its world and welcome it
  uint64_t session = 0;
  friend bool operator==(const Admit&, const Admit&) = default;
};
struct Queued {  // the session waits: tell it its place (PROTOCOL.md's `queued`)
  uint64_t session = 0;
  uint32_t position = 0;  // 1-based
  uint32_t wait_ms = 0;   // estimated
  uint32_t queue = 0;     // sessions waiting
  friend bool operator==(const Queued&, const Queued&) = default;
};
struct Refuse {  // overloaded, fatal: come back after retry_after_ms
  uint64_t session = 0;
  uint32_t retry_after_ms = 0;
  bool queue_full = false;  // else: the client cannot wait in the queue
  friend bool operator==(const Refuse&, const Refuse&) = default;
};
}  // namespace adm
using AdmissionAction = std::variant<adm::Admit, adm::Queued, adm::Refuse>;

class AdmissionQueue {
 public:
  explicit AdmissionQueue(AdmissionConfig config);

  // ---- events ----
  // A session said a valid hello. `can_queue`: it understands `queued` (hello.queue); one that
  // does not is admitted or refused, never left waiting in silence. Returns Admit, Queued or
  // Refuse for it (also queued as an action). An id already known is ignored (nullopt).
  std::optional<AdmissionAction> enter(uint64_t session, bool can_queue, AdmissionTime now);
  // A session admitted or queued is gone. An admitted one's place goes to the head of the queue
  // at once: the load stays what it was. Unknown ids are ignored.
  void leave(uint64_t session, AdmissionTime now);
  // A periodic measurement (every few hundred milliseconds): updates behind/caught up and the
  // burst budget, opens the next interval's budget, admits from the queue into it once caught
  // up, and sends due place updates.
  void measure(const AdmissionSample& sample, AdmissionTime now);

  // The actions since the last call, in order.
  std::vector<AdmissionAction> take();

  const AdmissionConfig& config() const { return config_; }
  bool behind() const { return behind_; }
  size_t admitted() const { return admitted_.size(); }
  size_t queued() const { return queue_.size(); }
  // Players admitted when the service last fell behind: what it held then (0: never behind).
  size_t capacity() const { return capacity_; }
  // Newcomers this measurement interval may let in (the learned budget), and how many of them
  // can still enter at once before the next measurement.
  size_t burst() const { return burst_; }
  size_t burst_left() const { return entered_ < burst_ ? burst_ - entered_ : 0; }
  // The estimated wait of the n-th place (1-based): n over the rate at which the queue's head
  // was admitted within rate_window (call after expiring it: measure() does).
  std::chrono::milliseconds estimate(size_t position) const;

 private:
  struct Waiter {
    uint64_t session = 0;
    AdmissionTime since{};
    AdmissionTime told_at{};  // when its last Queued went out
    uint32_t told_position = 0;
    uint32_t told_wait_s = 0;  // its estimate, whole seconds (smaller changes are not news)
  };
  void admit(uint64_t session, AdmissionTime now);
  bool room_for_one() const;  // not behind, under max_players, within the burst budget
  void admit_head(AdmissionTime now);
  void tell(Waiter& w, uint32_t position, AdmissionTime now, bool force);
  void tell_all(AdmissionTime now, bool force);
  uint32_t retry_after(size_t position) const;
  void forget_old_admissions(AdmissionTime now);
  template <class A>
  void emit(A action) {
    actions_.emplace_back(std::in_place_type<A>, action);
  }

  const AdmissionConfig config_;
  bool behind_ = false;
  size_t capacity_ = 0;
  size_t burst_ = 0;    // the budget of newcomers a measurement interval
  size_t entered_ = 0;  // newcomers admitted since the last measurement
  bool slow_ = false;   // the last measurements were slow for the budget (none quick since)
  // Since when every interval used up the budget and every measurement was quick (none: the
  // last did not, or the budget just changed): a window of it doubles the budget.
  std::optional<AdmissionTime> used_since_;
  // The time between the last two measurements (zero: fewer than two yet), for the estimated
  // wait of a queue that has not been admitted from yet.
  std::optional<AdmissionTime> measured_at_;
  std::chrono::milliseconds interval_{0};
  std::set<uint64_t> admitted_;
  std::deque<Waiter> queue_;
  // Since when every measurement was young (under caught_up_below); none: the last was not.
  std::optional<AdmissionTime> young_since_;
  std::deque<AdmissionTime> admissions_;  // from the queue, within rate_window, oldest first
  std::vector<AdmissionAction> actions_;
};

// ---- a balancer's question at the door (PROTOCOL.md, "Balancers") ----
//
// A balancer that can try several replicas marks a newcomer's WebSocket upgrade (the
// X-Grotto-Balancer header); a replica that would not let a newcomer in at once declines it before
// the upgrade, and the balancer tries the next one. Only when every replica declines does it send
// the newcomer unmarked, to be admitted or queued as by a replica alone. The decision is a
// function of what the server holds at that moment, under its sessions lock.

// Why a marked newcomer is sent on (kNone: it would get in at once here).
enum class Redirect : uint8_t {
  kNone,
  kStopping,        // the server drains: it answers every upgrade with service_restart
  kMaxConnections,  // players, with the upgrades on their way in, at max_connections
  kMaxHandshakes,   // max_handshakes upgrades still wait for their hello
  kQueue,           // newcomers already wait in the admission queue: nobody passes them
  kMaxPlayers,      // players admitted, with the upgrades on their way in, at max_players
  kBehind,          // the players are not served in time (admission-late-ms): newcomers queue
  kBurst,           // this measurement interval's burst budget of newcomers is taken
};
inline constexpr size_t kRedirectCount = 8;

// What the server holds when a marked upgrade arrives.
struct Door {
  bool stopping = false;
  size_t players = 0;     // sessions past hello with a world open (not the queued ones)
  size_t handshakes = 0;  // upgraded sessions whose hello is not answered yet
  size_t max_connections = 0;
  size_t max_handshakes = 0;
  // The admission queue's state; all zero and false while admission is off.
  bool admission = false;
  size_t admitted = 0;
  size_t queued = 0;
  size_t max_players = 0;  // 0: no fixed bound
  bool behind = false;
  size_t burst_left = 0;  // newcomers the interval's burst budget still lets in at once
};

// The first reason, in the enum's order, that a newcomer would not enter at once. Upgrades on
// their way in (handshakes) count as taken places: a crowd that arrives together is spread over
// the replicas instead of all trying the one with a single place left.
Redirect redirect_newcomer(const Door& door);
// The reason as the metric's label and the refusal's body say it ("max_players", ...).
std::string_view redirect_name(Redirect reason);

}  // namespace grotto::server
