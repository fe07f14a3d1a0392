// grotto-load's engine: N simulated players (walker.hpp), each with its own stream::Stream, all
// sharing one stream::Runtime, against a server given by url or an in-process one. One
// simulation thread ticks every walker in real time and feeds each Stream its pose, exactly as a
// game client's frame loop would; what the Streams measure becomes a LoadReport (report.hpp).
#pragma once
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "client/load/report.hpp"
#include "client/load/walker.hpp"
#include "client/stream/options.hpp"
#include "common/core/result.hpp"

namespace grotto::load {

// grotto-load is a client of client/stream through and through: its names read unqualified.
using namespace grotto::stream;  // NOLINT(google-build-using-namespace)

enum class Mode {
  kWalk,   // players walk the portal graph for duration_s (default 20 s)
  kBurst,  // players stand still and want everything within radius_m at once
  kSoak,   // as walk, for long (default 600 s)
};
const char* mode_name(Mode mode);

// Brace-init runs 4 walking players for 20 s against an embedded server.
struct LoadOptions {
  std::string url;  // ws://host:port/ws; empty: start a server in-process on 127.0.0.1
  Mode mode = Mode::kWalk;
  int players = 4;
  // Players join over this many seconds, player i at i x ramp_s / players (0: all at once, the
  // mass start a fresh replica sees when every player reconnects to it). The run's duration
  // counts from the first join; each player's time to first room from its own.
  double ramp_s = 0;
  double duration_s = 0;   // 0: the mode's default (walk 20, soak 600, burst 60: a bound)
  double speed = 4.0;      // m/s walking (bursts of running: walker.burst_factor)
  double horizon_s = 4.0;  // the Streams' prefetch horizon (walk and soak)
  // Adaptive horizon within [min(this, horizon_s), horizon_s] (StreamOptions::min_horizon_s,
  // the default); 0: the fixed horizon_s.
  double min_horizon_s = kDefaultMinHorizonS;
  uint32_t protocol_version = 0;  // offered in hello: 0 every version, else that one
  double radius_m = 60;           // burst mode: the radius wanted (horizon = radius / speed)
  // The world. Embedded: the seed it serves (absent: ServerConfig's default). Remote: the world
  // asked for in hello (absent: the server's); --spread needs it to lay out the start rooms.
  std::optional<uint64_t> seed;
  // Several worlds (--seeds): player i asks for seeds[i % seeds.size()]; empty: `seed` for all.
  // Exclusive with `seed`; more than one needs a server that serves many worlds (--server).
  std::vector<uint64_t> seeds;
  // The shared secret sent in hello (proto/token.hpp); "": none. The embedded server requires
  // it too when set.
  std::string token;
  std::string device;      // embedded server: OpenCL device (server/config.hpp --opencl-device)
  int server_workers = 0;  // embedded server: generation threads (0: one per hardware thread)
  int io_threads = 1;      // the Runtime's I/O threads
  int decode_workers = 0;  // the Runtime's decode workers (0: one per hardware thread)
  uint64_t rng_seed = 1;   // player i's walker is seeded with rng_seed + i
  bool spread = false;     // player i starts in interior room 0 of sector (3i, 0, 0)
  bool verify = false;     // check every received room, seam and the portal graph
  int max_stalls = -1;     // more stalls than this: exit 3 (-1: no limit)
  int max_errors = 0;      // more error messages than this (all players): exit 1
  // Each player's room store (decoded meshes kept around it): what bounds grotto-load's memory.
  // A player needs the rooms within its horizon, a few MB; a game client keeps far more.
  size_t store_bytes = size_t{8} << 20;
  double max_p99_ms = -1;  // request->room p99 above this: exit 4 (-1: no limit)
  double tick_hz = 20;     // simulation steps per second
  bool progress = false;   // a live progress line on stderr (grotto-load: when it is a TTY)
  WalkerOptions walker{};  // speed is taken from `speed`
  NetProfile net{};        // every player's simulated network (StreamOptions::net); zero: none
};

// Default duration of a mode when duration_s is 0.
double default_duration_s(Mode mode);

// Runs the load and reports it. Errors: invalid options, a url that does not parse, an embedded
// server that cannot start, a Stream that cannot start. Failures *during* the run (errors from
// the server, stalls, verification) are in the report, not errors.
Result<LoadReport> run_load(const LoadOptions& options);

// The players' starts with --spread: player i starts in interior room 0 of sector (3i, 0, 0) of
// its world, seeds[i], at the room's sphere's centre (three sectors apart, players share no rooms
// for a while, so the server's cache does not hide generation). Errors: a seed the layout
// refuses, a sector without an interior room.
Result<std::vector<std::pair<cave::RoomId, Vec3>>> spread_starts(std::span<const uint64_t> seeds);

// The command line (CLI11): options to run with, or text to print and an exit code (0 after
// --help, 2 for an invalid flag: the text names it).
struct CommandLine {
  LoadOptions options;
  std::string json_path;           // --json FILE; empty: none
  std::string log_level = "warn";  // spdlog level
  bool quiet = false;              // no progress line and no table
  bool run = false;
  int exit_code = 0;
  std::string text;
};
CommandLine parse_command_line(int argc, const char* const* argv);

}  // namespace grotto::load
