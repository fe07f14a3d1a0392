// The server's metrics, rendered in the Prometheus text exposition format (version 0.0.4) at
// /metrics. A fixed set of named series, so every series is documented here and in
// docs/OPERATING.md; updates are lock-free atomics, safe from any thread.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "common/core/result.hpp"
#include "server/admission.hpp"

namespace grotto::server {

class Counter {
 public:
  void add(uint64_t n = 1) { value_.fetch_add(n, std::memory_order_relaxed); }
  uint64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<uint64_t> value_{0};
};

class Gauge {
 public:
  void set(int64_t v) { value_.store(v, std::memory_order_relaxed); }
  void add(int64_t d) { value_.fetch_add(d, std::memory_order_relaxed); }
  int64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<int64_t> value_{0};
};

// Cumulative buckets with fixed upper bounds (seconds), plus sum and count.
class Histogram {
 public:
  static constexpr std::array<double, 14> kBounds = {0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05,
                                                     0.1,    0.2,   0.5,   1.0,   2.0,  5.0,  10.0};
  void observe(double seconds);
  uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  double sum() const;
  // Observations ≤ kBounds[i] (cumulative, as Prometheus wants); index kBounds.size() is +Inf.
  uint64_t bucket(size_t i) const;

 private:
  std::array<std::atomic<uint64_t>, kBounds.size() + 1> buckets_{};
  std::atomic<uint64_t> count_{0};
  std::atomic<uint64_t> sum_micros_{0};
};

class Metrics {
 public:
  // Connections (sessions on the WebSocket path; HTTP requests counted apart).
  Counter connections_total;     // grotto_connections_total
  Gauge connections_open;        // grotto_connections_open
  Counter connections_rejected;  // grotto_connections_rejected_total (max_connections or
                                 // max_handshakes)
  Gauge handshakes_open;         // grotto_handshakes_open (sessions not yet past hello)
  // Admission past capacity (server/admission.hpp).
  Gauge sessions_queued;                 // grotto_sessions_queued (valid hellos waiting to enter)
  Counter sessions_admitted_from_queue;  // grotto_sessions_admitted_from_queue_total
  Counter sessions_refused;              // grotto_sessions_refused_total (overloaded at hello)
  Gauge admission_capacity;  // grotto_admission_capacity (players when it last fell behind)
  Gauge admission_behind;    // grotto_admission_behind (1 while newcomers wait)
  Gauge admission_burst;     // grotto_admission_burst (newcomers let in a measurement interval)
  Gauge oldest_urgent_ms;    // grotto_oldest_urgent_ms (players' oldest urgent wants, p90)
  // Upgrades a balancer marked (X-Grotto-Balancer: try-others) that were sent on to another
  // replica before the upgrade, by reason: grotto_admission_redirected_total{reason="..."}.
  // Neither connections nor refusals: the newcomer goes to another replica, or comes back
  // unmarked once every replica has sent it on.
  void count_redirect(Redirect reason);
  uint64_t redirects(Redirect reason) const;
  Counter http_requests_total;  // grotto_http_requests_total
  // Rooms over HTTP (PROTOCOL.md, "Rooms over HTTP"): GETs of a room URL answered with the room
  // (a peer replica's owner fetch, a cache or CDN, any client), answered 304 (the client's ETag
  // matched), and refused (any 4xx or 5xx, by status). HEAD counts as a GET.
  Counter rooms_http_served;        // grotto_rooms_http_served_total
  Counter rooms_http_not_modified;  // grotto_rooms_http_not_modified_total
  Counter rooms_http_bytes;         // grotto_rooms_http_bytes_total (frame bytes in 200 bodies)
  // grotto_rooms_http_refused_total{status="..."}: one of kRoomHttpStatuses (another counts as
  // 500).
  static constexpr std::array<int, 7> kRoomHttpStatuses = {400, 401, 404, 405, 429, 500, 503};
  void count_room_http_refusal(int status);
  uint64_t room_http_refusals(int status) const;
  Counter accept_failures;  // grotto_accept_failures_total (EMFILE and the like)
  Gauge sockets_open;       // grotto_sockets_open (accepted TCP sockets, upgraded or not)
  Counter sockets_shed;     // grotto_sockets_shed_total (closed at accept: too many open)
  // Out of file descriptors, a few reserve descriptors are traded for connections that are
  // answered health-only (/healthz, /readyz, /metrics; server.cpp, "the fd reserve").
  Gauge fd_reserve_held;               // grotto_fd_reserve_held (reserve descriptors held now)
  Counter fd_reserve_connections;      // grotto_fd_reserve_connections_total (answered health-only)
  Counter fd_reserve_refill_failures;  // grotto_fd_reserve_refill_failures_total
  // Control messages received, and room wants they carried.
  Counter messages_total;   // grotto_messages_total
  Counter rooms_requested;  // grotto_rooms_requested_total
  // The generation service. Generator updates these (rooms_served excepted), the latency
  // histogram (want received by request() -> delivery callback; cache hits observe 0) and the
  // compute path; the network layer updates the rest, errors included (errors are counted
  // where they are sent, so the generator never calls count_error).
  Counter rooms_built;              // grotto_rooms_built_total (each build counts once)
  Counter rooms_served;             // grotto_rooms_served_total (room frames sent)
  Counter rooms_from_cache;         // grotto_rooms_cache_hits_total
  Counter rooms_cancelled;          // grotto_rooms_cancelled_total (wants cancelled before sent)
  Counter rooms_deduplicated;       // grotto_rooms_deduplicated_total (joined a job in flight)
  Counter rooms_failed;             // grotto_rooms_failed_total
  Counter rooms_fetched;            // grotto_rooms_fetched_total (from their owner replica)
  Counter owner_failures;           // grotto_owner_failures_total (fetches built here instead)
  Counter batches;                  // grotto_batches_total (build calls)
  Counter device_launches;          // grotto_device_launches_total (the shared device's)
  Histogram device_launch_seconds;  // grotto_device_launch_seconds (each shared launch)
  Gauge queue_depth;                // grotto_queue_depth (jobs queued, not building)
  Gauge rooms_in_flight;            // grotto_rooms_in_flight (wants not yet answered, all clients)
  Gauge cache_bytes;                // grotto_cache_bytes
  Gauge cache_entries;              // grotto_cache_entries
  Gauge worlds_open;                // grotto_worlds_open (the server's own included)
  Counter worlds_opened;            // grotto_worlds_opened_total (for clients that named them)
  Counter worlds_refused;           // grotto_worlds_refused_total (max_worlds open, each in use)
  Histogram build_seconds;          // grotto_build_seconds (per room)
  Histogram encode_seconds;         // grotto_encode_seconds (per room)
  Histogram room_latency_seconds;   // grotto_room_latency_seconds (want received -> frame queued)
  Counter bytes_sent;               // grotto_bytes_sent_total (all frames)
  Counter slow_clients_dropped;     // grotto_slow_clients_dropped_total (send queue over limit)
  Counter bandwidth_waits;          // grotto_bandwidth_waits_total (ready rooms held: max_kbps)

  // Errors sent to clients, by wire code: grotto_errors_total{code="..."}.
  void count_error(ErrorCode code);
  uint64_t errors(ErrorCode code) const;

  // grotto_compute_path_info{path="..."} 1 (set once the generator knows it).
  void set_compute_path(std::string path);

  // The whole exposition, every series with # HELP and # TYPE lines.
  std::string render() const;

 private:
  std::array<Counter, 32> errors_{};
  std::array<Counter, kRoomHttpStatuses.size()> room_http_refusals_{};
  std::array<Counter, kRedirectCount> redirects_{};
  mutable std::mutex path_mutex_;
  std::string compute_path_;
};

}  // namespace grotto::server
