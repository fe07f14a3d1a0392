// grotto-load --verify: checks every room the players receive, off the simulation thread so a
// slow check never delays a walker. Per player: verify_room on the room, verify_seam against
// each neighbour that player holds (each pair once), and the room added to the player's own
// PortalGraph, which refuses portals that disagree with a neighbour's side.
#pragma once
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "client/load/report.hpp"
#include "client/stream/portal_graph.hpp"
#include "client/stream/room_store.hpp"

namespace grotto::load {

// grotto-load is a client of client/stream through and through: its names read unqualified.
using namespace grotto::stream;  // NOLINT(google-build-using-namespace)

// The room `player` holds now, or nullptr. Called on the verifier's thread.
using RoomLookup = std::function<std::shared_ptr<const ReadyRoom>(int player, cave::RoomId id)>;

// The checks for one player, without a thread (the tests call it directly).
class PlayerVerifier {
 public:
  // Checks `room` and adds what it found to `report` (rooms_checked, seams_checked, failures,
  // first_failures up to kMaxMessages).
  void check(const ReadyRoom& room,
             const std::function<std::shared_ptr<const ReadyRoom>(cave::RoomId)>& neighbour,
             VerifyReport& report);
  static constexpr size_t kMaxMessages = 10;

 private:
  PortalGraph graph_;
  std::set<std::pair<uint64_t, uint64_t>> seams_;  // packed ids, smaller first
};

class Verifier {
 public:
  Verifier(int players, RoomLookup lookup);
  ~Verifier();  // finish()
  Verifier(const Verifier&) = delete;
  Verifier& operator=(const Verifier&) = delete;

  void push(int player, std::shared_ptr<const ReadyRoom> room);
  // Checks what is queued, stops the thread and returns the totals. Idempotent.
  VerifyReport finish();
  uint64_t failures() const;  // so far, for the progress line

 private:
  void run();

  RoomLookup lookup_;
  std::vector<PlayerVerifier> players_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::pair<int, std::shared_ptr<const ReadyRoom>>> queue_;
  bool stopping_ = false;
  VerifyReport report_;  // guarded by mutex_
  std::thread thread_;
};

}  // namespace grotto::load
