// The Runtime's decode queue (client/stream/decode_queue.hpp): the frame due soonest is decoded
// next, whichever Stream queued it and however much prefetch waits ahead of it. Run ordered and
// unordered (first in, first out, as Runtimes once did): the two must differ.
#include "client/stream/decode_queue.hpp"

#include <gtest/gtest.h>

#include <string>
#include <thread>
#include <vector>

namespace grotto::stream {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

std::vector<std::string> run(bool ordered) {
  DecodeQueue q(ordered);
  std::vector<std::string> done;
  const auto t0 = Clock::now();
  auto push = [&](const std::string& name, int due_ms) {
    q.push(t0 + milliseconds(due_ms), [&done, name] { done.push_back(name); });
  };
  // Three players' far prefetch, then one player's next room, then a tie.
  push("far-a", 3000);
  push("far-b", 2500);
  push("far-c", 3800);
  push("next", 200);
  push("far-b2", 2500);
  EXPECT_EQ(q.size(), 5u);
  while (auto job = q.pop())
    job();
  EXPECT_EQ(q.size(), 0u);
  return done;
}

TEST(DecodeQueue, the_next_room_overtakes_queued_prefetch) {
  const auto ordered = run(true);
  const auto fifo = run(false);
  EXPECT_EQ(ordered, (std::vector<std::string>{"next", "far-b", "far-b2", "far-a", "far-c"}));
  EXPECT_EQ(fifo, (std::vector<std::string>{"far-a", "far-b", "far-c", "next", "far-b2"}));
}

TEST(DecodeQueue, pop_on_empty_is_an_empty_job_and_pushes_from_threads_all_arrive) {
  DecodeQueue q;
  EXPECT_FALSE(q.pop());
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&q, t] {
      for (int i = 0; i < 100; ++i)
        q.push(Clock::now() + milliseconds(i * 4 + t), [] {});
    });
  }
  for (auto& t : threads)
    t.join();
  EXPECT_EQ(q.size(), 400u);
  int popped = 0;
  while (q.pop())
    ++popped;
  EXPECT_EQ(popped, 400);
}

}  // namespace
}  // namespace grotto::stream
