#include "client/load/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <nlohmann/json.hpp>

namespace grotto::load {

double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  // Nearest rank: rank = ceil(p/100 × n), 1-based.
  double rank = std::ceil(p / 100.0 * static_cast<double>(sorted.size()));
  size_t i = rank < 1 ? 0 : static_cast<size_t>(rank) - 1;
  return sorted[std::min(i, sorted.size() - 1)];
}

Distribution summarize(std::vector<double> samples) {
  Distribution d;
  if (samples.empty()) return d;
  std::sort(samples.begin(), samples.end());
  d.count = samples.size();
  double sum = 0;
  for (double s : samples)
    sum += s;
  d.mean = sum / static_cast<double>(samples.size());
  d.p50 = percentile(samples, 50);
  d.p90 = percentile(samples, 90);
  d.p99 = percentile(samples, 99);
  d.max = samples.back();
  return d;
}

void total_players(LoadReport& r) {
  r.rooms_ready = r.rooms_received = r.bytes = r.requests = r.cancels = 0;
  r.stalls = 0;
  r.stall_total_s = 0;
  r.reconnects = 0;
  r.restart_notices = 0;
  r.rooms_entered = r.turn_backs = 0;
  r.distance_m = 0;
  r.players_without_room = 0;
  r.rooms_received_by_seed.clear();
  for (const auto& p : r.players_detail) {
    if (p.seed) r.rooms_received_by_seed[*p.seed] += p.rooms_received;
    r.players_without_room += p.first_room_ms < 0 && !p.queued_at_end ? 1 : 0;
    r.rooms_ready += p.rooms_ready;
    r.rooms_received += p.rooms_received;
    r.bytes += p.bytes;
    r.requests += p.requests;
    r.cancels += p.cancels;
    r.stalls += p.stalls;
    r.stall_total_s += p.stall_s;
    r.reconnects += p.reconnects;
    r.restart_notices += p.restart_notices;
    r.rooms_entered += p.rooms_entered;
    r.turn_backs += p.turn_backs;
    r.distance_m += p.distance_m;
  }
  r.errors_total = 0;
  for (const auto& [code, n] : r.errors)
    r.errors_total += n;
  if (r.elapsed_s > 0) {
    r.rooms_per_s = static_cast<double>(r.rooms_ready) / r.elapsed_s;
    r.mb_per_s = static_cast<double>(r.bytes) / 1e6 / r.elapsed_s;
  }
  std::vector<double> means, peaks, horizons;
  for (const auto& p : r.players_detail) {
    means.push_back(p.mean_kbps);
    peaks.push_back(p.peak_kbps);
    horizons.push_back(p.horizon_s);
  }
  r.final_horizon_s = summarize(std::move(horizons));
  r.player_kbps = summarize(std::move(means));
  r.player_peak_kbps = summarize(std::move(peaks));
  r.rooms_per_room_entered = r.rooms_entered > 0 ? static_cast<double>(r.rooms_received) /
                                                       static_cast<double>(r.rooms_entered)
                                                 : 0;
}

int exit_code(const LoadReport& r) {
  if (r.errors_total > static_cast<uint64_t>(std::max(r.max_errors, 0)) || r.streams_failed > 0 ||
      r.players_without_room > 0 || r.players_disconnected > 0 || r.verify.failures() > 0) {
    return kExitErrors;
  }
  if (r.max_stalls >= 0 && r.stalls > static_cast<uint64_t>(r.max_stalls)) return kExitStalls;
  if (r.max_p99_ms >= 0 && r.latency_ms.p99 > r.max_p99_ms) return kExitLatency;
  return kExitOk;
}

namespace {

void appendf(std::string& out, const char* format, ...) __attribute__((format(printf, 2, 3)));
void appendf(std::string& out, const char* format, ...) {
  char buf[512];
  va_list args;
  va_start(args, format);
  int n = std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  if (n > 0) out.append(buf, std::min(static_cast<size_t>(n), sizeof buf - 1));
}

void distribution_row(std::string& out, const char* name, const Distribution& d) {
  appendf(out, "  %-22s %8llu %9.1f %9.1f %9.1f %9.1f %9.1f\n", name,
          static_cast<unsigned long long>(d.count), d.mean, d.p50, d.p90, d.p99, d.max);
}

nlohmann::json to_json(const Distribution& d) {
  return {{"count", d.count}, {"mean", d.mean}, {"p50", d.p50},
          {"p90", d.p90},     {"p99", d.p99},   {"max", d.max}};
}

}  // namespace

std::string format_table(const LoadReport& r) {
  std::string out;
  auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  appendf(out, "grotto-load: %s, %d players, %.1f s (asked %.1f s), server %s%s\n", r.mode.c_str(),
          r.players, r.elapsed_s, r.duration_s, r.url.c_str(),
          r.embedded_server ? " (embedded)" : "");
  appendf(out, "  world seed %s, %s; speed %.1f m/s, horizon %.1f s\n",
          r.seed ? std::to_string(*r.seed).c_str() : "(the server's)",
          r.server.empty() ? "server unknown" : r.server.c_str(), r.speed, r.horizon_s);
  if (r.ramp_s > 0) appendf(out, "  players joined over %.1f s\n", r.ramp_s);
  if (r.net != "off") appendf(out, "  simulated network: %s\n", r.net.c_str());
  if (!r.compute.empty()) appendf(out, "  embedded server compute: %s\n", r.compute.c_str());
  appendf(out, "\n  %-22s %8s %9s %9s %9s %9s %9s\n", "", "count", "mean", "p50", "p90", "p99",
          "max");
  distribution_row(out, "time to first room ms", r.first_room_ms);
  distribution_row(out, "request->room ms", r.latency_ms);
  distribution_row(out, "  due within 1 s", r.urgent_latency_ms);
  distribution_row(out, "decode ms", r.decode_ms);
  distribution_row(out, "stall ms", r.stall_ms);
  distribution_row(out, "player kbit/s (mean)", r.player_kbps);
  distribution_row(out, "player kbit/s (peak s)", r.player_peak_kbps);
  if (r.min_horizon_s > 0) distribution_row(out, "horizon s at the end", r.final_horizon_s);
  appendf(out, "\n  rooms ready       %10llu  (%.1f rooms/s)\n", u(r.rooms_ready), r.rooms_per_s);
  appendf(out, "  bytes received    %10llu  (%.2f MB/s)\n", u(r.bytes), r.mb_per_s);
  appendf(out, "  rooms received    %10llu  rejected %llu, evicted %llu, given up %llu\n",
          u(r.rooms_received), u(r.rooms_rejected), u(r.rooms_evicted), u(r.rooms_given_up));
  appendf(out, "  distinct rooms    %10llu  (world, lod, room)\n", u(r.rooms_unique));
  for (const auto& [seed, n] : r.rooms_received_by_seed) {
    appendf(out, "    of seed %-8s %10llu\n", std::to_string(seed).c_str(), u(n));
  }
  appendf(out, "  requested         %10llu  cancelled %llu\n", u(r.requests), u(r.cancels));
  appendf(out, "  stalls            %10llu  total %.2f s%s\n", u(r.stalls), r.stall_total_s,
          r.max_stalls >= 0 ? (" (limit " + std::to_string(r.max_stalls) + ")").c_str() : "");
  appendf(out, "  walked            %10.0f m, %llu portals, %llu turn-backs\n", r.distance_m,
          u(r.rooms_entered), u(r.turn_backs));
  appendf(out, "  rooms per portal  %10.2f  (rooms received / portals crossed: prefetch waste)\n",
          r.rooms_per_room_entered);
  appendf(out, "  reconnects        %10llu  drops %llu, streams failed %llu, drain notices %llu\n",
          u(r.reconnects), u(r.drops), u(r.streams_failed), u(r.restart_notices));
  if (r.queued.players > 0) {
    appendf(out,
            "  queued            %10llu  players, p50 %.1f s, p99 %.1f s; still waiting at the end "
            "%llu\n",
            u(r.queued.players), r.queued.ms.p50 / 1000, r.queued.ms.p99 / 1000,
            u(r.queued.at_end));
  }
  if (r.players_without_room > 0) {
    appendf(out, "  players without a room %llu\n", u(r.players_without_room));
  }
  if (r.players_disconnected > 0) {
    appendf(out, "  players not connected at the end %llu (the server was lost)\n",
            u(r.players_disconnected));
  }
  for (const auto& p : r.players_detail) {
    // The first player's last error says why, when a player never started, a stream failed or
    // the server was lost.
    if (!p.last_error.empty() &&
        (r.players_without_room > 0 || r.streams_failed > 0 || r.players_disconnected > 0)) {
      appendf(out, "  last error (player %d): %s\n", p.index, p.last_error.c_str());
      break;
    }
  }
  appendf(out, "  errors            %10llu", u(r.errors_total));
  for (const auto& [code, n] : r.errors)
    appendf(out, "  %s=%llu", code.c_str(), u(n));
  out += "\n";
  if (r.mode == "burst") {
    if (r.burst_s >= 0) {
      appendf(out, "  burst: every player's %.0f m radius ready after %.2f s\n", r.radius_m,
              r.burst_s);
    } else {
      appendf(out, "  burst: not every player's %.0f m radius was ready in time\n", r.radius_m);
    }
  }
  if (r.verify.enabled) {
    appendf(out, "  verify: %llu rooms, %llu seams; failures: room %llu, seam %llu, graph %llu\n",
            u(r.verify.rooms_checked), u(r.verify.seams_checked), u(r.verify.room_failures),
            u(r.verify.seam_failures), u(r.verify.graph_failures));
    for (const auto& f : r.verify.first_failures)
      appendf(out, "    %s\n", f.c_str());
  }
  int code = exit_code(r);
  appendf(out, "\n  result: %s (exit %d)\n",
          code == kExitOk        ? "pass"
          : code == kExitStalls  ? "too many stalls"
          : code == kExitLatency ? "latency p99 over --max-p99-ms"
                                 : "errors",
          code);
  return out;
}

std::string to_json_text(const LoadReport& r) {
  nlohmann::json players = nlohmann::json::array();
  for (const auto& p : r.players_detail) {
    players.push_back(
        {{"index", p.index},
         {"seed", p.seed ? nlohmann::json(std::to_string(*p.seed)) : nlohmann::json(nullptr)},
         {"start_room", p.start_room},
         {"joined_s", p.joined_s},
         {"first_room_ms", p.first_room_ms},
         {"rooms_ready", p.rooms_ready},
         {"rooms_received", p.rooms_received},
         {"bytes", p.bytes},
         {"mean_kbps", p.mean_kbps},
         {"peak_kbps", p.peak_kbps},
         {"horizon_s", p.horizon_s},
         {"requests", p.requests},
         {"cancels", p.cancels},
         {"rooms_entered", p.rooms_entered},
         {"turn_backs", p.turn_backs},
         {"distance_m", p.distance_m},
         {"stalls", p.stalls},
         {"stall_s", p.stall_s},
         {"reconnects", p.reconnects},
         {"restart_notices", p.restart_notices},
         {"queued_ms", p.queued_ms},
         {"times_queued", p.times_queued},
         {"queued_at_end", p.queued_at_end},
         {"errors", p.errors},
         {"state", p.state},
         {"last_error", p.last_error},
         {"burst_complete_s", p.burst_complete_s},
         {"burst_rooms", p.burst_rooms}});
  }
  nlohmann::json verify = {{"enabled", r.verify.enabled},
                           {"rooms_checked", r.verify.rooms_checked},
                           {"seams_checked", r.verify.seams_checked},
                           {"room_failures", r.verify.room_failures},
                           {"seam_failures", r.verify.seam_failures},
                           {"graph_failures", r.verify.graph_failures},
                           {"failures", r.verify.failures()},
                           {"first_failures", r.verify.first_failures}};
  // Keys are decimal seeds (strings, as 64-bit seeds travel in JSON).
  nlohmann::json by_seed = nlohmann::json::object();
  for (const auto& [seed, n] : r.rooms_received_by_seed)
    by_seed[std::to_string(seed)] = n;
  nlohmann::json by_second = nlohmann::json::array();
  for (const Distribution& d : r.latency_by_second_ms)
    by_second.push_back(to_json(d));
  nlohmann::json doc = {
      {"tool", "grotto-load"},
      {"mode", r.mode},
      {"url", r.url},
      {"embedded_server", r.embedded_server},
      // A string: 64-bit seeds do not fit a JSON double (PROTOCOL.md); null: the server's own.
      {"seed", r.seed ? nlohmann::json(std::to_string(*r.seed)) : nlohmann::json(nullptr)},
      {"server", r.server},
      {"compute", r.compute},
      {"players", r.players},
      {"rng_seed", std::to_string(r.rng_seed)},
      {"spread", r.spread},
      {"net", r.net},
      {"speed_m_s", r.speed},
      {"horizon_s", r.horizon_s},
      {"min_horizon_s", r.min_horizon_s},
      {"protocol_version_offered", r.protocol_version},
      {"final_horizon_s", to_json(r.final_horizon_s)},
      {"radius_m", r.radius_m},
      {"duration_s", r.duration_s},
      {"ramp_s", r.ramp_s},
      {"elapsed_s", r.elapsed_s},
      {"first_room_ms", to_json(r.first_room_ms)},
      {"latency_ms", to_json(r.latency_ms)},
      {"urgent_latency_ms", to_json(r.urgent_latency_ms)},
      {"latency_by_second_ms", by_second},
      {"decode_ms", to_json(r.decode_ms)},
      {"stall_ms", to_json(r.stall_ms)},
      {"rooms",
       {{"ready", r.rooms_ready},
        {"received", r.rooms_received},
        {"unique", r.rooms_unique},
        {"rejected", r.rooms_rejected},
        {"evicted", r.rooms_evicted},
        {"given_up", r.rooms_given_up},
        {"requested", r.requests},
        {"cancelled", r.cancels}}},
      {"rooms_received_by_seed", by_seed},
      {"bytes", r.bytes},
      {"rooms_per_s", r.rooms_per_s},
      {"mb_per_s", r.mb_per_s},
      {"player_kbps", to_json(r.player_kbps)},
      {"player_peak_kbps", to_json(r.player_peak_kbps)},
      {"rooms_per_room_entered", r.rooms_per_room_entered},
      {"stalls", {{"count", r.stalls}, {"total_s", r.stall_total_s}, {"max", r.max_stalls}}},
      {"reconnects", r.reconnects},
      {"restart_notices", r.restart_notices},
      {"queued",
       {{"players", r.queued.players},
        {"ms", to_json(r.queued.ms)},
        {"at_end", r.queued.at_end},
        {"waiting_by_second", r.queued.waiting_by_second},
        {"length_by_second", r.queued.length_by_second}}},
      {"drops", r.drops},
      {"streams_failed", r.streams_failed},
      {"players_without_room", r.players_without_room},
      {"players_disconnected", r.players_disconnected},
      {"errors", r.errors},
      {"errors_total", r.errors_total},
      {"gates",
       {{"max_stalls", r.max_stalls}, {"max_errors", r.max_errors}, {"max_p99_ms", r.max_p99_ms}}},
      {"walk",
       {{"rooms_entered", r.rooms_entered},
        {"turn_backs", r.turn_backs},
        {"distance_m", r.distance_m}}},
      {"burst_s", r.burst_s},
      {"verify", verify},
      {"per_player", players},
      {"exit_code", exit_code(r)},
  };
  return doc.dump(2);
}

}  // namespace grotto::load
