// grotto-load as a user runs it: a real process, its exit codes, its --help, and end to end
// against the embedded server (CPU reference: --device none).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>

#include "client/load/load.hpp"
#include "common/cave/layout.hpp"
#include "server/server.hpp"

namespace {

struct ProcessResult {
  int exit_code;
  std::string output;  // stdout and stderr together
};

ProcessResult run_command(const std::string& command) {
  std::string cmd = command + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  ProcessResult r{-1, {}};
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0)
    r.output.append(buf, n);
  int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

ProcessResult run(const std::string& args) {
  return run_command(std::string("'") + GROTTO_LOAD_BIN + "' " + args);
}

// As run(), with one VAR=value in the environment (and GROTTO_TOKEN otherwise unset).
ProcessResult run_with_env(const std::string& assignment, const std::string& args) {
  return run_command("env -u GROTTO_TOKEN " + assignment + " '" + GROTTO_LOAD_BIN + "' " + args);
}

std::filesystem::path temp_dir(const char* name) {
  auto dir =
      std::filesystem::temp_directory_path() / (std::string(name) + "-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

nlohmann::json read_json(const std::filesystem::path& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return nlohmann::json::parse(ss.str(), nullptr, false);
}

TEST(GrottoLoad, help_describes_every_option) {
  ProcessResult r = run("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag :
       {"--server",     "--mode",           "--players",    "--duration",   "--speed",
        "--horizon",    "--radius",         "--seed",       "--device",     "--server-workers",
        "--io-threads", "--decode-workers", "--rng-seed",   "--spread",     "--verify",
        "--max-stalls", "--tick-hz",        "--turn-back",  "--burst-rate", "--json",
        "--quiet",      "--log-level",      "--token-file", "GROTTO_TOKEN", "--seeds",
        "--ramp",       "Exit codes"}) {
    EXPECT_NE(r.output.find(flag), std::string::npos) << flag;
  }
}

TEST(GrottoLoad, bad_flags_exit_2_with_a_message_naming_the_flag) {
  const std::pair<const char*, const char*> cases[] = {
      {"--players 0", "--players"},
      {"--players many", "--players"},
      {"--speed -1", "--speed"},
      {"--speed nan", "--speed"},
      {"--duration -5", "--duration"},
      {"--mode fly", "--mode"},
      {"--seed -3", "--seed"},
      {"--seed 18446744073709551616", "--seed"},
      {"--server http://example.com/", "--server"},
      {"--max-stalls -2", "--max-stalls"},
      {"--turn-back 2", "--turn-back"},
      {"--store-mb 0", "--store-mb"},
      {"--max-p99-ms -5", "--max-p99-ms"},
      {"--max-errors -1", "--max-errors"},
      {"--spread --server ws://127.0.0.1:1/ws", "--spread"},
      {"--no-such-flag", "--no-such-flag"},
      {"--token-file /nonexistent/grotto-token", "token-file /nonexistent/grotto-token"},
      {"--seeds 7,x", "--seeds: 'x'"},
      {"--seeds 7,,8 --server ws://127.0.0.1:1/ws", "--seeds: ''"},
      {"--seeds 7 --seed 7", "--seeds conflicts with --seed"},
      {"--seeds 7,8", "--seeds with more than one seed needs --server"},
      {"--ramp -1", "--ramp"},
      {"--ramp 5 --duration 5", "--ramp must be shorter than the run"},
      {"--ramp 1 --mode burst", "--ramp is for walk and soak"},
      {"--net rtt=150", "--net: rtt must be a time"},
      {"--net loss=1%", "--net: unknown part 'loss'"},
      {"--net stall=2s/1s", "--net: stall must be"},
  };
  for (const auto& [args, flag] : cases) {
    ProcessResult r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(flag), std::string::npos) << args << ": " << r.output;
  }
}

TEST(GrottoLoad, parse_command_line_fills_the_options) {
  const char* argv[] = {"grotto-load", "--players", "7",        "--mode",   "soak",
                        "--seed",      "42",        "--spread", "--verify", "--max-stalls",
                        "3",           "--json",    "x.json"};
  auto cli = grotto::load::parse_command_line(static_cast<int>(std::size(argv)), argv);
  ASSERT_TRUE(cli.run) << cli.text;
  EXPECT_EQ(cli.options.players, 7);
  EXPECT_EQ(cli.options.mode, grotto::load::Mode::kSoak);
  EXPECT_EQ(cli.options.seed, 42u);
  EXPECT_TRUE(cli.options.spread);
  EXPECT_TRUE(cli.options.verify);
  EXPECT_EQ(cli.options.max_stalls, 3);
  EXPECT_EQ(cli.json_path, "x.json");
  EXPECT_EQ(grotto::load::default_duration_s(cli.options.mode), 600);
}

// The figures of a run's JSON agree with each other and with the players'.
void expect_consistent(const nlohmann::json& j, int players) {
  ASSERT_TRUE(j.is_object());
  ASSERT_EQ(j["per_player"].size(), static_cast<size_t>(players));
  uint64_t ready = 0, received = 0, bytes = 0, stalls = 0, errors = 0;
  for (const auto& p : j["per_player"]) {
    ready += p["rooms_ready"].get<uint64_t>();
    received += p["rooms_received"].get<uint64_t>();
    bytes += p["bytes"].get<uint64_t>();
    stalls += p["stalls"].get<uint64_t>();
    errors += p["errors"].get<uint64_t>();
    EXPECT_GE(p["first_room_ms"].get<double>(), 0) << "every player got its first room";
  }
  EXPECT_EQ(j["rooms"]["ready"].get<uint64_t>(), ready);
  EXPECT_EQ(j["rooms"]["received"].get<uint64_t>(), received);
  // Distinct (world, lod, room): at least one when anything came, at most what came.
  EXPECT_LE(j["rooms"]["unique"].get<uint64_t>(), received);
  EXPECT_EQ(j["rooms"]["unique"].get<uint64_t>() > 0, received > 0);
  EXPECT_EQ(j["bytes"].get<uint64_t>(), bytes);
  EXPECT_EQ(j["stalls"]["count"].get<uint64_t>(), stalls);
  EXPECT_EQ(j["stall_ms"]["count"].get<uint64_t>(), stalls);
  uint64_t by_code = 0;
  for (const auto& [code, n] : j["errors"].items())
    by_code += n.get<uint64_t>();
  EXPECT_EQ(j["errors_total"].get<uint64_t>(), by_code);
  EXPECT_EQ(j["errors_total"].get<uint64_t>(), errors);
  EXPECT_GT(ready, 0u);
  EXPECT_GE(received, ready);
  EXPECT_GT(bytes, 0u);
  EXPECT_GT(j["latency_ms"]["count"].get<uint64_t>(), 0u);
  EXPECT_LE(j["latency_ms"]["count"].get<uint64_t>(), received);
  EXPECT_EQ(j["first_room_ms"]["count"].get<int>(), players);
  const double elapsed = j["elapsed_s"].get<double>();
  EXPECT_NEAR(j["rooms_per_s"].get<double>(), static_cast<double>(ready) / elapsed, 1e-6);
  EXPECT_NEAR(j["mb_per_s"].get<double>(), static_cast<double>(bytes) / 1e6 / elapsed, 1e-9);
}

// Walking speed, 4 s of prefetch: no player may ever wait at a portal (--max-stalls 0 exits 3).
TEST(GrottoLoad, four_players_walk_the_embedded_server_without_errors_or_stalls) {
  auto dir = temp_dir("grotto-load-walk");
  auto json = dir / "out.json";
  ProcessResult r =
      run("--players 4 --duration 5 --device none --server-workers 2 --verify --max-stalls 0 "
          "--json '" +
          json.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("request->room ms"), std::string::npos) << r.output;
  auto j = read_json(json);
  expect_consistent(j, 4);
  EXPECT_EQ(j["errors_total"], 0) << j.dump(2);
  EXPECT_EQ(j["streams_failed"], 0);
  EXPECT_EQ(j["verify"]["failures"], 0) << j["verify"].dump(2);
  EXPECT_GT(j["verify"]["rooms_checked"].get<uint64_t>(), 0u);
  EXPECT_GE(j["elapsed_s"].get<double>(), 5.0);
  EXPECT_GT(j["walk"]["distance_m"].get<double>(), 0);
  // Bandwidth: each player's mean is its bytes over the run, and no whole second beats its peak.
  for (const auto& p : j["per_player"]) {
    const double mean = p["mean_kbps"].get<double>();
    EXPECT_NEAR(mean, p["bytes"].get<double>() * 8 / 1000 / j["elapsed_s"].get<double>(), 1e-6);
    EXPECT_GT(mean, 0);
    EXPECT_GE(p["peak_kbps"].get<double>(), mean);
  }
  EXPECT_EQ(j["player_kbps"]["count"], 4);
  EXPECT_GT(j["rooms_per_room_entered"].get<double>(), 0);
  std::filesystem::remove_all(dir);
}

// Over a simulated network: a 400 ms round trip and a 1 Mbit/s downlink. The first room
// takes the connect, the upgrade, hello, spawn and the request (five round trips: >= 2 s) and the
// frame's time on the link; every room's latency includes a round trip; the report names the
// profile; nothing is lost or refused on the way.
TEST(GrottoLoad, players_over_a_simulated_slow_link_see_its_latency) {
  auto dir = temp_dir("grotto-load-net");
  auto json = dir / "out.json";
  ProcessResult r =
      run("--players 2 --duration 6 --device none --server-workers 2 --verify "
          "--net rtt=400ms,jitter=20ms,kbps=1000 --json '" +
          json.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("simulated network: rtt=400ms,jitter=20ms,kbps=1000"), std::string::npos)
      << r.output;
  auto j = read_json(json);
  EXPECT_EQ(j["net"], "rtt=400ms,jitter=20ms,kbps=1000");
  EXPECT_EQ(j["errors_total"], 0) << j.dump(2);
  EXPECT_EQ(j["verify"]["failures"], 0);
  EXPECT_GE(j["first_room_ms"]["p50"].get<double>(), 2000.0) << j["first_room_ms"].dump();
  EXPECT_GE(j["latency_ms"]["p50"].get<double>(), 400.0) << j["latency_ms"].dump();
  EXPECT_GT(j["rooms"]["ready"].get<uint64_t>(), 2u);
  EXPECT_EQ(j["rooms"]["rejected"], 0);
  std::filesystem::remove_all(dir);
}

// --spread: player i starts in room 0 of sector (3i, 0, 0) of its own world, whatever the other
// players' worlds (one sector each, not every player's sector in every world).
TEST(GrottoLoadSpread, each_player_starts_in_its_sector_of_its_world) {
  const std::vector<uint64_t> seeds = {7, 8, 7, 9, 8};
  auto starts = grotto::load::spread_starts(seeds);
  ASSERT_TRUE(starts.ok()) << starts.error().message;
  ASSERT_EQ(starts->size(), seeds.size());
  for (size_t i = 0; i < seeds.size(); ++i) {
    auto world = grotto::cave::World::create(seeds[i], {}).value();
    auto layout = grotto::cave::generate_sector(world, {3 * static_cast<int>(i), 0, 0});
    ASSERT_FALSE(layout.rooms.empty());
    EXPECT_EQ((*starts)[i].first, layout.rooms[0].id) << "player " << i;
    const grotto::Vec3 at = (*starts)[i].second, centre = layout.rooms[0].sphere.centre;
    EXPECT_TRUE(at.x == centre.x && at.y == centre.y && at.z == centre.z) << "player " << i;
  }
  EXPECT_TRUE(grotto::load::spread_starts({}).ok());
}

// --ramp: player i's Stream starts at i x ramp / players; its time to first room and its mean
// bandwidth count from then, and the per-second latencies hold every sample.
TEST(GrottoLoad, players_join_over_the_ramp) {
  auto dir = temp_dir("grotto-load-ramp");
  auto json = dir / "out.json";
  ProcessResult r =
      run("--players 4 --spread --ramp 2 --duration 4 --device none --server-workers 2 "
          "--max-stalls 0 --json '" +
          json.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("players joined over 2.0 s"), std::string::npos) << r.output;
  auto j = read_json(json);
  expect_consistent(j, 4);
  EXPECT_EQ(j["ramp_s"].get<double>(), 2.0);
  const double elapsed = j["elapsed_s"].get<double>();
  for (int i = 0; i < 4; ++i) {
    const auto& p = j["per_player"][static_cast<size_t>(i)];
    const double joined = p["joined_s"].get<double>();
    EXPECT_GE(joined, 0.5 * i) << "player " << i << " joined before its time";
    EXPECT_LT(joined, 0.5 * i + 0.5) << "player " << i << " joined late";
    EXPECT_NEAR(p["mean_kbps"].get<double>(),
                p["bytes"].get<double>() * 8 / 1000 / (elapsed - joined), 1e-6);
  }
  uint64_t by_second = 0;
  for (const auto& second : j["latency_by_second_ms"])
    by_second += second["count"].get<uint64_t>();
  EXPECT_EQ(by_second, j["latency_ms"]["count"].get<uint64_t>());
  // Players joined until 1.5 s and walked on to 4 s: rooms came in the last seconds too.
  EXPECT_GE(j["latency_by_second_ms"].size(), 4u);
  std::filesystem::remove_all(dir);
}

TEST(GrottoLoad, burst_mode_gets_everything_within_the_radius) {
  auto dir = temp_dir("grotto-load-burst");
  auto json = dir / "out.json";
  ProcessResult r =
      run("--mode burst --players 2 --spread --radius 40 --duration 60 "
          "--device none --server-workers 2 --json '" +
          json.string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  auto j = read_json(json);
  expect_consistent(j, 2);
  EXPECT_GT(j["burst_s"].get<double>(), 0) << j.dump(2);
  EXPECT_LT(j["elapsed_s"].get<double>(), 60);
  for (const auto& p : j["per_player"]) {
    EXPECT_GE(p["burst_complete_s"].get<double>(), 0);
    EXPECT_GT(p["burst_rooms"].get<uint64_t>(), 1u);
    EXPECT_EQ(p["distance_m"].get<double>(), 0) << "burst players stand still";
  }
  EXPECT_NE(j["per_player"][0]["start_room"], j["per_player"][1]["start_room"]);
  std::filesystem::remove_all(dir);
}

TEST(GrottoLoad, a_server_that_is_not_there_is_an_error_not_a_hang) {
  // A port nothing listens on: the Streams keep reconnecting; the run ends at its duration with
  // no room and no player started, which is a failed gate (not 0).
  ProcessResult r = run("--server ws://127.0.0.1:1/ws --players 1 --duration 1 --quiet");
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.exit_code, 2) << r.output;
}

// A server in this process on 127.0.0.1 (seed 7 alone, CPU reference), requiring `token` if not
// empty.
grotto::Result<std::unique_ptr<grotto::server::Server>> start_server(const std::string& token) {
  grotto::server::ServerConfig c;
  c.generator.max_worlds = 1;
  c.port = 0;
  c.io_threads = 1;
  c.generator.workers = 2;
  c.generator.builder.device.device = "none";
  c.log_level = "off";
  c.token = token;
  return grotto::server::Server::start(c);
}

// A server lost mid-run is a failure by default (exit 1, named in the table), not a pass; a
// latency gate no run can meet exits 4.
TEST(GrottoLoad, a_server_lost_mid_run_fails_and_the_latency_gate_exits_4) {
  auto server = start_server("");
  ASSERT_TRUE(server.ok()) << server.error().message;
  std::string url = "--server ws://127.0.0.1:" + std::to_string((*server)->port()) + "/ws ";
  ProcessResult strict = run(url + "--players 2 --duration 2 --max-p99-ms 0.000001");
  EXPECT_EQ(strict.exit_code, 4) << strict.output;
  EXPECT_NE(strict.output.find("latency p99 over --max-p99-ms"), std::string::npos)
      << strict.output;
  ProcessResult lost;
  std::thread load([&] { lost = run(url + "--players 2 --duration 4"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  (*server)->stop(std::chrono::milliseconds(0));
  load.join();
  EXPECT_EQ(lost.exit_code, 1) << lost.output;
  EXPECT_NE(lost.output.find("not connected at the end"), std::string::npos) << lost.output;
}

// A server that wants a token: grotto-load with the right one (from --token-file, or from
// GROTTO_TOKEN) passes; without it or with a wrong one every stream is refused (exit 1).
TEST(GrottoLoad, sends_the_token_from_its_file_or_the_environment) {
  auto server = start_server("load-secret");
  ASSERT_TRUE(server.ok()) << server.error().message;
  auto dir = temp_dir("grotto-load-token");
  auto file = dir / "token";
  std::ofstream(file) << "load-secret\n";
  std::string common = "--server ws://127.0.0.1:" + std::to_string((*server)->port()) +
                       "/ws --players 1 --duration 2 --quiet ";
  ProcessResult from_file =
      run_with_env("GROTTO_TOKEN=ignored", "--token-file '" + file.string() + "' " + common);
  EXPECT_EQ(from_file.exit_code, 0) << from_file.output;
  ProcessResult from_env = run_with_env("GROTTO_TOKEN=load-secret", common);
  EXPECT_EQ(from_env.exit_code, 0) << from_env.output;
  ProcessResult none = run_with_env("GROTTO_TOKEN=", common);  // empty: no token sent
  EXPECT_EQ(none.exit_code, 1) << none.output;
  EXPECT_NE(none.output.find("unauthorized"), std::string::npos) << none.output;
  ProcessResult wrong = run_with_env("GROTTO_TOKEN=load-secreT", common);
  EXPECT_EQ(wrong.exit_code, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("unauthorized"), std::string::npos) << wrong.output;
  std::filesystem::remove_all(dir);
}

// --seeds: players take the seeds round-robin and the report counts rooms per seed. Against a
// server of one world (seed 7), the players asking for seed 8 are refused (world_mismatch) and
// receive nothing, those of seed 7 stream.
TEST(GrottoLoad, seeds_are_assigned_round_robin_and_rooms_counted_per_seed) {
  const char* argv[] = {"grotto-load", "--seeds", "7,8,18446744073709551615", "--server",
                        "ws://127.0.0.1:1/ws"};
  auto cli = grotto::load::parse_command_line(static_cast<int>(std::size(argv)), argv);
  ASSERT_TRUE(cli.run) << cli.text;
  EXPECT_EQ(cli.options.seeds, (std::vector<uint64_t>{7, 8, 18446744073709551615ull}));
  EXPECT_FALSE(cli.options.seed.has_value());

  auto server = start_server("");
  ASSERT_TRUE(server.ok()) << server.error().message;
  auto dir = temp_dir("grotto-load-seeds");
  auto json = dir / "out.json";
  ProcessResult r =
      run("--server ws://127.0.0.1:" + std::to_string((*server)->port()) +
          "/ws --seeds 7,8 --players 4 --duration 2 --quiet --json '" + json.string() + "'");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  auto j = read_json(json);
  ASSERT_TRUE(j.is_object()) << r.output;
  ASSERT_EQ(j["per_player"].size(), 4u);
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ(j["per_player"][i]["seed"], i % 2 == 0 ? "7" : "8") << i;
  EXPECT_GT(j["rooms_received_by_seed"]["7"].get<uint64_t>(), 0u) << j.dump(2);
  EXPECT_EQ(j["rooms_received_by_seed"]["8"].get<uint64_t>(), 0u) << j.dump(2);
  EXPECT_EQ(j["rooms_received_by_seed"]["7"].get<uint64_t>(),
            j["rooms"]["received"].get<uint64_t>());
  EXPECT_EQ(j["errors"]["world_mismatch"].get<uint64_t>(), 2u) << j["errors"].dump();
  // Players 0 and 2 start in the same room of world 7: their rooms count once in rooms.unique.
  EXPECT_LT(j["rooms"]["unique"].get<uint64_t>(), j["rooms"]["received"].get<uint64_t>());
  std::filesystem::remove_all(dir);
}

}  // namespace
