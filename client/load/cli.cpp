// grotto-load's command line (CLI11). Every flag is described in --help; a bad value gives a
// message that names the flag and exit code 2.
#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string_view>

#include "client/load/load.hpp"
#include "client/stream/stream.hpp"
#include "proto/token.hpp"

namespace grotto::load {

namespace {

constexpr const char* kDescription =
    "grotto-load: simulated players walking a Grotto cave over client/stream, measuring what "
    "players get: time to first room, request->room latency, rooms/s and MB/s, stalls (a player "
    "at a portal whose room is not ready), errors, reconnects, drain notices and decode time.\n"
    "Without --server it starts a server in-process on 127.0.0.1.\n"
    "Exit codes: 0 pass; 1 errors (more error messages from the server than --max-errors, a "
    "stream refused for good, a player still reconnecting when the run ends because the server "
    "was lost, --verify failures, or the run could not start; a draining server's "
    "service_restart is a notice, not an error); 2 invalid flags; 3 more stalls than "
    "--max-stalls; 4 a request->room p99 over --max-p99-ms. 1 wins over 3, 3 over 4.";

// A finite double within [lo, hi] (CLI::Range lets NaN through).
std::string check_number(const char* flag, double v, double lo, double hi) {
  if (!std::isfinite(v) || v < lo || v > hi) {
    return std::string(flag) + ": must be a number in [" + CLI::detail::to_string(lo) + ", " +
           CLI::detail::to_string(hi) + "] (got " + CLI::detail::to_string(v) + ")";
  }
  return {};
}

// A decimal unsigned 64-bit integer, the whole text.
std::optional<uint64_t> parse_u64(std::string_view text) {
  uint64_t v = 0;
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || p != end || text.empty()) return std::nullopt;
  return v;
}

}  // namespace

CommandLine parse_command_line(int argc, const char* const* argv) {
  CommandLine out;
  LoadOptions& o = out.options;
  CLI::App app{kDescription, "grotto-load"};
  app.get_formatter()->column_width(30);

  std::string mode = "walk";
  std::string seed_text;
  size_t store_mb = o.store_bytes >> 20;
  app.add_option("--server", o.url,
                 "Server WebSocket url, ws://HOST:PORT[/PATH] (default path /ws); without it a "
                 "server runs in-process on 127.0.0.1")
      ->type_name("URL");
  app.add_option("--mode", mode,
                 "walk: players walk the portal graph; burst: players stand still and want "
                 "everything within --radius at once (ends when all is ready); soak: walk for "
                 "long")
      ->check(CLI::IsMember({"walk", "burst", "soak"}))
      ->capture_default_str();
  app.add_option("--players", o.players, "Simulated players, one Stream (connection) each")
      ->check(CLI::Range(1, 10'000))
      ->capture_default_str();
  app.add_option("--duration", o.duration_s,
                 "Seconds to run (default: walk 20, soak 600; burst: at most 60)")
      ->type_name("SECONDS");
  app.add_option("--speed", o.speed,
                 "Walking speed in m/s; players sprint at 2.5x now and then (--burst-rate)")
      ->capture_default_str();
  app.add_option("--horizon", o.horizon_s,
                 "Prefetch horizon in seconds: rooms reachable within it are requested (walk, "
                 "soak)")
      ->capture_default_str();
  app.add_option("--min-horizon", o.min_horizon_s,
                 "Adaptive prefetch (the default): the horizon follows the latency of the rooms "
                 "due within a second (1 s + 2 x their recent p90) between this and --horizon, "
                 "starting here; 0: the fixed horizon, always --horizon (walk, soak)")
      ->capture_default_str();
  app.add_option("--protocol", o.protocol_version,
                 "Protocol version offered in hello: 0 every version this client speaks (the "
                 "server picks the highest), 1 or 2 that one alone (2 leaves normals out of the "
                 "room payload; proto/PROTOCOL.md)")
      ->check(CLI::Range(0, 2))
      ->capture_default_str();
  app.add_option("--radius", o.radius_m,
                 "burst mode: metres of walking distance wanted around each player")
      ->capture_default_str();
  app.add_option("--seed", seed_text,
                 "World seed (unsigned 64-bit). Embedded server: the world it serves (default "
                 "7); remote: the world asked for (default: the server's)");
  std::string token_file;
  std::string net_text;
  std::string seeds_text;
  app.add_option("--seeds", seeds_text,
                 "Several worlds: comma-separated seeds, player i asks for seed i mod count "
                 "(round-robin); the report counts rooms received per seed. Conflicts with "
                 "--seed; more than one seed needs --server (a server serving many worlds)")
      ->type_name("LIST");
  app.add_option("--token-file", token_file,
                 "File whose first line (trimmed) is the shared-secret token sent in hello "
                 "(1-256 bytes of printable ASCII). Without it $GROTTO_TOKEN is used; with "
                 "neither (or GROTTO_TOKEN empty) no token is sent. The embedded server then "
                 "requires the same token")
      ->type_name("FILE");
  app.add_option("--device", o.device,
                 "Embedded server's OpenCL device: auto, gpu, accelerator, cpu, none (CPU "
                 "reference) or a name substring; empty: $GROTTO_OPENCL_DEVICE, else auto");
  app.add_option("--server-workers", o.server_workers,
                 "Embedded server's generation threads (0: one per hardware thread)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--io-threads", o.io_threads, "Client I/O threads shared by all players")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--decode-workers", o.decode_workers,
                 "Client decode threads shared by all players (0: one per hardware thread)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--rng-seed", o.rng_seed,
                 "Seed of the players' walks (player i uses rng-seed + i): same seed, same "
                 "choices")
      ->capture_default_str();
  app.add_option("--ramp", o.ramp_s,
                 "Players join over this many seconds, player i at i x ramp / players (0: all "
                 "at once); time to first room counts from each player's own join")
      ->check(CLI::Range(0.0, 3600.0))
      ->type_name("SECONDS")
      ->capture_default_str();
  app.add_option("--net", net_text,
                 "Simulate each player's network: rtt=150ms,jitter=20ms,kbps=2000,stall=0.5s/30s "
                 "(each part optional: round trip, jitter without reordering, the player's "
                 "downlink cap in kbit/s, a stall of the link and its period)")
      ->type_name("PROFILE");
  app.add_flag("--spread", o.spread,
               "Player i starts in room 0 of sector (3i, 0, 0) instead of the spawn point, so "
               "players share no rooms (with --server, give --seed or --seeds)");
  app.add_flag("--verify", o.verify,
               "Check every received room (mesh against descriptor), every seam with a received "
               "neighbour (bit-identical rims) and the portal graph; failures exit 1");
  app.add_option("--max-stalls", o.max_stalls,
                 "More stalls than this (all players together) exit 3; -1: no limit")
      ->check(CLI::Range(-1, 1'000'000'000))
      ->capture_default_str();
  app.add_option("--store-mb", store_mb,
                 "Each player's room store in MiB (decoded rooms kept around it; the farthest "
                 "go first): bounds grotto-load's memory at about players x this")
      ->check(CLI::Range(1, 65536))
      ->capture_default_str();
  app.add_option("--max-errors", o.max_errors,
                 "More error messages than this (all players together) exit 1")
      ->check(CLI::Range(0, 1'000'000'000))
      ->capture_default_str();
  app.add_option("--max-p99-ms", o.max_p99_ms,
                 "A request->room latency p99 above this (milliseconds) exits 4; -1: no limit")
      ->capture_default_str();
  app.add_option("--tick-hz", o.tick_hz, "Simulation steps per second")->capture_default_str();
  app.add_option("--turn-back", o.walker.turn_back_chance,
                 "Chance per room entered that a player turns round part-way and goes back")
      ->capture_default_str();
  app.add_option("--burst-rate", o.walker.burst_rate,
                 "Sprints started per second of walking (each 2-5 s at 2.5x speed)")
      ->capture_default_str();
  app.add_option("--json", out.json_path, "Write every figure as JSON to this file")
      ->type_name("FILE");
  app.add_flag("--quiet", out.quiet,
               "No progress line and no table (the progress line is shown only when stderr is "
               "a terminal)");
  app.add_option("--log-level", out.log_level, "Log level on stderr")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}))
      ->capture_default_str();

  auto fail = [&](const std::string& message) {
    out.exit_code = kExitBadFlags;
    out.text = "grotto-load: " + message + " (see --help)";
    return out;
  };
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    out.text = app.help();
    return out;
  } catch (const CLI::ParseError& e) {
    return fail(e.what());
  }

  o.mode = mode == "burst" ? Mode::kBurst : (mode == "soak" ? Mode::kSoak : Mode::kWalk);
  for (const std::string& m : {check_number("--duration", o.duration_s, 0, 1e7),
                               check_number("--speed", o.speed, 0.01, 1000),
                               check_number("--horizon", o.horizon_s, 0.01, 3600),
                               check_number("--min-horizon", o.min_horizon_s, 0, 3600),
                               check_number("--radius", o.radius_m, 0.01, 100'000),
                               check_number("--tick-hz", o.tick_hz, 1, 1000),
                               check_number("--turn-back", o.walker.turn_back_chance, 0, 1),
                               check_number("--burst-rate", o.walker.burst_rate, 0, 100),
                               check_number("--max-p99-ms", o.max_p99_ms, -1, 1e9)}) {
    if (!m.empty()) return fail(m);
  }
  o.store_bytes = store_mb << 20;
  if (!seed_text.empty()) {
    o.seed = parse_u64(seed_text);
    if (!o.seed) {
      return fail("--seed: must be an unsigned 64-bit integer (got '" + seed_text + "')");
    }
  }
  if (!seeds_text.empty()) {
    if (o.seed) return fail("--seeds conflicts with --seed: give one or the other");
    std::string_view rest = seeds_text;
    while (true) {
      std::string_view item = rest.substr(0, rest.find(','));
      auto seed = parse_u64(item);
      if (!seed) {
        return fail("--seeds: '" + std::string(item) +
                    "' is not an unsigned 64-bit integer (expected a list like 7,8,9)");
      }
      o.seeds.push_back(*seed);
      if (item.size() == rest.size()) break;
      rest.remove_prefix(item.size() + 1);
    }
  }
  auto net = parse_net_profile(net_text);
  if (!net) return fail(net.error().message);
  o.net = *net;
  auto token = proto::resolve_token(token_file, std::getenv(proto::kTokenEnvVariable));
  if (!token) return fail(token.error().message);
  o.token = std::move(token).value();
  if (!o.url.empty()) {
    if (auto url = parse_url(o.url); !url) return fail("--server: " + url.error().message);
  }
  if (o.seeds.size() > 1 && o.url.empty()) {
    return fail(
        "--seeds with more than one seed needs --server (the embedded server serves "
        "one world)");
  }
  if (o.spread && !o.url.empty() && !o.seed && o.seeds.empty()) {
    return fail("--spread with --server needs --seed (start rooms are laid out locally)");
  }
  out.run = true;
  return out;
}

}  // namespace grotto::load
