// The report: nearest-rank percentiles, totals, exit codes, and a JSON document with every figure.
#include "client/load/report.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace {

using grotto::load::Distribution;
using grotto::load::LoadReport;
using grotto::load::percentile;
using grotto::load::PlayerReport;
using grotto::load::summarize;

TEST(Report, percentiles_are_nearest_rank) {
  // The textbook example: 15, 20, 35, 40, 50.
  std::vector<double> s{15, 20, 35, 40, 50};
  EXPECT_EQ(percentile(s, 5), 15);
  EXPECT_EQ(percentile(s, 30), 20);
  EXPECT_EQ(percentile(s, 40), 20);
  EXPECT_EQ(percentile(s, 50), 35);
  EXPECT_EQ(percentile(s, 100), 50);
  EXPECT_EQ(percentile({}, 50), 0);
  EXPECT_EQ(percentile({7}, 99), 7);

  std::vector<double> hundred;
  for (int i = 100; i >= 1; --i)
    hundred.push_back(i);  // unsorted on purpose
  Distribution d = summarize(hundred);
  EXPECT_EQ(d.count, 100u);
  EXPECT_EQ(d.p50, 50);
  EXPECT_EQ(d.p90, 90);
  EXPECT_EQ(d.p99, 99);
  EXPECT_EQ(d.max, 100);
  EXPECT_DOUBLE_EQ(d.mean, 50.5);
  EXPECT_EQ(summarize({}).count, 0u);
}

LoadReport sample_report() {
  LoadReport r;
  r.mode = "walk";
  r.url = "ws://127.0.0.1:1234/ws";
  r.embedded_server = true;
  r.seed = 18446744073709551615ull;
  r.server = "grotto-server 0.3.0";
  r.compute = "cpu: test";
  r.players = 2;
  r.rng_seed = 5;
  r.spread = true;
  r.speed = 4;
  r.horizon_s = 4;
  r.duration_s = 10;
  r.elapsed_s = 10;
  r.latency_ms = summarize({10, 20, 30});
  r.decode_ms = summarize({1, 2});
  r.first_room_ms = summarize({100, 200});
  r.stall_ms = summarize({500, 1500, 1000});
  r.errors = {{"overloaded", 2}, {"not_found", 1}};
  r.rooms_rejected = 4;
  r.drops = 1;
  for (int i = 0; i < 2; ++i) {
    PlayerReport p;
    p.index = i;
    p.first_room_ms = 100 + 100 * i;
    p.rooms_ready = 100 + i;
    p.rooms_received = 110 + i;
    p.bytes = 1'000'000;
    p.mean_kbps = 800;
    p.peak_kbps = 1000 + 500 * i;
    p.requests = 120;
    p.cancels = 7;
    p.rooms_entered = 30;
    p.turn_backs = 2;
    p.distance_m = 40;
    p.stalls = 1 + i;
    p.stall_s = 1.0;
    p.reconnects = i;
    p.restart_notices = 2 * i;
    r.players_detail.push_back(p);
  }
  grotto::load::total_players(r);
  return r;
}

TEST(Report, totals_add_up_the_players_and_rates_use_elapsed_time) {
  LoadReport r = sample_report();
  EXPECT_EQ(r.rooms_ready, 201u);
  EXPECT_EQ(r.rooms_received, 221u);
  EXPECT_EQ(r.bytes, 2'000'000u);
  EXPECT_EQ(r.stalls, 3u);
  EXPECT_DOUBLE_EQ(r.stall_total_s, 2.0);
  EXPECT_EQ(r.reconnects, 1u);
  EXPECT_EQ(r.restart_notices, 2u);
  EXPECT_EQ(r.errors_total, 3u);
  EXPECT_DOUBLE_EQ(r.rooms_per_s, 20.1);
  EXPECT_DOUBLE_EQ(r.mb_per_s, 0.2);
  EXPECT_EQ(r.player_kbps.count, 2u);
  EXPECT_DOUBLE_EQ(r.player_kbps.mean, 800);
  EXPECT_DOUBLE_EQ(r.player_peak_kbps.max, 1500);
  EXPECT_DOUBLE_EQ(r.player_peak_kbps.mean, 1250);
  EXPECT_DOUBLE_EQ(r.rooms_per_room_entered, 221.0 / 60.0);
}

TEST(Report, exit_code_is_1_for_errors_3_for_too_many_stalls_and_errors_win) {
  using grotto::load::exit_code;
  LoadReport r = sample_report();
  EXPECT_EQ(exit_code(r), 1);  // error messages
  r.errors.clear();
  grotto::load::total_players(r);
  EXPECT_EQ(exit_code(r), 0);        // no limit on stalls by default
  ASSERT_GT(r.restart_notices, 0u);  // drain notices are no errors
  r.max_stalls = 3;
  EXPECT_EQ(exit_code(r), 0);
  r.max_stalls = 2;
  EXPECT_EQ(exit_code(r), 3);
  r.verify.enabled = true;
  r.verify.seam_failures = 1;
  EXPECT_EQ(exit_code(r), 1);
  r.verify.seam_failures = 0;
  r.streams_failed = 1;
  EXPECT_EQ(exit_code(r), 1);
  r.streams_failed = 0;
  r.players_detail[0].first_room_ms = -1;  // a player that never got a room
  grotto::load::total_players(r);
  EXPECT_EQ(exit_code(r), 1);
}

TEST(Report, the_gates_errors_lost_server_and_latency) {
  using grotto::load::exit_code;
  LoadReport r = sample_report();
  ASSERT_GT(r.errors_total, 0u);
  EXPECT_EQ(exit_code(r), 1);
  r.max_errors = static_cast<int>(r.errors_total);  // as many as allowed
  EXPECT_EQ(exit_code(r), 0);
  r.players_disconnected = 1;  // the server was lost: an error whatever the other gates say
  EXPECT_EQ(exit_code(r), 1);
  r.players_disconnected = 0;
  r.max_p99_ms = r.latency_ms.p99;  // at the limit passes
  EXPECT_EQ(exit_code(r), 0);
  r.max_p99_ms = r.latency_ms.p99 * 0.5;
  EXPECT_EQ(exit_code(r), 4);
  r.max_stalls = 0;  // stalls win over latency
  ASSERT_GT(r.stalls, 0u);
  EXPECT_EQ(exit_code(r), 3);
}

TEST(Report, json_holds_every_figure) {
  LoadReport r = sample_report();
  r.verify.enabled = true;
  r.verify.rooms_checked = 9;
  r.verify.graph_failures = 1;
  r.verify.first_failures = {"portal 3 disagrees"};
  auto j = nlohmann::json::parse(grotto::load::to_json_text(r));
  EXPECT_EQ(j["tool"], "grotto-load");
  EXPECT_EQ(j["mode"], "walk");
  EXPECT_EQ(j["compute"], "cpu: test");
  EXPECT_EQ(j["seed"], "18446744073709551615");
  EXPECT_EQ(j["players"], 2);
  EXPECT_EQ(j["rng_seed"], "5");
  EXPECT_EQ(j["spread"], true);
  EXPECT_EQ(j["latency_ms"]["p50"], 20);
  EXPECT_EQ(j["latency_ms"]["count"], 3);
  EXPECT_EQ(j["latency_ms"]["p99"], 30);
  EXPECT_EQ(j["decode_ms"]["max"], 2);
  EXPECT_EQ(j["first_room_ms"]["p90"], 200);
  EXPECT_EQ(j["stall_ms"]["p50"], 1000);
  EXPECT_EQ(j["rooms"]["ready"], 201);
  EXPECT_EQ(j["rooms"]["received"], 221);
  EXPECT_EQ(j["rooms"]["rejected"], 4);
  EXPECT_EQ(j["rooms"]["requested"], 240);
  EXPECT_EQ(j["rooms"]["cancelled"], 14);
  EXPECT_EQ(j["bytes"], 2'000'000);
  EXPECT_DOUBLE_EQ(j["rooms_per_s"].get<double>(), 20.1);
  EXPECT_DOUBLE_EQ(j["mb_per_s"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(j["player_kbps"]["mean"].get<double>(), 800);
  EXPECT_DOUBLE_EQ(j["player_peak_kbps"]["max"].get<double>(), 1500);
  EXPECT_DOUBLE_EQ(j["per_player"][1]["peak_kbps"].get<double>(), 1500);
  EXPECT_DOUBLE_EQ(j["rooms_per_room_entered"].get<double>(), 221.0 / 60.0);
  EXPECT_EQ(j["stalls"]["count"], 3);
  EXPECT_DOUBLE_EQ(j["stalls"]["total_s"].get<double>(), 2.0);
  EXPECT_EQ(j["reconnects"], 1);
  EXPECT_EQ(j["restart_notices"], 2);
  EXPECT_EQ(j["per_player"][1]["restart_notices"], 2);
  EXPECT_EQ(j["drops"], 1);
  EXPECT_EQ(j["errors"]["overloaded"], 2);
  EXPECT_EQ(j["errors"]["not_found"], 1);
  EXPECT_EQ(j["errors_total"], 3);
  EXPECT_EQ(j["walk"]["turn_backs"], 4);
  EXPECT_EQ(j["verify"]["rooms_checked"], 9);
  EXPECT_EQ(j["verify"]["failures"], 1);
  EXPECT_EQ(j["verify"]["first_failures"][0], "portal 3 disagrees");
  ASSERT_EQ(j["per_player"].size(), 2u);
  EXPECT_EQ(j["per_player"][1]["rooms_ready"], 101);
  EXPECT_EQ(j["per_player"][1]["stalls"], 2);
  EXPECT_EQ(j["exit_code"], 1);
  r.seed.reset();
  EXPECT_TRUE(nlohmann::json::parse(grotto::load::to_json_text(r))["seed"].is_null());
}

TEST(Report, table_names_the_figures_and_the_outcome) {
  LoadReport r = sample_report();
  std::string t = grotto::load::format_table(r);
  for (const char* s : {"request->room ms", "time to first room", "decode ms", "stall ms",
                        "rooms/s", "MB/s", "player kbit/s (mean)", "player kbit/s (peak s)",
                        "rooms per portal", "overloaded=2", "reconnects", "exit 1"}) {
    EXPECT_NE(t.find(s), std::string::npos) << s << "\n" << t;
  }
}

}  // namespace
