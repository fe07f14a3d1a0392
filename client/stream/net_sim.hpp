// A simulated network between a player and the server: latency each way, jitter that
// never reorders (TCP delivers in order), a bandwidth cap on what the player receives, and the
// link stalling for a moment now and then. Every figure Grotto had was measured on loopback (0 ms,
// no cap); players are 20-200 ms away on links of 1-20 Mbit/s. The kernel's netem needs root and a
// module these machines lack, so the simulation lives in the stream's own transport (stream.cpp
// holds each message until its link delivers it): the same code for grotto-load and
// grotto-client (`--net rtt=150ms,jitter=20ms,kbps=2000,stall=0.5s/30s`).
//
// Sans-I/O: NetLink answers when a message handed to it at `now` reaches the other end; it holds
// no clock, socket or thread, so tables of inputs test it.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/core/random.hpp"
#include "common/core/result.hpp"

namespace grotto::stream {

struct NetProfile {
  std::chrono::microseconds rtt{0};     // round trip: half of it each way
  std::chrono::microseconds jitter{0};  // each message up to this much later (uniform), in order
  uint32_t kbps = 0;  // what the player receives, kilobits (1000 bits) a second; 0: no cap
  std::chrono::microseconds stall{0};        // the link stops for this long...
  std::chrono::microseconds stall_every{0};  // ...once in every period this long (0: never)

  // Anything to simulate (a zero profile is loopback as it is).
  bool active() const {
    return rtt.count() > 0 || jitter.count() > 0 || kbps > 0 || stall.count() > 0;
  }
};

// "rtt=150ms,jitter=20ms,kbps=2000,stall=0.5s/30s": comma-separated parts, each optional, in any
// order, none twice; times with a unit (us, ms, s); kbps a whole number >= 1; stall a duration
// and a period (the period longer than the stall). "" and "off" are no simulation. Errors
// (kInvalidArgument) name the part and what was wrong.
Result<NetProfile> parse_net_profile(std::string_view text);
// The profile in parse_net_profile's form ("off" when inactive).
std::string net_profile_text(const NetProfile& profile);

// One direction of a simulated link, from the moment it opened (`start`, when the connection
// was made: stalls come one period after it, then every period). A message handed to it at `now`
// leaves once the link has sent what came before it (at the cap, `bytes` x 8 / kbps), travels
// rtt/2 plus its jitter, and never arrives before an earlier message. A stall holds everything
// that would travel or arrive during it until it ends.
class NetLink {
 public:
  using Time = std::chrono::steady_clock::time_point;
  // `capped`: whether the profile's kbps applies to this direction (the player's downlink).
  NetLink(const NetProfile& profile, bool capped, Time start, uint64_t seed);

  // When a message of `bytes` handed to the link at `now` arrives; never earlier than the
  // previous message's arrival.
  Time arrival(Time now, size_t bytes);

 private:
  // `t` moved past the stall that holds it, if any.
  Time after_stall(Time t) const;

  NetProfile profile_;
  bool capped_;
  Time start_;
  Time wire_free_;  // when the link has sent everything handed to it so far
  Time last_;       // the latest arrival so far
  Rng rng_;
};

}  // namespace grotto::stream
