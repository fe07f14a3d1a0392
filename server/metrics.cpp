#include "server/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "proto/messages.hpp"

namespace grotto::server {
namespace {

// The last ErrorCode; errors_ is indexed by the enum's value.
constexpr int kErrorCodeCount = static_cast<int>(ErrorCode::kTimeout) + 1;
static_assert(kErrorCodeCount <= 32, "Metrics::errors_ holds 32 codes");

// Prometheus text format 0.0.4: a label value escapes backslash, double quote and newline;
// HELP text escapes backslash and newline.
std::string escape_label(std::string_view v) {
  std::string out;
  out.reserve(v.size());
  for (char c : v) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

// Numbers as Prometheus reads them.
std::string number(double v) {
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  if (std::isnan(v)) return "NaN";
  char buf[64];
  // The shortest form that reads back as the same double ("0.005", not "0.0050000000000000001").
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

void header(std::string& out, const char* name, const char* type, const char* help) {
  out += "# HELP ";
  out += name;
  out += ' ';
  out += help;
  out += "\n# TYPE ";
  out += name;
  out += ' ';
  out += type;
  out += '\n';
}

void counter(std::string& out, const char* name, const char* help, uint64_t v) {
  header(out, name, "counter", help);
  out += name;
  out += ' ';
  out += std::to_string(v);
  out += '\n';
}

void gauge(std::string& out, const char* name, const char* help, int64_t v) {
  header(out, name, "gauge", help);
  out += name;
  out += ' ';
  out += std::to_string(v);
  out += '\n';
}

void histogram(std::string& out, const char* name, const char* help, const Histogram& h) {
  header(out, name, "histogram", help);
  // Read count first and clamp buckets to it, so a concurrent observe never shows a bucket
  // above the total (the +Inf bucket must equal _count).
  uint64_t count = h.count();
  for (size_t i = 0; i <= Histogram::kBounds.size(); ++i) {
    std::string le = i < Histogram::kBounds.size() ? number(Histogram::kBounds[i]) : "+Inf";
    uint64_t b = i < Histogram::kBounds.size() ? std::min(h.bucket(i), count) : count;
    out += name;
    out += "_bucket{le=\"" + le + "\"} " + std::to_string(b) + '\n';
  }
  out += name;
  out += "_sum " + number(h.sum()) + '\n';
  out += name;
  out += "_count " + std::to_string(count) + '\n';
}

}  // namespace

void Histogram::observe(double seconds) {
  if (!(seconds >= 0)) seconds = 0;  // NaN and negative clock steps count as 0
  for (size_t i = 0; i < kBounds.size(); ++i) {
    if (seconds <= kBounds[i]) buckets_[i].fetch_add(1, std::memory_order_relaxed);
  }
  sum_micros_.fetch_add(static_cast<uint64_t>(std::llround(seconds * 1e6)),
                        std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
}

double Histogram::sum() const {
  return static_cast<double>(sum_micros_.load(std::memory_order_relaxed)) * 1e-6;
}

uint64_t Histogram::bucket(size_t i) const {
  if (i >= kBounds.size()) return count();
  return buckets_[i].load(std::memory_order_relaxed);
}

void Metrics::count_error(ErrorCode code) {
  int i = static_cast<int>(code);
  if (i >= 0 && i < kErrorCodeCount) errors_[i].add();
}

uint64_t Metrics::errors(ErrorCode code) const {
  int i = static_cast<int>(code);
  return i >= 0 && i < kErrorCodeCount ? errors_[i].value() : 0;
}

namespace {
size_t room_http_status_index(int status) {
  const auto& all = Metrics::kRoomHttpStatuses;
  auto it = std::find(all.begin(), all.end(), status);
  if (it == all.end()) it = std::find(all.begin(), all.end(), 500);
  return static_cast<size_t>(it - all.begin());
}
}  // namespace

void Metrics::count_room_http_refusal(int status) {
  room_http_refusals_[room_http_status_index(status)].add();
}

uint64_t Metrics::room_http_refusals(int status) const {
  return room_http_refusals_[room_http_status_index(status)].value();
}

void Metrics::count_redirect(Redirect reason) {
  const auto i = static_cast<size_t>(reason);
  if (i < redirects_.size()) redirects_[i].add();
}

uint64_t Metrics::redirects(Redirect reason) const {
  const auto i = static_cast<size_t>(reason);
  return i < redirects_.size() ? redirects_[i].value() : 0;
}

void Metrics::set_compute_path(std::string path) {
  std::lock_guard lock(path_mutex_);
  compute_path_ = std::move(path);
}

std::string Metrics::render() const {
  std::string out;
  out.reserve(8192);
  counter(out, "grotto_connections_total", "WebSocket sessions accepted.",
          connections_total.value());
  gauge(out, "grotto_connections_open", "WebSocket sessions open now.", connections_open.value());
  gauge(out, "grotto_handshakes_open",
        "WebSocket sessions that have not said hello yet (max-handshakes bounds them).",
        handshakes_open.value());
  gauge(out, "grotto_sessions_queued",
        "Sessions past a valid hello waiting in the admission queue (max-queue bounds them).",
        sessions_queued.value());
  counter(out, "grotto_sessions_admitted_from_queue_total",
          "Queued sessions let in (a player left, or the service caught up).",
          sessions_admitted_from_queue.value());
  counter(out, "grotto_sessions_refused_total",
          "Hellos refused with overloaded: the queue was full, or the client cannot wait in it.",
          sessions_refused.value());
  gauge(out, "grotto_admission_capacity",
        "Players admitted when the service last fell behind (0: never behind).",
        admission_capacity.value());
  gauge(out, "grotto_admission_behind",
        "1 while the players are not served in time and newcomers wait in the queue.",
        admission_behind.value());
  gauge(out, "grotto_admission_burst",
        "Newcomers let in per measurement interval, at once or from the queue: learned from the "
        "measurements (doubles while they stay quick, halves when the service falls behind).",
        admission_burst.value());
  header(out, "grotto_admission_redirected_total", "counter",
         "Upgrades a balancer marked (X-Grotto-Balancer) sent on to another replica before the "
         "upgrade, by reason (stopping, max_connections, max_handshakes, queue, max_players, "
         "behind, burst). Not connections, not refusals.");
  for (size_t i = 1; i < kRedirectCount; ++i) {
    out += "grotto_admission_redirected_total{reason=\"";
    out += redirect_name(static_cast<Redirect>(i));
    out += "\"} " + std::to_string(redirects_[i].value()) + '\n';
  }
  gauge(out, "grotto_oldest_urgent_ms",
        "Players' oldest urgent room wants still queued, 90th percentile over the players, in ms.",
        oldest_urgent_ms.value());
  gauge(out, "grotto_sockets_open", "Accepted TCP sockets open now, upgraded or not.",
        sockets_open.value());
  counter(out, "grotto_sockets_shed_total",
          "Sockets closed as soon as accepted: max-connections + max-handshakes + 64 were open.",
          sockets_shed.value());
  counter(out, "grotto_accept_failures_total",
          "Failed accepts (no file descriptors left, ...); accepting pauses after each.",
          accept_failures.value());
  gauge(out, "grotto_fd_reserve_held",
        "Reserve file descriptors held for health checks while the process is out of them.",
        fd_reserve_held.value());
  counter(out, "grotto_fd_reserve_connections_total",
          "Connections accepted on a reserve descriptor while out of file descriptors and "
          "answered health-only.",
          fd_reserve_connections.value());
  counter(out, "grotto_fd_reserve_refill_failures_total",
          "Times a reserve descriptor could not be opened again (retried on the next accept).",
          fd_reserve_refill_failures.value());
  counter(out, "grotto_connections_rejected_total",
          "Connections refused at the door: max_connections players or max_handshakes waiting for "
          "hello.",
          connections_rejected.value());
  counter(out, "grotto_http_requests_total", "Plain HTTP requests answered.",
          http_requests_total.value());
  counter(out, "grotto_rooms_http_served_total",
          "Room URLs answered with the room (GET or HEAD): peer replicas, caches, any client.",
          rooms_http_served.value());
  counter(out, "grotto_rooms_http_not_modified_total",
          "Room URLs answered 304: the request's If-None-Match held the room's ETag.",
          rooms_http_not_modified.value());
  counter(out, "grotto_rooms_http_bytes_total", "Room frame bytes in 200 answers to room URLs.",
          rooms_http_bytes.value());
  header(out, "grotto_rooms_http_refused_total", "counter",
         "Room URLs refused, by HTTP status (400 bad path, 401 token, 404 not served or no such "
         "room, 405 method, 429 rate, 503 overloaded or stopping, 500 failed).");
  for (size_t i = 0; i < kRoomHttpStatuses.size(); ++i) {
    out += "grotto_rooms_http_refused_total{status=\"" + std::to_string(kRoomHttpStatuses[i]) +
           "\"} " + std::to_string(room_http_refusals_[i].value()) + '\n';
  }
  counter(out, "grotto_messages_total", "Control messages received from clients.",
          messages_total.value());
  counter(out, "grotto_rooms_requested_total", "Room wants received in requests.",
          rooms_requested.value());
  counter(out, "grotto_rooms_built_total", "Rooms built and encoded (each build counts once).",
          rooms_built.value());
  counter(out, "grotto_rooms_served_total", "Room frames sent to clients.", rooms_served.value());
  counter(out, "grotto_rooms_cache_hits_total", "Room wants answered from the encoded-room cache.",
          rooms_from_cache.value());
  counter(out, "grotto_rooms_cancelled_total", "Room wants cancelled before they were sent.",
          rooms_cancelled.value());
  counter(out, "grotto_rooms_deduplicated_total",
          "Room wants that joined a job already queued or building (single flight).",
          rooms_deduplicated.value());
  counter(out, "grotto_rooms_failed_total", "Room jobs that ended in an error.",
          rooms_failed.value());
  counter(out, "grotto_rooms_fetched_total",
          "Rooms this replica had from their owner through the room tier instead of building them.",
          rooms_fetched.value());
  counter(out, "grotto_owner_failures_total",
          "Rooms asked of their owner that failed, came late or were wrong, and were built here.",
          owner_failures.value());
  counter(out, "grotto_batches_total",
          "Room build calls (each a batch of up to batch-rooms rooms of one lod).",
          batches.value());
  counter(out, "grotto_device_launches_total",
          "Launches of the OpenCL device the workers share (each carries every batch that "
          "waited for it); 0 on the CPU reference or with opencl-queue per-worker.",
          device_launches.value());
  histogram(out, "grotto_device_launch_seconds",
            "Seconds of each launch of the shared OpenCL device, its transfers and copies "
            "included.",
            device_launch_seconds);
  gauge(out, "grotto_queue_depth", "Room jobs queued, not yet building.", queue_depth.value());
  gauge(out, "grotto_rooms_in_flight", "Room wants not yet answered, all clients.",
        rooms_in_flight.value());
  gauge(out, "grotto_cache_bytes", "Bytes of encoded room frames in the cache.",
        cache_bytes.value());
  gauge(out, "grotto_cache_entries", "Encoded room frames in the cache.", cache_entries.value());
  gauge(out, "grotto_worlds_open", "Worlds (seeds) open, the server's own included.",
        worlds_open.value());
  counter(out, "grotto_worlds_opened_total", "Worlds opened for clients that named them.",
          worlds_opened.value());
  counter(out, "grotto_worlds_refused_total",
          "Hellos refused because max_worlds worlds were open and each had players.",
          worlds_refused.value());
  histogram(out, "grotto_build_seconds", "Seconds to build one room (its share of its batch).",
            build_seconds);
  histogram(out, "grotto_encode_seconds", "Seconds to encode and frame one room.", encode_seconds);
  histogram(out, "grotto_room_latency_seconds",
            "Seconds from a room want received to its frame queued for sending.",
            room_latency_seconds);
  counter(out, "grotto_bytes_sent_total", "Bytes of all frames sent to clients.",
          bytes_sent.value());
  counter(out, "grotto_slow_clients_dropped_total",
          "Clients disconnected because their send queue passed its limit.",
          slow_clients_dropped.value());
  counter(out, "grotto_bandwidth_waits_total",
          "Times a player's ready rooms were held back by max_kbps (its bandwidth cap).",
          bandwidth_waits.value());

  // Several codes share a wire name (invalid_argument is sent as bad_message): sum them.
  std::map<std::string, uint64_t> by_wire;
  for (int i = 0; i < kErrorCodeCount; ++i) {
    auto code = static_cast<ErrorCode>(i);
    by_wire[proto::wire_code_name(code)] += errors_[i].value();
  }
  header(out, "grotto_errors_total", "counter", "Error messages sent to clients, by wire code.");
  for (const auto& [name, value] : by_wire) {
    out +=
        "grotto_errors_total{code=\"" + escape_label(name) + "\"} " + std::to_string(value) + '\n';
  }

  std::string path;
  {
    std::lock_guard lock(path_mutex_);
    path = compute_path_;
  }
  header(out, "grotto_compute_path_info", "gauge",
         "The room builder's compute path (opencl: <device> or cpu: <why>).");
  if (!path.empty()) {
    out += "grotto_compute_path_info{path=\"" + escape_label(path) + "\"} 1\n";
  }
  return out;
}

}  // namespace grotto::server
