// What grotto-load measured, as plain data, and its three outputs: the final table for people,
// the JSON document (--json) for scripts and CI, and the exit code that gates a deployment.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace grotto::load {

// Nearest-rank percentile of ascending `sorted` samples: the smallest sample with at least p% of
// the samples at or below it (p in (0, 100]). 0 for no samples.
double percentile(const std::vector<double>& sorted, double p);

struct Distribution {
  uint64_t count = 0;
  double mean = 0, p50 = 0, p90 = 0, p99 = 0, max = 0;
};
// Summarises samples in any order (nearest rank).
Distribution summarize(std::vector<double> samples);

// One simulated player.
struct PlayerReport {
  int index = 0;
  std::optional<uint64_t> seed;  // the world it asked for, else the one the server served
  std::string start_room;        // text id; empty when the player never got a start
  double joined_s = 0;           // when its Stream started, seconds into the run (--ramp)
  double first_room_ms = -1;     // its join → start room ready; -1: never
  uint64_t rooms_ready = 0;      // rooms decoded and stored by its Stream
  uint64_t rooms_received = 0;   // room frames accepted
  uint64_t bytes = 0;            // bytes received
  double mean_kbps = 0;          // bytes x 8 / 1000 over the time since it joined
  double horizon_s = 0;          // the prefetch horizon in use at the end (--min-horizon)
  double peak_kbps = 0;          // the most received in one whole second of the run, x 8 / 1000
  uint64_t requests = 0;         // rooms requested
  uint64_t cancels = 0;          // rooms cancelled
  uint64_t rooms_entered = 0;    // portals crossed by the walker
  uint64_t turn_backs = 0;
  double distance_m = 0;
  uint64_t stalls = 0;  // finished and open
  double stall_s = 0;   // their total time
  uint64_t reconnects = 0;
  uint64_t restart_notices = 0;  // service_restart notices of draining servers (not errors)
  double queued_ms = 0;          // time spent in servers' admission queues (PROTOCOL.md `queued`)
  uint64_t times_queued = 0;     // connections that waited in one before their welcome
  bool queued_at_end = false;    // still waiting when the run ended (not an error)
  uint64_t errors = 0;           // error messages received
  std::string state;             // the Stream's state at the end
  std::string last_error;        // its last error at the end, for people (empty: none)
  double burst_complete_s = -1;  // burst mode: everything within the radius ready; -1: not
  uint64_t burst_rooms = 0;      // burst mode: rooms within the radius (the last plan)
};

struct VerifyReport {
  bool enabled = false;
  uint64_t rooms_checked = 0;
  uint64_t seams_checked = 0;
  uint64_t room_failures = 0;   // verify_room
  uint64_t seam_failures = 0;   // verify_seam
  uint64_t graph_failures = 0;  // PortalGraph::add: portals that disagree with a neighbour
  std::vector<std::string> first_failures;  // the first few messages
  uint64_t failures() const { return room_failures + seam_failures + graph_failures; }
};

struct LoadReport {
  // What was run.
  std::string mode;  // walk, burst, soak
  std::string url;
  bool embedded_server = false;
  std::optional<uint64_t> seed;  // the world asked for or served embedded; absent: the server's
  std::string server;            // welcome.server
  std::string compute;           // embedded server: its compute path ("opencl: ..." or "cpu: ...")
  int players = 0;
  uint64_t rng_seed = 0;    // the walks' seed (player i: rng_seed + i)
  bool spread = false;      // players started in sectors (3i, 0, 0) instead of the spawn point
  std::string net = "off";  // the simulated network, as --net takes it (net_sim.hpp)
  double speed = 0;
  double horizon_s = 0;
  double radius_m = 0;    // burst mode
  double duration_s = 0;  // asked for
  double ramp_s = 0;      // players joined over this (0: all at once)
  double elapsed_s = 0;   // measured, start of the run to the Streams' stop

  // Figures over all players.
  Distribution first_room_ms;  // per player, the players who got one
  Distribution latency_ms;     // request → room frame, every sample
  // The same for rooms requested due within a second (kUrgentPriorityMs): the room a player walks
  // into next, which goes before far prefetch at every stage
  Distribution urgent_latency_ms;
  // The same samples by the second of the run in which the room was taken from its Stream
  // (index 0: [0, 1) s): where in the run the tail is, e.g. the start of a crowd.
  std::vector<Distribution> latency_by_second_ms;
  Distribution decode_ms;
  Distribution stall_ms;  // every stall (finished or open at the end)
  uint64_t rooms_ready = 0, rooms_received = 0, rooms_rejected = 0, rooms_evicted = 0,
           rooms_given_up = 0, requests = 0, cancels = 0, bytes = 0;
  // Distinct (world, lod, room) the players received, whoever and however often: what a cluster
  // had to build at least (compare the replicas' grotto_rooms_built_total).
  uint64_t rooms_unique = 0;
  double rooms_per_s = 0, mb_per_s = 0;  // rooms_ready and bytes over elapsed_s (MB = 10^6 B)
  // Bandwidth per player in kbit/s (1000 bit/s): each player's mean over the run, and each
  // player's peak second (the sample is one per player).
  Distribution player_kbps, player_peak_kbps;
  // Prefetch waste: rooms received per portal crossed (0 with no crossing). 1 means each room
  // arrived once and was entered; prefetch asks for rooms the player may not take, so it is more.
  double rooms_per_room_entered = 0;
  Distribution final_horizon_s;  // each player's horizon at the end (adaptive with --min-horizon)
  double min_horizon_s = 0;
  uint32_t protocol_version = 0;  // offered (0: every version the client speaks)
  uint64_t stalls = 0;
  double stall_total_s = 0;
  uint64_t reconnects = 0, drops = 0, streams_failed = 0;
  uint64_t restart_notices = 0;       // servers that drained gracefully under a player (not errors)
  uint64_t players_without_room = 0;  // never got their start room (counts as an error)
  uint64_t players_disconnected = 0;  // not connected when the run ended: server lost (an error)
  std::map<std::string, uint64_t> errors;  // error messages by wire code
  uint64_t errors_total = 0;
  std::map<uint64_t, uint64_t> rooms_received_by_seed;  // players that named a seed, by seed
  uint64_t rooms_entered = 0, turn_backs = 0;
  double distance_m = 0;
  double burst_s = -1;  // burst mode: time until every player had its radius ready; -1: not
  VerifyReport verify;
  // Servers past their capacity hold newcomers in a queue (PROTOCOL.md, "Waiting to enter").
  struct Queue {
    uint64_t players = 0;  // players that waited at least once
    uint64_t at_end = 0;   // players still waiting when the run ended (neither an error nor
                           // counted among players_without_room or players_disconnected)
    Distribution ms;       // their total time queued
    // By second of the run: players waiting then, and the longest queue a server reported.
    std::vector<uint64_t> waiting_by_second;
    std::vector<uint64_t> length_by_second;
  } queued;
  std::vector<PlayerReport> players_detail;

  // The gates: stalls (-1: no limit), error messages, request->room p99 (-1: no limit).
  int max_stalls = -1;
  int max_errors = 0;
  double max_p99_ms = -1;
};

// Sums the players into the totals (rooms, bytes, stalls, ...) and derives the rates; leaves the
// distributions and errors (filled from raw samples) alone.
void total_players(LoadReport& report);

// Exit codes: 0 pass, 1 errors (more error messages than max_errors, a Stream that failed for
// good, a player that never got its start room or was not connected at the end because the server
// was lost, verification failures), 3 more stalls than max_stalls, 4 a request->room p99 over
// max_p99_ms; 1 wins over 3, 3 over 4.
inline constexpr int kExitOk = 0;
inline constexpr int kExitErrors = 1;
inline constexpr int kExitBadFlags = 2;
inline constexpr int kExitStalls = 3;
inline constexpr int kExitLatency = 4;
int exit_code(const LoadReport& report);

std::string format_table(const LoadReport& report);
// The JSON document: every figure of the report, exit_code included.
std::string to_json_text(const LoadReport& report);

}  // namespace grotto::load
