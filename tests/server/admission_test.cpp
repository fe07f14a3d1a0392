// Admission past capacity without sockets (server/admission.hpp): each row feeds the queue a
// script of events on a simulated clock and checks the actions it returned, as lines of text.
// Events: "enter 3 q" (session 3 said hello and can wait in the queue), "enter 3" (it cannot),
// "leave 3", "measure 300" (the oldest urgent want is 300 ms old), "measure 0 backlog=9000",
// "later 500" (the clock moves on).
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
      uint64_t id = 0;
      std::string flag;
      in >> id >> flag;
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
  AdmissionQueue q(small());
  run(q, {"enter 1", "enter 2", "enter 3", "measure 100", "measure 400", "enter 4 q"});
  EXPECT_TRUE(q.behind());
  EXPECT_EQ(q.capacity(), 3u);
  EXPECT_EQ(q.admitted(), 3u);
  EXPECT_EQ(q.queued(), 1u);
}

}  // namespace
}  // namespace grotto::server
