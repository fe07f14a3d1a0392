// The decodes waiting for a worker, most urgent first. Every Stream of a Runtime (grotto-load runs
// hundreds) hands its frames to the same few decode threads; taken in arrival order, the frame of
// the room a player is about to walk into waits behind every other player's far prefetch. Here a
// job carries when its room is due (the request's time + its priority: when the player can reach
// it) and workers take the earliest due first, ties in arrival order: urgent rooms go first at
// every stage.
//
// Thread-safe: any thread pushes, any worker pops.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <utility>

namespace grotto::stream {

class DecodeQueue {
 public:
  using Job = std::function<void()>;
  // `ordered` false: first in, first out (tests show the difference).
  explicit DecodeQueue(bool ordered = true) : ordered_(ordered) {}

  void push(std::chrono::steady_clock::time_point due, Job job);
  // The most urgent job, or an empty one when none waits.
  Job pop();
  size_t size() const;

 private:
  const bool ordered_;
  mutable std::mutex mu_;
  // By (due, arrival): the first entry is the most urgent.
  std::map<std::pair<std::chrono::steady_clock::time_point, uint64_t>, Job> jobs_;
  uint64_t next_seq_ = 0;
};

}  // namespace grotto::stream
