// The simulated network (client/stream/net_sim.hpp): the --net profile's text, and
// when a link delivers what it is handed: half the round trip, jitter that never reorders, the
// downlink's cap, stalls.
#include <gtest/gtest.h>

#include <string>

#include "client/stream/net_sim.hpp"

namespace grotto::stream {
namespace {

using std::chrono::microseconds;
using std::chrono::milliseconds;
using Time = NetLink::Time;

double ms_between(Time a, Time b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

TEST(NetProfile, parses_every_part_and_prints_it_back) {
  auto p = parse_net_profile("rtt=150ms,jitter=20ms,kbps=2000,stall=0.5s/30s");
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_EQ(p->rtt, milliseconds(150));
  EXPECT_EQ(p->jitter, milliseconds(20));
  EXPECT_EQ(p->kbps, 2000u);
  EXPECT_EQ(p->stall, milliseconds(500));
  EXPECT_EQ(p->stall_every, milliseconds(30000));
  EXPECT_TRUE(p->active());
  EXPECT_EQ(net_profile_text(*p), "rtt=150ms,jitter=20ms,kbps=2000,stall=500ms/30s");
  auto again = parse_net_profile(net_profile_text(*p));
  ASSERT_TRUE(again);
  EXPECT_EQ(again->stall, p->stall);
  // Parts are optional, in any order.
  auto q = parse_net_profile("kbps=512,rtt=0.3s");
  ASSERT_TRUE(q);
  EXPECT_EQ(q->rtt, milliseconds(300));
  EXPECT_EQ(q->jitter.count(), 0);
  EXPECT_FALSE(parse_net_profile("")->active());
  EXPECT_FALSE(parse_net_profile("off")->active());
}

TEST(NetProfile, refuses_what_is_not_a_profile_naming_the_part) {
  for (const char* bad :
       {"rtt=150", "rtt=-5ms", "rtt=abcms", "kbps=0", "kbps=1.5", "stall=1s", "stall=2s/1s",
        "stall=0s/10s", "loss=1%", "rtt", "rtt=1ms,rtt=2ms", "rtt=150ms,,kbps=1"}) {
    auto p = parse_net_profile(bad);
    EXPECT_FALSE(p) << bad;
    if (!p) {
      EXPECT_NE(p.error().message.find("--net"), std::string::npos) << p.error().message;
    }
  }
  EXPECT_NE(parse_net_profile("loss=1%").error().message.find("unknown part 'loss'"),
            std::string::npos);
}

TEST(NetLink, delivers_after_half_the_round_trip) {
  NetProfile p;
  p.rtt = milliseconds(150);
  const Time t0{};
  NetLink link(p, true, t0, 1);
  EXPECT_DOUBLE_EQ(ms_between(t0, link.arrival(t0, 100)), 75.0);
  EXPECT_DOUBLE_EQ(ms_between(t0, link.arrival(t0 + milliseconds(10), 100)), 85.0);
}

TEST(NetLink, the_downlink_cap_spaces_messages_by_their_size) {
  NetProfile p;
  p.kbps = 1000;  // 125 bytes a millisecond
  const Time t0{};
  NetLink down(p, true, t0, 1);
  // Three 12,500-byte frames handed over at once: 100 ms of wire each, one after the other.
  EXPECT_NEAR(ms_between(t0, down.arrival(t0, 12'500)), 100.0, 1e-6);
  EXPECT_NEAR(ms_between(t0, down.arrival(t0, 12'500)), 200.0, 1e-6);
  EXPECT_NEAR(ms_between(t0, down.arrival(t0, 12'500)), 300.0, 1e-6);
  // Once the link is idle again, a message waits for no earlier one.
  EXPECT_NEAR(ms_between(t0, down.arrival(t0 + milliseconds(1000), 125)), 1001.0, 1e-6);
  // The uplink is not capped (the cap is what the player receives).
  NetLink up(p, false, t0, 1);
  EXPECT_NEAR(ms_between(t0, up.arrival(t0, 1'000'000)), 0.0, 1e-6);
}

TEST(NetLink, jitter_delays_but_never_reorders) {
  NetProfile p;
  p.rtt = milliseconds(100);
  p.jitter = milliseconds(40);
  const Time t0{};
  NetLink link(p, true, t0, 42);
  Time last = t0;
  double lo = 1e9, hi = 0;
  for (int i = 0; i < 2000; ++i) {
    const Time sent = t0 + microseconds(500 * i);  // a message every 0.5 ms, closer than jitter
    const Time got = link.arrival(sent, 10);
    ASSERT_GE(got, last) << "message " << i << " overtook the one before it";
    last = got;
    const double delay = ms_between(sent, got);
    lo = std::min(lo, delay);
    hi = std::max(hi, delay);
  }
  EXPECT_GE(lo, 50.0);
  EXPECT_GT(hi, 80.0);  // the jitter is there (delays spread over 50-90 ms and more behind others)
}

TEST(NetLink, a_stall_holds_what_would_travel_during_it) {
  NetProfile p;
  p.rtt = milliseconds(20);
  p.stall = milliseconds(500);
  p.stall_every = milliseconds(10'000);
  const Time t0{};
  NetLink link(p, true, t0, 1);
  // Before the first period is over: no stall.
  EXPECT_NEAR(ms_between(t0, link.arrival(t0 + milliseconds(5000), 10)), 5010.0, 1e-6);
  // Handed over during the stall at 10 s: leaves when it ends.
  EXPECT_NEAR(ms_between(t0, link.arrival(t0 + milliseconds(10'100), 10)), 10'510.0, 1e-6);
  // Travelling into the stall (sent at 9.995 s, due at 10.005 s): held to its end.
  NetLink other(p, true, t0, 1);
  EXPECT_NEAR(ms_between(t0, other.arrival(t0 + milliseconds(9995), 10)), 10'500.0, 1e-6);
  // And the next period's stall, at 20 s.
  EXPECT_NEAR(ms_between(t0, other.arrival(t0 + milliseconds(20'200), 10)), 20'510.0, 1e-6);
}

}  // namespace
}  // namespace grotto::stream
