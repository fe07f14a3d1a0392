#include "client/load/load.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <thread>
#include <tuple>
#include <vector>

#include "client/load/verifier.hpp"
#include "client/stream/stream.hpp"
#include "common/cave/layout.hpp"
#include "common/core/parallel.hpp"
#include "server/embedded.hpp"

namespace grotto::load {

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::kWalk:
      return "walk";
    case Mode::kBurst:
      return "burst";
    case Mode::kSoak:
      return "soak";
  }
  return "walk";
}

double default_duration_s(Mode mode) {
  switch (mode) {
    case Mode::kWalk:
      return 20;
    case Mode::kBurst:
      return 60;
    case Mode::kSoak:
      return 600;
  }
  return 20;
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0, Clock::time_point t) {
  return std::chrono::duration<double>(t - t0).count();
}

struct Player {
  int index = 0;
  double join_at_s = 0;            // --ramp: when its Stream starts
  double joined_s = 0;             // when it did
  std::unique_ptr<Stream> stream;  // null until the player joins
  bool joined() const { return stream != nullptr; }
  std::unique_ptr<Walker> walker;
  std::optional<cave::RoomId> start;
  PortalGraph graph;  // burst mode: the rooms received, for the plan over the radius
  double burst_complete_s = -1;
  uint64_t burst_rooms = 0;
  StreamStats final_stats;
  uint64_t window_bytes = 0;  // bytes received when the current one-second window began
  double peak_kbps = 0;
  StreamState final_state = StreamState::kConnecting;  // before stop()
  std::string final_error;                             // before stop()
  bool queued_at_end = false;  // in a server's admission queue (before stop())
};

Status check(const LoadOptions& o) {
  if (o.players < 1 || o.players > 10'000)
    return invalid_argument("--players must be in [1, 10000]");
  if (!(o.speed > 0)) return invalid_argument("--speed must be > 0");
  if (!(o.horizon_s > 0)) return invalid_argument("--horizon must be > 0");
  if (!(o.min_horizon_s >= 0) || !std::isfinite(o.min_horizon_s)) {
    return invalid_argument("--min-horizon must be 0 (fixed horizon) or a positive number");
  }
  if (!(o.radius_m > 0)) return invalid_argument("--radius must be > 0");
  if (!(o.duration_s >= 0)) return invalid_argument("--duration must be >= 0");
  if (!(o.ramp_s >= 0)) return invalid_argument("--ramp must be >= 0");
  if (o.ramp_s > 0 && o.mode == Mode::kBurst)
    return invalid_argument("--ramp is for walk and soak (burst ends when every player is done)");
  const double duration = o.duration_s > 0 ? o.duration_s : default_duration_s(o.mode);
  if (o.ramp_s >= duration)
    return invalid_argument("--ramp must be shorter than the run (--duration)");
  if (!(o.tick_hz > 0)) return invalid_argument("tick_hz must be > 0");
  if (o.seed && !o.seeds.empty()) return invalid_argument("--seeds conflicts with --seed");
  if (o.seeds.size() > 1 && o.url.empty()) {
    return invalid_argument(
        "--seeds with more than one world needs --server (the embedded server serves one "
        "world)");
  }
  if (o.spread && !o.url.empty() && !o.seed && o.seeds.empty()) {
    return invalid_argument(
        "--spread with --server needs --seed (the start rooms are laid out "
        "locally, so the world must be known)");
  }
  return {};
}

// One line, rewritten in place (\r, erase to end of line).
void print_progress(double t, const std::vector<Player>& players, uint64_t latency_p50_ms,
                    uint64_t verify_failures) {
  uint64_t rooms = 0, bytes = 0, errors = 0, stalls = 0, waiting = 0;
  double stall_s = 0;
  size_t joined = 0;
  for (const auto& p : players) {
    if (!p.joined()) continue;
    ++joined;
    StreamStats s = p.stream->stats();
    rooms += s.rooms_ready;
    bytes += s.bytes_received;
    for (const auto& [code, n] : s.errors)
      errors += n;
    const auto& w = p.walker->stats();
    stalls += w.stalls_s.size() + (p.walker->state() == WalkerState::kStalled ? 1 : 0);
    for (double d : w.stalls_s)
      stall_s += d;
    stall_s += p.walker->open_stall_s();
    waiting += p.walker->state() == WalkerState::kWaiting ? 1 : 0;
  }
  std::fprintf(
      stderr,
      "\r[%6.1f s] rooms %llu (%.1f/s) %.2f MB/s  p50 %llu ms  stalls %llu (%.1f s)  "
      "waiting %llu/%zu  errors %llu%s\x1b[K",
      t, static_cast<unsigned long long>(rooms), t > 0 ? static_cast<double>(rooms) / t : 0,
      t > 0 ? static_cast<double>(bytes) / 1e6 / t : 0,
      static_cast<unsigned long long>(latency_p50_ms), static_cast<unsigned long long>(stalls),
      stall_s, static_cast<unsigned long long>(waiting), joined,
      static_cast<unsigned long long>(errors),
      verify_failures ? (" verify failures " + std::to_string(verify_failures)).c_str() : "");
  std::fflush(stderr);
}

// Burst mode: is everything within the player's radius known and ready?
void check_burst(Player& p, double t, const PlanOptions& plan_options) {
  if (!p.joined() || p.burst_complete_s >= 0 || p.walker->state() == WalkerState::kWaiting) return;
  auto plan = p.graph.plan(*p.walker->room(), p.walker->pose(), plan_options);
  p.burst_rooms = plan.size();
  for (const auto& room : plan) {
    if (!room.known || !p.stream->ready(room.id)) return;
  }
  p.burst_complete_s = t;
}

}  // namespace

// One sector a player, laid out on every hardware thread (each is a pure function of its world and
// coordinates): 300 players over 300 worlds took 71 s when each world laid out every player's
// sector on one thread.
Result<std::vector<std::pair<cave::RoomId, Vec3>>> spread_starts(std::span<const uint64_t> seeds) {
  std::map<uint64_t, cave::World> worlds;
  for (uint64_t seed : seeds) {
    if (worlds.contains(seed)) continue;
    auto world = cave::World::create(seed, {});
    if (!world) return world.error();
    worlds.emplace(seed, std::move(world).value());
  }
  std::vector<std::optional<std::pair<cave::RoomId, Vec3>>> found(seeds.size());
  for_each_index(
      seeds.size(), static_cast<int>(std::max(1u, std::thread::hardware_concurrency())),
      [&](size_t i) {
        auto layout = cave::generate_sector(worlds.at(seeds[i]), {3 * static_cast<int>(i), 0, 0});
        if (!layout.rooms.empty()) {
          found[i].emplace(layout.rooms[0].id, layout.rooms[0].sphere.centre);
        }
      });
  std::vector<std::pair<cave::RoomId, Vec3>> out;
  for (size_t i = 0; i < seeds.size(); ++i) {
    if (!found[i]) {
      return Error{ErrorCode::kNotFound, "--spread: sector " +
                                             cave::to_string({3 * static_cast<int>(i), 0, 0}) +
                                             " has no interior room"};
    }
    out.push_back(*found[i]);
  }
  return out;
}

Result<LoadReport> run_load(const LoadOptions& options) {
  if (Status s = check(options); !s) return s.error();
  const double duration =
      options.duration_s > 0 ? options.duration_s : default_duration_s(options.mode);
  const bool burst = options.mode == Mode::kBurst;

  LoadReport report;
  report.mode = mode_name(options.mode);
  report.players = options.players;
  report.speed = options.speed;
  report.horizon_s = burst ? options.radius_m / options.speed : options.horizon_s;
  report.min_horizon_s = burst ? 0 : options.min_horizon_s;
  report.protocol_version = options.protocol_version;
  report.radius_m = burst ? options.radius_m : 0;
  report.net = net_profile_text(options.net);
  report.duration_s = duration;
  report.ramp_s = options.ramp_s;
  report.max_stalls = options.max_stalls;
  report.max_errors = options.max_errors;
  report.max_p99_ms = options.max_p99_ms;
  report.seed = options.seed;
  report.rng_seed = options.rng_seed;
  report.spread = options.spread;

  // The embedded server: loopback, an ephemeral port, the world and device asked for.
  std::unique_ptr<server::Server> server;
  std::string url = options.url;
  if (url.empty()) {
    server::ServerConfig config = server::embedded_config();
    if (options.seed) config.seed = *options.seed;
    if (!options.seeds.empty()) config.seed = options.seeds.front();
    config.token = options.token;
    config.generator.builder.device.device = options.device;
    config.generator.workers = options.server_workers;
    // Every player is one connection; the default cap (1024) must not be what a big run measures.
    config.max_connections = std::max(config.max_connections, options.players + 16);
    auto started = server::start_embedded(config);
    if (!started) return started.error();
    url = started.value().url;
    server = std::move(started.value().server);
    report.embedded_server = true;
    report.seed = config.seed;
    report.compute = server->generator().compute_path();
    spdlog::info("event=embedded_server url={} compute={}", url,
                 server->generator().compute_path());
  }
  report.url = url;

  // The world of player i: round-robin over --seeds, else the one seed (or the server's).
  auto seed_of = [&](int i) -> std::optional<uint64_t> {
    if (options.seeds.empty()) return options.seed;
    return options.seeds[static_cast<size_t>(i) % options.seeds.size()];
  };
  std::vector<std::pair<cave::RoomId, Vec3>> starts;  // by player
  if (options.spread) {
    std::vector<uint64_t> seeds;
    for (int i = 0; i < options.players; ++i)
      seeds.push_back(seed_of(i) ? *seed_of(i) : *report.seed);
    auto s = spread_starts(seeds);
    if (!s) return s.error();
    starts = std::move(s).value();
  }

  PlanOptions plan_options;
  plan_options.horizon_s = report.horizon_s;

  // The Runtime outlives the Streams (declared first, destroyed last); the Streams stop before
  // the embedded server so that its shutdown is no error of theirs.
  Runtime runtime(options.io_threads, options.decode_workers);
  std::vector<Player> players(static_cast<size_t>(options.players));
  // Player i's Stream, walker and start; called when its join time comes (--ramp).
  auto join = [&](Player& p, double t) -> Status {
    const int i = p.index;
    StreamOptions so;
    so.url = url;
    so.seed = seed_of(i);
    so.name = "grotto-load";
    so.token = options.token;
    so.plan = plan_options;
    so.min_horizon_s = burst ? 0 : options.min_horizon_s;  // burst wants its radius at once
    so.protocol_version = options.protocol_version;
    so.spawn = !options.spread;
    so.store_bytes = options.store_bytes;
    so.net = options.net;
    auto stream = Stream::start(so, runtime);
    if (!stream) return stream.error();
    p.stream = std::move(stream).value();
    p.joined_s = t;
    Stream* s = p.stream.get();
    WorldView view{[s](cave::RoomId id) { return s->descriptor(id); },
                   [s](cave::RoomId id) { return s->ready(id); }};
    WalkerOptions wo = options.walker;
    wo.speed = options.speed;
    p.walker = std::make_unique<Walker>(std::move(view), wo, options.rng_seed + i);
    if (options.spread) {
      const auto& [room, position] = starts[static_cast<size_t>(i)];
      p.start = room;
      p.walker->place(room, position);
      p.stream->set_pose(p.walker->pose());
    }
    return {};
  };
  // Time zero is before the first Stream starts connecting: time to first room includes the
  // connection, the welcome and the spawn point (a walker's clock starts at its join).
  const auto t0 = Clock::now();
  for (int i = 0; i < options.players; ++i) {
    Player& p = players[static_cast<size_t>(i)];
    p.index = i;
    p.join_at_s = options.ramp_s * i / options.players;
    if (p.join_at_s > 0) continue;
    if (Status st = join(p, 0); !st) return st.error();
  }

  std::unique_ptr<Verifier> verifier;
  if (options.verify) {
    verifier = std::make_unique<Verifier>(options.players, [&players](int i, cave::RoomId id) {
      return players[static_cast<size_t>(i)].stream->room(id);
    });
  }

  // The distinct rooms the players received: (world, wire lod, room). Against what servers
  // built (their grotto_rooms_built_total), it tells how often a room was built more than once.
  std::set<std::tuple<uint64_t, uint8_t, uint64_t>> unique_rooms;
  std::vector<double> latencies, urgent_latencies, decodes;
  std::vector<std::vector<double>> latencies_by_second;
  double t = 0;  // seconds since t0, as of the loop's current step
  auto drain = [&](Player& p) {
    for (auto& room : p.stream->take_new_rooms()) {
      unique_rooms.emplace(seed_of(p.index).value_or(report.seed.value_or(0)), room->lod,
                           room->room.id.packed());
      if (burst) (void)p.graph.add(room->room);  // disagreements: --verify counts them
      if (verifier) verifier->push(p.index, std::move(room));
    }
    for (const auto& sample : p.stream->take_samples()) {
      latencies.push_back(sample.latency_ms);
      if (sample.priority_ms <= kUrgentPriorityMs) urgent_latencies.push_back(sample.latency_ms);
      decodes.push_back(sample.decode_ms);
      const auto second = static_cast<size_t>(std::max(0.0, t));
      if (latencies_by_second.size() <= second) latencies_by_second.resize(second + 1);
      latencies_by_second[second].push_back(sample.latency_ms);
    }
  };

  // The simulation: real time, one thread. While a player waits for its first room the loop
  // ticks at 200 Hz so that time to first room is measured to ~5 ms.
  auto last = t0;
  double next_progress = 1.0, next_burst_check = 0;
  // Each player's peak bandwidth: bytes over windows of (at least) one second.
  double window_start = 0;
  for (;;) {
    const auto now = Clock::now();
    const double dt = seconds_since(last, now);
    last = now;
    t = seconds_since(t0, now);
    bool waiting = false, all_failed = true;
    for (auto& p : players) {
      if (!p.joined() && t >= p.join_at_s) {
        if (Status st = join(p, t); !st) return st.error();
      }
      if (!p.joined()) {
        all_failed = false;  // not every player has had its chance
        continue;
      }
      if (!p.walker->placed()) {
        if (auto spawn = p.stream->spawn_point()) {
          p.start = spawn->room;
          p.walker->place(spawn->room, spawn->position);
        }
      }
      // Burst players stand where they start; their walker only measures time to first room.
      if (!burst || p.walker->state() == WalkerState::kWaiting) p.walker->advance(dt);
      if (p.walker->placed()) {
        Pose pose = p.walker->pose();
        if (burst) pose.speed = options.speed;
        p.stream->set_pose(pose);
      }
      waiting |= p.walker->state() == WalkerState::kWaiting;
      all_failed &= p.stream->state() == StreamState::kFailed;
      drain(p);
    }
    // Once a second: how many wait in an admission queue, and how long the servers say it is.
    if (const auto second = static_cast<size_t>(t);
        second >= report.queued.waiting_by_second.size()) {
      uint64_t waiting_now = 0, length = 0;
      for (auto& p : players) {
        if (!p.joined()) continue;
        if (auto place = p.stream->stats().queued) {
          ++waiting_now;
          length = std::max<uint64_t>(length, place->queue);
        }
      }
      report.queued.waiting_by_second.resize(second + 1, waiting_now);
      report.queued.length_by_second.resize(second + 1, length);
    }
    if (burst && t >= next_burst_check) {
      next_burst_check = t + 0.1;
      bool all = true;
      for (auto& p : players) {
        check_burst(p, t, plan_options);
        all &= p.burst_complete_s >= 0;
      }
      if (all) {
        report.burst_s = t;
        break;
      }
    }
    if (t - window_start >= 1.0) {
      for (auto& p : players) {
        if (!p.joined()) continue;
        const uint64_t bytes = p.stream->stats().bytes_received;
        p.peak_kbps = std::max(p.peak_kbps, static_cast<double>(bytes - p.window_bytes) * 8.0 /
                                                1000.0 / (t - window_start));
        p.window_bytes = bytes;
      }
      window_start = t;
    }
    if (options.progress && t >= next_progress) {
      next_progress = t + 1.0;
      // The median by selection: linear, so a long soak's millions of samples stay cheap.
      double p50 = 0;
      if (!latencies.empty()) {
        std::vector<double> copy = latencies;
        auto mid = copy.begin() + static_cast<std::ptrdiff_t>((copy.size() - 1) / 2);
        std::nth_element(copy.begin(), mid, copy.end());
        p50 = *mid;
      }
      print_progress(t, players, static_cast<uint64_t>(p50), verifier ? verifier->failures() : 0);
    }
    if (t >= duration || all_failed) break;
    const double interval = waiting ? 0.005 : 1.0 / options.tick_hz;
    std::this_thread::sleep_until(
        now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(interval)));
  }
  if (options.progress) std::fprintf(stderr, "\r\x1b[K");
  report.elapsed_s = seconds_since(t0, Clock::now());

  // Every player's end state before any stops: a player leaving a full server lets one waiting
  // in its admission queue in, which would otherwise read as welcomed at the end.
  for (auto& p : players) {
    if (!p.joined()) continue;  // a run cut short (all others failed) before its join
    StreamStats before = p.stream->stats();
    p.final_state = before.state;
    p.final_error = before.last_error;
    p.queued_at_end = before.queued.has_value();
  }
  for (auto& p : players) {
    if (!p.joined()) continue;
    p.stream->stop();
    drain(p);  // what arrived between the last step and the stop
    p.final_stats = p.stream->stats();
  }
  if (verifier) report.verify = verifier->finish();

  std::vector<double> first_rooms, stalls, queued_ms;
  for (auto& p : players) {
    if (!p.joined()) continue;
    const StreamStats& s = p.final_stats;
    const WalkerStats& w = p.walker->stats();
    PlayerReport pr;
    pr.index = p.index;
    pr.seed = seed_of(p.index);
    if (!pr.seed) pr.seed = s.seed;  // the world the server said it serves
    if (p.start) pr.start_room = p.start->to_string();
    pr.joined_s = p.joined_s;
    if (w.first_room_s) {
      pr.first_room_ms = *w.first_room_s * 1000.0;
      first_rooms.push_back(pr.first_room_ms);
    }
    pr.rooms_ready = s.rooms_ready;
    pr.rooms_received = s.rooms_received;
    pr.bytes = s.bytes_received;
    pr.horizon_s = s.horizon_s;
    const double connected_s = report.elapsed_s - p.joined_s;
    pr.mean_kbps = connected_s > 0 ? static_cast<double>(pr.bytes) * 8.0 / 1000.0 / connected_s : 0;
    // A run shorter than a second has no whole window: its mean is its peak.
    pr.peak_kbps = std::max(p.peak_kbps, pr.mean_kbps);
    pr.requests = s.requests_sent;
    pr.cancels = s.cancels_sent;
    pr.rooms_entered = w.rooms_entered;
    pr.turn_backs = w.turn_backs;
    pr.distance_m = w.distance_m;
    for (double d : w.stalls_s) {
      stalls.push_back(d * 1000.0);
      pr.stall_s += d;
    }
    pr.stalls = w.stalls_s.size();
    if (p.walker->state() == WalkerState::kStalled) {
      stalls.push_back(p.walker->open_stall_s() * 1000.0);
      pr.stall_s += p.walker->open_stall_s();
      ++pr.stalls;
    }
    pr.reconnects = s.reconnects;
    pr.restart_notices = s.restart_notices;
    pr.queued_ms = s.queued_ms;
    pr.times_queued = s.times_queued;
    pr.queued_at_end = p.queued_at_end;
    report.queued.at_end += p.queued_at_end ? 1 : 0;
    if (s.times_queued > 0) {
      ++report.queued.players;
      queued_ms.push_back(s.queued_ms);
    }
    for (const auto& [code, n] : s.errors) {
      pr.errors += n;
      report.errors[code] += n;
    }
    pr.state = state_name(p.final_state);
    pr.last_error = p.final_error;
    pr.burst_complete_s = p.burst_complete_s;
    pr.burst_rooms = p.burst_rooms;
    report.rooms_rejected += s.rooms_rejected;
    report.rooms_evicted += s.rooms_evicted;
    report.rooms_given_up += s.rooms_given_up;
    report.drops += s.drops;
    report.streams_failed += p.final_state == StreamState::kFailed ? 1 : 0;
    // Still trying to connect when the run ends: the server was lost (a drain that another
    // replica picked up is not, since the player is connected again by then).
    // A player waiting in an admission queue is connected and told where it stands.
    report.players_disconnected += !p.queued_at_end && (p.final_state == StreamState::kConnecting ||
                                                        p.final_state == StreamState::kBackoff);
    if (!s.server.empty()) report.server = s.server;
    report.players_detail.push_back(std::move(pr));
  }
  report.rooms_unique = unique_rooms.size();
  report.first_room_ms = summarize(std::move(first_rooms));
  report.latency_ms = summarize(std::move(latencies));
  report.urgent_latency_ms = summarize(std::move(urgent_latencies));
  for (auto& second : latencies_by_second)
    report.latency_by_second_ms.push_back(summarize(std::move(second)));
  report.decode_ms = summarize(std::move(decodes));
  report.stall_ms = summarize(std::move(stalls));
  report.queued.ms = summarize(std::move(queued_ms));
  // Without --seed the report names the world the server served (welcome.seed).
  if (!report.seed) {
    for (const PlayerReport& pr : report.players_detail)
      if (pr.seed) report.seed = pr.seed;
  }
  total_players(report);

  players.clear();  // the Streams go before the Runtime and the server
  if (server) server->stop(server->config().drain_timeout);
  return report;
}

}  // namespace grotto::load
