// Admission past capacity without sockets (server/admission.hpp): each row feeds the queue a
// script of events on a simulated clock and checks the actions it returned, as lines of text.
// Events: "enter 3 q" (session 3 said hello and can wait in the queue), "enter 3" (it cannot),
// "enter 10-309 q" (sessions 10 to 309, one after another), "leave 3", "measure 300" (the oldest
// urgent want is 300 ms old), "measure 0 backlog=9000", "later 500" (the clock moves on).
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "server/admission.hpp"

namespace grotto::server {
namespace {

using namespace std::chrono_literals;

std::string describe(const AdmissionAction& action) {
  struct Visitor {
    std::string operator()(const adm::Admit& a) { return "admit " + std::to_string(a.session); }
    std::string operator()(const adm::Queued& a) {
      return "queued " + std::to_string(a.session) + " pos=" + std::to_string(a.position) +
             " wait=" + std::to_string(a.wait_ms) + " of=" + std::to_string(a.queue);
    }
    std::string operator()(const adm::Refuse& a) {
      return "refuse " + std::to_string(a.session) + " retry=" + std::to_string(a.retry_after_ms) +
             (a.queue_full ? " full" : " no_queue");
    }
  };
  return std::visit(Visitor{}, action);
}

// Runs `events` and returns every action, in order.
std::vector<std::string> run(AdmissionQueue& q, const std::vector<std::string>& events) {
  AdmissionTime now{};
  std::vector<std::string> out;
  for (const std::string& e : events) {
    std::istringstream in(e);
    std::string verb;
    in >> verb;
    if (verb == "enter") {
      std::string ids, flag;
      in >> ids >> flag;
      const auto dash = ids.find('-');
      const uint64_t first = std::stoull(ids.substr(0, dash));
      const uint64_t last = dash == std::string::npos ? first : std::stoull(ids.substr(dash + 1));
      for (uint64_t id = first; id <= last; ++id)
        q.enter(id, flag == "q", now);
    } else if (verb == "leave") {
      uint64_t id = 0;
      in >> id;
      q.leave(id, now);
    } else if (verb == "measure") {
      int64_t ms = 0;
      std::string backlog;
      in >> ms >> backlog;
      AdmissionSample s;
      s.oldest_urgent = std::chrono::milliseconds{ms};
      s.oldest_want = s.oldest_urgent;
      if (backlog.starts_with("backlog=")) s.send_backlog_bytes = std::stoull(backlog.substr(8));
      q.measure(s, now);
    } else if (verb == "later") {
      int64_t ms = 0;
      in >> ms;
      now += std::chrono::milliseconds{ms};
    } else {
      ADD_FAILURE() << "unknown event " << e;
    }
    for (const AdmissionAction& a : q.take())
      out.push_back(describe(a));
  }
  return out;
}

AdmissionConfig small() {
  AdmissionConfig c;
  c.max_queue = 2;
  c.late_after = 250ms;
  c.caught_up_below = 100ms;
  c.window = 1000ms;
  c.admit_per_measurement = 1;
  c.burst_start = 2;
  c.rate_window = 10'000ms;
  c.unmeasured_wait = 2'000ms;
  c.update_every = 1'000ms;
  c.min_retry = 1'000ms;
  c.max_retry = 60'000ms;
  c.max_send_backlog_bytes = 8000;
  return c;
}

struct Row {
  const char* name;
  std::vector<std::string> events;
  std::vector<std::string> actions;
};

TEST(Admission, rules_by_table) {
  const std::vector<Row> rows = {
      {"in time, everyone enters at once, queue or not",
       {"enter 1 q", "enter 2", "measure 200", "enter 3"},
       {"admit 1", "admit 2", "admit 3"}},
      {"behind, a client that can wait is queued with its place and estimate",
       {"enter 1", "measure 250", "enter 2 q", "enter 3 q"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2"}},
      {"behind, a client that cannot wait is refused with a retry, never left silent",
       {"enter 1", "measure 300", "enter 2"},
       {"admit 1", "refuse 2 retry=2000 no_queue"}},
      {"past max_queue a newcomer is refused though it could wait",
       {"enter 1", "measure 300", "enter 2 q", "enter 3 q", "enter 4 q"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2",
        "refuse 4 retry=6000 full"}},
      {"admitted players are never dropped, however late the service",
       {"enter 1", "enter 2", "measure 5000", "later 1000", "measure 9000", "enter 3 q"},
       {"admit 1", "admit 2", "queued 3 pos=1 wait=2000 of=1"}},
      {"a player leaving lets the head in at once, even while behind",
       {"enter 1", "measure 300", "enter 2 q", "enter 3 q", "later 1000", "leave 1"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2", "admit 2",
        "queued 3 pos=1 wait=10000 of=1"}},
      {"hysteresis: one young sample does not end behind; a window of them does",
       {"enter 1", "measure 300", "enter 2 q", "later 250", "measure 50", "later 250",
        "measure 150", "later 250", "measure 50", "later 500", "measure 50", "later 500",
        "measure 50"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "admit 2"}},
      {"between the thresholds nothing flips: not behind stays not behind",
       {"enter 1", "measure 200", "later 250", "measure 240", "enter 2"},
       {"admit 1", "admit 2"}},
      {"caught up, the queue comes in a few a measurement, first come first",
       {"enter 1", "measure 300", "enter 2 q", "enter 3 q", "later 100", "measure 0", "later 1000",
        "measure 0", "later 250", "measure 0"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2", "admit 2",
        "queued 3 pos=1 wait=10000 of=1", "admit 3"}},
      {"nobody passes the queue: a newcomer waits behind it even once caught up",
       {"enter 1", "measure 300", "enter 2 q", "enter 3 q", "later 1000", "measure 0", "later 1000",
        "measure 0", "enter 4 q"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2", "admit 2",
        "queued 3 pos=1 wait=10000 of=1", "queued 4 pos=2 wait=20000 of=2"}},
      {"a send backlog over its bound is behind too",
       {"enter 1", "measure 0 backlog=9000", "enter 2 q"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1"}},
      {"a queued session leaving moves those behind it up, told at most once a second",
       {"enter 1", "measure 300", "enter 2 q", "enter 3 q", "leave 2", "later 1000", "measure 300"},
       {"admit 1", "queued 2 pos=1 wait=2000 of=1", "queued 3 pos=2 wait=4000 of=2",
        "queued 3 pos=1 wait=2000 of=1"}},
      {"the estimate follows the measured admission rate",
       {"enter 1", "enter 2", "measure 300", "enter 3 q", "enter 4 q", "leave 1", "leave 2",
        "enter 5 q", "enter 6 q"},
       {"admit 1", "admit 2", "queued 3 pos=1 wait=2000 of=1", "queued 4 pos=2 wait=4000 of=2",
        "admit 3", "admit 4", "queued 5 pos=1 wait=5000 of=1", "queued 6 pos=2 wait=10000 of=2"}},
  };
  for (const Row& row : rows) {
    AdmissionQueue q(small());
    EXPECT_EQ(run(q, row.events), row.actions) << row.name;
  }
}

TEST(Admission, max_players_bounds_the_players_however_well_served) {
  AdmissionConfig c = small();
  c.max_players = 2;
  const std::vector<Row> rows = {
      {"the third waits though the service is quick",
       {"enter 1", "enter 2 q", "measure 0", "enter 3 q", "later 1000", "measure 0"},
       {"admit 1", "admit 2", "queued 3 pos=1 wait=2000 of=1"}},
      {"a player leaving lets it in",
       {"enter 1", "enter 2", "enter 3 q", "leave 2"},
       {"admit 1", "admit 2", "queued 3 pos=1 wait=2000 of=1", "admit 3"}},
      {"one that cannot wait is refused",
       {"enter 1", "enter 2", "enter 3"},
       {"admit 1", "admit 2", "refuse 3 retry=2000 no_queue"}},
  };
  for (const Row& row : rows) {
    AdmissionQueue q(c);
    EXPECT_EQ(run(q, row.events), row.actions) << row.name;
  }
}

TEST(Admission, capacity_is_what_was_admitted_when_it_fell_behind) {
  AdmissionConfig c = small();
  c.burst_start = 16;
  AdmissionQueue q(c);
  run(q, {"enter 1", "enter 2", "enter 3", "measure 100", "measure 400", "enter 4 q"});
  EXPECT_TRUE(q.behind());
  EXPECT_EQ(q.capacity(), 3u);
  EXPECT_EQ(q.admitted(), 3u);
  EXPECT_EQ(q.queued(), 1u);
}

// The burst budget with the defaults (burst_start 16, admit_per_measurement 2, 250 ms
// measurements): each step is one event and what came of it, summed up ("measure 50 want=300":
// the oldest urgent want 50 ms old, the oldest of any kind 300; without want= both the same):
// "admit 17-48" (the sessions admitted, in order, consecutive ids joined), "queued 284" (how many
// Queued went out), "refuse 2", then the budget after it: "burst=32".
std::string summary(AdmissionQueue& q, const std::string& event, AdmissionTime& now) {
  std::istringstream in(event);
  std::string verb;
  in >> verb;
  if (verb == "later") {
    int64_t ms = 0;
    in >> ms;
    now += std::chrono::milliseconds{ms};
  } else if (verb == "measure") {
    int64_t ms = 0;
    std::string want;
    in >> ms >> want;
    AdmissionSample sample;
    sample.oldest_urgent = std::chrono::milliseconds{ms};
    sample.oldest_want = sample.oldest_urgent;
    if (want.starts_with("want="))
      sample.oldest_want = std::chrono::milliseconds{std::stoll(want.substr(5))};
    q.measure(sample, now);
  } else if (verb == "enter") {
    std::string ids, flag;
    in >> ids >> flag;
    const auto dash = ids.find('-');
    const uint64_t first = std::stoull(ids.substr(0, dash));
    const uint64_t last = dash == std::string::npos ? first : std::stoull(ids.substr(dash + 1));
    for (uint64_t id = first; id <= last; ++id)
      q.enter(id, flag == "q", now);
  } else if (verb == "leave") {
    uint64_t id = 0;
    in >> id;
    q.leave(id, now);
  } else {
    ADD_FAILURE() << "unknown event " << event;
  }
  std::string out;
  std::vector<uint64_t> admits;
  size_t queued = 0, refused = 0;
  for (const AdmissionAction& a : q.take()) {
    if (auto* admit = std::get_if<adm::Admit>(&a)) admits.push_back(admit->session);
    if (std::holds_alternative<adm::Queued>(a)) ++queued;
    if (std::holds_alternative<adm::Refuse>(a)) ++refused;
  }
  for (size_t i = 0; i < admits.size();) {
    size_t j = i;
    while (j + 1 < admits.size() && admits[j + 1] == admits[j] + 1)
      ++j;
    out += "admit " + std::to_string(admits[i]) +
           (j > i ? "-" + std::to_string(admits[j]) : std::string{}) + "; ";
    i = j + 1;
  }
  if (queued > 0) out += "queued " + std::to_string(queued) + "; ";
  if (refused > 0) out += "refuse " + std::to_string(refused) + "; ";
  return out + "burst=" + std::to_string(q.burst());
}

struct BurstRow {
  const char* name;
  std::vector<std::pair<std::string, std::string>> steps;  // event, what came of it
};

TEST(AdmissionBurst, the_budget_follows_the_measurements_by_table) {
  const std::vector<BurstRow> rows = {
      {"a crowd at once: the first burst enters, the rest queue and come in a budget a time",
       {{"measure 0", "burst=16"},
        {"later 250", "burst=16"},
        {"measure 0", "burst=16"},  // an idle interval is no evidence: the budget stays
        {"enter 1-300 q", "admit 1-16; queued 284; burst=16"},
        {"later 250", "burst=16"},
        {"measure 50", "admit 17-32; burst=16"},
        {"later 250", "burst=16"},
        {"measure 50", "admit 33-48; burst=16"},
        {"later 250", "burst=16"},
        {"measure 50", "admit 49-64; burst=16"},
        {"later 250", "burst=16"},
        // A window of used-up budgets and young measurements: it doubles. Those waiting hear
        // their new places (a second since they were last told).
        {"measure 50", "admit 65-96; queued 204; burst=32"},
        {"later 250", "burst=32"},
        // Between young and late: no evidence for more, none for less.
        {"measure 150", "admit 97-128; burst=32"},
        {"later 250", "burst=32"},
        {"measure 300", "burst=16"},  // behind: it halves, and the queue waits
        {"later 250", "burst=16"},
        {"measure 400", "burst=16"},  // still behind: the same excess, halved once
        {"enter 301 q", "queued 1; burst=16"}}},
      {"caught up after falling behind, the queue drains at the halved budget",
       {{"measure 0", "burst=16"},
        {"enter 1-40 q", "admit 1-16; queued 24; burst=16"},
        {"later 250", "burst=16"},
        {"measure 300", "burst=8"},
        {"later 250", "burst=8"},
        {"measure 50", "burst=8"},
        {"later 500", "burst=8"},
        {"measure 50", "burst=8"},
        {"later 500", "burst=8"},
        {"measure 50", "admit 17-24; queued 16; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50", "admit 25-32; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50", "admit 33-40; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50", "burst=8"},
        {"later 250", "burst=8"},
        {"measure 50", "burst=8"},  // the queue is empty: a budget not used does not grow
        {"enter 41-60 q", "admit 41-48; queued 12; burst=8"}}},
      {"falling behind again and again halves it down to admit_per_measurement, never below",
       {{"enter 1 q", "admit 1; burst=16"},
        {"measure 300", "burst=8"},
        {"later 1000", "burst=8"},
        {"measure 0", "burst=8"},
        {"later 1000", "burst=8"},
        {"measure 0", "burst=8"},
        {"measure 300", "burst=4"},
        {"later 1000", "burst=4"},
        {"measure 0", "burst=4"},
        {"later 1000", "burst=4"},
        {"measure 0", "burst=4"},
        {"measure 300", "burst=2"},
        {"later 1000", "burst=2"},
        {"measure 0", "burst=2"},
        {"later 1000", "burst=2"},
        {"measure 0", "burst=2"},
        {"measure 300", "burst=2"}}},
      {"a steady trickle under the budget is never queued, and does not grow it",
       {{"measure 0", "burst=16"},
        {"enter 1-10 q", "admit 1-10; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 11-20 q", "admit 11-20; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 21-35 q", "admit 21-35; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 36-51 q", "admit 36-51; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"}}},
      {"arrivals that use the budget up, young for a window, double it; one slow sample resets",
       {{"measure 0", "burst=16"},
        {"enter 1-16 q", "admit 1-16; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 17-32 q", "admit 17-32; burst=16"},
        {"later 250", "burst=16"},
        {"measure 120", "burst=16"},  // not young: the window starts again
        {"enter 33-48 q", "admit 33-48; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 49-64 q", "admit 49-64; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 65-80 q", "admit 65-80; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=16"},
        {"enter 81-96 q", "admit 81-96; burst=16"},
        {"later 250", "burst=16"},
        {"measure 20", "burst=32"},
        {"enter 97-128 q", "admit 97-128; burst=32"}}},
      {"slow prefetch halves the budget, once a run, without holding the queue; growth needs it "
       "quick",
       {{"measure 0", "burst=16"},
        {"enter 1-40 q", "admit 1-16; queued 24; burst=16"},
        {"later 250", "burst=16"},
        {"measure 50 want=300", "admit 17-24; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50 want=400", "admit 25-32; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50 want=150", "admit 33-40; burst=8"},  // neither slow nor quick: no change
        {"enter 41-60 q", "queued 20; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50 want=50", "admit 41-48; burst=8"},
        {"later 250", "burst=8"},
        {"measure 50 want=300", "admit 49-52; burst=4"}}},
      {"a leaver's place goes to the queue's head at once, past the budget too",
       {{"measure 0", "burst=16"},
        {"enter 1-20 q", "admit 1-16; queued 4; burst=16"},
        {"leave 3", "admit 17; burst=16"},
        {"enter 21", "refuse 1; burst=16"},  // cannot wait: refused, never left silent
        {"later 250", "burst=16"},
        {"measure 0", "admit 18-20; burst=16"}}},
  };
  for (const BurstRow& row : rows) {
    AdmissionQueue q{AdmissionConfig{}};
    AdmissionTime now{};
    size_t step = 0;
    for (const auto& [event, expected] : row.steps) {
      EXPECT_EQ(summary(q, event, now), expected) << row.name << ", step " << step << ": " << event;
      ++step;
    }
  }
}

// What a queued member of a crowd is told: its place and, before anyone has been admitted from
// the queue, a wait of one measurement interval for each budget ahead of it.
TEST(AdmissionBurst, a_crowd_is_told_places_and_waits_by_the_budget) {
  AdmissionQueue q{AdmissionConfig{}};
  AdmissionTime now{};
  q.measure({}, now);
  now += 250ms;
  q.measure({}, now);
  for (uint64_t id = 1; id <= 300; ++id)
    q.enter(id, true, now);
  std::vector<std::string> lines;
  for (const AdmissionAction& a : q.take())
    lines.push_back(describe(a));
  ASSERT_EQ(lines.size(), 300u);
  EXPECT_EQ(lines[15], "admit 16");
  EXPECT_EQ(lines[16], "queued 17 pos=1 wait=250 of=1");
  EXPECT_EQ(lines[31], "queued 32 pos=16 wait=250 of=16");
  EXPECT_EQ(lines[32], "queued 33 pos=17 wait=500 of=17");
  EXPECT_EQ(lines[299], "queued 300 pos=284 wait=4500 of=284");
  EXPECT_EQ(q.admitted(), 16u);
  EXPECT_EQ(q.queued(), 284u);
  EXPECT_EQ(q.burst_left(), 0u);
  EXPECT_FALSE(q.behind());
  EXPECT_EQ(q.capacity(), 0u);  // never behind: nothing measured as the most it holds
}

// A balancer's question at the door (redirect_newcomer): a row is the server's state in a few
// words and the reason the newcomer is sent on. Words: "stopping", "players=N", "handshakes=N",
// "admission" (on, with "admitted=N", "queued=N", "max_players=N", "behind", "burst_left=N");
// max_connections is 10, max_handshakes 4 and burst_left 100 unless a row says otherwise.
Door door_of(const std::string& words) {
  Door d;
  d.max_connections = 10;
  d.max_handshakes = 4;
  d.burst_left = 100;
  std::istringstream in(words);
  std::string w;
  while (in >> w) {
    const auto eq = w.find('=');
    const std::string key = w.substr(0, eq);
    const size_t n = eq == std::string::npos ? 0 : std::stoul(w.substr(eq + 1));
    if (key == "stopping") {
      d.stopping = true;
    } else if (key == "players") {
      d.players = n;
    } else if (key == "handshakes") {
      d.handshakes = n;
    } else if (key == "admission") {
      d.admission = true;
    } else if (key == "admitted") {
      d.admitted = n;
    } else if (key == "queued") {
      d.queued = n;
    } else if (key == "max_players") {
      d.max_players = n;
    } else if (key == "behind") {
      d.behind = true;
    } else if (key == "burst_left") {
      d.burst_left = n;
    } else {
      ADD_FAILURE() << "unknown word " << w;
    }
  }
  return d;
}

TEST(AdmissionRedirect, a_balancers_newcomer_is_sent_on_by_table) {
  struct RedirectRow {
    const char* name;
    const char* door;
    const char* reason;
  };
  const std::vector<RedirectRow> rows = {
      {"an idle server takes it", "", "none"},
      {"room for players, admission off: taken", "players=9", "none"},
      {"room under max_players, nobody waiting, in time: taken",
       "players=1 admission admitted=1 max_players=2", "none"},
      {"draining: sent on, whatever else holds", "stopping players=1 admission queued=3",
       "stopping"},
      {"max_connections players", "players=10", "max_connections"},
      {"the last place has an upgrade on its way in", "players=9 handshakes=1", "max_connections"},
      {"max_handshakes upgrades waiting for their hello", "players=1 handshakes=4",
       "max_handshakes"},
      {"somebody waits in the queue: nobody passes it",
       "players=1 admission admitted=1 queued=1 max_players=5", "queue"},
      {"at max_players", "players=2 admission admitted=2 max_players=2", "max_players"},
      {"the last place under max_players has an upgrade on its way in",
       "players=1 handshakes=1 admission admitted=1 max_players=2", "max_players"},
      {"behind, nobody queued yet", "players=3 admission admitted=3 behind", "behind"},
      {"behind, queue and max_players: the queue is named first",
       "players=2 admission admitted=2 queued=1 max_players=2 behind", "queue"},
      {"max_players 0 is no bound", "players=7 admission admitted=7", "none"},
      {"this interval's burst budget is taken", "players=7 admission admitted=7 burst_left=0",
       "burst"},
      {"the budget's last places have upgrades on their way in",
       "players=1 handshakes=2 admission admitted=1 burst_left=2", "burst"},
      {"one place left in the budget, nobody on the way: taken",
       "players=1 admission admitted=1 burst_left=1", "none"},
      {"behind and the budget taken: behind is named first",
       "players=3 admission admitted=3 behind burst_left=0", "behind"},
      {"admission off: its state is not looked at", "players=2 queued=1 max_players=1 behind",
       "none"},
  };
  for (const RedirectRow& row : rows)
    EXPECT_EQ(redirect_name(redirect_newcomer(door_of(row.door))), row.reason) << row.name;
}

// The answer a balancer gets agrees with what the queue does with the next newcomer: sent on
// exactly when a hello now would not be admitted at once (no upgrade on its way in).
TEST(AdmissionRedirect, agrees_with_what_enter_would_do) {
  AdmissionConfig c = small();
  c.max_players = 2;
  c.max_queue = 10;
  const std::vector<std::vector<std::string>> scripts = {
      {},
      {"enter 1"},
      {"enter 1", "enter 2"},
      {"enter 1", "enter 2", "enter 3 q", "leave 1"},
      {"enter 1", "measure 300"},
      {"enter 1", "measure 300", "enter 2 q"},
      {"enter 1", "measure 300", "enter 2 q", "later 1000", "measure 0", "later 1000", "measure 0"},
      {"enter 1", "measure 300", "later 250", "measure 50", "later 1000", "measure 50"},
      {"measure 0", "enter 1", "leave 1", "enter 2", "leave 2"},
      {"measure 0", "enter 1", "leave 1", "enter 2", "leave 2", "later 250", "measure 0"},
  };
  for (const auto& script : scripts) {
    AdmissionQueue q(c);
    run(q, script);
    Door d;
    d.max_connections = 100;
    d.max_handshakes = 100;
    d.players = q.admitted();
    d.admission = true;
    d.admitted = q.admitted();
    d.queued = q.queued();
    d.max_players = q.config().max_players;
    d.behind = q.behind();
    d.burst_left = q.burst_left();
    const Redirect r = redirect_newcomer(d);
    auto entered = q.enter(99, true, AdmissionTime{} + std::chrono::hours{1});
    ASSERT_TRUE(entered);
    const bool admitted = std::holds_alternative<adm::Admit>(*entered);
    std::string joined;
    for (const auto& e : script)
      joined += e + "; ";
    EXPECT_EQ(r == Redirect::kNone, admitted) << joined << "-> " << redirect_name(r);
  }
}

}  // namespace
}  // namespace grotto::server
