// A simulated player for grotto-load: it walks the portal graph the way a person exploring the
// cave would, from portal centre to portal centre in straight lines (both lie inside the room's
// sphere, so the segment does too), runs in bursts, sometimes turns back (which is what makes a
// client cancel prefetched rooms), and stops at a portal whose room is not ready yet: a *stall*,
// the one thing a player of a streamed world must never see.
//
// No threads and no network: the Walker sees the world only through a WorldView, so the tests
// drive it over an in-process layout (common/cave) and grotto-load over a stream::Stream. Not
// thread-safe; deterministic for a given seed, view and sequence of advance() steps.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <vector>

#include "client/stream/portal_graph.hpp"
#include "common/cave/layout.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/vec3.hpp"

namespace grotto::load {

// grotto-load is a client of client/stream through and through: its names read unqualified.
using namespace grotto::stream;  // NOLINT(google-build-using-namespace)

// What a player knows of the world. descriptor: the room's sphere and portals once received
// (nullopt before); ready: the room can be drawn (decoded and stored). Both are called from
// advance() only.
struct WorldView {
  std::function<std::optional<cave::Room>(cave::RoomId)> descriptor;
  std::function<bool(cave::RoomId)> ready;
};

// How a walker moves. Brace-init gives a person walking (4 m/s) with occasional sprints.
struct WalkerOptions {
  double speed = 4.0;         // m/s, walking
  double burst_factor = 2.5;  // running speed = speed × burst_factor
  double burst_rate = 0.05;   // bursts started per second of walking (Poisson)
  double burst_min_s = 2.0;   // a burst lasts uniformly between these
  double burst_max_s = 5.0;
  double turn_back_chance = 0.1;  // per room entered: turn round part-way and go back
  // A player fades in: it starts walking once the start room's neighbours are ready too (a game
  // shows its first frame when what the player can reach at once is there), or after this many
  // seconds of the start room alone. Without it a spawn point near a portal is a stall at once.
  double start_wait_s = 2.0;
};

enum class WalkerState {
  kWaiting,  // placed, but the start room (or its neighbours: start_wait_s) is not ready yet;
             // or not placed
  kWalking,  // moving towards the target portal
  kStalled,  // at the target portal; the room behind it is not ready
};
const char* walker_state_name(WalkerState state);

struct WalkerStats {
  std::optional<double> first_room_s;  // time from the first advance() to the start room ready
  uint64_t rooms_entered = 0;          // portals crossed
  uint64_t turn_backs = 0;             // chosen reversals (turn_back_chance)
  uint64_t dead_ends = 0;              // rooms left by the only portal, the one entered by
  uint64_t bursts = 0;                 // sprints started
  double distance_m = 0;               // metres walked
  std::vector<double> stalls_s;        // durations of finished stalls, in order
};

class Walker {
 public:
  Walker(WorldView view, const WalkerOptions& options, uint64_t seed);

  // Where the player starts (a spawn point, or a chosen room's centre). Until then, and until the
  // start room is ready with its descriptor known, the walker waits.
  void place(cave::RoomId room, Vec3 position);
  bool placed() const { return room_.has_value(); }

  // Simulates `dt` seconds (dt ≥ 0). A step may cross several portals at high speed.
  void advance(double dt);

  // The pose for Stream::set_pose: position, forward = direction of travel (the last one while
  // standing), speed = the current walking or running speed, room = the current room.
  Pose pose() const;

  WalkerState state() const { return state_; }
  std::optional<cave::RoomId> room() const { return room_; }
  std::optional<cave::RoomId> target() const;  // the room behind the portal walked to
  double time() const { return time_; }        // seconds simulated
  // The stall under way: how long so far (0 when not stalled).
  double open_stall_s() const { return state_ == WalkerState::kStalled ? time_ - stall_since_ : 0; }
  const WalkerStats& stats() const { return stats_; }

 private:
  // Enters `room` (known and ready) arriving from `from` (none at the start), picks the next
  // portal.
  void enter(const cave::Room& room, std::optional<cave::RoomId> from);
  void choose_portal(std::optional<cave::RoomId> from);
  void update_burst(double dt);
  double current_speed() const;

  WorldView view_;
  WalkerOptions options_;
  std::mt19937_64 rng_;

  WalkerState state_ = WalkerState::kWaiting;
  double time_ = 0;
  std::optional<cave::RoomId> room_;
  std::optional<cave::Room> current_;  // the current room's descriptor once ready
  Vec3 position_;
  Vec3 forward_{0, 0, -1};
  std::optional<cave::Portal> target_;  // the portal walked to (in the current room)
  // Walked to before the target: a dead end's centre, so that the walker goes into the room
  // before it leaves by the portal it came in by.
  std::optional<Vec3> waypoint_;
  std::optional<cave::RoomId> came_from_;
  // A planned reversal: after walking turn_after_m metres in this room, head back to came_from_.
  std::optional<double> turn_after_m_;
  double walked_in_room_m_ = 0;
  double burst_left_s_ = 0;
  double stall_since_ = 0;
  WalkerStats stats_;
};

}  // namespace grotto::load
